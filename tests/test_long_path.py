"""Load paths of any length (issue 26): a path of 600 tiny steps — past step 509, where MPICH's
2048 communicators ran out when every step kept its PETSc objects and functions — runs to the
end with the communicators MPI can still create and the live PETSc objects constant after the
first steps, and the memory growing by no more than the few KiB of figures a released step
keeps.  Serially through the API; through `contact run` on two ranks a path of 250 steps (the
free communicators and live objects flat from step 50 on would run out nowhere, and 250 steps
at the ~65 KiB a step kept before is 13 MiB of growth, 5× the limit: a 600-step CLI run cost
67 s of the suite).  The same run with 2000 steps: demos/bench/bench_long_path.py (its CSV in
demos/results/long_path/).

The CLI run writes the scene's default outputs (the field series, pictures at the end): a
step's memory (its figures go to disk as it finishes, the path forgets it) and the time it
takes to write its files must not grow with the steps before it.  Before, solution.xdmf and
solution.pvd were rewritten whole at every step, from every step's XML kept in memory:
23 KiB per step (friction_block_2d, 8 × 2 cells, 2 ranks)."""

import csv
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
MPIRUN = Path(sys.executable).parent / "mpirun"
BENCH = ROOT / "demos" / "bench" / "bench_long_path.py"
STEPS, EVERY = 600, 50
#: the steps of the CLI run on two ranks
CLI_STEPS = 250
#: RSS growth allowed per step from a third of the path on: a released step keeps its figures
#: (history, options, timings: ~2-5 KiB measured); before, each step kept ~65 KiB on this
#: scene (8 MiB over steps 200-600)
RSS_GROWTH_MIB_PER_STEP = 8.0 / 400
#: the same for `contact run`, which forgets released steps: 1.1-1.6 KiB per step measured on
#: 2 ranks, of which ~0.6 KiB is CPython 3.12's pathlib, whose interned path parts are
#: immortal (108 B per distinct file name, six new names a step); before, 22 KiB per step.
#: The RSS depends on the allocator; the exact check of the CLI runs is the count of Python
#: objects, which must not change from step to step (check_flat's ``objects``)
CLI_RSS_GROWTH_MIB_PER_STEP = 3.0 / 1024
#: a path that forgets its steps keeps fewer Python objects than one per this many steps
OBJECT_STEPS = 10
#: the steps of the first and the last window whose per-step times are compared (serial CLI
#: run: on 2 ranks a rank's CPU time counts its waits for the other, which the load of other
#: jobs on the machine sways by 2x and more)
WINDOW = 100
#: the median CPU seconds of writing a step's files, last window over the first: 0.97-0.99
#: measured serially on a loaded machine (60 and 2000 steps); before, the collections'
#: rewriting made it grow with the steps
OUTPUT_TIME_RATIO = 1.25


def run_bench(tmp_path: Path, ranks: int, *args: str, steps: int = STEPS) -> list[dict]:
    out = tmp_path / "long_path.csv"
    cmd = [
        sys.executable,
        str(BENCH),
        "--steps",
        str(steps),
        "--every",
        str(EVERY),
        "--out",
        str(out),
        *args,
    ]
    if ranks > 1:
        cmd = [str(MPIRUN), "-n", str(ranks), *cmd]
    proc = subprocess.run(
        cmd,
        capture_output=True,
        text=True,
        timeout=1200,
        cwd=ROOT,
        env={**os.environ, "OMP_NUM_THREADS": "1"},
    )
    assert proc.returncode == 0, proc.stderr[-2000:]
    return [
        {k: v if k in ("scene", "mode", "converged") else float(v) for k, v in row.items()}
        for row in csv.DictReader(open(out))
    ]


def check_flat(
    rows: list[dict],
    steps: int = STEPS,
    growth: float = RSS_GROWTH_MIB_PER_STEP,
    objects: bool = False,
) -> None:
    """Converged to the last step; from the sample at step 50 on (two steps alive, as from
    step 2 on) the free communicators and the live PETSc objects do not change; with
    ``objects`` (a path that forgets its released steps) the objects Python's garbage
    collector tracks — an exact count, the same on any machine — grow by fewer than one per
    OBJECT_STEPS steps (a step that kept anything would keep at least one object; a cache
    filled once along the path is a few objects: 5 measured); PETSc's options database is
    empty between steps, and the memory grows by less than ``growth`` (MiB) a step from the
    sample nearest a third of the path on."""
    at = {int(r["step"]): r for r in rows}
    assert max(at) == steps and all(r["converged"] == "True" for r in rows)
    first, last = at[EVERY], at[steps]
    for key in ("free_communicators", "petsc_objects"):
        assert [r[key] for r in rows[1:]] == [first[key]] * (len(rows) - 1), key
    if objects:
        kept = last["python_objects"] - first["python_objects"]
        assert kept < (steps - EVERY) / OBJECT_STEPS, [r["python_objects"] for r in rows]
    assert {r["petsc_options"] for r in rows} == {0.0}  # each solve deletes its own
    start = min(at, key=lambda k: abs(k - steps / 3))
    assert last["rss_mib"] - at[start]["rss_mib"] < growth * (steps - start)


