"""Shared pieces of the Dynamixel tests: a virtual clock and emulator fixtures."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from servoid.drivers import clock as clock_module
from servoid.drivers.dynamixel.emulator import DynamixelEmulator

#: Latency timer (ms) for tests, so reply timeouts are 2 x this + 2 ms: generous, because on a
#: loaded 2-core machine an emulator (thread or process) was seen to wait over 40 ms to be scheduled.
TEST_LATENCY_MS = 100


class VirtualClock(clock_module.VirtualClock):
    """The drivers' virtual clock, moved in seconds."""

    def advance(self, seconds: float) -> None:
        self.advance_ns(round(seconds * clock_module.NS_PER_S))


@pytest.fixture
def clock() -> VirtualClock:
    return VirtualClock()


@pytest.fixture
def emulator(clock: VirtualClock) -> Iterator[DynamixelEmulator]:
    """Servos 1 and 2 on one bus, served from a thread, with the virtual clock."""
    with DynamixelEmulator(ids=[1, 2], clock=clock, return_delay_us=0, servo="model") as emu:
        yield emu


def url(emu: DynamixelEmulator, servo_id: int = 1, **options: object) -> str:
    """A driver URL for a thread-served emulator, with test-friendly timeouts."""
    options.setdefault("latency_ms", TEST_LATENCY_MS)
    return emu.url(servo_id, **options)
