"""Time to accuracy: the adaptive loop against uniform meshes, at equal energy error.

For each scene with an exact solution: the adaptive loop in each variant (``--variant
NAME:KEY=VALUE,…``: the scene's ``adapt`` section, or any scene key, with those overrides;
by default growth 2, Dörfler's set alone, the residual indicators marking, h-adaptive P2
and hp) records the wall and CPU seconds from its start to each level's energy error
(``Level.elapsed``, ``Level.cpu``; outputs not counted); each uniform reference
(``--uniform NAME:KEY=VALUE,…``; by default P1 and P2 on the scene's mesh) solves the scene
once on meshes 1, 2, 4, … times finer than the scene's (``mesh.cells`` scaled,
``adapt=none``, grid sequencing as by default), the last one the mesh the observed rate
predicts to reach the target, and records the seconds of each such run: mesh, solve and
error — the run a user who knew the mesh needed would make.  A variant or reference the
scene does not take (P2 or hp on an obstacle scene: a ConfigError) is skipped, said so.
All in this process, the uniform runs first; each run is preceded by an untimed one of the
same kind to a 4× looser error or 20,000 DoFs (its forms compiled or loaded), so the ratios
adaptive/uniform are of one machine state.  At the target error e*: the seconds of the
first adaptive level with error ≤ e* against those of the first uniform mesh with
error ≤ e*, and the same at e* exactly (log-log interpolation of seconds against error
between the levels around it); if the uniform meshes stop short of e* (``--max-dofs``), at
the smallest error both reached, and against the uniform CPU seconds extrapolated to e* from
the last two meshes.  Per scene and variant, the speed-up (uniform / adaptive CPU seconds
at e*) against each uniform reference and against the fastest of them.  Prints a table,
writes CSV (one row per level or uniform run, then one row per scene, variant and uniform
reference with the ratios; written after each scene).

    python demos/bench/bench_time_to_accuracy.py --max-dofs 1400000 \
        --out demos/results/time_to_accuracy.csv
    python demos/bench/bench_time_to_accuracy.py A lshape --variant hp:adapt.strategy=hp \
        --uniform uniform: --uniform uniform_p3:mesh.degree=3
    python demos/bench/bench_time_to_accuracy.py ex9 --target 1e-2 --variant adaptive: \
        --variant g3:adapt.growth=3
    python demos/bench/bench_time_to_accuracy.py ex9 --target 4e-3 --max-dofs 1300000 \
        --variant res2:adapt.growth=2,adapt.indicators=residual --plain

``--uniform-bound`` compares at equal certification too: a user without the exact solution
must bound the error to know the target is reached.  Each uniform mesh's solution is given
the guaranteed bound the loop certifies with (the scene's estimator), timed apart, and the
meshes go on, driven by that bound, until it is ≤ the target (it is ≥ the error: finer
meshes than the exact stop's).  A variant with its own ``adapt.tol`` then stops where the
loop does (its bound ≤ tol, or ``--max-dofs``), its bounds in its seconds.  Per variant and
reference, the adaptive CPU seconds to its certified level (the first whose bound is ≤ the
target, else its last bounded one, at its η) over the uniform ones to certify the same η:
on the mesh that does (solve and bound), and on every mesh a user refining until the bound
certifies makes (each solved and bounded).

    python demos/bench/bench_time_to_accuracy.py ex9 --target 4e-3 --max-dofs 1400000 \
        --variant res3:adapt.growth=3,adapt.indicators=residual,adapt.tol=4e-3 \
        --variant p2:mesh.degree=2,adapt.growth=2,adapt.tol=4e-3 --uniform-bound

A variant on a level budget (``adapt.max_levels`` given) stops there; with
``adapt.estimate_last=false`` its last level is not estimated, and its seconds are those of
a loop that ends with its last solution, as the uniform run does:

    python demos/bench/bench_time_to_accuracy.py ex9 --target 4e-3 --max-dofs 1400000 \
        --set adapt.growth=3 adapt.indicators=residual \
        --variant budget3:adapt.max_levels=8,adapt.estimate_last=false

``--repeat N`` runs every reference and variant N times, the references then the variants in
each repeat, and takes each row's clocks as the medians of its repeats (the runs of one process
vary by ±5 % at 1M DoFs, with the memory the runs before left behind).

``--plain`` runs each variant a second time with the plain paths of the estimators, the
refinement and the loop (:data:`PLAIN`: one assembly per DG0 term, NumPy's ``np.unique``,
…), the same numbers, so the gain of the default paths is a ratio of one run.
"""

