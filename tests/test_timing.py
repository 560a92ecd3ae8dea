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


def test_timer_started_and_stopped_across_calls() -> None:
    """The linear solve's Timer starts in the Jacobian callback and stops in SNES's
    post-solve hook: start() / stop() add up like the ``with`` block."""
    seconds: dict[str, float] = {"solve": 0.5}
    timer = Timer(seconds, "solve").start()
    time.sleep(0.01)
    elapsed = timer.stop()
    assert elapsed >= 0.01 and seconds["solve"] == pytest.approx(0.5 + elapsed)


def test_stopwatch_counts_earlier_work() -> None:
    """A solve that assembled its problem first counts the assembly in its total."""
    from contact.base.timing import Stopwatch

    fresh, late = Stopwatch(), Stopwatch(before=2.0)
    time.sleep(0.01)
    assert 0.01 <= fresh.seconds < late.seconds and late.seconds >= 2.01


def test_the_solvers_and_the_study_time_through_the_helper() -> None:
    """No hand-placed perf_counter left in contact.solvers and the study runner (issue 28)."""
    from clirun import ROOT

    files = [*sorted((ROOT / "contact" / "solvers").glob("*.py")), ROOT / "contact/app/study.py"]
    assert [f.name for f in files if "perf_counter" in f.read_text()] == []
