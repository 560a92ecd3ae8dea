"""Exit codes, one-line failure messages, and how MPI ranks agree on a failure.

=====  ==================================================================================
code   meaning
=====  ==================================================================================
0      solved (and written)
1      the solver did not converge (the finished adaptive levels are kept: docs/guide/safe-runs.md)
2      bad input: one line ``contact: error: <key path, file or option>: <problem>``
3      internal error: one line ``contact: internal error: <what failed> (rerun with
       --debug for the traceback)``; ``--debug`` or ``CONTACT_DEBUG=1`` prints it
130    interrupted (Ctrl-C, SIGINT): one line ``contact: interrupted``
143    terminated (SIGTERM: ``kill``, a batch system's end of job): one line
       ``contact: terminated (SIGTERM)``, handled as Ctrl-C is
=====  ==================================================================================

Every message the tool prints about a failure goes through :func:`one_line`: whitespace
(newlines included) collapsed, at most :data:`MAX_LINE` characters.  :func:`describe`
turns any exception into such a line; for a PETSc error it keeps PETSc's own message (the
last line of its report), not the stack of function names above it.

**Failures under MPI.**  Every rank enters every collective, in the same order, and the
code follows two rules so that an exception on one rank can never leave the others
waiting:

1. The decision to enter a collective depends only on data that is the same on every rank
   (the configuration, global sizes, reduced or broadcast values) — never on the rank
   number alone or on data that only some ranks hold (a table gathered on rank 0 is
   None elsewhere: decide on rank 0 and broadcast).
2. No collective on the way out of an exception: ``except``, ``finally`` and ``__exit__``
   code does not communicate (destroying PETSc objects and removing files is local).  A
   rank that raises goes straight to a handler that calls :func:`all_failed` — a
   non-blocking barrier on a communicator used for nothing else, waited for at most
   :data:`AGREE_SECONDS`.  If every rank failed (a collective failure: bad input, a PETSc
   error raised on every rank, Ctrl-C forwarded to every rank by mpiexec) the ranks
   return together and rank 0 reports once; otherwise the failing rank reports with its
   rank number and :func:`abort` ends the job with ``MPI_Abort(code)``, whose code mpiexec
   returns — the other ranks may be waiting in a collective the failing rank will never
   enter.  The handlers are ``contact.app.cli.main`` and, for one run of a study,
   ``contact.app.study.run_one`` (a failure on every rank is a row, on some ranks an abort).

Collective checks that raise after a reduction (the same exception on every rank) and
probes whose expected outcome is an exception (PETSc's answer to a set of options) are
not failures in this sense.
"""

from __future__ import annotations

import sys
import time

from ..base.errors import petsc_message

SOLVED, NOT_CONVERGED, BAD_INPUT, INTERNAL = 0, 1, 2, 3
INTERRUPTED = 130  # Ctrl-C: 128 + SIGINT, what a shell reports for a program SIGINT ended
TERMINATED = 143  # SIGTERM: 128 + 15
MAX_LINE = 300  # characters of one failure message
AGREE_SECONDS = 5.0  # how long a failing rank waits for the others to fail too (MPI)
# a failing rank's pause between its line and MPI_Abort (once, the line was lost)
ABORT_GRACE_SECONDS = 0.5


def one_line(text: object, limit: int = MAX_LINE) -> str:
    """``text`` on one line (runs of whitespace become one space), cut to ``limit``
    characters with a trailing ``…``."""
    line = " ".join(str(text).split())
    return line if len(line) <= limit else line[: limit - 1].rstrip() + "…"


def describe(err: BaseException, limit: int = MAX_LINE) -> str:
    """One line (at most ``limit`` characters) naming what failed: ``TypeName: message``;
    for PETSc errors PETSc's own message, for MemoryError "out of memory"."""
    text = str(err)
    if isinstance(err, MemoryError):
        text = f"out of memory{': ' + text if text else ''}"
    elif type(err).__name__ == "Error" and type(err).__module__.startswith("petsc4py"):
        message = petsc_message(err)
        text = f"PETSc error {getattr(err, 'ierr', '?')}" + (
            "" if message.startswith("error code") else f": {message}"
        )
    else:
        text = f"{type(err).__name__}: {text}" if text else type(err).__name__
    return one_line(text, limit)


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised by the handler the command line installs (:func:`on_sigterm`) where
    Python next runs — as Python raises KeyboardInterrupt for SIGINT — so that it takes
    Ctrl-C's way out (the output folder left as it was, every rank agreeing), with its own
    exit code :data:`TERMINATED`."""


def on_sigterm(signum, frame) -> None:
    """The SIGTERM handler of the command line (it replaces PETSc's, which prints its error
    stack and calls MPI_Abort): raise :class:`Terminated`."""
    raise Terminated()


def interruption(err: BaseException | None) -> KeyboardInterrupt | None:
    """The interrupt behind ``err`` (Ctrl-C's KeyboardInterrupt or SIGTERM's
    :class:`Terminated`): ``err`` itself or an error it caused (petsc4py turns a
    KeyboardInterrupt raised in a Python callback of a PETSc solve into PETSc error 101 with
    the interrupt as its cause); None if there is none."""
    seen: set[int] = set()
    while err is not None and id(err) not in seen:
        if isinstance(err, KeyboardInterrupt):
            return err
        seen.add(id(err))
        err = err.__cause__ or err.__context__
    return None


def interrupted(err: BaseException | None) -> bool:
    """Whether ``err`` is Ctrl-C or SIGTERM, or an error one of them caused
    (:func:`interruption`)."""
    return interruption(err) is not None


def interrupt_report(err: BaseException | None) -> tuple[int, str]:
    """The exit code and the line of an interrupted run: SIGTERM's (143, ``contact:
    terminated (SIGTERM)``) or Ctrl-C's (130, ``contact: interrupted``)."""
    if isinstance(interruption(err), Terminated):
        return TERMINATED, "contact: terminated (SIGTERM)"
    return INTERRUPTED, "contact: interrupted"


def all_failed(agree, seconds: float = AGREE_SECONDS) -> bool:
    """Called by a failing rank: whether every rank of ``agree`` (a communicator used for
    nothing else, e.g. a ``Dup`` of the job's) makes this call within ``seconds``, i.e.
    failed too.  A non-blocking barrier polled every 10 ms: a rank that waits in another
    collective never arrives.  True at once without MPI (``agree`` None or one rank)."""
    if agree is None or agree.size == 1:
        return True
    request, start = agree.Ibarrier(), time.monotonic()
    while not request.Test():
        if time.monotonic() - start > seconds:
            return False
        time.sleep(0.01)
    return True


def abort(comm, code: int, line: str) -> None:
    """End the whole MPI job with exit code ``code`` after printing ``line`` (one line,
    ``contact:`` becoming ``contact (rank r):``) on stderr: the way out of a failure on
    some ranks only (the module doc).  Does not return."""
    line = line.replace("contact:", f"contact (rank {comm.rank}):", 1)
    print(one_line(line), file=sys.stderr, flush=True)
    time.sleep(ABORT_GRACE_SECONDS)  # let mpiexec forward the line before it kills the job
    comm.Abort(code)
