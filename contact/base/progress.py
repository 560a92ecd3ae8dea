"""Progress lines during long work: at most one every ``PERIOD`` seconds, on rank 0 only.

The CLI switches them on for a verbose run (:func:`enable`).  Library code reports at the
boundaries of its phases (:func:`note`: assembled, solved, estimated, refined, written)
and from the Krylov iterations of its linear solves (:func:`watch`); a line is printed only
when ``PERIOD`` seconds have passed since the last one, so a short run prints none and a
long 3D level shows what it is doing instead of staying silent for a minute.  A phase
without callbacks inside (a direct factorization, GAMG's set-up, a mesh refinement) is
reported when it ends.  Off (the default, as for the Python API) every call returns at
once.
"""

from __future__ import annotations

import time
from collections.abc import Callable

from mpi4py import MPI
from petsc4py import PETSc

PERIOD = 5.0  # seconds between two progress lines at least

_state = {"on": False, "root": False, "last": 0.0, "period": PERIOD}


def enable(comm: MPI.Comm, period: float = PERIOD) -> None:
    """Print progress lines from now on (rank 0 of ``comm``; the other ranks stay silent).
    Call it on every rank: :func:`watch` then sets the same monitors everywhere (a monitor
    can make PETSc compute a residual norm, a collective)."""
    _state.update(on=True, root=comm.rank == 0, last=time.monotonic(), period=period)


def disable() -> None:
    _state["on"] = False


def note(text: str | Callable[[], str]) -> bool:
    """Print ``  … text`` if ``PERIOD`` seconds passed since the last line (``text`` may be a
    function, called only then); True if printed."""
    if not (_state["on"] and _state["root"]):
        return False
    now = time.monotonic()
    if now - _state["last"] < _state["period"]:
        return False
    _state["last"] = now
    print(f"  … {text() if callable(text) else text}", flush=True)
    return True


def heard() -> None:
    """Another line was just printed (a Newton iteration, a level row): restart the clock."""
    _state["last"] = time.monotonic()


def watch(ksp: PETSc.KSP, label: str) -> None:
    """Report the Krylov iterations of ``ksp``'s solves (``label``: which solve), at most
    once per ``PERIOD`` seconds: iterations so far, residual norm, seconds in this solve
    (collective: the monitor is set on every rank, only rank 0 prints)."""
    if not _state["on"]:
        return
    start = [time.monotonic()]

    def monitor(_ksp, its: int, rnorm: float) -> None:
        if its == 0:  # a new solve
            start[0] = time.monotonic()
            return
        note(
            lambda: (
                f"{label}: {its} Krylov iterations, |r| = {rnorm:.2e}, "
                f"{time.monotonic() - start[0]:.0f} s in this solve"
            )
        )

    ksp.setMonitor(monitor)