from __future__ import annotations

import argparse
import importlib
import math
import statistics
import time
from pathlib import Path

import contact
from contact.adaptivity.energy_error import solution_error
from contact.base.errors import ConfigError

from common import save_csv

ROOT = Path(__file__).resolve().parents[2]
#: scene, file, target energy error of the default run
SCENES = {
    "ex9": ("configs/peers/petsc_ex9.yaml", 4e-3),
    "A": ("configs/signorini_free_boundary.yaml", 2e-3),
    "lshape": ("configs/lshape_corner.yaml", 2e-3),
}


def scaled_cells(scene: contact.Scene, factor: int) -> str:
    """The ``mesh.cells`` override of a mesh ``factor`` times finer in each direction."""
    cells = scene.config.mesh.cells
    if isinstance(cells, int):
        return f"mesh.cells={cells * factor}"
    return f"mesh.cells=[{', '.join(str(c * factor) for c in cells)}]"


def uniform(
    path: Path,
    target: float,
    max_dofs: int,
    sets: list[str],
    name: str = "uniform",
    echo: bool = True,
    bound: bool = False,
) -> list[dict]:
    """Single solves on meshes 1, 2, 4, … times finer until one reaches ``target`` (or the
    next would exceed ``max_dofs``): a row each with its wall and CPU seconds (mesh + solve
    + error; ``run``: the reference's ``name``).  Where the next doubling would pass the
    target, the last mesh is the one the observed rate error ∝ h^r predicts to reach it (1 %
    finer): the run a user who knew the mesh needed would make.

    With ``bound``, each mesh's solution is also given the guaranteed bound the adaptive
    loop certifies with (the scene's estimator, ``contact.estimate``), timed apart
    (``bound_seconds``, ``bound_cpu``; its η in ``eta``), and the meshes go on as a user
    without the exact solution would refine: the same sequence driven by η instead of the
    error, until η ≤ ``target`` (η ≥ error: it may need finer meshes than the exact stop).
    ``certified`` marks the rows of that η-driven sequence (a mesh the exact sequence
    predicted from the error and η's would not have made is not on it).  Rows in mesh order."""
    sets = [s for s in sets if not s.startswith("adapt.")]  # the loop's options
    base = contact.load_scene(path, ["output.verbose=false", "adapt=none", *sets])
    dim = base.mesh.topology.dim
    runs: dict[int, dict] = {}

    def run(factor: int) -> dict:
        t0, c0 = time.perf_counter(), time.process_time()
        scene = contact.load_scene(
            path, ["output.verbose=false", "adapt=none", *sets, scaled_cells(base, factor)]
        )
        result = contact.solve(scene, verbose=False)
        error = solution_error(result.problem, result)
        seconds, cpu = time.perf_counter() - t0, time.process_time() - c0
        assert result.converged and error is not None, (path, factor)
        row = {"run": name, "level": factor, "dofs": result.dofs, "error": error}
        row.update(seconds=round(seconds, 4), cpu=round(cpu, 4))
        if bound:
            t0, c0 = time.perf_counter(), time.process_time()
            eta = contact.estimate(result.problem, result, scene.config.estimator).eta
            row.update(bound_seconds=round(time.perf_counter() - t0, 4))
            row.update(bound_cpu=round(time.process_time() - c0, 4), eta=eta)
            row.update(estimator=scene.config.estimator, certified=False)
        if echo:
            print(
                f"  {name} ×{factor:<4d} {result.dofs:9d} DoFs  error {error:.3e}  "
                f"{seconds:7.2f} s wall {cpu:7.2f} s CPU"
                + (f"  eta {row['eta']:.3e} bound {row['bound_cpu']:.2f} s CPU" if bound else ""),
                flush=True,
            )
        result.release()
        return row

    def sequence(key: str) -> list[dict]:
        """The meshes a user stopping on ``key`` ≤ target makes (the runs made once)."""
        made, factor = [], 1
        while True:
            if factor not in runs:
                runs[factor] = run(factor)
            made.append(runs[factor])
            value = made[-1][key]
            if value <= target:
                return made
            rate = (
                math.log(made[-2][key] / value) / math.log(factor / made[-2]["level"])
                if len(made) > 1
                else 1.0
            )
            reaching = math.ceil(factor * (1.01 * value / target) ** (1 / max(rate, 0.1)))
            after = min(2 * factor, reaching)
            if made[-1]["dofs"] * (after / factor) ** dim > max_dofs:
                return made
            factor = after

    sequence("error")
    if bound:
        for row in sequence("eta"):
            row["certified"] = True
    return [runs[f] for f in sorted(runs)]


