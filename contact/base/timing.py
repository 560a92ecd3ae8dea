"""Wall-clock seconds of the phases of a run: the one timing helper of the package.

    seconds: dict[str, float] = {}
    with Timer(seconds, "estimate"):
        est = estimate(scene, result)

replaces the pair ``t0 = time.perf_counter()`` … ``seconds["estimate"] = time.perf_counter()
- t0`` written by hand around every phase; the dict is what the outputs record (a level's
``seconds``: levels.csv, summary.json; a solve's ``timings``).  A phase timed twice under one
name adds up.  A phase that begins in one PETSc callback and ends in another (the linear
solve: from the end of the Jacobian to SNES's post-solve hook) uses :meth:`Timer.start` and
:meth:`Timer.stop`.  :class:`Stopwatch` is the time since a start, for totals (a solve's
``total``, a study run's ``seconds``)."""

from __future__ import annotations

import time
from types import TracebackType


class Timer:
    """Adds the wall-clock seconds spent in its ``with`` block (or between :meth:`start` and
    :meth:`stop`) to ``seconds[name]`` (also when the block raises)."""

    def __init__(self, seconds: dict[str, float], name: str):
        self.seconds, self.name = seconds, name
        self._t0 = 0.0

    def start(self) -> Timer:
        self._t0 = time.perf_counter()
        return self

    def stop(self) -> float:
        """Add the seconds since :meth:`start`; return them."""
        elapsed = time.perf_counter() - self._t0
        self.seconds[self.name] = self.seconds.get(self.name, 0.0) + elapsed
        return elapsed

    def __enter__(self) -> Timer:
        return self.start()

    def __exit__(
        self,
        kind: type[BaseException] | None,
        error: BaseException | None,
        trace: TracebackType | None,
    ) -> None:
        self.stop()


class Stopwatch:
    """Wall-clock seconds since it was made (``seconds``), counting ``before`` seconds of
    work done earlier as spent already (a solve that assembled its problem first)."""

    def __init__(self, before: float = 0.0):
        self._t0 = time.perf_counter() - before

    @property
    def seconds(self) -> float:
        return time.perf_counter() - self._t0
