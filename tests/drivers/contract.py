"""The transports every driver contract test runs over: one entry per driver.

Each :class:`Transport` knows how to start its device (the simulated servo,
the compiled firmware on a pseudo-terminal, ...) with some faults injected,
and hands out a driver for it, not yet open. ``test_contract.py`` runs every
test over every entry of :data:`TRANSPORTS`.

Adding a driver is one entry: write a factory
``def _my_servo(faults: Faults, limits: Limits | None) -> AbstractContextManager[Driver]``
that starts its emulator with ``faults`` (those it cannot inject it leaves
out of ``Transport.faults``, with the reason in ``Transport.cannot``, and the
fault tests skip it saying so), yields a driver built from a URL (so the URL
options are exercised) with ``limits``, and stops the emulator on exit; then
append ``Transport("my", _my_servo, ...)``.

How each device learns the host's slots (so that its plant follows the
session through missed slots): the simulated servo from the driver, the
serial firmware from the slot number in its set-point request, the CiA 402
drive from the SYNC counter; the Dynamixel and the ODrive protocols carry no
sample number, so their emulators, which run in this process, are told the
driver's slots out of band (``slot_source``, fed by :func:`_slots_out_of_band`;
see :mod:`servoid.drivers.dynamixel.emulated_servo` and
:mod:`servoid.drivers.can.sim_odrive` for what they do without it).
"""

from __future__ import annotations

import contextlib
import math
import uuid
from collections import deque
from collections.abc import Callable, Iterator
from contextlib import AbstractContextManager
from dataclasses import dataclass, field
from pathlib import Path

