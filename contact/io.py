"""Output: an atomically written result folder with JSON and CSV files (VTK: :mod:`contact.series`).

``atomic_folder`` gives a temporary sibling directory; only when everything inside was
written does rank 0 rename it to the requested name.  After a failure there is either
no folder or the previous complete one — never a half-written folder.
"""
from __future__ import annotations

import contextlib
import csv
import json
import os
import shutil
import tempfile
from pathlib import Path
from typing import Any, Iterator, Mapping

from mpi4py import MPI

from dolfinx import fem


@contextlib.contextmanager
def atomic_folder(outdir: str | Path, comm: MPI.Comm = MPI.COMM_WORLD) -> Iterator[Path]:
    """Yield a temporary directory that becomes ``outdir`` on success (collective)."""
    outdir = Path(outdir).resolve()
    tmp = None
    if comm.rank == 0:
        outdir.parent.mkdir(parents=True, exist_ok=True)
        tmp = tempfile.mkdtemp(prefix=f".{outdir.name}.partial-", dir=outdir.parent)
    tmp = Path(comm.bcast(tmp, root=0))
    ok = False
    try:
        yield tmp
        ok = True
    finally:
        ok = comm.allreduce(ok, op=MPI.LAND)
        if comm.rank == 0:
            if ok:
                old = None
                if outdir.exists():
                    old = outdir.with_name(f".{outdir.name}.old-{os.getpid()}")
                    outdir.rename(old)
                umask = os.umask(0)
                os.umask(umask)
                tmp.chmod(0o777 & ~umask)  # mkdtemp makes 0700; give the folder the usual mode
                tmp.rename(outdir)
                if old is not None:
                    shutil.rmtree(old, ignore_errors=True)
            else:
                shutil.rmtree(tmp, ignore_errors=True)
        comm.barrier()


def write_json(path: str | Path, data: Mapping[str, Any], comm: MPI.Comm = MPI.COMM_WORLD) -> None:
    if comm.rank == 0:
        Path(path).write_text(json.dumps(data, indent=2, default=_jsonable) + "\n")


def write_csv(path: str | Path, rows: list[Mapping[str, Any]], comm: MPI.Comm = MPI.COMM_WORLD) -> None:
    """Rows of dicts to CSV (header from the union of keys, in first-seen order)."""
    if comm.rank != 0:
        return
    keys: list[str] = []
    for row in rows:
        keys += [k for k in row if k not in keys]
    with open(path, "w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=keys)
        writer.writeheader()
        writer.writerows(rows)


def _jsonable(obj: Any) -> Any:
    if hasattr(obj, "item"):
        return obj.item()
    if isinstance(obj, Path):
        return str(obj)
    raise TypeError(f"not JSON serialisable: {type(obj).__name__}")


def gather_nodal(fn: fem.Function) -> tuple:
    """(coordinates, values) of all owned nodes of a P-k function (values (n, bs) for
    vector functions) on rank 0, sorted
    lexicographically by coordinate (so serial and parallel runs compare entry by entry);
    ``(None, None)`` on other ranks."""
    import numpy as np

    V = fn.function_space
    n, bs = V.dofmap.index_map.size_local, V.dofmap.index_map_bs
    X = V.tabulate_dof_coordinates()[:n]
    vals = fn.x.array[: n * bs].reshape(n, bs) if bs > 1 else fn.x.array[:n]
    parts = V.mesh.comm.gather((X, vals), root=0)
    if V.mesh.comm.rank != 0:
        return None, None
    X = np.vstack([p[0] for p in parts])
    vals = np.concatenate([p[1] for p in parts])
    order = np.lexsort(np.round(X, 12).T[::-1])
    return X[order], vals[order]
