"""Time to accuracy: the adaptive loop against uniform meshes, at equal energy error.

For each scene with an exact solution: the adaptive loop (the scene's ``adapt`` section,
``--set`` overrides) records the wall seconds from its start to each level's energy error
(``Level.elapsed``, outputs not counted); the uniform reference solves the scene once on
meshes 1, 2, 4, … times finer than the scene's (``mesh.cells`` scaled, ``adapt=none``, grid
sequencing as by default) and records the seconds of each such run: mesh, solve and error —
the run a user who knew the mesh needed would make.  Both in this process, the uniform runs
first, after one warm-up solve (the JIT cache), so the ratio adaptive/uniform is of one
machine state.  At the target error e*: the seconds of the first adaptive level with
error ≤ e* against those of the coarsest uniform mesh with error ≤ e*, and the same at e*
exactly (log-log interpolation of seconds against error between the levels around it);
if one of the two stops short of e* (``--max-dofs``), at the smallest error both reached.
Prints a table, writes CSV (one row per level or uniform run, then one row per scene with
the ratios).

    python demos/bench/bench_time_to_accuracy.py --out demos/results/time_to_accuracy.csv
    python demos/bench/bench_time_to_accuracy.py ex9 --target 4e-3 --max-dofs 1300000
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

import contact
from contact.adaptivity.energy_error import solution_error

from common import save_csv

ROOT = Path(__file__).resolve().parents[2]
#: scene, file, target energy error of the default run (a few minutes on 2 loaded cores)
SCENES = {
    "ex9": ("configs/peers/petsc_ex9.yaml", 1e-2),
    "A": ("configs/signorini_free_boundary.yaml", 4e-3),
    "lshape": ("configs/lshape_corner.yaml", 4e-3),
}


def scaled_cells(scene: contact.Scene, factor: int) -> str:
    """The ``mesh.cells`` override of a mesh ``factor`` times finer in each direction."""
    cells = scene.config.mesh.cells
    if isinstance(cells, int):
        return f"mesh.cells={cells * factor}"
    return f"mesh.cells=[{', '.join(str(c * factor) for c in cells)}]"


def uniform(path: Path, target: float, max_dofs: int, sets: list[str]) -> list[dict]:
    """Single solves on meshes 1, 2, 4, … times finer until one reaches ``target`` (or the
    next would exceed ``max_dofs``): a row each with its wall and CPU seconds (mesh + solve
    + error)."""
    sets = [s for s in sets if not s.startswith("adapt.")]  # the loop's options
    base = contact.load_scene(path, ["output.verbose=false", "adapt=none", *sets])
    rows, factor = [], 1
    while True:
        t0, c0 = time.perf_counter(), time.process_time()
        scene = contact.load_scene(
            path, ["output.verbose=false", "adapt=none", *sets, scaled_cells(base, factor)]
        )
        result = contact.solve(scene, verbose=False)
        error = solution_error(result.problem, result)
        seconds, cpu = time.perf_counter() - t0, time.process_time() - c0
        assert result.converged and error is not None, (path, factor)
        rows.append({"run": "uniform", "level": factor, "dofs": result.dofs, "error": error})
        rows[-1].update(seconds=round(seconds, 4), cpu=round(cpu, 4))
        print(
            f"  uniform ×{factor:<3d} {result.dofs:9d} DoFs  error {error:.3e}  "
            f"{seconds:7.2f} s wall {cpu:7.2f} s CPU",
            flush=True,
        )
        result.release()
        if error <= target or 4 * result.dofs > max_dofs:
            return rows
        factor *= 2


class Reached(Exception):
    """A level reached the target error: the loop stops there."""


def adaptive(path: Path, target: float, max_dofs: int, sets: list[str]) -> list[dict]:
    """The adaptive loop until a level reaches ``target`` (earlier levels released as it
    goes): a row per level with the loop's wall seconds (``Level.elapsed``) and CPU seconds
    up to it."""
    scene = contact.load_scene(path, ["output.verbose=false", *sets])
    rows: list[dict] = []
    c0 = time.process_time()

    def on_level(level) -> None:
        cpu = time.process_time() - c0
        rows.append({"run": "adaptive", "level": level.index, "dofs": level.result.dofs})
        rows[-1].update(error=level.error, seconds=round(level.elapsed, 4), cpu=round(cpu, 4))
        print(
            f"  adaptive L{level.index:<3d} {level.result.dofs:8d} DoFs  error "
            f"{level.error:.3e}  {level.elapsed:7.2f} s wall {cpu:7.2f} s CPU",
            flush=True,
        )
        if level.error <= target:  # reached: no finer level
            raise Reached

    try:
        contact.adapt(
            scene,
            tol=0.0,
            max_levels=80,
            max_dofs=max_dofs,
            keep=lambda lv: False,
            on_level=on_level,
        )
    except Reached:
        pass
    return rows


def first_reaching(rows: list[dict], target: float, clock: str = "seconds") -> float:
    """Seconds (``clock``: wall ``seconds`` or ``cpu``) of the first row with error ≤ target
    (inf if none)."""
    return next((r[clock] for r in rows if r["error"] <= target), math.inf)


def at_error(rows: list[dict], target: float, clock: str = "seconds") -> float:
    """Seconds at error = target exactly: log-log interpolation between the last row above
    and the first at or below it (inf if no row reaches it)."""
    for above, below in zip(rows, rows[1:]):
        if above["error"] > target >= below["error"]:
            s = math.log(above["error"] / target) / math.log(above["error"] / below["error"])
            return math.exp((1 - s) * math.log(above[clock]) + s * math.log(below[clock]))
    return first_reaching(rows[:1], target, clock)


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("scenes", nargs="*", default=list(SCENES), help=", ".join(SCENES))
    ap.add_argument("--target", type=float, default=None, help="energy error e* (per scene)")
    ap.add_argument("--max-dofs", type=int, default=600_000)
    ap.add_argument("--set", dest="overrides", nargs="*", default=[], metavar="KEY=VALUE")
    ap.add_argument("--out", default=None, help="CSV file")
    args = ap.parse_args()
    warm = contact.load_scene(ROOT / SCENES["ex9"][0], ["output.verbose=false", "adapt=none"])
    contact.solve(warm, verbose=False).release()  # JIT cache and first-call costs
    rows, summary = [], []
    for name in args.scenes:
        file, default_target = SCENES[name]
        target = args.target or default_target
        print(f"{name}: to energy error {target:.1e}")
        uni = uniform(ROOT / file, target, args.max_dofs, args.overrides)
        ada = adaptive(ROOT / file, target, args.max_dofs, args.overrides)
        rows += [{"scene": name, **r} for r in uni + ada]
        # at the target, or at the smallest error both reached (the uniform meshes stop
        # before max_dofs)
        error = max(target, *(min(r["error"] for r in run) for run in (uni, ada)))
        ratio = {"scene": name, "run": "ratio", "target": target, "error": error}
        for clock in ("seconds", "cpu"):
            first = first_reaching(ada, error, clock) / first_reaching(uni, error, clock)
            exact = at_error(ada, error, clock) / at_error(uni, error, clock)
            ratio[f"first_reaching_{clock}"] = round(first, 3)
            ratio[f"interpolated_{clock}"] = round(exact, 3)
            print(
                f"{name}: adaptive/uniform {'wall' if clock == 'seconds' else 'CPU'} seconds at "
                f"error {error:.2e}: {first:.2f} (first level reaching it), {exact:.2f} "
                "(interpolated to it)",
                flush=True,
            )
        summary.append(ratio)
    if args.out:
        save_csv(args.out, rows + summary)


if __name__ == "__main__":
    main()
