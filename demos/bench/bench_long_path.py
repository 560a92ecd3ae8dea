"""A long load path on a tiny mesh: MPI communicators, PETSc objects and memory step by step.

A load path releases each step once the next one is solved (contact/drivers/load_path.py) and every
solve destroys the PETSc objects it made (contact/base/lifetime.py), so these figures must stay
flat however many steps run.  Before, every step kept its PETSc objects and functions: the
communicators ran out (MPICH has 2048) and a path ended at step 509 with an MPI abort.

    python demos/bench/bench_long_path.py                          # 2000 steps, the API, serial
    mpirun -n 2 python demos/bench/bench_long_path.py
    mpirun -n 2 python demos/bench/bench_long_path.py --cli \\
        --scene configs/friction_block_2d.yaml --set "mesh.cells=[8,2]"   # `contact run`, its files
    python demos/bench/bench_long_path.py --steps 600 --every 50 --out /tmp/long_path.csv

The API mode runs :func:`contact.run_load_path`; the CLI mode runs ``contact run`` in this
process with the scene's outputs (every format and the pictures unless ``--set`` turns
them off), taking its figures after each step's files are written. Every ``--every``
steps, and at the ends of the first and the last ``--window`` steps, after Python's
garbage collection (``--no-collect``: without; reference cycles, e.g. UFL's, then wait for
Python's own): the wall and CPU seconds so far, the resident set size (MiB, the largest
over the ranks), the communicators MPI can still create
(:func:`contact.base.lifetime.free_communicators`), the live PETSc objects
(:func:`contact.base.lifetime.petsc_objects`), the objects Python's garbage collector
tracks and the entries of PETSc's options database (the largest counts over the ranks),
and in CLI mode the seconds spent writing the steps' files. Prints one row per sample and
a summary — with the time per step of the last ``--window`` steps over that of the first
(wall and CPU, of the whole step and of writing its files: the cost of a step must not
grow with the steps before it; the solve's own cost changes along a path with its Newton
iterations; per window also the median and the fastest step, which the load of other jobs
on a shared machine sways less) and the RSS growth per step from the end of the first
window on — and writes CSV (default demos/results/long_path/<scene>_<mode>_np<ranks>.csv).
"""

from __future__ import annotations

import argparse
import gc
import shutil
import tempfile
import time
from pathlib import Path

import contact  # noqa: F401  (before petsc4py)
from contact.base.lifetime import free_communicators, petsc_objects, rss_mib

import numpy as np
from common import save_csv
from mpi4py import MPI
from petsc4py import PETSc

ROOT = Path(__file__).resolve().parents[2]


#: the per-step series kept for the two windows: the whole step and writing its files
SERIES = ("step_wall", "step_cpu", "output_wall", "output_cpu")


class Sampler:
    """The figures of the steps ``every``, 2·``every``, … and of the steps in ``also`` (and
    step 1); and the seconds of each step of the first and the last ``window`` steps of a
    path of ``steps`` (the first window from step 2: step 1 compiles the forms), the
    sampling itself left out."""

    def __init__(
        self,
        every: int,
        comm: MPI.Comm,
        collect: bool = True,
        also: tuple = (),
        window: int = 0,
        steps: int = 0,
    ):
        self.every, self.comm, self.collect, self.also = every, comm, collect, set(also)
        self.rows: list[dict] = []
        self.wall, self.cpu = time.perf_counter(), time.process_time()
        self.output = [0.0, 0.0]  # wall and CPU seconds in the step writer (CLI mode)
        self.window, self.steps = window, steps
        self.series: dict[str, dict[str, list[float]]] = {"first": {}, "last": {}}
        self.previous = self._clock()

    def _clock(self) -> np.ndarray:
        return np.array([time.perf_counter(), time.process_time(), *self.output])

    def _track(self, k: int) -> None:
        """Keep step k's seconds (the largest over the ranks) if it is in a window."""
        if 1 < k <= self.window:
            which = "first"
        elif k > self.steps - self.window and self.window:
            which = "last"
        else:
            return
        seconds = np.empty(4)
        self.comm.Allreduce(self._clock() - self.previous, seconds, op=MPI.MAX)
        for name, value in zip(SERIES, seconds):
            self.series[which].setdefault(name, []).append(float(value))

    def __call__(self, step) -> None:
        self._track(step.index)
        try:
            self._sample(step)
        finally:
            self.previous = self._clock()  # the next step's seconds start after the sample

    def _sample(self, step) -> None:
        if step.index != 1 and step.index % self.every and step.index not in self.also:
            return
        if self.collect:
            gc.collect()
        comm = self.comm
        row = {
            "step": step.index,
            "converged": bool(step.result.converged),
            "seconds": round(time.perf_counter() - self.wall, 2),
            "cpu_seconds": round(comm.allreduce(time.process_time() - self.cpu, op=MPI.MAX), 2),
            "output_seconds": round(comm.allreduce(self.output[0], op=MPI.MAX), 3),
            "output_cpu_seconds": round(comm.allreduce(self.output[1], op=MPI.MAX), 3),
            "rss_mib": round(comm.allreduce(rss_mib(), op=MPI.MAX), 2),
            # the objects Python's garbage collector tracks (the most over the ranks): an
            # exact count, the same on any machine, where the RSS depends on the allocator
            "python_objects": comm.allreduce(len(gc.get_objects()), op=MPI.MAX),
            "free_communicators": free_communicators(comm),
            "petsc_objects": comm.allreduce(sum(petsc_objects().values()), op=MPI.MAX),
            "petsc_options": comm.allreduce(len(PETSc.Options().getAll()), op=MPI.MAX),
        }
        self.rows.append(row)
        if comm.rank == 0:
            print("  ".join(f"{k} {v}" for k, v in row.items()), flush=True)


