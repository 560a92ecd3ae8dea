"""The ground floor: what every layer may use and that imports nothing of ``contact``.

* :mod:`.lifetime` — who destroys which PETSc object; counting communicators, PETSc
  objects and memory;
* :mod:`.norms` — ‖v‖₂ of a PETSc vector, typed as a float;
* :mod:`.progress` — progress lines of long runs;
* :mod:`.timing` — :class:`~.timing.Timer`, the seconds of a phase into the caller's dict;
* :mod:`.version` — the package's version.
"""
