"""Wall-clock seconds of the phases of a run, recorded into the caller's dict.

    seconds: dict[str, float] = {}
    with Timer(seconds, "estimate"):
        est = estimate(scene, result)

replaces the pair ``t0 = time.perf_counter()`` … ``seconds["estimate"] = time.perf_counter()
- t0`` written by hand around every phase; the dict is what the outputs record (a level's
``seconds``: levels.csv, summary.json).  A phase timed twice under one name adds up."""

from __future__ import annotations

import time
from types import TracebackType


class Timer:
    """Adds the wall-clock seconds spent in its ``with`` block to ``seconds[name]``
    (also when the block raises)."""

    def __init__(self, seconds: dict[str, float], name: str):
        self.seconds, self.name = seconds, name
        self._t0 = 0.0

    def __enter__(self) -> Timer:
        self._t0 = time.perf_counter()
        return self

    def __exit__(
        self,
        kind: type[BaseException] | None,
        error: BaseException | None,
        trace: TracebackType | None,
    ) -> None:
        elapsed = time.perf_counter() - self._t0
        self.seconds[self.name] = self.seconds.get(self.name, 0.0) + elapsed
