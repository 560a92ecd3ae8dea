"""The Newton solves of the adaptive loop's levels against the uniform run's, step by step.

Runs the adaptive loop on a scene (its defaults unless ``--set``) up to ``--max-dofs``, then
the uniform run on a mesh ``--uniform`` times finer than the scene's (``adapt=none``, grid
sequencing as by default), in this process, and prints per level (and per grid-sequencing
level of the uniform run): the DoFs, the linear solver, the Newton steps and polishing
solves, ‖Φ‖ at the start (after prolongation: the nested or sequenced guess) and at the
end, and the seconds of the solve (wall), of its Krylov solves and how many GAMG set-ups
they made; with ``--krylov`` every Krylov solve (its relative tolerance, iterations,
seconds, set-ups); with ``--history`` every Newton step (‖Φ‖, active nodes, how many
changed state, whether the step was polished).  Writes CSV (one row per level and per
sequencing level).

``--switch MODULE.NAME`` measures a module-level switch (``NAME = True`` the new path,
``False`` the old one): the loop (and the uniform run, if any) runs ``--pairs`` times with
the switch off, then on, alternating in this process, and prints per pair the loop's CPU
seconds to its last level old/new, whether both made the same levels, and the largest
relative difference of their energy errors.

    python demos/bench/bench_level_solves.py ex9 --max-dofs 1400000 --uniform 64 \\
        --set adapt.growth=3 adapt.indicators=residual adapt.tol=4e-3
    python demos/bench/bench_level_solves.py ex9 --max-dofs 400000 --uniform 0 \\
        --set adapt.growth=3 adapt.indicators=residual adapt.tol=4e-3 --krylov

    python demos/bench/bench_level_solves.py ex9 --max-dofs 1400000 --pairs 2 \\
        --set adapt.growth=3 adapt.indicators=residual adapt.tol=4e-3 \\
        --switch contact.solvers.snes.ADMISSIBLE_GUESS

Scenes: ``ex9`` (configs/peers/petsc_ex9.yaml), ``A`` (configs/signorini_free_boundary.yaml),
``lshape`` (configs/lshape_corner.yaml) or a path.
"""

from __future__ import annotations

import argparse
import importlib
import time
from pathlib import Path

import contact
from contact.adaptivity.energy_error import solution_error
from contact.setup import run as loop

from common import save_csv

ROOT = Path(__file__).resolve().parents[2]
SCENES = {
    "ex9": "configs/peers/petsc_ex9.yaml",
    "A": "configs/signorini_free_boundary.yaml",
    "lshape": "configs/lshape_corner.yaml",
}


def solve_row(run: str, level: int, result, error: float | None, seconds: float) -> dict:
    """The figures of one solve: its Newton steps, residuals and Krylov solves."""
    history = result.history
    log = result.krylov_log
    return {
        "run": run,
        "level": level,
        "dofs": result.dofs,
        "error": error if error is not None else "",
        "linear": result.linear,
        "newton_iterations": result.iterations,
        "polish_solves": result.polish_solves,
        "phi_start": history[0]["residual"] if history else "",
        "phi_end": result.residual,
        "stopping": "adaptive" if result.stopping is not None else "fixed",
        "seconds_solve": round(seconds, 4),
        "krylov_solves": len(log),
        "krylov_iterations": result.krylov_iterations,
        "krylov_seconds": round(sum(k["seconds"] for k in log), 4),
        "gamg_setups": sum(k.get("setups", 0) for k in log),
    }


def show(row: dict, krylov: list[dict] | None = None) -> None:
    """Print a row (and, given, its Krylov solves)."""
    error = f"{row['error']:.4e}" if row["error"] != "" else "-"
    phi0 = f"{row['phi_start']:.2e}" if row["phi_start"] != "" else "-"
    parts = [
        f"{row['run']:>8s} L{row['level']:<2d} {row['dofs']:9d} DoFs err {error:>10s}",
        f"{row['linear']:>6s} {row['newton_iterations']}+{row['polish_solves']}",
        f"({row['stopping']}) |Phi| {phi0} -> {row['phi_end']:.2e}",
        f" solve {row['seconds_solve']:.2f} s, Krylov {row['krylov_solves']} solves",
        f"{row['krylov_iterations']} its {row['krylov_seconds']:.2f} s",
        f"{row['gamg_setups']} set-ups",
    ]
    print("  " + " ".join(parts), flush=True)
    for k in krylov or []:
        rtol, its, seconds = k["rtol"], k["iterations"], k["seconds"]
        setups, fixed = k.get("setups", 0), k.get("fixed_rows", "")
        print(f"      rtol {rtol:.1e} its {its:3d} {seconds:.3f} s set-ups {setups} fixed {fixed}")


