"""The virtual clock and the ticker's fixed-rate, drift-free schedule."""

from __future__ import annotations

import threading
from datetime import UTC, datetime

import pytest

from dms.kernel.clock import RealClock, Ticker, VirtualClock, iso


def test_virtual_clock_moves_only_forward() -> None:
    clock = VirtualClock(datetime(2026, 11, 22, 10, 0, tzinfo=UTC))
    assert clock.advance(0.5) == datetime(2026, 11, 22, 10, 0, 0, 500000, tzinfo=UTC)
    assert clock.monotonic() == 0.5
    with pytest.raises(ValueError):
        clock.advance(-1)


def test_iso_has_milliseconds_and_z() -> None:
    assert iso(datetime(2026, 11, 22, 10, 0, 0, 500999, tzinfo=UTC)) == "2026-11-22T10:00:00.500Z"


class _SteppingClock:
    """A monotonic clock that the test moves; the ticker's waits return at once."""

    def __init__(self) -> None:
        self.t = 100.0

    def now(self) -> datetime:
        return datetime.fromtimestamp(self.t, UTC)

    def monotonic(self) -> float:
        return self.t


def test_ticker_deadlines_do_not_drift_with_work_time() -> None:
    clock = _SteppingClock()
    ticker = Ticker(clock, period=0.5)
    dues = []
    for timing, urgent in ticker:
        assert timing is not None and not urgent
        dues.append(timing.due)
        clock.t = timing.due + 0.5  # the work took a whole period: the next is due now
        if len(dues) == 10:
            break
    assert dues == [100.0 + 0.5 * i for i in range(10)]
    assert ticker.missed == 0


def test_ticker_skips_rather_than_bunches_when_far_behind() -> None:
    clock = _SteppingClock()
    ticker = Ticker(clock, period=0.5)
    iterator = iter(ticker)
    first, _ = next(iterator)
    assert first is not None
    clock.t += 3.0  # stalled for six periods
    second, _ = next(iterator)
    assert second is not None
    assert second.due == pytest.approx(103.0)
    assert ticker.missed == 5


def test_wake_yields_an_urgent_iteration_before_the_deadline() -> None:
    ticker = Ticker(RealClock(), period=30.0)
    iterator = iter(ticker)
    next(iterator)  # the first tick is due at once
    woke = threading.Timer(0.01, ticker.wake)
    woke.start()
    timing, urgent = next(iterator)
    assert timing is None and urgent
    ticker.stop()
    assert list(iterator) == []
