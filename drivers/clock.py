"""Clocks for sampling: the real one, and a virtual one for deterministic tests.

Everything that schedules samples or simulates device latency asks a
:class:`Clock` for the time and to wait, instead of calling :mod:`time`
directly, so that a test can hand the sampling session and the simulated
servo one :class:`VirtualClock` and get the same result on every machine.

Times are integers in nanoseconds (``time.perf_counter_ns``): a float of
seconds loses sub-microsecond resolution after a few days of uptime, and
integer deadlines ``t0 + k * period`` never drift.

This lives in ``servoid.drivers`` (not the app layer) because the simulated
servo needs it too, and the pillars never import the app.
"""

from __future__ import annotations

import time
from typing import Protocol, runtime_checkable

from servoid import validation
from servoid.errors import ConfigError

__all__ = ["Clock", "MonotonicClock", "VirtualClock", "NS_PER_S"]

NS_PER_S = 1_000_000_000


@runtime_checkable
class Clock(Protocol):
    """What a sampler needs from a clock."""

    def now_ns(self) -> int:
        """Monotonic time in nanoseconds (arbitrary origin)."""

    def sleep_until_ns(self, deadline_ns: int) -> int:
        """Return at ``deadline_ns`` (at once if it has passed), with the time then (:meth:`now_ns`).

        The time comes with the wake-up because a sampler reads it there at every
        sample: a second read would cost as much again.
        """

    def sleep_ns(self, duration_ns: int) -> None:
        """Wait ``duration_ns`` nanoseconds."""


class MonotonicClock:
    """The real clock: ``time.perf_counter_ns``, sleep most of the way, then spin.

    Parameters
    ----------
    spin_s : float
        How long before a deadline to stop sleeping and spin. ``time.sleep``
        overshoots by about 50 us (more on a loaded machine); sleeping to
        ``spin_s`` before the deadline and spinning the rest hits it within a
        microsecond, at the cost of ``spin_s`` of CPU per sample.
    """

    def __init__(self, *, spin_s: float = 300e-6) -> None:
        self.spin_ns = int(validation.non_negative("spin_s", spin_s) * NS_PER_S)

    def now_ns(self) -> int:
        return time.perf_counter_ns()

    def sleep_until_ns(self, deadline_ns: int) -> int:
        remaining = deadline_ns - time.perf_counter_ns()
        if remaining > self.spin_ns:
            time.sleep((remaining - self.spin_ns) / NS_PER_S)
        while (now := time.perf_counter_ns()) < deadline_ns:
            pass
        return now

    def sleep_ns(self, duration_ns: int) -> None:
        self.sleep_until_ns(time.perf_counter_ns() + duration_ns)


class VirtualClock:
    """A clock that only moves when asked to: waiting advances it instantly.

    Parameters
    ----------
    start_ns : int
        Initial time.

    Notes
    -----
    Give the same instance to the session and the simulated servo: the
    servo's latency then moves the session's time, and late and missed
    samples happen exactly where the test puts them.
    """

    def __init__(self, start_ns: int = 0) -> None:
        self.t_ns = int(start_ns)

    def now_ns(self) -> int:
        return self.t_ns

    def sleep_until_ns(self, deadline_ns: int) -> int:
        if deadline_ns > self.t_ns:
            self.t_ns = int(deadline_ns)
        return self.t_ns

    def sleep_ns(self, duration_ns: int) -> None:
        self.advance_ns(duration_ns)

    def advance_ns(self, duration_ns: int) -> None:
        """Move time forward (a stall of the host, a slow reply)."""
        if duration_ns < 0:
            raise ConfigError(f"duration_ns (={duration_ns}) must be >= 0: time does not run backwards")
        self.t_ns += int(duration_ns)