class Reached(Exception):
    """A level reached the target error: the loop stops there."""


def adaptive(
    path: Path,
    target: float,
    max_dofs: int,
    sets: list[str],
    variant: str = "adaptive",
    echo: bool = True,
    bound: bool = False,
) -> list[dict]:
    """The adaptive loop until a level reaches ``target`` (earlier levels released as it
    goes): a row per level with the loop's wall and CPU seconds up to it (``Level.elapsed``,
    ``Level.cpu``; ``run``: the variant's name).  With ``adapt.indicators=residual`` the
    level that reaches ``target`` is charged the scene's estimator too (``bound_cpu``), as
    the loop computes it on its last level.  A variant with its own ``adapt.tol`` runs until
    the loop stops (η ≤ tol on its bound, or ``max_dofs``): each level's seconds hold the
    bounds the loop computed, and the last level's error may lie above or below ``target``.
    A variant with its own ``adapt.max_levels`` runs on that level budget; with
    ``adapt.estimate_last=false`` its last level is solved and not estimated (no bound charged
    to it: ``estimator`` ``none``, ``eta`` None), the run a user who knew the level the target
    needs would make.  The last row also has the seconds of the ``contact.adapt`` call from its
    start to its return (``call_seconds``, ``call_cpu``: the wall time the user sees).
    With ``bound`` each row has the level's η (``eta``) and the estimator of it
    (``estimator``: the scene's bound, or ``residual`` where the residual indicators
    marked)."""
    scene = contact.load_scene(path, ["output.verbose=false", *sets])
    kind = scene.config.estimator
    certified = any(s.startswith("adapt.tol=") for s in sets)
    rows: list[dict] = []

    def on_level(level) -> None:
        wall, cpu, charged = level.elapsed, level.cpu, 0.0
        eta, estimator = level.estimate.eta, level.estimator or kind
        if not level.estimate.computed:  # adapt.estimate_last false: the last level
            eta, estimator = None, "none"
        reached = level.error <= target and not certified
        if reached and estimator not in (kind, "none"):
            # adapt.indicators residual: the loop would compute the bound on its last level
            c0 = time.process_time()
            t0 = time.perf_counter()
            eta, estimator = contact.estimate(level.problem, level.result, kind).eta, kind
            charged = time.process_time() - c0
            wall, cpu = wall + time.perf_counter() - t0, cpu + charged
        rows.append({"run": variant, "level": level.index, "dofs": level.result.dofs})
        rows[-1].update(error=level.error, seconds=round(wall, 4), cpu=round(cpu, 4))
        rows[-1]["bound_cpu"] = round(charged, 4)
        # up to the level's solution and error only: a loop stopping there on a level budget
        rows[-1]["solved_seconds"] = round(level.solved_elapsed, 4)
        rows[-1]["solved_cpu"] = round(level.solved_cpu, 4)
        if bound:
            rows[-1].update(eta=eta, estimator=estimator)
        if echo:
            print(
                f"  {variant} L{level.index:<3d} {level.result.dofs:8d} DoFs  error "
                f"{level.error:.3e}  {wall:7.2f} s wall {cpu:7.2f} s CPU"
                + (f" (of it the bound {charged:.2f})" if charged else "")
                + (f"  eta {eta:.3e} ({estimator})" if bound and eta is not None else ""),
                flush=True,
            )
        if reached:  # no finer level
            raise Reached

    budget = any(s.startswith("adapt.max_levels=") for s in sets)
    t0, c0 = time.perf_counter(), time.process_time()
    try:
        contact.adapt(
            scene,
            tol=None if certified else 0.0,  # None: the variant's own
            max_levels=None if budget else 80,  # None: the variant's level budget
            max_dofs=max_dofs,
            keep=lambda lv: False,
            on_level=on_level,
        )
    except Reached:
        pass
    if rows:  # the call as a user makes it, from its start to its return (outputs: echo)
        rows[-1]["call_seconds"] = round(time.perf_counter() - t0, 4)
        rows[-1]["call_cpu"] = round(time.process_time() - c0, 4)
        if echo:
            print(
                f"  {variant}: contact.adapt returned after {rows[-1]['call_seconds']:.2f} s "
                f"wall, {rows[-1]['call_cpu']:.2f} s CPU",
                flush=True,
            )
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


