"""The guaranteed bound's CPU on the last level of an adaptive loop, its default paths against
the plain ones, in turn in one process, and against the level's solve.

Runs the scene's adaptive loop (default ex9, growth 2, the residual indicators marking: the
loop of the time-to-accuracy runs) up to ``--max-dofs``, then computes the equilibrated bound
of its last level ``--repeat`` times with the plain paths (each switch of :data:`SWITCHES`
False) and with the default ones, alternately, and prints the CPU seconds of each, their
ratio (default / plain, median of the pairs) and the ratio to the CPU seconds of the level's
solve in the loop, and the resident memory the bound adds at its peak (sampled every 2 ms,
above the process's before it).  The bounds must agree bit for bit (η, η_T, the terms; else exit 1).
Writes CSV.

    python demos/bench/bench_bound_cost.py --max-dofs 300000 \\
        --out demos/results/adaptive_cost/bound_cost_ex9_250k.csv
    python demos/bench/bench_bound_cost.py --max-dofs 1100000 --repeat 2 \\
        --out demos/results/adaptive_cost/bound_cost_ex9_1M.csv
"""

from __future__ import annotations

import argparse
import importlib
import statistics
import sys
import threading
import time
from pathlib import Path

import contact
from contact.adaptivity.equilibration.bound import guaranteed_bound
from contact.base.lifetime import return_freed_memory, rss_mib
from contact.setup import run as loop

import numpy as np
from common import count_phase_cpu, save_csv

ROOT = Path(__file__).resolve().parents[2]
SCENES = {"ex9": "configs/peers/petsc_ex9.yaml", "A": "configs/signorini_free_boundary.yaml"}
#: the bound's switches whose False is the plain path (module, name)
SWITCHES = (
    ("contact.adaptivity.equilibration.flux", "NODAL_MULTIPLIER"),
    ("contact.adaptivity.equilibration.cells", "VERTEX_NODES"),
    ("contact.adaptivity.equilibration.bound", "DIRICHLET_SUBMESH"),
    ("contact.adaptivity.equilibration.bound", "DIRICHLET_ON_SUBMESH"),
    ("contact.adaptivity.equilibration.flux", "UNIT_KAPPA"),
)


class Peak:
    """The largest resident set size (MiB) while ``with`` it, sampled by a thread."""

    def __enter__(self) -> Peak:
        self.before = self.peak = rss_mib()
        self.running = True
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()
        return self

    def _run(self) -> None:
        while self.running:
            self.peak = max(self.peak, rss_mib())
            time.sleep(0.002)

    def __exit__(self, *exc) -> None:
        self.running = False
        self.thread.join()
        self.peak = max(self.peak, rss_mib())


def switch(on: bool) -> None:
    """Set every switch of :data:`SWITCHES` to ``on``."""
    for module, name in SWITCHES:
        setattr(importlib.import_module(module), name, on)


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("scene", nargs="?", default="ex9", help=f"one of {', '.join(SCENES)} or a file")
    ap.add_argument("--max-dofs", type=int, default=300_000)
    ap.add_argument("--repeat", type=int, default=3, help="bounds of each path, in turn")
    ap.add_argument(
        "--set",
        dest="overrides",
        nargs="*",
        default=["adapt.growth=2", "adapt.indicators=residual", "adapt.max_levels=40"],
        metavar="KEY=VALUE",
    )
    ap.add_argument("--out", default=None, help="CSV file")
    args = ap.parse_args()
    path = ROOT / SCENES.get(args.scene, args.scene)
    scene = contact.load_scene(path, ["output.verbose=false", *args.overrides])
    cpu = count_phase_cpu()
    solve_cpu: list[float] = []

    def on_level(level) -> None:
        solve_cpu.append(cpu.pop("solve", 0.0))
        cpu.clear()

    run = loop.adapt(scene, on_level=on_level, max_dofs=args.max_dofs, keep=lambda level: False)
    last = run.levels[-1]
    problem, result = last.problem, last.result
    print(
        f"{args.scene}: {len(run.levels)} levels, last {result.dofs} DoFs, its solve "
        f"{solve_cpu[-1]:.2f} s CPU ({run.stop})",
        flush=True,
    )
    rows, first = [], None
    for r in range(args.repeat):
        for path_name, on in (("plain", False), ("default", True)):
            switch(on)
            return_freed_memory()  # as the loop does before its bound
            with Peak() as peak:
                c = time.process_time()
                bound = guaranteed_bound(problem, result)
                seconds = time.process_time() - c
            key = (bound.eta, bound.eta_T.x.array.copy(), dict(bound.terms))
            del bound
            if first is None:
                first = key
            same = key[0] == first[0] and np.array_equal(key[1], first[1]) and key[2] == first[2]
            rows.append(
                {
                    "scene": args.scene,
                    "dofs": result.dofs,
                    "run": r,
                    "path": path_name,
                    "bound_cpu": round(seconds, 3),
                    "peak_added_mib": round(peak.peak - peak.before, 1),
                    "solve_cpu": round(solve_cpu[-1], 3),
                    "eta": key[0],
                    "same_as_first": same,
                }
            )
            print(
                f"  run {r} {path_name:7s} bound {seconds:.2f} s CPU, peak +"
                f"{peak.peak - peak.before:.0f} MiB, eta {key[0]!r}"
                f"{'' if same else '  DIFFERS'}",
                flush=True,
            )
    switch(True)
    plain = [x["bound_cpu"] for x in rows if x["path"] == "plain"]
    default = [x["bound_cpu"] for x in rows if x["path"] == "default"]
    ratio = statistics.median(d / p for d, p in zip(default, plain, strict=True))
    print(
        f"bound CPU at {result.dofs} DoFs: plain {statistics.median(plain):.2f} s (min "
        f"{min(plain):.2f}), default {statistics.median(default):.2f} s (min {min(default):.2f});"
        f" default / plain {ratio:.3f} (median of {len(plain)} pairs); the level's solve "
        f"{solve_cpu[-1]:.2f} s: bound / solve plain {statistics.median(plain) / solve_cpu[-1]:.2f}"
        f", default {statistics.median(default) / solve_cpu[-1]:.2f}",
        flush=True,
    )
    if args.out:
        save_csv(args.out, rows)
    if not all(x["same_as_first"] for x in rows):
        print("the paths' bounds differ", file=sys.stderr)
        sys.exit(1)


if __name__ == "__main__":
    main()