@pytest.mark.slow
def test_a_long_path_keeps_communicators_objects_and_memory_flat(tmp_path):
    check_flat(run_bench(tmp_path, 1))


@pytest.mark.slow
@pytest.mark.mpi
def test_contact_run_of_a_long_path_on_two_ranks(tmp_path):
    """`contact run` under mpirun with its default outputs (every step's field files and
    contact CSV written as it goes; the API's path inside): on more than one rank a PETSc
    object that is not destroyed is never freed; no Python object is kept per step (the
    step's figures go to disk, the collections are appended to); the memory stays flat."""
    rows = run_bench(tmp_path, 2, "--cli", steps=CLI_STEPS)
    check_flat(rows, CLI_STEPS, CLI_RSS_GROWTH_MIB_PER_STEP, objects=True)


@pytest.mark.slow
def test_contact_run_writes_each_step_in_the_same_time(tmp_path):
    """`contact run` serially with its default outputs: writing step k's files takes as long
    late in the path as early (median CPU seconds of the last 100 steps over the first 100)."""
    rows = run_bench(tmp_path, 1, "--cli", "--window", str(WINDOW), steps=CLI_STEPS)
    check_flat(rows, CLI_STEPS, CLI_RSS_GROWTH_MIB_PER_STEP, objects=True)
    assert rows[0]["output_cpu_median_ratio"] <= OUTPUT_TIME_RATIO, rows[0]


def test_series_append_each_step_and_keep_nothing_per_step(tmp_path):
    """The collections solution.xdmf, contact_surface.xdmf and solution.pvd are appended to,
    step by step: an entry once written is never rewritten (a step's cost does not grow with
    the steps before it: before, the files were rewritten whole at every step, from every
    step's XML kept in memory), the files are valid after every step, and the writers keep
    no per-step state."""
    from contact.output.surface import SurfaceFiles
    from contact.output.vtk import Series
    from contact.output.xdmf import XdmfSeries
    from contact.setup.meshes import Boundary

    import meshio
    import numpy as np
    from dolfinx import fem, mesh
    from mpi4py import MPI
    from readback import xdmf_steps

    msh = mesh.create_unit_square(MPI.COMM_SELF, 2, 2)
    V = fem.functionspace(msh, ("Lagrange", 1))
    u = fem.Function(V, name="u")
    fields = [fem.Function(V, name=n) for n in ("u_h", "lambda_h", "gap", "active")]
    msh.topology.create_connectivity(1, 2)
    bottom = mesh.locate_entities_boundary(msh, 1, lambda x: x[1] < 1e-10)
    tags = mesh.meshtags(msh, 1, bottom, np.full(len(bottom), 1, dtype=np.int32))
    boundary = Boundary(tags, {"bottom": 1}, {"bottom": "contact"})
    xdmf, pvd = XdmfSeries(tmp_path, "s", MPI.COMM_SELF), Series(tmp_path, "s", MPI.COMM_SELF)
    surface = SurfaceFiles(tmp_path, False, MPI.COMM_SELF)
    writers = (xdmf, pvd, surface, surface._series)
    surface_path = surface._series.path

    def state() -> dict:  # every attribute of the writers, containers by their length
        return {
            (type(w).__name__, k): len(v) if hasattr(v, "__len__") else type(v).__name__
            for w in writers
            for k, v in vars(w).items()
            if k not in ("count",)
        }

    for k in range(40):
        u.x.array[:] = k
        xdmf.write(0.5 * k, [u])
        pvd.write(0.5 * k, [u])
        surface.write_step(0.5 * k, boundary, fields)
        if k == 9:  # mark the first entries: a rewrite of the whole file would undo it
            before = state()
            marks = ((xdmf.path, 'Value="0.0"'), (pvd.path, 'timestep="0.0"'))
            for path, old in (*marks, (surface_path, 'Value="0.0"')):
                text = path.read_text()
                assert text.count(old) == 1
                path.write_text(text.replace(old, old.replace("0.0", "9.0")))
        if k in (10, 39):
            assert len(xdmf_steps(xdmf.path)) == k + 1
            assert len(xdmf_steps(surface_path)) == k + 1
            assert len(meshio_times(pvd.path)) == k + 1
    assert state() == before
    times = [9.0] + [0.5 * k for k in range(1, 40)]
    assert [s["time"] for s in xdmf_steps(xdmf.path)] == times
    assert [s["time"] for s in xdmf_steps(surface_path)] == times
    assert meshio_times(pvd.path) == times
    for path in (xdmf.path, surface_path):
        with meshio.xdmf.TimeSeriesReader(path) as reader:
            assert reader.num_steps == 40


def meshio_times(pvd) -> list[float]:
    """The time values of a .pvd (its XML)."""
    import xml.etree.ElementTree as ET

    return [float(d.get("timestep")) for d in ET.parse(pvd).getroot().iter("DataSet")]
