"""contact.base.timing.Timer: the seconds of a ``with`` block land in the caller's dict."""

import time

from contact.base.timing import Timer

import pytest


def test_timer_records_and_adds_up() -> None:
    seconds: dict[str, float] = {"other": 1.0}
    with Timer(seconds, "phase"):
        time.sleep(0.02)
    first = seconds["phase"]
    assert first >= 0.02 and seconds["other"] == 1.0  # perf_counter is monotonic
    with Timer(seconds, "phase"):
        time.sleep(0.01)
    assert seconds["phase"] >= first + 0.01  # a second block under one name adds


def test_timer_records_a_failing_block() -> None:
    seconds: dict[str, float] = {}
    with pytest.raises(RuntimeError), Timer(seconds, "phase"):
        time.sleep(0.01)
        raise RuntimeError("boom")
    assert seconds["phase"] >= 0.01
