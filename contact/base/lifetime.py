"""The lifetime of PETSc objects and MPI communicators: who destroys what, and how to count.

MPI can hold a few thousand communicators at once (MPICH: 2048 context ids), and a load
path solves one problem per step, so nothing of a step may outlive it unnoticed:

* on more than one rank, petsc4py does not destroy a PETSc object whose last wrapper is
  collected: it queues it for a collective ``PETSc.garbage_cleanup`` on the object's
  communicator (DOLFINx index maps each have their own), which nothing calls — the object
  and communicators with it stay (2 per solve, measured).  Serially it goes with its
  wrapper: at once, or when the cycle collector gets to a cycle the wrapper is in;
* every live DOLFINx vector (a function) holds two neighbourhood communicators on more than
  one rank, every function space one.

So the PETSc objects of a solve and of a problem are destroyed explicitly
(:func:`destroy`, :class:`Owner`, ``DiscreteProblem.destroy``) and a load path releases
each finished step (``Result.release``, ``Step.release``).  Before, a path ended at step 509
(issue 26: 4 communicators per step).  Three figures a long run must keep flat
(:func:`free_communicators`, :func:`petsc_objects`, :func:`rss_mib`) serve the tests and
``demos/bench/bench_long_path.py``.
"""

from __future__ import annotations

import ctypes
import hashlib
import re
import tempfile
from pathlib import Path
from typing import Any, TypeVar

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc

T = TypeVar("T")


def destroy(*objects: Any) -> None:
    """``destroy()`` each object given: PETSc objects (None and destroyed ones skipped) and
    objects of this package that own some (a ``destroy`` method)."""
    for obj in objects:
        if obj is None or isinstance(obj, PETSc.Object) and not obj.handle:
            continue
        obj.destroy()


class Owner:
    """The PETSc objects of one task (or objects holding some, see :func:`destroy`),
    destroyed together by :meth:`close` or on leaving a ``with`` block:
    ``x = owner.own(problem.b.duplicate())``."""

    def __init__(self) -> None:
        self._objects: list[Any] = []

    def own(self, obj: T) -> T:
        """Register ``obj`` for destruction; returns it."""
        self._objects.append(obj)
        return obj

    def close(self) -> None:
        """Destroy every owned object, the last owned first."""
        objects, self._objects = self._objects[::-1], []
        destroy(*objects)

    def __enter__(self) -> Owner:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()


def free_communicators(comm: MPI.Comm = MPI.COMM_WORLD, limit: int = 4096) -> int:
    """How many more communicators MPI can create right now (``comm.Dup`` until MPI refuses,
    at most ``limit``; all freed again).  Collective."""
    handler = comm.Get_errhandler()
    comm.Set_errhandler(MPI.ERRORS_RETURN)
    made: list[MPI.Comm] = []
    try:
        while len(made) < limit:
            made.append(comm.Dup())
    except MPI.Exception:
        pass
    finally:
        for c in made:
            c.Free()
        comm.Set_errhandler(handler)
        handler.Free()
    return comm.allreduce(len(made), op=MPI.MIN)


def petsc_objects() -> dict[str, int]:
    """Live PETSc objects per class on this rank (created − destroyed since
    ``PETSc.Log.begin()``, which must have been called first, before the objects counted)."""
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "log.txt"
        viewer = PETSc.Viewer().createASCII(str(path), comm=PETSc.COMM_SELF)
        PETSc.Log.view(viewer)
        viewer.destroy()
        text = path.read_text()
    live: dict[str, int] = {}
    table = text.split("Object Type", 1)[-1].split("=" * 20, 1)[0]
    for name, made, gone in re.findall(r"^\s*(\S.*?)\s+(\d+)\s+(\d+)\s*$", table, re.M):
        live[name] = live.get(name, 0) + int(made) - int(gone)
    live.pop("Viewer", None)  # the viewer of this very call
    return {k: v for k, v in live.items() if v}


def rss_mib() -> float:
    """Resident set size of this process (MiB; Linux ``/proc/self/status``)."""
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024.0
    return float("nan")


#: give freed heap memory back to the system after a level is released (glibc only;
#: False: the old path, where the allocator keeps it for later requests)
TRIM = True


def return_freed_memory() -> bool:
    """Ask the C allocator to give its free heap pages back to the system (glibc's
    ``malloc_trim(0)``); returns whether it could be asked (glibc) and :data:`TRIM` is on.

    Freed arrays of a released level stay in the process as free heap that a later, larger
    level can rarely reuse whole (its arrays are bigger), so the resident size keeps
    growing with the levels without this (demos/RESULTS.md §14)."""
    if not TRIM:
        return False
    try:
        libc = ctypes.CDLL("libc.so.6")
        trim = libc.malloc_trim
    except (OSError, AttributeError):  # not glibc
        return False
    trim(0)
    return True


#: :func:`record` keeps a digest of the arrays (False: a copy of them, the path before)
DIGESTS = True


def record(*arrays: Any) -> bytes | tuple[Any, ...]:
    """A record of the arrays' values that :func:`matches` compares later arrays with.

    A solver that skips work while its input has not changed (the law a preconditioner was
    built from, the iterate a residual was evaluated at) needs to know whether new arrays
    equal old ones, not the old values themselves.  With :data:`DIGESTS` the record is a
    32-byte BLAKE2b digest of the arrays' bytes, dtypes and shapes instead of a copy: at
    10⁶ DoFs a copy of a vector is 8 MB, and a solver holds several such records through
    its whole solve.  Equal bytes give equal digests; different ones give the same digest
    with probability 2⁻²⁵⁶.  (Bytes, not values: −0.0 and 0.0 differ, so a record errs
    only towards "changed", i.e. towards doing the work again.)

    Args:
        arrays: NumPy arrays (or objects :func:`numpy.asarray` takes).

    Returns:
        The digest (:data:`DIGESTS`), or a tuple of copies of the arrays.
    """
    if not DIGESTS:
        return tuple(np.array(a, copy=True) for a in arrays)
    digest = hashlib.blake2b(digest_size=32)
    for a in arrays:
        a = np.ascontiguousarray(a)
        digest.update(f"{a.dtype.str}{a.shape}".encode())
        digest.update(memoryview(a).cast("B"))
    return digest.digest()


def matches(old: bytes | tuple[Any, ...] | None, *arrays: Any) -> bool:
    """Whether ``arrays`` equal those of the :func:`record` ``old`` (None: no record, False).

    Args:
        old: a record made by :func:`record`, or None.
        arrays: the arrays to compare, in the order of the record's.

    Returns:
        True if every array equals its recorded one (a digest: its bytes; copies: its values).
    """
    if old is None:
        return False
    if isinstance(old, bytes):
        return old == record(*arrays) if DIGESTS else False
    return len(old) == len(arrays) and all(
        np.array_equal(a, b) for a, b in zip(old, arrays, strict=True)
    )
