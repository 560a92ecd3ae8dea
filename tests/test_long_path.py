"""Load paths of any length (issue 26): a path of 600 tiny steps — past step 509, where MPICH's
2048 communicators ran out when every step kept its PETSc objects and functions — runs to the
end with the communicators MPI can still create and the live PETSc objects constant after the
first steps, and the memory growing by no more than the few KiB of figures a released step
keeps.  Serially through the API; through `contact run` on two ranks a path of 250 steps (the
free communicators and live objects flat from step 50 on would run out nowhere, and 250 steps
at the ~65 KiB a step kept before is 13 MiB of growth, 5× the limit: a 600-step CLI run cost
67 s of the suite).  The same run with 2000 steps: demos/bench/bench_long_path.py (its CSV in
demos/results/long_path/)."""

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


def check_flat(rows: list[dict], steps: int = STEPS) -> None:
    """Converged to the last step; from the sample at step 50 on (two steps alive, as from
    step 2 on) the free communicators and the live PETSc objects do not change, PETSc's
    options database is empty between steps, and the memory grows by less than
    RSS_GROWTH_MIB_PER_STEP a step from the sample nearest a third of the path on."""
    at = {int(r["step"]): r for r in rows}
    assert max(at) == steps and all(r["converged"] == "True" for r in rows)
    first, last = at[EVERY], at[steps]
    for key in ("free_communicators", "petsc_objects"):
        assert [r[key] for r in rows[1:]] == [first[key]] * (len(rows) - 1), key
    assert {r["petsc_options"] for r in rows} == {0.0}  # each solve deletes its own
    start = min(at, key=lambda k: abs(k - steps / 3))
    assert last["rss_mib"] - at[start]["rss_mib"] < RSS_GROWTH_MIB_PER_STEP * (steps - start)


@pytest.mark.slow
def test_a_long_path_keeps_communicators_objects_and_memory_flat(tmp_path):
    check_flat(run_bench(tmp_path, 1))


@pytest.mark.slow
@pytest.mark.mpi
def test_contact_run_of_a_long_path_on_two_ranks(tmp_path):
    """`contact run` under mpirun (one contact CSV per step written as it goes; the API's
    path inside): on more than one rank a PETSc object that is not destroyed is never freed."""
    check_flat(run_bench(tmp_path, 2, "--cli", steps=CLI_STEPS), CLI_STEPS)
