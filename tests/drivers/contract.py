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

Every device runs a physical twin (the default of its transport: the
XM430 behind ``sim://`` and the Dynamixel, the CiA 402 drive's and the
ODrive's own), and the tests hold its readings against the same twin
stepped in this process on the recorded commands
(:meth:`Transport.expected`): each transport says how its protocol carries
a set point to the twin and a reading back (``command``, ``observe``).

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

import numpy as np

from servoid.drivers import Driver, Limits, driver_from_url
from servoid.drivers.clock import VirtualClock
from servoid.drivers.sim import SimDriver
from servoid.drivers.twin import Twin, TwinPlant, TwinReading, preset

__all__ = ["Faults", "Transport", "TRANSPORTS", "RATE_HZ"]

#: The sample rate of the contract tests' sessions, Hz (the devices on their own clock are told it).
RATE_HZ = 500.0


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
    servo : str
        The twin preset behind the driver (its default twin, default seed).
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
    command : callable
        A recorded command (user unit) -> the twin's set point (output rad), as the protocol carries it.
    observe : callable
        A twin's reading -> the position the driver reports (user unit), as the protocol carries it.
    """

    name: str
    open_servo: Callable[[Faults, Limits | None], AbstractContextManager[Driver]]
    faults: frozenset[str] = field(default_factory=frozenset)
    servo: str = "xm430"
    resolution: float = 0.0
    virtual_time: bool = False
    bad_url: str = ""
    sent_readings: Callable[[Path], set[tuple[int, int]]] | None = None
    cannot: dict[str, str] = field(default_factory=dict)
    command: Callable[[float], float] = float
    observe: Callable[[TwinReading], float] = lambda r: r.position_rad

    def expected(self, u: np.ndarray, period_s: float = 1.0 / RATE_HZ) -> np.ndarray:
        """What the driver reads at each slot: the twin stepped one period per slot on the commands ``u``."""
        plant = TwinPlant(Twin(preset(self.servo)), period_s)
        out = np.empty(u.size)
        for k, value in enumerate(u):
            plant.step(self.command(float(value)))
            out[k] = self.observe(plant.reading)
        return out


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
    driver = driver_from_url("sim://xm430?" + "&".join(opts))
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


def _noisy_once_open(driver: Driver, emu, flip: float) -> None:  # type: ignore[no-untyped-def]
    """Make the emulator's line noisy once the driver is open.

    Opening reads the control table (71 bytes) in one READ, which at the flip
    rates tested fails three tries in a row about once in thirty opens (retries
    while opening are tested in test_dxl_faults.py); the run is what is tested.
    """
    open_quietly = driver.open

    def open_then_noisy() -> Driver:
        open_quietly()
        emu.flip = flip
        return driver

    driver.open = open_then_noisy  # type: ignore[method-assign]


@contextlib.contextmanager
def _dxl(faults: Faults, limits: Limits | None) -> Iterator[Driver]:
    from servoid.drivers.dynamixel.emulator import DynamixelEmulator

    with DynamixelEmulator(
        ids=[1], return_delay_us=0, seed=faults.seed, trace=faults.trace, period_s=1 / RATE_HZ
    ) as emu:
        link = emu.faults(1)
        link.mute_after, link.drop = faults.mute_after, faults.drop
        # the reply timeout is 2 x latency_ms + 2 ms
        driver = driver_from_url(emu.url(1, latency_ms=max((faults.timeout * 1e3 - 2) / 2, 0.5)))
        emu.servo(1).slot_source = _slots_out_of_band(driver)  # Protocol 2.0 has no room for it
        if faults.flip:
            _noisy_once_open(driver, emu, faults.flip)
        with _handed_out(driver, limits):
            yield driver


def _dxl_sent(trace: Path) -> set[tuple[int, int]]:
    sent = set()
    for line in trace.read_text().splitlines():
        servo_id, tick_ms, counts = (int(v) for v in line.split())
        sent.add((tick_ms * 1000, counts))
    return sent


@contextlib.contextmanager
def _feetech(faults: Faults, limits: Limits | None) -> Iterator[Driver]:
    from servoid.drivers.feetech.emulator import FeetechEmulator

    with FeetechEmulator(
        ids=[1], seed=faults.seed, trace=faults.trace, period_s=1 / RATE_HZ, restart_after=faults.restart_after
    ) as emu:
        link = emu.faults(1)
        link.mute_after, link.drop = faults.mute_after, faults.drop
        driver = driver_from_url(emu.url(1, latency_ms=max((faults.timeout * 1e3 - 2) / 2, 0.5)))
        emu.servo(1).slot_source = _slots_out_of_band(driver)  # the STS protocol has no room for it
        if faults.flip:
            _noisy_once_open(driver, emu, faults.flip)
        with _handed_out(driver, limits):
            yield driver


def _feetech_sent(trace: Path) -> set[tuple[int, int]]:
    return {(0, int(line.split()[1])) for line in trace.read_text().splitlines()}


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
        node=3, bus=_private_bus(), mute_after=faults.mute_after, drop=faults.drop, seed=faults.seed,
        period_s=1 / RATE_HZ,
    ) as axis:  # fmt: skip
        driver = driver_from_url(axis.url(timeout=faults.timeout))
        axis.slot_source = _slots_out_of_band(driver)  # CAN Simple has no room for it
        with _handed_out(driver, limits):
            yield driver


#: Why CAN drives cannot have flipped bits.
_CAN_CRC = (
    "the CAN controller checks every frame's CRC and retransmits a corrupted one: software never receives "
    "a flipped bit (and python-can's virtual bus has none to flip)"
)


def _float32_turns(rad: float) -> float:
    """An angle as CAN Simple carries it: float32 turns."""
    return float(np.float32(rad / (2 * math.pi)))


_ODRIVE_RATIO = preset("odrive").gear_ratio

#: Every driver the contract tests run over.
TRANSPORTS = [
    Transport(
        "sim",
        _sim,
        frozenset({"mute_after", "restart_after", "drop"}),
        "xm430",
        0.0,
        True,
        "sim://?bogus=1",
        cannot={"flip": "the simulated servo has no byte stream to corrupt"},
    ),
    Transport(
        "serial",
        _serial,
        frozenset({"mute_after", "restart_after", "drop", "flip", "trace"}),
        "xm430",
        2 * math.pi / 4096,
        False,
        "serial:///dev/ttyUSB0?bogus=1",
        _serial_sent,
    ),
    Transport(
        "dxl",
        _dxl,
        frozenset({"mute_after", "drop", "flip", "trace"}),
        "xm430",
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
        "feetech",
        _feetech,
        frozenset({"mute_after", "restart_after", "drop", "flip", "trace"}),
        "sts3215",
        2 * math.pi / 4096,
        False,
        "feetech:///dev/ttyUSB0?id=1&bogus=1",
        _feetech_sent,
    ),
    Transport(
        "cia402",
        _cia402,
        frozenset({"mute_after", "restart_after", "drop"}),
        "cia402",
        2 * math.pi / 2**20,  # the load encoder, 0x60E4 sub 1 (the driver's encoder=auto)
        False,
        "can://virtual/ch0?protocol=cia402&bogus=1",
        cannot={"flip": _CAN_CRC},
    ),
    Transport(
        "odrive",
        _odrive,
        frozenset({"mute_after", "drop"}),
        "odrive",
        2 * math.pi * 2.0**-20,  # float32 turns of the motor
        False,
        "can://virtual/ch0?protocol=odrive&bogus=1",
        cannot={
            "flip": _CAN_CRC,
            "restart_after": "CAN Simple has no boot counter: a rebooted ODrive is an axis that left closed-loop "
            "control, which the driver reports as a DeviceFault (test_session_faults.py)",
        },
        # the axis counts turns of its motor (its loop's encoder) and reports its encoder PLL's estimate
        command=lambda u: _float32_turns(u) * 2 * math.pi / _ODRIVE_RATIO,
        observe=lambda r: float(np.float32(r.position_estimate_rad * (_ODRIVE_RATIO / (2 * math.pi)))) * 2 * math.pi,
    ),
]
