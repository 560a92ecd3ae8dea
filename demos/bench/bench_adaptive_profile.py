"""Where the adaptive loop's time and memory go, level by level.

Runs SOLVE → ESTIMATE → MARK → REFINE (:func:`contact.setup.run.adapt`, the scene's
defaults unless ``--set``) up to ``--max-dofs`` in this process and prints, per level: the
DoFs and energy error, the CPU seconds of each phase (assembly, solve, estimate, error,
mark, refine, output: the level's files as ``contact run`` writes them, with ``--output``;
``other``: the rest of the level, Python between the phases), the level's wall and CPU
seconds and their running totals, the resident memory after the level (garbage collected)
and its peak during the level (the kernel's high-water mark, reset per phase; sampled every
2 ms where it cannot be reset) and during each phase (``bound``: the guaranteed bound's,
within the estimate), and what is
still alive of earlier levels: dolfinx meshes and PETSc objects (matrices, vectors, KSP,
PC); at the end the last level's peak per DoF against the 1.6 KB/DoF target.  Writes CSV.
``--whole-table`` selects the old path of the equilibrated flux's patch data (all at once),
``--table-once`` that of its cell table (whole but for two columns before the blocks),
``--keep-level`` that of the level before the last (whole but for its operator during the
last solve, not stowed), ``--keep-operator`` the one before (whole, operator included),
``--trim-each-level`` that of the heap given back (the loop's trims before each
level and after the level before is stowed and released, not only before a bound),
``--copies`` that of the solver's records of laws and iterates (copies, not digests),
``--keep-bound-operator`` that of the last level (whole during its bound), ``--terms-whole``
that of the estimators' DG0 terms (every cell's coefficients packed at once).

    python demos/bench/bench_adaptive_profile.py ex9 --max-dofs 1300000 \\
        --out demos/results/adaptive_cost/profile_ex9.csv
    python demos/bench/bench_adaptive_profile.py ex9 --max-dofs 300000 --keep all
    python demos/bench/bench_adaptive_profile.py ex9 --max-dofs 300000 --keep last --no-trim
    python demos/bench/bench_adaptive_profile.py ex9 --max-dofs 300000 --whole-table
    python demos/bench/bench_adaptive_profile.py ex9 --max-dofs 300000 --table-once

Scenes: ``ex9`` (configs/peers/petsc_ex9.yaml), ``A`` (configs/signorini_free_boundary.yaml),
``lshape`` (configs/lshape_corner.yaml), ``hertz_2d`` (configs/hertz_2d.yaml) or a path.
"""

from __future__ import annotations

import argparse
import gc
import tempfile
import threading
import time
from pathlib import Path

import contact
from contact.base import lifetime
from contact.base.lifetime import petsc_objects, rss_mib
from contact.drivers import adaptive
from contact.setup import run as loop

from common import PHASES, count_phase_cpu, save_csv, wrap_phases
from petsc4py import PETSc

ROOT = Path(__file__).resolve().parents[2]
SCENES = {
    "ex9": "configs/peers/petsc_ex9.yaml",
    "A": "configs/signorini_free_boundary.yaml",
    "lshape": "configs/lshape_corner.yaml",
    "hertz_2d": "configs/hertz_2d.yaml",
}


#: the phases whose peaks are recorded: the loop's, and the bound's within the estimate
PEAKS = (*PHASES.values(), "bound")
#: peak memory per final DoF the loop should stay below (bytes)
TARGET_BYTES_PER_DOF = 1600


class PeakSampler:
    """The largest resident set size since :meth:`reset` (MiB).

    The kernel's high-water mark (``VmHWM``), reset through ``/proc/self/clear_refs``: exact,
    where a thread sampling ``VmRSS`` misses the peaks inside C calls that hold the GIL (a
    Krylov solve, an assembly); where the mark cannot be reset, sampled every ``interval``
    seconds by a thread.
    """

    def __init__(self, interval: float = 0.002):
        self.peak = rss_mib()
        self.interval = interval
        self.exact = clear_high_water_mark()
        if not self.exact:
            threading.Thread(target=self._run, daemon=True).start()

    def _run(self) -> None:
        while True:
            self.peak = max(self.peak, rss_mib())
            time.sleep(self.interval)

    def reset(self) -> float:
        if self.exact:
            self.peak = max(self.peak, high_water_mark_mib())
            clear_high_water_mark()
        peak, self.peak = self.peak, rss_mib()
        return peak


