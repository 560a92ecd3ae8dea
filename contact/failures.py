"""Exit codes and one-line failure messages.

=====  ==================================================================================
code   meaning
=====  ==================================================================================
0      solved (and written)
1      the solver did not converge (completed adaptive levels are kept, see the README)
2      bad input: one line ``contact: error: <key path, file or option>: <problem>``
3      internal error: one line ``contact: internal error: <what failed> (rerun with
       --debug for the traceback)``; ``--debug`` or ``CONTACT_DEBUG=1`` prints it
=====  ==================================================================================

Every message the tool prints about a failure goes through :func:`one_line`: whitespace
(newlines included) collapsed, at most :data:`MAX_LINE` characters.  :func:`describe`
turns any exception into such a line; for a PETSc error it keeps PETSc's own message (the
last line of its report), not the stack of function names above it.
"""
from __future__ import annotations

import re

SOLVED, NOT_CONVERGED, BAD_INPUT, INTERNAL = 0, 1, 2, 3
MAX_LINE = 300  # characters of one failure message


def one_line(text: object, limit: int = MAX_LINE) -> str:
    """``text`` on one line (runs of whitespace become one space), cut to ``limit``
    characters with a trailing ``…``."""
    line = " ".join(str(text).split())
    return line if len(line) <= limit else line[: limit - 1].rstrip() + "…"


def petsc_message(err: BaseException) -> str:
    """PETSc's own message of a ``petsc4py.PETSc.Error``: the last line of its report that
    is not a stack frame (``[0] Could not locate solver type ...``), without the rank
    prefix; the error code when the report has no such line."""
    lines = [re.sub(r"^\[\d+\]\s*", "", ln.strip()) for ln in str(err).strip().splitlines()]
    text = [ln for ln in lines if ln and not _FRAME.match(ln) and not ln.startswith("error code")]
    return text[-1] if text else f"error code {getattr(err, 'ierr', '?')}"


_FRAME = re.compile(r"^\w+\(\) at \S+:\d+$")  # "KSPSetUp() at .../itfunc.c:428"


def describe(err: BaseException, limit: int = MAX_LINE) -> str:
    """One line (at most ``limit`` characters) naming what failed: ``TypeName: message``;
    for PETSc errors PETSc's own message, for MemoryError "out of memory"."""
    text = str(err)
    if isinstance(err, MemoryError):
        text = f"out of memory{': ' + text if text else ''}"
    elif type(err).__name__ == "Error" and type(err).__module__.startswith("petsc4py"):
        message = petsc_message(err)
        text = f"PETSc error {getattr(err, 'ierr', '?')}" + ("" if message.startswith("error code") else f": {message}")
    else:
        text = f"{type(err).__name__}: {text}" if text else type(err).__name__
    return one_line(text, limit)