def run_api(scene_file: str, sets: list[str], sample: Sampler) -> None:
    scene = contact.load_scene(scene_file, [*sets, "output.verbose=false"])
    path = contact.run_load_path(scene, on_step=sample)
    if not path.converged:
        raise SystemExit(f"bench_long_path: {path.stop}")


def run_cli(scene_file: str, sets: list[str], sample: Sampler, comm: MPI.Comm) -> None:
    """``contact run`` into a temporary folder, ``sample`` called after each step's files."""
    from contact.app import cli
    from contact.output import step_report

    write = step_report.StepWriter.__call__

    def write_and_sample(writer, step) -> None:
        wall, cpu = time.perf_counter(), time.process_time()
        write(writer, step)
        sample.output[0] += time.perf_counter() - wall
        sample.output[1] += time.process_time() - cpu
        sample(step)

    step_report.StepWriter.__call__ = write_and_sample
    folder = comm.bcast(tempfile.mkdtemp(prefix="long_path_") if comm.rank == 0 else None)
    try:
        args = ["run", scene_file, "-o", str(Path(folder) / "out"), "-q"]
        for s in sets:
            args += ["--set", s]
        code = cli.main(args)
    finally:
        step_report.StepWriter.__call__ = write
        comm.barrier()
        if comm.rank == 0:
            shutil.rmtree(folder, ignore_errors=True)
    if code != 0:
        raise SystemExit(f"bench_long_path: contact run exited with {code}")


def step_statistics(series: dict[str, dict[str, list[float]]]) -> dict:
    """Median and fastest seconds of a step (whole, and writing its files; wall and CPU) in
    the first and the last window, and last over first.  On a shared machine the load of
    other jobs changes along a long run: the fastest step of a window is the cost of a step
    when the machine lets it run, the median what it cost in that window's load."""
    out = {}
    for name in SERIES:
        first, last = series["first"].get(name), series["last"].get(name)
        if not first or not last:
            continue
        for stat, f in (("median", np.median), ("min", np.min)):
            a, b = float(f(first)), float(f(last))
            out[f"{name}_{stat}_first"], out[f"{name}_{stat}_last"] = round(a, 5), round(b, 5)
            out[f"{name}_{stat}_ratio"] = round(b / a, 3) if a > 0 else float("nan")
    return out


def windows(rows: list[dict], steps: int, window: int) -> dict:
    """The cost of a step late in the path against early: wall and CPU seconds per step of
    the last ``window`` steps over those of the first (from the end of step 1, whose forms
    are compiled, to step ``window``), and the RSS growth per step (KiB) from step
    ``window`` to the last."""
    at = {r["step"]: r for r in rows}
    first, early, late, last = at[1], at[window], at[steps - window], at[steps]
    out = {}
    for key in ("seconds", "cpu_seconds", "output_seconds", "output_cpu_seconds"):
        a = (early[key] - first[key]) / (window - 1)
        b = (last[key] - late[key]) / window
        out[f"{key}_per_step_first"], out[f"{key}_per_step_last"] = round(a, 5), round(b, 5)
        out[f"{key}_ratio"] = round(b / a, 3) if a > 0 else float("nan")
    growth = 1024 * (last["rss_mib"] - early["rss_mib"]) / (steps - window)
    out["rss_kib_per_step"] = round(growth, 3)
    return out


