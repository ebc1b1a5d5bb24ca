"""The transports every driver contract test runs over: one entry per driver.

Each :class:`Transport` knows how to start its device (the simulated servo,
the compiled firmware on a pseudo-terminal, ...) with some faults injected,
and hands out a driver for it, not yet open. ``test_contract.py`` runs every
test over every entry of :data:`TRANSPORTS`.

Adding a driver (CAN, Dynamixel) is one entry: write a factory
``def _my_servo(faults: Faults, limits: Limits | None) -> ContextManager[Driver]``
that starts its emulator with ``faults`` (those it cannot inject it leaves
out of ``Transport.faults``, and the fault tests skip it), yields a driver
built from a URL (so the URL options are exercised) with ``limits``, and
stops the emulator on exit; then append ``Transport("my", _my_servo, ...)``.
"""

from __future__ import annotations

import contextlib
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, ContextManager, Iterator

from servoid.drivers import Driver, Limits, driver_from_url
from servoid.drivers.bench import BENCH_PLANT
from servoid.drivers.clock import VirtualClock
from servoid.drivers.sim import SimDriver
from servoid.ident.model import BacklashModel

__all__ = ["Faults", "Transport", "TRANSPORTS"]


@dataclass(frozen=True, kw_only=True)
class Faults:
    """Faults to inject into a device.

    Attributes
    ----------
    mute_after : int, optional
        The device stops answering after this many replies.
    restart_after : int, optional
        The device restarts after this many requests.
    flip : float
        Probability per byte of a flipped bit (both directions).
    drop : float
        Probability that a reply is lost.
    trace : Path, optional
        Where the device writes every reply it sends, before corruption.
    timeout : float
        The driver's reply timeout, seconds (short, to keep fault tests fast).
    seed : int
        Seed of the faults.
    """

    mute_after: int | None = None
    restart_after: int | None = None
    flip: float = 0.0
    drop: float = 0.0
    trace: Path | None = None
    timeout: float = 0.05
    seed: int = 0


@dataclass(frozen=True)
class Transport:
    """One driver with its device, as the contract tests see it.

    Attributes
    ----------
    name : str
        Test id.
    servo : callable
        ``servo(faults, limits)`` -> context manager yielding a driver (not yet open).
    faults : frozenset of str
        The :class:`Faults` fields this device can inject.
    plant : BacklashModel
        The plant behind the driver, in the driver's user unit.
    resolution : float
        Quantisation of positions and commands in the user unit (0: none).
    virtual_time : bool
        Whether the driver runs in simulated time (timing is then exact).
    bad_url : str
        A URL of this scheme with an unknown option.
    """

    name: str
    servo: Callable[[Faults, Limits | None], ContextManager[Driver]]
    faults: frozenset[str] = field(default_factory=frozenset)
    plant: BacklashModel = BENCH_PLANT
    resolution: float = 0.0
    virtual_time: bool = False
    bad_url: str = ""


@contextlib.contextmanager
def _handed_out(driver: Driver, limits: Limits | None) -> Iterator[Driver]:
    """The driver with the test's limits, closed (torque off) whatever the test did."""
    if limits is not None:
        driver.limits = limits
    try:
        yield driver
    finally:
        driver.close()


@contextlib.contextmanager
def _sim(faults: Faults, limits: Limits | None) -> Iterator[Driver]:
    # driver_from_url first, so that the URL options are what is tested
    opts = [f"seed={faults.seed}", f"timeout={faults.timeout}", f"drop={faults.drop}"]
    if faults.mute_after is not None:
        opts.append(f"mute_after={faults.mute_after}")
    if faults.restart_after is not None:
        opts.append(f"restart_after={faults.restart_after}")
    driver = driver_from_url("sim://?" + "&".join(opts))
    assert isinstance(driver, SimDriver)
    driver.clock = VirtualClock()
    with _handed_out(driver, limits):
        yield driver


@contextlib.contextmanager
def _serial(faults: Faults, limits: Limits | None) -> Iterator[Driver]:
    from servoid.drivers.serial.emulator import FirmwareEmulator, FirmwareOptions

    options = FirmwareOptions(
        seed=faults.seed, flip_tx=faults.flip, flip_rx=faults.flip, drop=faults.drop,
        mute_after=faults.mute_after, restart_after=faults.restart_after, trace=faults.trace,
    )  # fmt: skip
    with FirmwareEmulator(options) as emu:
        driver = driver_from_url(f"{emu.url}?timeout={faults.timeout}")
        with _handed_out(driver, limits):
            yield driver


#: Every driver the contract tests run over.
TRANSPORTS = [
    Transport(
        "sim", _sim, frozenset({"mute_after", "restart_after", "drop"}), BENCH_PLANT, 0.0, True,
        "sim://?bogus=1",
    ),
    Transport(
        "serial", _serial, frozenset({"mute_after", "restart_after", "drop", "flip", "trace"}), BENCH_PLANT,
        2 * math.pi / 65536, False, "serial:///dev/ttyUSB0?bogus=1",
    ),
]