def show_history(result) -> None:
    """Print a solve's Newton steps: ‖Φ‖, active nodes, changes, polished."""
    for h in result.history:
        polished = " polished" if h["polished"] else ""
        print(
            f"      it {h['iteration']:2d} |Phi| {h['residual']:.3e} active {h['active']:8d} "
            f"changed {h['changed']:6d}{polished}",
            flush=True,
        )


def adaptive_run(
    scene: contact.Scene, max_dofs: int, label: str, krylov: bool, history: bool = False
) -> list[dict]:
    """The loop's levels, a row each (earlier levels released as it goes)."""
    rows: list[dict] = []

    def on_level(level) -> None:
        row = solve_row(label, level.index, level.result, level.error, level.seconds["solve"])
        row["cpu_cumulative"] = round(level.cpu, 4)
        row["eta"] = level.estimate.eta
        rows.append(row)
        show(row, level.result.krylov_log if krylov else None)
        if history:
            show_history(level.result)

    out = loop.adapt(scene, on_level=on_level, max_dofs=max_dofs, keep=lambda level: False)
    print(f"  {label}: {out.stop}", flush=True)
    return rows


def uniform_run(
    path: Path, factor: int, sets: list[str], krylov: bool, history: bool = False, label: str = ""
) -> list[dict]:
    """The uniform run on a mesh ``factor`` times finer: its sequencing levels and its solve."""
    base = contact.load_scene(path, ["output.verbose=false", "adapt=none", *sets])
    cells = base.config.mesh.cells
    scaled = cells * factor if isinstance(cells, int) else [c * factor for c in cells]
    scene = contact.load_scene(
        path, ["output.verbose=false", "adapt=none", *sets, f"mesh.cells={scaled}"]
    )
    wall, cpu = time.perf_counter(), time.process_time()
    result = contact.solve(scene, verbose=False)
    error = solution_error(result.problem, result)
    cpu = time.process_time() - cpu
    rows = []
    for k, lv in enumerate(result.sequence):
        row = {"run": "sequence", "level": k, "dofs": lv.dofs, "linear": lv.linear}
        row.update(newton_iterations=lv.newton_iterations, polish_solves=lv.polish_solves)
        row.update(krylov_iterations=lv.krylov_iterations, seconds_solve=round(lv.seconds, 4))
        rows.append(row)
        print(
            f"  sequence L{k:<2d} {lv.dofs:9d} DoFs {lv.linear:>6s} "
            f"{lv.newton_iterations}+{lv.polish_solves} {lv.seconds:.2f} s",
            flush=True,
        )
    timings = result.timings
    row = solve_row(f"uniform{label}", factor, result, error, timings["solve"])
    row["cpu_cumulative"] = round(cpu, 4)
    row["seconds_coarse"] = round(timings.get("coarse", 0.0), 4)
    rows.append(row)
    show(row, result.krylov_log if krylov else None)
    if history:
        show_history(result)
    print(
        f"  uniform ×{factor}: {time.perf_counter() - wall:.2f} s wall {cpu:.2f} s CPU "
        f"(assembly {timings['assembly']:.2f}, coarse levels {timings.get('coarse', 0):.2f}, "
        f"solve {timings['solve']:.2f})",
        flush=True,
    )
    result.release()
    return rows


def set_switch(name: str, value: bool) -> None:
    """Set the module-level switch ``name`` (``package.module.NAME``), which must exist."""
    module, _, attr = name.rpartition(".")
    mod = importlib.import_module(module)
    if not isinstance(getattr(mod, attr, None), bool):
        raise SystemExit(f"--switch: {name} is not a module-level True/False switch")
    setattr(mod, attr, value)