#: the loop's variants compared by default, each against the same uniform runs: growth 2
#: (the loop refines until the DoFs double), the old marking (Dörfler's set alone: ~1.7× the
#: DoFs per level), the residual indicators marking with the equilibrated bound on the last
#: level only, h-adaptive P2, and hp (degrees 1 … 6, Dörfler's θ of the hp loop)
VARIANTS = (
    "adaptive:adapt.growth=2",
    "dorfler:adapt.growth=1",
    "indicators:adapt.growth=2,adapt.indicators=residual",
    "p2:mesh.degree=2,adapt.growth=2",
    "hp:adapt.strategy=hp,adapt.p_max=6,adapt.theta=0.85",
)
#: the uniform references: P1 and P2 on meshes 1, 2, 4, … times finer than the scene's
UNIFORM = ("uniform:", "uniform_p2:mesh.degree=2")
#: the untimed run before each timed one stops at this multiple of the target error, or
#: before this many DoFs
WARM_FACTOR, WARM_DOFS = 4.0, 20_000


#: the switches of the estimators' and refinement's plain paths (module, name): ``--plain``
#: runs each variant a second time with all of them False
PLAIN = (
    ("contact.adaptivity.cellwise", "MERGED"),
    ("contact.adaptivity.equilibration.flux", "P1_SHORTCUT"),
    ("contact.adaptivity.equilibration.bound", "DIRICHLET_CELLS"),
    ("contact.adaptivity.equilibration.cells", "KEEP_EXPRESSIONS"),
    ("contact.adaptivity.transfer", "TAGGED_PARENTS_ONLY"),
    ("contact.adaptivity.equilibration.multiplier", "EINSUM"),
    ("contact.adaptivity.equilibration.flux", "SORTED_BLOCKS"),
    ("contact.adaptivity.equilibration.flux", "NODAL_MULTIPLIER"),
    ("contact.adaptivity.equilibration.cells", "VERTEX_NODES"),
    ("contact.adaptivity.equilibration.bound", "DIRICHLET_SUBMESH"),
    ("contact.adaptivity.equilibration.bound", "DIRICHLET_ON_SUBMESH"),
    ("contact.adaptivity.equilibration.flux", "UNIT_KAPPA"),
    ("contact.base.indices", "SORTED"),
    ("contact.adaptivity.transfer", "LOCAL_PULL"),
    ("contact.drivers.adaptive", "FREEZE_HEAP"),
    ("contact.drivers.adaptive", "PREDICT_BOUND"),
    ("contact.drivers.adaptive", "EDGES_ONCE"),
    ("contact.adaptivity.transfer", "SHARED_SPACE"),
    ("contact.base.spaces", "ELEMENT_KEYS"),
    ("contact.setup.data", "SHARED_POINTS"),
    ("contact.setup.scalar", "SHARED_SPACE"),
    ("contact.setup.scalar", "DIRICHLET_NODES"),
    ("contact.setup.checks", "POINTS_ONCE"),
)


def plain_paths(on: bool) -> None:
    """Select the plain paths of :data:`PLAIN` (``on``) or the default ones."""
    for module, name in PLAIN:
        setattr(importlib.import_module(module), name, not on)