def summary(rows: list[dict], steps: int, start: int) -> str:
    """Per-step cost and the change of each figure from the sample at ``start`` on."""
    first = next(r for r in rows if r["step"] >= start)
    last = rows[-1]
    span = max(last["step"] - first["step"], 1)

    def change(key: str) -> str:
        return f"{first[key]} -> {last[key]}"

    cpu = last["cpu_seconds"]
    growth = 1024 * (last["rss_mib"] - first["rss_mib"]) / span
    return (
        f"{last['step']} of {steps} steps in {last['seconds']:.1f} s ({cpu:.1f} s CPU, "
        f"{1000 * cpu / last['step']:.1f} ms CPU per step); from step {first['step']} to "
        f"{last['step']}: free communicators {change('free_communicators')}, live PETSc "
        f"objects {change('petsc_objects')}, PETSc options {change('petsc_options')}, RSS "
        f"{change('rss_mib')} MiB ({growth:.2f} KiB per step)"
    )


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--scene", default=str(ROOT / "configs" / "signorini_square.yaml"))
    p.add_argument(
        "--set",
        dest="sets",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="scene overrides (default for the default scene: mesh.cells=[4,4])",
    )
    p.add_argument("--steps", type=int, default=2000)
    p.add_argument("--every", type=int, default=100, help="steps between two samples")
    p.add_argument(
        "--start", type=int, default=200, help="the summary's changes count from this step"
    )
    p.add_argument(
        "--window",
        type=int,
        default=250,
        help="steps of the first and the last window compared (time per step, RSS growth)",
    )
    p.add_argument("--cli", action="store_true", help="run `contact run` instead of the API")
    p.add_argument(
        "--no-collect",
        action="store_true",
        help="no garbage collection before a sample (what is left to Python's own)",
    )
    p.add_argument(
        "--out", help="CSV file (default: demos/results/long_path/<scene>_<mode>_np<ranks>.csv)"
    )
    args = p.parse_args()
    comm = MPI.COMM_WORLD
    default_scene = args.scene.endswith("signorini_square.yaml")
    sets = args.sets or (["mesh.cells=[4,4]"] if default_scene else [])
    sets = [*sets, f"load.steps={args.steps}"]
    mode = "cli" if args.cli else "api"
    if comm.rank == 0:
        print(
            f"bench_long_path: {Path(args.scene).name} {' '.join(sets)}, {mode}, "
            f"{comm.size} rank(s)",
            flush=True,
        )
    window = min(args.window, args.steps // 2)
    also = (window, args.steps - window, args.steps)
    sample = Sampler(
        args.every, comm, collect=not args.no_collect, also=also, window=window, steps=args.steps
    )
    if args.cli:
        run_cli(args.scene, sets, sample, comm)
    else:
        run_api(args.scene, sets, sample)
    flat = windows(sample.rows, args.steps, window) if window > 1 else {}
    stats = step_statistics(sample.series) if window > 1 else {}
    flat.update(stats)
    if comm.rank == 0:
        print(summary(sample.rows, args.steps, args.start), flush=True)
        if flat:
            print(
                f"time per step, last {window} steps / first {window}: wall "
                f"{1000 * flat['seconds_per_step_last']:.1f} / "
                f"{1000 * flat['seconds_per_step_first']:.1f} ms = {flat['seconds_ratio']:.3f}, "
                f"CPU {1000 * flat['cpu_seconds_per_step_last']:.1f} / "
                f"{1000 * flat['cpu_seconds_per_step_first']:.1f} ms = "
                f"{flat['cpu_seconds_ratio']:.3f}; of which writing the step's files: wall "
                f"{1000 * flat['output_seconds_per_step_last']:.1f} / "
                f"{1000 * flat['output_seconds_per_step_first']:.1f} ms = "
                f"{flat['output_seconds_ratio']:.3f}, CPU "
                f"{1000 * flat['output_cpu_seconds_per_step_last']:.1f} / "
                f"{1000 * flat['output_cpu_seconds_per_step_first']:.1f} ms = "
                f"{flat['output_cpu_seconds_ratio']:.3f}; RSS growth from step {window} on "
                f"{flat['rss_kib_per_step']:.2f} KiB per step",
                flush=True,
            )
            for name in SERIES:
                if f"{name}_median_ratio" in stats:
                    print(
                        f"  {name} (ms, last {window} / first {window}): median "
                        f"{1000 * stats[f'{name}_median_last']:.1f} / "
                        f"{1000 * stats[f'{name}_median_first']:.1f} = "
                        f"{stats[f'{name}_median_ratio']:.3f}, fastest "
                        f"{1000 * stats[f'{name}_min_last']:.1f} / "
                        f"{1000 * stats[f'{name}_min_first']:.1f} = "
                        f"{stats[f'{name}_min_ratio']:.3f}",
                        flush=True,
                    )
    name = Path(args.scene).stem
    out = args.out or ROOT / "demos" / "results" / "long_path" / f"{name}_{mode}_np{comm.size}.csv"
    save_csv(
        out,
        [{"scene": name, "mode": mode, "ranks": comm.size, **r, **flat} for r in sample.rows],
    )


if __name__ == "__main__":
    PETSc.Log.begin()  # petsc_objects counts from here
    main()