from servoid.drivers import Driver, Limits, driver_from_url
from servoid.drivers.clock import VirtualClock
from servoid.drivers.model_plant import MODEL_PLANT
from servoid.drivers.sim import SimDriver
from servoid.ident.models.pseudo_wiener import BacklashModel

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
    sent_readings : callable, optional
        ``sent_readings(trace)`` -> the set of ``(device time in us, position
        in native units)`` the device wrote to its ``trace`` (for ``flip``).
    cannot : dict
        Why the device cannot inject a fault it leaves out of ``faults``
        (the skip reason); default "cannot inject <fault>".
    """

    name: str
    servo: Callable[[Faults, Limits | None], AbstractContextManager[Driver]]
    faults: frozenset[str] = field(default_factory=frozenset)
    plant: BacklashModel = MODEL_PLANT
    resolution: float = 0.0
    virtual_time: bool = False
    bad_url: str = ""
    sent_readings: Callable[[Path], set[tuple[int, int]]] | None = None
    cannot: dict[str, str] = field(default_factory=dict)


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


def _serial_sent(trace: Path) -> set[tuple[int, int]]:
    sent = set()
    for line in trace.read_text().splitlines():
        fields = line.split("*")[0].split(" ")
        if fields[1] == "P":
            sent.add((int(fields[4]), int(fields[5])))  # (device us, counts) as the firmware sent them
    return sent


def _slots_out_of_band(driver: Driver) -> Callable[[], int | None]:
    """A ``slot_source`` for an emulator in this process: the driver's slot of each command, in sending order.

    The driver's ``_exchange`` notes the slot of each command it sends, and the
    emulator takes them in the order it handles the commands: a command handled
    late (the emulator's thread held up past the reply timeout) still gets its
    own slot, not the one the session has moved on to.
    """
    slots: deque[int | None] = deque()
    send = driver._exchange

    def exchange(command: float, slot: int | None):  # type: ignore[no-untyped-def]
        if driver.torque_enabled:  # with the torque off nothing is sent (the driver refuses)
            slots.append(slot)
        return send(command, slot)

    driver._exchange = exchange  # type: ignore[method-assign]
    return lambda: slots.popleft() if slots else None


@contextlib.contextmanager
def _dxl(faults: Faults, limits: Limits | None) -> Iterator[Driver]:
    from servoid.drivers.dynamixel.emulator import DynamixelEmulator

    with DynamixelEmulator(ids=[1], return_delay_us=0, seed=faults.seed, trace=faults.trace) as emu:
        link = emu.faults(1)
        link.mute_after, link.drop = faults.mute_after, faults.drop
        # the reply timeout is 2 x latency_ms + 2 ms
        driver = driver_from_url(emu.url(1, latency_ms=max((faults.timeout * 1e3 - 2) / 2, 0.5)))
        emu.servo(1).slot_source = _slots_out_of_band(driver)  # Protocol 2.0 has no room for it
        if faults.flip:
            # The line turns noisy once the driver is open: opening reads the 71-byte control table in
            # one READ, which at this flip rate fails three tries in a row about once in thirty opens
            # (retries while opening are tested in test_dxl_faults.py); the run is what is tested here.
            open_quietly = driver.open

            def open_then_noisy() -> Driver:
                open_quietly()
                emu.flip = faults.flip
                return driver

            driver.open = open_then_noisy  # type: ignore[method-assign]
        with _handed_out(driver, limits):
            yield driver


def _dxl_sent(trace: Path) -> set[tuple[int, int]]:
    sent = set()
    for line in trace.read_text().splitlines():
        servo_id, tick_ms, counts = (int(v) for v in line.split())
        sent.add((tick_ms * 1000, counts))
    return sent


def _private_bus():  # type: ignore[no-untyped-def]
    from servoid.drivers.can._bus import BusAddress

    return BusAddress("virtual", f"test-{uuid.uuid4().hex[:10]}")


@contextlib.contextmanager
def _cia402(faults: Faults, limits: Limits | None) -> Iterator[Driver]:
    from servoid.drivers.can.sim_cia402 import SimCia402Drive

    with SimCia402Drive(
        node=1, bus=_private_bus(), mute_after=faults.mute_after, drop=faults.drop,
        restart_after=faults.restart_after, seed=faults.seed,
    ) as drive:  # fmt: skip
        driver = driver_from_url(drive.url(timeout=faults.timeout))
        with _handed_out(driver, limits):
            yield driver


@contextlib.contextmanager
def _odrive(faults: Faults, limits: Limits | None) -> Iterator[Driver]:
    from servoid.drivers.can.sim_odrive import SimOdriveAxis

    with SimOdriveAxis(
        node=3, bus=_private_bus(), mute_after=faults.mute_after, drop=faults.drop, seed=faults.seed
    ) as axis:
        driver = driver_from_url(axis.url(timeout=faults.timeout))
        axis.slot_source = _slots_out_of_band(driver)  # CAN Simple has no room for it
        with _handed_out(driver, limits):
            yield driver


#: Why CAN drives cannot have flipped bits.
_CAN_CRC = (
    "the CAN controller checks every frame's CRC and retransmits a corrupted one: software never receives "
    "a flipped bit (and python-can's virtual bus has none to flip)"
)

#: Every driver the contract tests run over.
TRANSPORTS = [
    Transport(
        "sim",
        _sim,
        frozenset({"mute_after", "restart_after", "drop"}),
        MODEL_PLANT,
        0.0,
        True,
        "sim://?bogus=1",
        cannot={"flip": "the simulated servo has no byte stream to corrupt"},
    ),
    Transport(
        "serial",
        _serial,
        frozenset({"mute_after", "restart_after", "drop", "flip", "trace"}),
        MODEL_PLANT,
        2 * math.pi / 65536,
        False,
        "serial:///dev/ttyUSB0?bogus=1",
        _serial_sent,
    ),
    Transport(
        "dxl",
        _dxl,
        frozenset({"mute_after", "drop", "flip", "trace"}),
        MODEL_PLANT,
        2 * math.pi / 4096,
        False,
        "dxl:///dev/ttyUSB0?id=1&bogus=1",
        _dxl_sent,
        cannot={
            "restart_after": "an X-series servo has no boot id or restart counter to read per sample: after a "
            "brown-out it answers again with its torque off, and its Realtime Tick restarting cannot be told "
            "from the tick's own wrap every 32.768 s (docs/dynamixel.md)",
        },
    ),
    Transport(
        "cia402",
        _cia402,
        frozenset({"mute_after", "restart_after", "drop"}),
        MODEL_PLANT,
        2 * math.pi / 2**17,
        False,
        "can://virtual/ch0?protocol=cia402&bogus=1",
        cannot={"flip": _CAN_CRC},
    ),
    Transport(
        "odrive",
        _odrive,
        frozenset({"mute_after", "drop"}),
        MODEL_PLANT,
        2 * math.pi * 2.0**-23,
        False,
        "can://virtual/ch0?protocol=odrive&bogus=1",
        cannot={
            "flip": _CAN_CRC,
            "restart_after": "CAN Simple has no boot counter: a rebooted ODrive is an axis that left closed-loop "
            "control, which the driver reports as a DeviceFault (test_session_faults.py)",
        },
    ),
]
