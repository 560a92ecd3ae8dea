"""A long load path on a tiny mesh: MPI communicators, PETSc objects and memory step by step.

A load path releases each step once the next one is solved (contact/drivers/load_path.py) and every
solve destroys the PETSc objects it made (contact/base/lifetime.py), so these figures must stay
flat however many steps run.  Before, every step kept its PETSc objects and functions: the
communicators ran out (MPICH has 2048) and a path ended at step 509 with an MPI abort.

    python demos/bench/bench_long_path.py                          # 2000 steps, the API, serial
    mpirun -n 2 python demos/bench/bench_long_path.py
    python demos/bench/bench_long_path.py --cli --scene configs/friction_block_2d.yaml \\
        --set "mesh.cells=[8,2]"                                    # `contact run`, its files too
    python demos/bench/bench_long_path.py --steps 600 --every 50 --out /tmp/long_path.csv

The API mode runs :func:`contact.run_load_path`; the CLI mode runs ``contact run`` in this
process (VTK and PNG off unless ``--set`` turns them on), taking its figures after each
step's files are written.  Every ``--every`` steps, after Python's garbage collection
(``--no-collect``: without; reference cycles, e.g. UFL's, then wait for Python's own): the
wall and CPU seconds so far, the resident set size (MiB, the largest over the ranks), the
communicators MPI can still create (:func:`contact.base.lifetime.free_communicators`), the
live PETSc objects (:func:`contact.base.lifetime.petsc_objects`) and the entries of PETSc's
options database (the largest counts over the ranks).  Prints one row per sample and a
summary, writes CSV (default demos/results/long_path/<scene>_<mode>_np<ranks>.csv).
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

from common import save_csv
from mpi4py import MPI
from petsc4py import PETSc

ROOT = Path(__file__).resolve().parents[2]


class Sampler:
    """The figures of the steps ``every``, 2·``every``, … (and step 1)."""

    def __init__(self, every: int, comm: MPI.Comm, collect: bool = True):
        self.every, self.comm, self.collect = every, comm, collect
        self.rows: list[dict] = []
        self.wall, self.cpu = time.perf_counter(), time.process_time()

    def __call__(self, step) -> None:
        if step.index != 1 and step.index % self.every:
            return
        if self.collect:
            gc.collect()
        comm = self.comm
        row = {
            "step": step.index,
            "converged": bool(step.result.converged),
            "seconds": round(time.perf_counter() - self.wall, 2),
            "cpu_seconds": round(comm.allreduce(time.process_time() - self.cpu, op=MPI.MAX), 2),
            "rss_mib": round(comm.allreduce(rss_mib(), op=MPI.MAX), 2),
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
        write(writer, step)
        sample(step)

    step_report.StepWriter.__call__ = write_and_sample
    folder = comm.bcast(tempfile.mkdtemp(prefix="long_path_") if comm.rank == 0 else None)
    try:
        args = ["run", scene_file, "-o", str(Path(folder) / "out"), "-q"]
        for s in ["output.vtk=false", "output.png=false", *sets]:
            args += ["--set", s]
        code = cli.main(args)
    finally:
        step_report.StepWriter.__call__ = write
        comm.barrier()
        if comm.rank == 0:
            shutil.rmtree(folder, ignore_errors=True)
    if code != 0:
        raise SystemExit(f"bench_long_path: contact run exited with {code}")


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
    sample = Sampler(args.every, comm, collect=not args.no_collect)
    if args.cli:
        run_cli(args.scene, sets, sample, comm)
    else:
        run_api(args.scene, sets, sample)
    if comm.rank == 0:
        print(summary(sample.rows, args.steps, args.start), flush=True)
    name = Path(args.scene).stem
    out = args.out or ROOT / "demos" / "results" / "long_path" / f"{name}_{mode}_np{comm.size}.csv"
    save_csv(out, [{"scene": name, "mode": mode, "ranks": comm.size, **r} for r in sample.rows])


if __name__ == "__main__":
    PETSc.Log.begin()  # petsc_objects counts from here
    main()