def compare(old: list[dict], new: list[dict]) -> dict:
    """One pair's figures: the loop's CPU seconds to its last level old and new and their
    ratio, whether both made the same levels (their DoFs), the largest relative difference of
    their energy errors and of their η, and each run's linear solves (Newton + polishing)."""
    same = [r["dofs"] for r in old] == [r["dofs"] for r in new]

    def rel(key: str) -> float:
        pairs = [(a[key], b[key]) for a, b in zip(old, new) if a[key] != "" and b[key] != ""]
        return max((abs(a - b) / abs(a) for a, b in pairs if a), default=0.0)

    def solves(rows: list[dict]) -> int:
        return sum(r["newton_iterations"] + r["polish_solves"] for r in rows)

    cpu_old, cpu_new = old[-1]["cpu_cumulative"], new[-1]["cpu_cumulative"]
    return {
        "cpu_old": cpu_old,
        "cpu_new": cpu_new,
        "ratio": cpu_old / cpu_new if cpu_new else float("nan"),
        "same_levels": same,
        "error_rel_diff": rel("error") if same else float("nan"),
        "eta_rel_diff": rel("eta") if same else float("nan"),
        "solves_old": solves(old),
        "solves_new": solves(new),
    }


def switch_runs(args, path: Path, scene: contact.Scene) -> list[dict]:
    """The loop (and the uniform run) with ``args.switch`` off and on, alternating."""
    rows: list[dict] = []
    for pair in range(args.pairs):
        runs = {}
        for value, tag in ((False, "old"), (True, "new")):
            set_switch(args.switch, value)
            runs[tag] = adaptive_run(scene, args.max_dofs, f"loop-{tag}", args.krylov, args.history)
            rows += runs[tag]
            if args.uniform:
                sets = [s for s in args.overrides if not s.startswith("adapt.")]
                rows += uniform_run(path, args.uniform, sets, args.krylov, args.history, f"-{tag}")
        c = compare(runs["old"], runs["new"])
        print(
            f"  pair {pair}: loop CPU old {c['cpu_old']:.2f} s new {c['cpu_new']:.2f} s, "
            f"old/new {c['ratio']:.3f}; linear solves {c['solves_old']} -> {c['solves_new']}; "
            f"same levels {c['same_levels']}, errors differ by {c['error_rel_diff']:.1e}, "
            f"eta by {c['eta_rel_diff']:.1e} (relative)",
            flush=True,
        )
        rows.append({"run": "pair", "level": pair, **c})
    set_switch(args.switch, True)
    return rows


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("scene", help=", ".join(SCENES) + " or a path")
    ap.add_argument("--max-dofs", type=int, default=400_000)
    ap.add_argument("--set", dest="overrides", nargs="*", default=[], metavar="KEY=VALUE")
    ap.add_argument(
        "--uniform", type=int, default=0, help="the uniform mesh's factor (0: no uniform run)"
    )
    ap.add_argument("--krylov", action="store_true", help="print every Krylov solve")
    ap.add_argument("--history", action="store_true", help="print every Newton step")
    ap.add_argument(
        "--switch", default=None, metavar="MODULE.NAME", help="a switch to measure old/new"
    )
    ap.add_argument("--pairs", type=int, default=2, help="old/new pairs with --switch")
    ap.add_argument("--out", default=None, help="CSV file")
    args = ap.parse_args()
    path = ROOT / SCENES.get(args.scene, args.scene)
    rows: list[dict] = []
    warm = contact.load_scene(path, ["output.verbose=false", "adapt=none"])
    contact.solve(warm, verbose=False).release()  # JIT cache and first-call costs
    scene = contact.load_scene(path, ["output.verbose=false", *args.overrides])
    if args.switch:
        set_switch(args.switch, True)  # checked before any run
        rows += switch_runs(args, path, scene)
    else:
        rows += adaptive_run(scene, args.max_dofs, "loop", args.krylov, args.history)
        if args.uniform:
            sets = [s for s in args.overrides if not s.startswith("adapt.")]
            rows += uniform_run(path, args.uniform, sets, args.krylov, args.history)
    if args.out:
        save_csv(args.out, rows)


if __name__ == "__main__":
    main()
