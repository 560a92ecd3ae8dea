"""Errors every layer raises or reads: :class:`ConfigError` (bad input, one line),
:class:`ContactWarning` (a one-line warning) and :func:`petsc_message` (PETSc's own message
of a ``petsc4py.PETSc.Error``, one line)."""

from __future__ import annotations

import re


class ConfigError(ValueError):
    """Invalid scene or study input; ``str(err)`` is the one-line message for the user."""


class ContactWarning(UserWarning):
    """A one-line warning about a problem or a scene (printed as ``contact: warning: ...`` by
    the CLI)."""


def petsc_message(err: BaseException) -> str:
    """PETSc's own message of a ``petsc4py.PETSc.Error``: the last line of its report that
    is not a stack frame (``[0] Could not locate solver type ...``), without the rank
    prefix; the error code when the report has no such line."""
    lines = [re.sub(r"^\[\d+\]\s*", "", ln.strip()) for ln in str(err).strip().splitlines()]
    text = [ln for ln in lines if ln and not _FRAME.match(ln) and not ln.startswith("error code")]
    return text[-1] if text else f"error code {getattr(err, 'ierr', '?')}"


_FRAME = re.compile(r"^\w+\(\) at \S+:\d+$")  # "KSPSetUp() at .../itfunc.c:428"