def variant_of(text: str) -> tuple[str, list[str]]:
    """``NAME:KEY=VALUE,KEY=VALUE`` → (name, ``--set`` overrides)."""
    name, _, sets = text.partition(":")
    return name, [s for s in sets.split(",") if s]


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("scenes", nargs="*", default=list(SCENES), help=", ".join(SCENES))
    ap.add_argument("--target", type=float, default=None, help="energy error e* (per scene)")
    ap.add_argument("--max-dofs", type=int, default=600_000)
    ap.add_argument("--set", dest="overrides", nargs="*", default=[], metavar="KEY=VALUE")
    ap.add_argument(
        "--variant",
        dest="variants",
        action="append",
        default=None,
        metavar="NAME:KEY=VALUE,…",
        help=f"an adaptive run (repeatable; default {' '.join(VARIANTS)})",
    )
    ap.add_argument(
        "--uniform",
        dest="uniforms",
        action="append",
        default=None,
        metavar="NAME:KEY=VALUE,…",
        help=f"a uniform reference (repeatable; default {' '.join(UNIFORM)})",
    )
    ap.add_argument(
        "--plain",
        action="store_true",
        help="each variant again with the plain paths of the estimators and refinement "
        "(variant NAME-plain)",
    )
    ap.add_argument(
        "--uniform-bound",
        action="store_true",
        help="bound each uniform mesh's solution as the loop certifies (timed apart), refine "
        "on until that bound meets the target, and compare at equal certification",
    )
    ap.add_argument(
        "--repeat",
        type=int,
        default=1,
        help="run every reference and variant this many times, alternating, each clock the "
        "median of the repeats",
    )
    ap.add_argument("--out", default=None, help="CSV file")
    args = ap.parse_args()
    warm = contact.load_scene(ROOT / SCENES["ex9"][0], ["output.verbose=false", "adapt=none"])
    contact.solve(warm, verbose=False).release()  # JIT cache and first-call costs
    rows, summary = [], []
    for name in args.scenes:
        file, default_target = SCENES[name]
        target = args.target or default_target
        print(f"{name}: to energy error {target:.1e}")
        references: dict[str, list[str]] = {}
        for reference, sets in map(variant_of, args.uniforms or UNIFORM):
            sets = [*args.overrides, *sets]
            try:  # untimed first: the reference's forms compiled or loaded
                loose = WARM_FACTOR * target
                uniform(ROOT / file, loose, WARM_DOFS, sets, echo=False, bound=args.uniform_bound)
            except ConfigError as error:
                print(f"  {reference}: skipped ({error})", flush=True)
                continue
            references[reference] = sets
        variants: dict[str, list[str]] = {}
        for variant, sets in map(variant_of, args.variants or VARIANTS):
            sets = [*args.overrides, *sets]
            try:
                adaptive(ROOT / file, WARM_FACTOR * target, WARM_DOFS, sets, echo=False)
            except ConfigError as error:
                print(f"  {variant}: skipped ({error})", flush=True)
                continue
            variants[variant] = sets
        # each repeat runs every reference, then every variant: the runs of one kind alternate
        # with the others', and each row's clocks are the medians of its repeats
        uni_runs: dict[str, list[list[dict]]] = {reference: [] for reference in references}
        ada_runs: dict[str, list[list[dict]]] = {}
        for repeat in range(args.repeat):
            if args.repeat > 1:
                print(f"  repeat {repeat + 1} of {args.repeat}", flush=True)
            for reference, sets in references.items():
                uni_runs[reference].append(
                    uniform(
                        ROOT / file,
                        target,
                        args.max_dofs,
                        sets,
                        reference or "uniform",
                        bound=args.uniform_bound,
                    )
                )
            for variant, sets in variants.items():
                for plain in (False, True) if args.plain else (False,):
                    plain_paths(plain)
                    label = f"{variant}-plain" if plain else variant
                    ada_runs.setdefault(label, []).append(
                        adaptive(
                            ROOT / file,
                            target,
                            args.max_dofs,
                            sets,
                            label,
                            bound=args.uniform_bound,
                        )
                    )
                plain_paths(False)
        uniforms = {reference: median_rows(runs) for reference, runs in uni_runs.items()}
        for uni in uniforms.values():
            rows += [{"scene": name, **r} for r in uni]
        for label, runs in ada_runs.items():
            ada = median_rows(runs)
            rows += [{"scene": name, **r} for r in ada]
            mine = [ratios(name, label, target, uni, ada, ref) for ref, uni in uniforms.items()]
            summary += verdict(name, label, target, mine)
        if args.out:  # after each scene: a long run interrupted keeps the scenes done
            save_csv(args.out, rows + summary)


