"""``contact run`` as a user runs it: an adaptive loop against a uniform run, whole processes.

Each run is a fresh process, ``python -m contact.app.cli run SCENE -o FOLDER -q --set …``:
its wall seconds from its start to its exit (start-up, scene, solves and files included),
its CPU seconds (user + system) and its peak resident memory, the operating system's
accounting of the finished child (``os.wait4``).  The two commands, A (``--a``) and B
(``--b``), run in turn, A B A B …, after one untimed run of each (bytecode and the forms'
JIT cache at hand), so that each pair's ratio A/B is of one machine state; the medians of
the runs and of the pairs' ratios are printed, with the DoFs and the energy error of each
command's last run (its summary.json).  Writes CSV: a row per run, then the medians.

By default A is PETSc's ex9 on a level budget — growth 3, the residual indicators marking,
8 levels, the last one not estimated (``adapt.estimate_last=false``), the files of the last
level only — and B the uniform run reaching the same energy error 4e-3 (the scene's 16 × 16
mesh 70 times finer: 1,256,641 DoFs, the mesh ``bench_time_to_accuracy.py`` finds), both
without pictures:

    python demos/bench/bench_run_wall.py --pairs 5 \\
        --out demos/results/adaptive_cost/run_wall_ex9.csv
    python demos/bench/bench_run_wall.py configs/lshape_corner.yaml --pairs 3 \\
        --a adapt.max_levels=10 --b adapt=none mesh.cells=64
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from common import save_csv

ROOT = Path(__file__).resolve().parents[2]
SCENE = "configs/peers/petsc_ex9.yaml"
#: the loop on a level budget, its last level not estimated (A)
LOOP = [
    "adapt.growth=3",
    "adapt.indicators=residual",
    "adapt.max_levels=8",
    "adapt.max_dofs=1400000",
    "adapt.estimate_last=false",
    "output.levels=last",
]
#: the uniform run to the same error (B)
UNIFORM = ["mesh.cells=[1120,1120]"]
#: both
COMMON = ["output.png=false"]


def run(scene: Path, folder: Path, sets: list[str]) -> dict:
    """One ``contact run`` in a fresh process: its wall and CPU seconds, peak memory, and
    what its summary.json says (DoFs, energy error, η).  Raises if it does not exit 0."""
    cmd = [sys.executable, "-m", "contact.app.cli", "run", str(scene), "-o", str(folder), "-q"]
    for item in sets:
        cmd += ["--set", item]
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    start = time.perf_counter()
    child = subprocess.Popen(cmd, cwd=ROOT, env=env, stdout=subprocess.DEVNULL)
    _, status, usage = os.wait4(child.pid, 0)
    wall = time.perf_counter() - start
    child.returncode = os.waitstatus_to_exitcode(status)
    if child.returncode != 0:
        raise SystemExit(f"exit {child.returncode}: {' '.join(cmd)}")
    summary = json.loads((folder / "summary.json").read_text())
    return {
        "wall": round(wall, 4),
        "cpu": round(usage.ru_utime + usage.ru_stime, 4),
        "sys": round(usage.ru_stime, 4),
        "peak_mib": round(usage.ru_maxrss / 1024, 1),  # KiB on Linux
        "dofs": summary["dofs"],
        "error": summary.get("error_energy"),
        "eta": summary.get("eta"),
        "levels": summary.get("levels", 1),
    }


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("scene", nargs="?", default=SCENE, help=f"scene file (default {SCENE})")
    ap.add_argument("--a", nargs="*", default=LOOP, metavar="KEY=VALUE", help="command A's sets")
    ap.add_argument("--b", nargs="*", default=UNIFORM, metavar="KEY=VALUE", help="command B's sets")
    ap.add_argument("--set", nargs="*", default=COMMON, metavar="KEY=VALUE", help="both")
    ap.add_argument("--pairs", type=int, default=5)
    ap.add_argument("--out", default=None, help="CSV file")
    args = ap.parse_args()
    scene = (ROOT / args.scene).resolve()
    commands = {"A": [*args.set, *args.a], "B": [*args.set, *args.b]}
    rows: list[dict] = []
    with tempfile.TemporaryDirectory(prefix="bench_run_wall_") as tmp:
        for name, sets in commands.items():  # untimed: bytecode and JIT cache
            run(scene, Path(tmp) / f"warm_{name}", sets)
        for pair in range(args.pairs):
            for name, sets in commands.items():
                row = {"run": name, "pair": pair, **run(scene, Path(tmp) / name, sets)}
                rows.append(row)
                print(
                    f"  pair {pair} {name}: {row['wall']:.2f} s wall {row['cpu']:.2f} s CPU "
                    f"(system {row['sys']:.2f}), peak {row['peak_mib']:.0f} MiB, "
                    f"{row['dofs']} DoFs, error {row['error']}",
                    flush=True,
                )
    print(f"A = {' '.join(commands['A'])}\nB = {' '.join(commands['B'])}")
    medians: dict = {"run": "median"}
    for key in ("wall", "cpu", "sys", "peak_mib"):
        for name in commands:
            medians[f"{name}_{key}"] = statistics.median(r[key] for r in rows if r["run"] == name)
        a = [r[key] for r in rows if r["run"] == "A"]
        b = [r[key] for r in rows if r["run"] == "B"]
        ratios = [x / y for x, y in zip(a, b)]
        medians[f"ratio_{key}"] = round(statistics.median(ratios), 4)
        medians[f"ratio_{key}_min"] = round(min(ratios), 4)
        medians[f"ratio_{key}_max"] = round(max(ratios), 4)
        print(
            f"{key}: A {medians[f'A_{key}']:.2f}, B {medians[f'B_{key}']:.2f} (medians); A/B "
            f"{medians[f'ratio_{key}']:.3f} (median of the pairs, {min(ratios):.3f} … "
            f"{max(ratios):.3f})",
            flush=True,
        )
    for name in commands:
        last = [r for r in rows if r["run"] == name][-1]
        medians.update({f"{name}_{k}": last[k] for k in ("dofs", "error", "eta", "levels")})
        medians[f"{name}_peak_b_per_dof"] = round(
            medians[f"{name}_peak_mib"] * 2**20 / last["dofs"]
        )
    medians["a_sets"], medians["b_sets"] = " ".join(commands["A"]), " ".join(commands["B"])
    medians["pairs"] = args.pairs
    rows.append(medians)
    print(
        f"A: {medians['A_dofs']} DoFs, error {medians['A_error']}; "
        f"B: {medians['B_dofs']} DoFs, error {medians['B_error']}"
    )
    if args.out:
        save_csv(args.out, rows)


if __name__ == "__main__":
    main()
