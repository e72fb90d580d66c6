"""Clocks: the wall-clock source fakes and replay pace themselves with (injectable for
tests)."""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Protocol


class Clock(Protocol):
    """Monotonic nanoseconds and a way to wait."""

    def now_ns(self) -> int: ...

    def sleep_s(self, seconds: float) -> None: ...


class MonotonicClock:
    """The real clock: ``time.monotonic_ns`` and ``time.sleep``."""

    def now_ns(self) -> int:
        return time.monotonic_ns()

    def sleep_s(self, seconds: float) -> None:
        if seconds > 0:
            time.sleep(seconds)


class CallableClock:
    """A clock made of two functions in seconds, ``monotonic() -> float`` and
    ``sleep(seconds)``: ``time.monotonic`` and ``time.sleep``, or a caller's stand-ins."""

    def __init__(self, monotonic: Callable[[], float], sleep: Callable[[float], None]) -> None:
        self._monotonic = monotonic
        self._sleep = sleep

    def now_ns(self) -> int:
        return round(self._monotonic() * 1e9)

    def sleep_s(self, seconds: float) -> None:
        if seconds > 0:
            self._sleep(seconds)


class ManualClock:
    """A clock that only moves when told to (or when something sleeps on it)."""

    def __init__(self, start_ns: int = 0) -> None:
        self._t = int(start_ns)

    def now_ns(self) -> int:
        return self._t

    def sleep_s(self, seconds: float) -> None:
        if seconds > 0:
            self._t += round(seconds * 1e9)

    def advance_s(self, seconds: float) -> None:
        self._t += round(seconds * 1e9)
