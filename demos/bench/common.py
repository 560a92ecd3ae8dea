"""Helpers shared by the benchmark scripts of this folder."""

from __future__ import annotations

from pathlib import Path

from contact.output.folder import write_csv

from mpi4py import MPI


def save_csv(path: str | Path, rows: list[dict]) -> None:
    """Write the rows (rank 0; the folder is made) and say where."""
    if MPI.COMM_WORLD.rank != 0:
        return
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    write_csv(out, rows)
    print(f"wrote {out}", flush=True)