#: the clocks of a row, the medians of its repeats (``median_rows``)
CLOCKS = (
    "seconds",
    "cpu",
    "bound_seconds",
    "bound_cpu",
    "solved_seconds",
    "solved_cpu",
    "call_seconds",
    "call_cpu",
)


def median_rows(runs: list[list[dict]]) -> list[dict]:
    """The rows of repeated runs of one reference or variant, each clock (:data:`CLOCKS`) the
    median of its repeats (``repeats``: how many, where more than one).  The repeats must
    have made the same meshes (serially they do: the same DoFs level by level)."""
    first = runs[0]
    for other in runs[1:]:
        dofs = [r["dofs"] for r in other]
        assert dofs == [r["dofs"] for r in first], f"a repeat made other meshes: {dofs}"
    out = []
    for k, row in enumerate(first):
        row = dict(row)
        for clock in CLOCKS:
            if clock in row:
                row[clock] = round(statistics.median(run[k][clock] for run in runs), 4)
        if len(runs) > 1:
            row["repeats"] = len(runs)
        out.append(row)
    return out


def ratios(
    name: str,
    variant: str,
    target: float,
    uni: list[dict],
    ada: list[dict],
    reference: str = "uniform",
) -> dict:
    """The row of adaptive / uniform seconds at the target error, or at the smallest error
    both reached (the uniform meshes stop before ``--max-dofs``); ``speedup_cpu``: uniform /
    adaptive CPU seconds at the target (interpolated, or against the uniform seconds
    extrapolated to it)."""
    error = max(target, *(min(r["error"] for r in run) for run in (uni, ada)))
    ratio = {"scene": name, "run": "ratio", "variant": variant, "reference": reference}
    ratio.update(target=target, error=error)
    # the loop's seconds to each level's error, and to its solution only: a loop that knew
    # its last level (a level budget) needs no estimate of it, as the uniform run has none
    budget = f"seconds to the solution at error {error:.2e}, stopping on a level budget"
    for clock in ("seconds", "cpu"):
        for key, mine, what in (
            ("", clock, f"seconds at error {error:.2e}"),
            ("budget_", f"solved_{clock}", budget + " (no estimate of the last level)"),
        ):
            first = first_reaching(ada, error, mine) / first_reaching(uni, error, clock)
            exact = at_error(ada, error, mine) / at_error(uni, error, clock)
            ratio[f"{key}first_reaching_{clock}"] = round(first, 3)
            ratio[f"{key}interpolated_{clock}"] = round(exact, 3)
            print(
                f"{name} {variant} / {reference}: {'wall' if clock == 'seconds' else 'CPU'} "
                f"{what}: {first:.3f} (first level reaching it), {exact:.3f} (interpolated "
                "to it)",
                flush=True,
            )
    if error == target:
        ratio["speedup_cpu"] = round(1 / ratio["interpolated_cpu"], 3)
    elif len(uni) > 1 and min(r["error"] for r in ada) <= target:
        # the uniform meshes stop short: their CPU seconds at the target extrapolated from
        # the last two (error and seconds power laws in the DoFs)
        a, b = uni[-2], uni[-1]
        s = math.log(a["error"] / target) / math.log(a["error"] / b["error"])
        extrapolated = math.exp((1 - s) * math.log(a["cpu"]) + s * math.log(b["cpu"]))
        ratio["uniform_extrapolated_cpu"] = round(extrapolated, 3)
        ratio["extrapolated_cpu"] = round(at_error(ada, target, "cpu") / extrapolated, 5)
        ratio["speedup_cpu"] = round(1 / ratio["extrapolated_cpu"], 3)
        print(
            f"{name} {variant} / {reference}: uniform CPU seconds at error {target:.1e} "
            f"extrapolated {extrapolated:.1f} s; adaptive/uniform {ratio['extrapolated_cpu']:.4f}",
            flush=True,
        )
    cert = certified(target, uni, ada)
    if "certified_last_cpu" in cert:
        print(
            f"{name} {variant} / {reference}: certified η ≤ {cert['certified_eta']:.3e}: "
            f"adaptive {cert['adaptive_certified_cpu']:.2f} s CPU "
            f"({cert['adaptive_certified_dofs']} DoFs) against uniform with its bound "
            f"{cert['uniform_bound_last_cpu']:.2f} s on the mesh certifying it "
            f"({cert.get('uniform_certified_dofs', 'extrapolated')} DoFs; ratio "
            f"{cert['certified_last_cpu']:.3f}, interpolated "
            f"{cert['certified_last_interp_cpu']:.3f}), {cert['uniform_bound_every_cpu']:.2f} s "
            f"bounding every mesh (ratio {cert['certified_every_cpu']:.3f})",
            flush=True,
        )
    ratio.update(cert)
    return ratio


