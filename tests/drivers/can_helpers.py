"""Shared pieces of the CAN driver tests: a private virtual bus per test, a recorded run."""

from __future__ import annotations

import socket
import uuid
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from servoid.drivers.base import Driver
from servoid.drivers.can._bus import BusAddress
from servoid.drivers.model_plant import MODEL_AMPLITUDE
from servoid.recording import RecordingWriter

#: Reply timeout, s, for tests that exchange many samples and do not test timeouts: a loaded
#: shared machine can stall a thread for tens of milliseconds, which is not what they test.
PATIENT_S = 1.0


def private_bus() -> BusAddress:
    """A python-can virtual channel no other test uses (channels are global to the process)."""
    return BusAddress("virtual", f"test-{uuid.uuid4().hex[:10]}")


def bench_input(n: int, seed: int) -> np.ndarray:
    """Seeded uniform input over the bench plant's range."""
    return np.random.default_rng(seed).uniform(-MODEL_AMPLITUDE, MODEL_AMPLITUDE, n)


def free_udp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("", 0))
        return int(s.getsockname()[1])


def recorded_run(
    driver: Driver, u: np.ndarray, path: Path, *, at: int = -1, event: Callable[[], None] = lambda: None
) -> None:
    """Exchange ``u`` sample by sample into a recording; call ``event`` before sample ``at``.

    What a sampling session does, reduced to the part the fault tests need:
    every sample is on disk before the next exchange, so an error keeps them.
    """
    with RecordingWriter(path, ["k", "u", "y"], metadata={"unit": "rad"}) as rec:
        for k, value in enumerate(u):
            if k == at:
                event()
            m = driver.exchange(float(value))
            rec.append(k, m.command, m.position)


@pytest.fixture(autouse=True)
def buses_closed():
    """Fail a test that leaves one of its virtual buses open (a driver or drive not closed)."""
    yield
    from can.interfaces import virtual

    left = sorted(str(ch) for ch, queues in virtual.channels.items() if str(ch).startswith("test-") and queues)
    for channel in left:
        del virtual.channels[channel]  # do not fail the next test for this one's leak
    assert not left, f"virtual CAN buses left open: {left}"
