"""Errors every layer raises or reads.

:class:`ConfigError` is bad input (one line); :class:`ContactWarning` a one-line warning;
:func:`petsc_message` is PETSc's own message of a ``petsc4py.PETSc.Error`` (one line).
"""

from __future__ import annotations

import re


class ConfigError(ValueError):
    """Invalid scene or study input; ``str(err)`` is the one-line message for the user.

    Raised by :func:`contact.load_scene` (and the keyword options of :func:`contact.solve`
    and :func:`contact.adapt`) for a wrong key, value, expression or file; the message
    names it, e.g. ``solver.method: 'fbb' is not one of fb, min, blend, vinewtonrsls,
    vinewtonssls``. ``contact run`` prints it as one line and exits with code 2. A
    ``ValueError``, so code that catches those catches it too.
    """


class ContactWarning(UserWarning):
    """A one-line warning about a problem or a scene.

    The CLI prints it as ``contact: warning: ...``.
    """


def petsc_message(err: BaseException) -> str:
    """Return PETSc's own message of a ``petsc4py.PETSc.Error``, one line.

    The last line of its report that is not a stack frame (``[0] Could not locate solver
    type ...``), without the rank prefix; the error code when the report has no such line.
    """
    lines = [re.sub(r"^\[\d+\]\s*", "", ln.strip()) for ln in str(err).strip().splitlines()]
    text = [ln for ln in lines if ln and not _FRAME.match(ln) and not ln.startswith("error code")]
    return text[-1] if text else f"error code {getattr(err, 'ierr', '?')}"


_FRAME = re.compile(r"^\w+\(\) at \S+:\d+$")  # "KSPSetUp() at .../itfunc.c:428"