def certified(target: float, uni: list[dict], ada: list[dict]) -> dict:
    """Adaptive / uniform CPU seconds at equal certification (``--uniform-bound``).

    The adaptive run's certified level: its first level whose bound η (``estimator`` not
    ``residual``) is ≤ ``target``, or, if none, its level of the smallest bound, at that η
    (the tolerance it certifies: a bound need not decrease level by level).  Against the
    uniform meshes certifying that η: the first mesh with η ≤ it, its solve and its bound
    (``uniform_bound_last_cpu``: a user who knew the mesh; also log-log interpolated in η,
    ``…_interp_cpu``), and the coarser meshes of the η-driven sequence whose η is above
    it, each with its bound, plus that mesh (``uniform_bound_every_cpu``: a user who refines until
    the bound certifies).  Where the uniform meshes stop short of that η, the last mesh's
    seconds are extrapolated from the last two (``uniform_extrapolated``).  Empty if the
    adaptive run has no bounded level or the uniform rows no η."""
    bounded = [r for r in ada if r.get("estimator", "residual") not in ("residual", "none")]
    if not bounded or len(uni) < 2 or "eta" not in uni[0]:
        return {}
    smallest = min(bounded, key=lambda r: r["eta"])  # the first of the smallest bound
    level = next((r for r in bounded if r["eta"] <= target), smallest)
    eta = max(target, level["eta"])
    out = {"certified_eta": eta, "adaptive_certified_dofs": level["dofs"]}
    out.update(adaptive_certified_error=level["error"], adaptive_certified_cpu=level["cpu"])
    cost = [{"error": r["eta"], "cpu": r["cpu"] + r["bound_cpu"]} for r in uni]
    reach = next((r for r in uni if r["eta"] <= eta), None)
    if reach is not None:
        last, interp = first_reaching(cost, eta, "cpu"), at_error(cost, eta, "cpu")
        out["uniform_certified_dofs"] = reach["dofs"]
    else:  # the meshes stop short (max_dofs): power laws from the last two
        a, b = cost[-2], cost[-1]
        s = math.log(a["error"] / eta) / math.log(a["error"] / b["error"])
        last = interp = math.exp((1 - s) * math.log(a["cpu"]) + s * math.log(b["cpu"]))
        out["uniform_extrapolated"] = True
    finest = math.inf if reach is None else reach["dofs"]
    before = [r for r in uni if r["certified"] and r["eta"] > eta and r["dofs"] < finest]
    every = sum(r["cpu"] + r["bound_cpu"] for r in before) + last
    out.update(uniform_bound_last_cpu=round(last, 4))
    out.update(uniform_bound_last_interp_cpu=round(interp, 4))
    out["uniform_bound_every_cpu"] = round(every, 4)
    for key, seconds in (("last", last), ("last_interp", interp), ("every", every)):
        out[f"certified_{key}_cpu"] = round(level["cpu"] / seconds, 3)
    return out


def verdict(name: str, variant: str, target: float, mine: list[dict]) -> list[dict]:
    """Print the variant's speed-up at the target against each uniform reference and the
    fastest one (``best_reference`` and ``speedup_vs_best_cpu`` on each row)."""
    known = [r for r in mine if "speedup_cpu" in r]
    if not known:
        return mine
    best = min(known, key=lambda r: r["speedup_cpu"])  # the fastest uniform run
    for r in mine:
        r["best_reference"] = best["reference"]
        r["speedup_vs_best_cpu"] = best["speedup_cpu"]
    print(
        f"{name} {variant} to {target:.1e}: CPU speed-up "
        + ", ".join(f"{r['speedup_cpu']:.2f}× against {r['reference']}" for r in known)
        + f"; against the fastest uniform ({best['reference']}) {best['speedup_cpu']:.2f}×",
        flush=True,
    )
    return mine


if __name__ == "__main__":
    main()