def high_water_mark_mib() -> float:
    """The peak resident set size of this process since its last reset (MiB, ``VmHWM``)."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) / 1024.0
    return float("nan")


def clear_high_water_mark() -> bool:
    """Reset ``VmHWM`` to the current resident size (Linux ≥ 4.0); whether it could."""
    try:
        Path("/proc/self/clear_refs").write_text("5")
    except OSError:
        return False
    return True


def count_phase_peaks(sampler: PeakSampler) -> dict[str, float]:
    """Wrap the loop's phase functions (``common.PHASES``, outside ``count_phase_cpu``'s
    wrappers) so that the largest resident size during each phase (MiB) is recorded under
    its name: the memory each phase needs on top of what the loop holds."""
    peaks: dict[str, float] = {}

    def sampled(fn, key):
        def call(*args, **kwargs):
            before = sampler.reset()
            try:
                return fn(*args, **kwargs)
            finally:
                during = sampler.reset()
                peaks[key] = max(peaks.get(key, 0.0), during)
                sampler.peak = max(sampler.peak, before, during)  # the level's peak goes on

        return call

    wrap_phases(sampled)
    # the guaranteed bound where it is reported (adapt.indicators: residual), within estimate
    adaptive.Bound.compute = sampled(adaptive.Bound.compute, "bound")  # type: ignore[method-assign]
    return peaks


def live_meshes() -> int:
    """dolfinx meshes alive in this process (found by the garbage collector)."""
    from dolfinx.mesh import Mesh

    return sum(1 for obj in gc.get_objects() if isinstance(obj, Mesh))


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("scene", help=f"one of {', '.join(SCENES)} or a scene file")
    ap.add_argument("--max-dofs", type=int, default=1_300_000)
    ap.add_argument("--max-levels", type=int, default=40)
    ap.add_argument("--set", dest="overrides", nargs="*", default=[], metavar="KEY=VALUE")
    ap.add_argument("--output", action="store_true", help="write each level's files")
    ap.add_argument(
        "--keep",
        choices=("all", "last"),
        default="last",
        help="all: every level stays whole (the old path); last: earlier levels are released",
    )
    ap.add_argument(
        "--no-trim",
        action="store_true",
        help="released levels' memory stays with the allocator (contact.base.lifetime.TRIM)",
    )
    ap.add_argument(
        "--trim-each-level",
        action="store_true",
        help="the freed heap given back at each level's start and once the level before is "
        "stowed and released, not only before a bound "
        "(contact.drivers.adaptive.TRIM_BEFORE_BOUNDS = False)",
    )
    ap.add_argument(
        "--whole-table",
        action="store_true",
        help="the equilibrated flux's patch data all at once (flux.BLOCK_CELLS = None)",
    )
    ap.add_argument(
        "--table-once",
        action="store_true",
        help="the flux's cell table made whole (but for t and τ) before its blocks "
        "(flux.BLOCK_TABLE = False)",
    )
    ap.add_argument(
        "--keep-level",
        action="store_true",
        help="a level to be released stays whole (its operator K aside) during the next "
        "level's solve, not stowed (contact.drivers.adaptive.STOW_PREVIOUS = False)",
    )
    ap.add_argument(
        "--keep-operator",
        action="store_true",
        help="a level to be released keeps its operator K during the next level's solve "
        "(contact.drivers.adaptive.SHED_PREVIOUS = False)",
    )
    ap.add_argument(
        "--copies",
        action="store_true",
        help="the CG + GAMG path keeps copies of its laws and iterate, not digests "
        "(contact.base.lifetime.DIGESTS = False)",
    )
    ap.add_argument(
        "--keep-bound-operator",
        action="store_true",
        help="the last level keeps its operator K during its bound "
        "(contact.drivers.adaptive.SHED_BOUND = False)",
    )
    ap.add_argument(
        "--terms-whole",
        action="store_true",
        help="the estimators' DG0 terms assembled over every cell at once "
        "(contact.adaptivity.cellwise.BLOCK_CELLS = None)",
    )
    ap.add_argument("--out", default=None, help="CSV file")
    args = ap.parse_args()
    PETSc.Log.begin()  # petsc_objects counts from here
    lifetime.TRIM = not args.no_trim
    lifetime.DIGESTS = not args.copies
    adaptive.TRIM_BEFORE_BOUNDS = not args.trim_each_level
    if args.whole_table:
        from contact.adaptivity.equilibration import flux

        flux.BLOCK_CELLS = None
    if args.keep_level or args.keep_operator:
        adaptive.STOW_PREVIOUS = False
        adaptive.SHED_PREVIOUS = not args.keep_operator
    if args.table_once:
        from contact.adaptivity.equilibration import flux

        flux.BLOCK_TABLE = False
    if args.keep_bound_operator:
        adaptive.SHED_BOUND = False
    if args.terms_whole:
        from contact.adaptivity import cellwise

        cellwise.BLOCK_CELLS = None
    path = ROOT / SCENES.get(args.scene, args.scene)
    scene = contact.load_scene(path, ["output.verbose=false", *args.overrides])
    baseline = rss_mib()
    sampler = PeakSampler()
    peaks = count_phase_peaks(sampler)
    CPU = count_phase_cpu()
    rows: list[dict] = []
    clock = {"wall": time.perf_counter(), "cpu": time.process_time()}
    start = dict(clock)
    writer = None
    if args.output:
        from contact.app.dispatch import report_of
        from contact.output.run_report import level_writer

        folder = tempfile.TemporaryDirectory()
        writer = level_writer(Path(folder.name), report_of(scene.config), scene.comm)

    def on_level(level) -> None:
        if writer is not None:
            c = time.process_time()
            writer(level)
            CPU["output"] += time.process_time() - c
        wall, cpu = time.perf_counter(), time.process_time()
        phases = {k: CPU.pop(k, 0.0) for k in (*PHASES.values(), "output")}
        gc.collect()
        row = {
            "level": level.index,
            "dofs": level.result.dofs,
            "error": level.error,
            "eta": level.estimate.eta,
            **{f"cpu_{k}": round(v, 3) for k, v in phases.items()},
            "cpu_other": round(cpu - clock["cpu"] - sum(phases.values()), 3),
            "cpu_level": round(cpu - clock["cpu"], 3),
            "wall_level": round(wall - clock["wall"], 3),
            "cpu_total": round(cpu - start["cpu"], 3),
            "wall_total": round(wall - start["wall"], 3),
            "rss_mib": round(rss_mib(), 1),
            "peak_mib": round(sampler.reset(), 1),
            **{f"peak_{k}_mib": round(peaks.pop(k, 0.0), 1) for k in PEAKS},
            "meshes": live_meshes(),
            **{f"petsc_{k}": v for k, v in sorted(petsc_objects().items())},
        }
        rows.append(row)
        print(
            f"L{row['level']:2d} {row['dofs']:8d} DoFs err {row['error']:.3e}  cpu "
            + " ".join(f"{k} {v:.2f}" for k, v in phases.items() if v >= 0.005)
            + f" other {row['cpu_other']:.2f} | level {row['cpu_level']:.2f} cpu "
            f"{row['wall_level']:.2f} wall, total {row['cpu_total']:.1f} cpu | rss "
            f"{row['rss_mib']:.0f} peak {row['peak_mib']:.0f} MiB "
            f"({row['peak_mib'] * 2**20 / row['dofs']:.0f} B/DoF) meshes {row['meshes']} "
            f"mats {row.get('petsc_Mat', 0)} vecs {row.get('petsc_Vector', 0)}\n     peak MiB "
            + " ".join(
                f"{k} {row[f'peak_{k}_mib']:.0f}" for k in PEAKS if row[f"peak_{k}_mib"] > 0
            ),
            flush=True,
        )
        clock.update(wall=time.perf_counter(), cpu=time.process_time())

    result = loop.adapt(
        scene,
        on_level=on_level,
        max_dofs=args.max_dofs,
        max_levels=args.max_levels,
        keep=None if args.keep == "all" else (lambda level: False),
    )
    print(f"stop: {result.stop}")
    last = rows[-1]
    per_dof = last["peak_mib"] * 2**20 / last["dofs"]
    print(
        f"last level {last['dofs']} DoFs: peak {last['peak_mib']:.0f} MiB = {per_dof:.0f} B/DoF "
        f"({per_dof / TARGET_BYTES_PER_DOF:.2f}x the {TARGET_BYTES_PER_DOF} B/DoF target; the "
        f"process before the loop {baseline:.0f} MiB = "
        f"{baseline * 2**20 / last['dofs']:.0f} B/DoF of it)"
    )
    if args.out:
        keys = sorted(
            {k for r in rows for k in r},
            key=lambda k: list(rows[-1]).index(k) if k in rows[-1] else 999,
        )
        save_csv(args.out, [{k: r.get(k, 0) for k in keys} for r in rows])


if __name__ == "__main__":
    main()
