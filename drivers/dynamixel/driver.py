"""The ROBOTIS Dynamixel driver (Protocol 2.0, X series) on the official ``dynamixel-sdk``.

URL::

    dxl:///dev/ttyUSB0?id=1&baud=1000000&mode=position

Per sample, :meth:`DynamixelDriver.exchange` writes the goal with a
GroupSyncWrite (a broadcast, never answered) and then READs from the goal's
address to 135 in one transaction: the goal itself (Goal Position 116, Goal
Current 102 or Goal PWM 100, by mode), Realtime Tick, Present PWM, Current,
Velocity and Position -- one contiguous block of the control table. Both
are one packet each way; the goal of the sample is in the servo before the
position is read. The goal read back confirms the write: a SYNC_WRITE the
servo received corrupted is dropped without a word (a broadcast is never
answered), and only the read-back shows it. A goal that differs from the one
written raises :class:`~servoid.errors.CommandUnconfirmed` (counted in
``stats.unconfirmed``): the sample is not used, and the session's guard
window follows it.

Units
-----
position (measured)      rad, ``(count - 2048) * 2 pi / 4096`` (0 rad at the middle of the range)
command, ``mode=position`` rad, the same conversion (Goal Position, rounded to whole counts)
command, ``mode=current``  A, 2.69 mA per unit (Goal Current)
command, ``mode=pwm``      percent of the supply voltage, 100/885 % per unit (Goal PWM)
velocity                 rad/s (Present Velocity, 0.229 rpm per unit)
current                  A (Present Current)
device_time              s, from the Realtime Tick (ms, wraps after 32.768 s; the base unwraps it)

What opening does
-----------------
PING the servo (a clear :class:`~servoid.errors.DriverTimeout` naming the ID,
port and baud rate if nothing answers), read its EEPROM and state in one READ,
refuse a servo with a pending hardware error (unless ``reboot=1``), switch the
torque off, make sure Status Return Level is 2 (every instruction answered),
and only then, with the torque off, write the EEPROM entries that differ from
what was asked: Operating Mode and Return Delay Time (``return_delay_us``,
default 0 us; the factory's 500 us costs half a millisecond per sample;
``return_delay_us=keep`` leaves it). Bus Watchdog (98) is cleared (a -1 left
by a host that died locks the goals) and, on every torque-on, set to
``watchdog`` (default 0.5 s, in units of 20 ms; 0: off): a host killed with
SIGKILL, or a cut cable, stops the servo within that time -- it holds where
it is, its goals locked until the next open (the e-manual's behaviour; X
series servos keep the torque on while stopped). The command limits default to the
servo's own (Min/Max Position Limit, Current Limit or PWM Limit), narrowed by
``min``/``max`` if given. Switching the torque on first sets the goal to the
present position, so the servo does not jump.

Pitfalls of the SDK handled here
--------------------------------
* Stray replies: per-sample commands go by GroupSyncWrite, which no servo
  answers, never by ``write...TxOnly`` (whose answer the next READ would take
  for its own); every READ's length is checked.
* Timeouts: the SDK measures them with the wall clock and assumes a 16 ms
  USB latency timer, so a missing answer costs 34 ms. The port handler here
  uses the monotonic clock and the adapter's real latency timer (read from
  ``/sys/bus/usb-serial/devices/ttyUSBn/latency_timer``; 10 ms for a
  pseudo-terminal, whose other end is a program; else 1 ms; URL option
  ``latency_ms``), and waits for bytes with ``select`` instead of spinning a
  core. That short timeout applies to the per-sample exchange; opening,
  switching the torque and rebooting allow at least 25 ms of latency, and
  try a transaction up to three times (a noisy line costs a retry there,
  not the run; a per-sample goal is never sent twice).
* Status codes and the error byte become exceptions:
  :class:`~servoid.errors.DriverTimeout` (no answer),
  :class:`~servoid.errors.ProtocolError` (corrupted answer, or the servo's
  error number, e.g. it received a corrupted packet), and
  :class:`~servoid.errors.DeviceFault` (the alert bit: the driver reads
  Hardware Error Status and names the fault).
* The SDK's busy flag stays set when a call raises: it is reset after every
  failure.
* A status packet whose LENGTH field was corrupted makes the SDK ask the port
  for a negative number of bytes (``os.read`` fails with Errno 22); the port
  here gives nothing instead, and the packet's CRC then fails: a rejected
  frame (``stats.rejected``), not a driver error.
* Not thread-safe (neither is the SDK): a driver belongs to the thread that
  opened it, and :meth:`exchange` from another thread raises.
"""

from __future__ import annotations

import logging
import math
import time
from typing import Any, TypeVar

from dynamixel_sdk import (
    COMM_RX_CORRUPT,
    COMM_RX_TIMEOUT,
    COMM_SUCCESS,
    GroupSyncRead,
    GroupSyncWrite,
    PacketHandler,
    PortHandler,
)

from servoid.drivers._sdk_port import (
    SdkTransactions,
    SelectPort,
    checked,
    parse_latency,
    parse_return_delay,
)
from servoid.drivers.base import Driver, Limits, Option, Reading, UnitConversion
from servoid.drivers.dynamixel import control_table as ct
from servoid.drivers.dynamixel.control_table import HardwareError, OperatingMode
from servoid.drivers.dynamixel.protocol import ALERT, MAX_ID, ErrorNumber, Instruction, describe_error
from servoid.errors import CommandUnconfirmed, ConfigError, DeviceFault, DriverError, DriverTimeout, ProtocolError

__all__ = ["DynamixelDriver", "MODES", "SUPPORTED_BAUD_RATES", "POSITION_UNIT", "COMMAND_UNITS"]

log = logging.getLogger("servoid.drivers.dynamixel")

T = TypeVar("T")

#: URL ``mode`` -> Operating Mode (11).
MODES: dict[str, OperatingMode] = {
    "position": OperatingMode.POSITION,
    "current": OperatingMode.CURRENT,
    "pwm": OperatingMode.PWM,
}
#: Goal entry written per sample in each mode.
_GOAL = {
    OperatingMode.POSITION: ct.GOAL_POSITION,
    OperatingMode.CURRENT: ct.GOAL_CURRENT,
    OperatingMode.PWM: ct.GOAL_PWM,
}
#: Baud rates both an X-series servo and the SDK accept (the SDK refuses 4.5 Mbps).
SUPPORTED_BAUD_RATES = (9600, 57600, 115200, 1_000_000, 2_000_000, 3_000_000, 4_000_000)
#: Factory baud rate of X-series servos.
DEFAULT_BAUD = 57600

POSITION_UNIT = UnitConversion("rad", ct.RAD_PER_COUNT, ct.POSITION_CENTRE)
COMMAND_UNITS = {
    OperatingMode.POSITION: POSITION_UNIT,
    OperatingMode.CURRENT: UnitConversion("A", ct.AMPERE_PER_UNIT, 0.0),
    OperatingMode.PWM: UnitConversion("%", ct.PERCENT_PER_PWM_UNIT, 0.0),
}

#: Bus Watchdog of the servo while its torque is on, s (URL ``watchdog``): it stops within this
#: time of the host's last packet. Far above any sample period servoid uses (1 kHz .. 50 Hz).
DEFAULT_WATCHDOG_S = 0.5

#: Time a rebooted servo gets to answer again (s).
REBOOT_TIMEOUT_S = 3.0


# ---- URL option parsers (each raises ValueError with what was expected) -------------------
def _servo_id(value: Any) -> int:
    number = int(value)
    if not 0 <= number <= MAX_ID:  # 253..255 are reserved (header byte, broadcast)
        raise ValueError("a servo ID is 0..252")
    return number


def _baud(value: Any) -> int:
    number = int(value)
    if number == 4_500_000:
        raise ValueError("the Dynamixel SDK refuses 4.5 Mbps; use 4000000 or less")
    if number not in SUPPORTED_BAUD_RATES:
        raise ValueError(f"expected one of {', '.join(map(str, SUPPORTED_BAUD_RATES))}")
    return number


def _mode(value: Any) -> str:
    text = str(value).lower()
    if text not in MODES:
        raise ValueError(f"expected one of {', '.join(MODES)}")
    return text


def _watchdog(value: Any) -> float:
    seconds = float(value)
    units = math.ceil(seconds / ct.SECONDS_PER_BUS_WATCHDOG_UNIT - 1e-9) if seconds > 0 else 0
    if not (math.isfinite(seconds) and seconds >= 0 and units <= 127):
        raise ValueError("the Bus Watchdog takes 0 (off) or up to 2.54 s, in steps of 20 ms")
    return units * ct.SECONDS_PER_BUS_WATCHDOG_UNIT


def _flag(value: Any) -> bool:
    text = str(value).lower()
    if text in ("1", "true", "yes", "on"):
        return True
    if text in ("0", "false", "no", "off"):
        return False
    raise ValueError("expected 1 or 0")


class _Port(SelectPort, PortHandler):  # type: ignore[misc]
    """The SDK's PortHandler with monotonic timeouts, the real latency timer, and no busy-polling."""


class DynamixelDriver(SdkTransactions, Driver):
    """A ROBOTIS X-series Dynamixel over Protocol 2.0 (see the module docstring).

    Parameters
    ----------
    port : str
        Serial port (``/dev/ttyUSB0``, ``/dev/pts/7``, ``COM3``).
    servo_id : int
        The servo's ID, 0..252 (URL ``id``, default 1).
    baud : int
        Baud rate of the port and the servo (default 57600, the factory setting).
    mode : {"position", "current", "pwm"}
        Operating mode and so the command's unit: rad, A or percent.
    return_delay_us : int or None
        Return Delay Time to set at open, even microseconds 0..508 (default 0);
        None keeps the servo's.
    latency_ms : float or None
        Latency timer for reply timeouts, which are 2 x it + 2 ms plus the wire
        time (default: the USB adapter's from sysfs, 10 ms for a pseudo-terminal,
        else 1 ms).
    reboot : bool
        Reboot a servo that reports a hardware error at open (default: refuse it).
    watchdog : float
        Bus Watchdog, seconds without an instruction packet before the servo
        stops (rounded up to 20 ms; 0 switches it off; at most 2.54).
    limits : Limits, optional
        Command limits in the mode's unit; narrowed to the servo's own at open.
    """

    scheme = "dxl"
    vendor = "Dynamixel"
    _group_classes = (GroupSyncWrite, GroupSyncRead)
    clock_wrap_s = ct.TICK_WRAP_S
    clock_resolution_s = 1e-3  # the Realtime Tick counts whole milliseconds
    options = {
        "id": Option(_servo_id, "servo ID 0..252 (default 1)", "servo_id"),
        "baud": Option(_baud, f"baud rate of port and servo, bit/s (default {DEFAULT_BAUD}, the factory setting)"),
        "mode": Option(_mode, "operating mode: position (command in rad), current (A) or pwm (%) (default position)"),
        "return_delay_us": Option(
            parse_return_delay, "Return Delay Time set at open, us, even, 0..508, or keep (default 0)"
        ),
        "latency_ms": Option(
            parse_latency, "reply timeout is 2 x this + 2 ms; ms, or auto: the adapter's, 10 on a pty (default)"
        ),
        "reboot": Option(_flag, "1: reboot a servo that reports a hardware error at open (default 0)"),
        "watchdog": Option(
            _watchdog,
            f"Bus Watchdog: s without a packet before the servo stops, 0: off (default {DEFAULT_WATCHDOG_S:g})",
        ),
    }

    def __init__(
        self,
        port: str,
        *,
        servo_id: int = 1,
        baud: int = DEFAULT_BAUD,
        mode: str = "position",
        return_delay_us: int | None = 0,
        latency_ms: float | None = None,
        reboot: bool = False,
        watchdog: float = DEFAULT_WATCHDOG_S,
        limits: Limits | None = None,
    ) -> None:
        if not isinstance(port, str) or not port:
            raise ConfigError(f"port (={port!r}) must name a serial port, e.g. /dev/ttyUSB0")
        self.port = port
        self.servo_id = checked("servo_id", servo_id, _servo_id)
        self.baud = checked("baud", baud, _baud)
        self.mode = checked("mode", mode, _mode)
        self.return_delay_us = checked("return_delay_us", return_delay_us, parse_return_delay)
        self.latency_ms = checked("latency_ms", latency_ms, parse_latency)
        self.reboot_on_error = bool(reboot)
        watchdog_s = checked("watchdog", watchdog, _watchdog)
        self._operating_mode = MODES[self.mode]
        self._goal = _GOAL[self._operating_mode]
        super().__init__(limits=limits, position_unit=POSITION_UNIT, command_unit=COMMAND_UNITS[self._operating_mode])
        # goals are whole units (counts, 2.69 mA, 0.113 %): the base rounds every command to one,
        # inside the limits, and reports the goal as the servo received it
        self.command_step = 1.0
        self._port: _Port | None = None
        self._ph: Any = None
        self._goal_writer: Any = None
        self._owner = 0
        self._attempts = 1  # SETUP_ATTEMPTS inside _setup()
        self._info: dict[str, Any] = {}
        self._position_range = (0, ct.POSITION_COUNTS_PER_TURN - 1)
        self.watchdog_s = watchdog_s or None

    _port_class = _Port

    def _packet_handler(self) -> Any:
        return PacketHandler(2.0)

    # ---- primitives (opening and closing: SdkTransactions) ------------------------------
    def _set_torque(self, enabled: bool) -> None:
        with self._setup():
            if enabled:
                self._torque_on()
            else:
                self._torque_off()

    def _torque_on(self) -> None:
        # start from where the servo is (position) or from rest (current, PWM): no jump
        start = 0
        if self._goal is ct.GOAL_POSITION:
            low, high = self._position_range
            start = min(max(self._read_value(ct.PRESENT_POSITION), low), high)
        self._write_value(self._goal, start)
        units = round((self.watchdog_s or 0.0) / ct.SECONDS_PER_BUS_WATCHDOG_UNIT)
        self._write_value(ct.BUS_WATCHDOG, units)  # armed from the torque coming on: a dead host stops the servo
        self._write_value(ct.TORQUE_ENABLE, 1)

    def _torque_off(self) -> None:
        # switching off matters most when the line is bad: retried (SETUP_ATTEMPTS) before giving up
        self._write_value(ct.TORQUE_ENABLE, 0, allow_alert=True)

    def _exchange(self, command: float, slot: int | None) -> Reading:  # noqa: ARG002 - runs on its own clock
        self._require_owner()
        if not self.torque_enabled:
            # a Dynamixel stores a goal written with the torque off and does nothing: refuse it here
            raise DriverError(f"{self.describe()}: the torque is off; call enable() first")
        value = int(round(command))  # whole already (command_step)
        self.drop_stale()
        writer = self._goal_writer
        writer.changeParam(self.servo_id, list(ct.encode_value(self._goal, value)))
        self._check(self._sdk(writer.txPacket), 0, "SYNC_WRITE of the goal")
        reading, goal = self._present()
        return self.confirm(reading, goal, value)

    def goal_entry(self) -> tuple[int, int]:
        """``(address, size)`` of the goal written per sample."""
        return self._goal.address, self._goal.size

    def encode_goal(self, value: int) -> list[int]:
        """A goal's bytes.

        Parameters
        ----------
        value : int
            The goal, native units.
        """
        return list(ct.encode_value(self._goal, value))

    def confirm_block(self, data: bytes, written: int) -> Reading:
        """The reading in the per-sample block ``data``, the goal ``written`` confirmed (:meth:`confirm`).

        Parameters
        ----------
        data : bytes
            The block (:meth:`present_block`).
        written : int
            The goal just written.
        """
        return self.confirm(*self.decode_present(data), written)

    def confirm(self, reading: Reading, goal: int, written: int) -> Reading:
        """``reading``, after checking that the servo holds the goal ``written`` (it read back ``goal``).

        Parameters
        ----------
        reading : Reading
            The present values read with the goal.
        goal : int
            The goal read back.
        written : int
            The goal just written.
        """
        if goal != written:
            self.stats.unconfirmed += 1
            if self._read_value(ct.BUS_WATCHDOG) == ct.BUS_WATCHDOG_EXPIRED:
                raise DeviceFault(
                    f"{self.describe()}: servo {self.servo_id}'s Bus Watchdog expired (no packet for "
                    f"{self.watchdog_s:g} s: the host stalled): it stopped and locks its goals until reopened"
                )
            raise CommandUnconfirmed(
                f"{self.describe()}: servo {self.servo_id} holds {self._goal.name} {goal}, not the {written} just "
                f"written: the goal was lost on its way (a corrupted SYNC_WRITE is dropped unanswered)"
            )
        return reading

    def _read(self) -> Reading:
        self._require_owner()
        return self._present()[0]

    def _identity(self) -> dict[str, Any]:
        return dict(self._info)

    # ---- public extras ------------------------------------------------------------------------
    def reboot(self) -> None:
        """REBOOT the servo (clears a hardware error; the torque comes back off) and wait for it."""
        self._require_open()
        with self._setup():
            self._call(self._reboot)
        self._torque = False

    # ---- configuration at open -------------------------------------------------------------------
    def _configure(self) -> None:
        model = self._retried(self._ping)
        self._ensure_status_return_level()
        state = self._read_block(0, ct.HARDWARE_ERROR_STATUS.end, "READ of the control table", allow_alert=True)
        hardware_error = ct.decode_value(ct.HARDWARE_ERROR_STATUS, state, ct.HARDWARE_ERROR_STATUS.address)
        if hardware_error:
            if not self.reboot_on_error:
                raise DeviceFault(
                    f"{self.describe()}: servo {self.servo_id} reports a hardware error "
                    f"({HardwareError(hardware_error).describe()}); remove the cause, then power-cycle it "
                    f"or open it with reboot=1"
                )
            self._reboot()
            state = self._read_block(0, ct.HARDWARE_ERROR_STATUS.end, "READ of the control table")
        if ct.decode_value(ct.TORQUE_ENABLE, state, ct.TORQUE_ENABLE.address):
            self._write_value(ct.TORQUE_ENABLE, 0, allow_alert=True)  # the EEPROM is locked while it is on
        # a Bus Watchdog that expired (-1, a host that died) locks the goals until it is cleared
        self._write_value(ct.BUS_WATCHDOG, 0, allow_alert=True)
        if ct.decode_value(ct.OPERATING_MODE, state, ct.OPERATING_MODE.address) != self._operating_mode:
            self._write_value(ct.OPERATING_MODE, int(self._operating_mode))
        return_delay = ct.decode_value(ct.RETURN_DELAY_TIME, state, ct.RETURN_DELAY_TIME.address)
        if self.return_delay_us is not None and return_delay != self.return_delay_us // 2:
            self._write_value(ct.RETURN_DELAY_TIME, self.return_delay_us // 2)
            return_delay = self.return_delay_us // 2
        self._info = self._describe_state(state, model, return_delay)
        self._position_range = (
            ct.decode_value(ct.MIN_POSITION_LIMIT, state, ct.MIN_POSITION_LIMIT.address),
            ct.decode_value(ct.MAX_POSITION_LIMIT, state, ct.MAX_POSITION_LIMIT.address),
        )
        self.limits = self._servo_limits(state)
        self._goal_writer = GroupSyncWrite(self._port, self._ph, self._goal.address, self._goal.size)
        self._goal_writer.addParam(self.servo_id, list(ct.encode_value(self._goal, 0)))

    def _ping(self) -> int:
        """PING the servo; its model number."""
        model, result, error = self._sdk(self._ph.ping, self._port, self.servo_id)
        if result == COMM_RX_TIMEOUT:
            raise DriverTimeout(
                f"{self.describe()}: no Dynamixel with ID {self.servo_id} answers on {self.port} at {self.baud} bit/s "
                f"(check the ID, the baud rate (factory setting 57600), power and wiring)"
            )
        self._check(result, error, "PING", allow_alert=True)
        return int(model)

    def _ensure_status_return_level(self) -> None:
        """Make the servo answer every instruction (Status Return Level 2).

        At level 0 a READ is not answered (it times out), at level 1 a WRITE is
        not: so the new level is written without waiting for an answer, and an
        answer that comes anyway (a servo judging by the new level) is drained
        before it can pass for the answer to the next READ.
        """
        try:
            level = self._read_value(ct.STATUS_RETURN_LEVEL, allow_alert=True)
        except DriverTimeout:
            level = 0  # it answered the PING, so it answers nothing else
        if level == 2:
            return
        self._sdk(self._ph.write1ByteTxOnly, self._port, self.servo_id, ct.STATUS_RETURN_LEVEL.address, 2)
        # a servo that judges the new level may answer after all: let that answer come and drop it
        port = self._open_port()
        time.sleep(port.timeout_ms(11) / 1000.0)
        port.clearPort()
        if self._read_value(ct.STATUS_RETURN_LEVEL, allow_alert=True) != 2:
            raise DriverError(f"{self.describe()}: servo {self.servo_id} keeps its Status Return Level below 2")

    def _describe_state(self, state: bytes, model: int, return_delay: int) -> dict[str, Any]:
        def value(field: ct.Field) -> int:
            return ct.decode_value(field, state, field.address)

        number = value(ct.MODEL_NUMBER) or model
        return {
            "driver": "dxl",
            "vendor": "ROBOTIS",
            "protocol": "2.0",
            "model_number": number,
            "model": ct.MODEL_NAMES.get(number, f"model {number}"),
            "firmware_version": value(ct.FIRMWARE_VERSION),
            "id": self.servo_id,
            "baud": self.baud,
            "port": self.port,
            "operating_mode": self.mode,
            "return_delay_us": 2 * return_delay,
        }

    def _servo_limits(self, state: bytes) -> Limits:
        """The limits set on the driver, narrowed to the servo's own (the servo ignores goals beyond them)."""
        if self._goal is ct.GOAL_POSITION:
            low, high = self._position_range
        else:
            limit_field = ct.CURRENT_LIMIT if self._goal is ct.GOAL_CURRENT else ct.PWM_LIMIT
            high = ct.decode_value(limit_field, state, limit_field.address)
            low = -high
        return self._narrowed_limits(low, high)

    def _reboot(self) -> None:
        result, error = self._sdk(self._ph.reboot, self._port, self.servo_id)
        self._check(result, error, "REBOOT", allow_alert=True)
        deadline = time.monotonic() + REBOOT_TIMEOUT_S
        while True:  # a real servo takes a moment to come back
            _, result, _ = self._sdk(self._ph.ping, self._port, self.servo_id)
            if result == COMM_SUCCESS:
                return
            if time.monotonic() > deadline:
                raise DriverTimeout(
                    f"{self.describe()}: servo {self.servo_id} did not come back within {REBOOT_TIMEOUT_S} s of the REBOOT"
                )

    # ---- transactions ----------------------------------------------------------------------------
    def _present(self) -> tuple[Reading, int]:
        """The present values and the goal the servo holds, in one READ from the goal to Present Position."""
        address, length = self.present_block()
        return self.decode_present(self._read_block(address, length, "READ of the present values"))

    def present_block(self) -> tuple[int, int]:
        """``(address, length)`` of the per-sample READ: from the goal of the mode to Present Position's end."""
        address = self._goal.address
        return address, ct.PRESENT_POSITION.end - address

    def decode_present(self, data: bytes | bytearray | list[int]) -> tuple[Reading, int]:
        """The reading and the goal in the per-sample block (:meth:`present_block`).

        Parameters
        ----------
        data : bytes
            The block's bytes.
        """
        address = self._goal.address
        reading = Reading(
            position=float(ct.decode_value(ct.PRESENT_POSITION, data, ct.PRESENT_POSITION.address - address)),
            device_time=ct.decode_value(ct.REALTIME_TICK, data, ct.REALTIME_TICK.address - address) / 1000.0,
            velocity=ct.decode_value(ct.PRESENT_VELOCITY, data, ct.PRESENT_VELOCITY.address - address)
            * ct.RAD_PER_S_PER_VELOCITY_UNIT,
            current=ct.decode_value(ct.PRESENT_CURRENT, data, ct.PRESENT_CURRENT.address - address)
            * ct.AMPERE_PER_UNIT,
        )
        return reading, ct.decode_value(self._goal, data, 0)

    def _read_block(self, address: int, length: int, what: str, *, allow_alert: bool = False) -> bytes:
        # The READ packet as the SDK's readTxRx builds it; sent through txRxPacket so that the
        # status packet's own length can be checked: readTxRx slices the data out of whatever
        # arrived and pads a short stray answer with its CRC bytes.
        request = [0] * 14
        request[4], request[5], request[7] = self.servo_id, 7, Instruction.READ
        request[8:12] = [address & 0xFF, address >> 8, length & 0xFF, length >> 8]

        def transaction() -> bytes:
            reply, result, error = self._sdk(self._ph.txRxPacket, self._port, request)
            self._check(result, error, what, allow_alert=allow_alert, reply_length=length)
            received = (reply[5] | reply[6] << 8) - 4  # LEN counts instruction, error and CRC too
            if received != length:
                # an answer meant for another request (a stray reply) has the wrong length
                raise ProtocolError(
                    f"{self.describe()}: the reply to the {what} has {received} data bytes, expected {length}"
                )
            return bytes(reply[9 : 9 + length])

        return self._retried(transaction)

    def _read_value(self, field: ct.Field, *, allow_alert: bool = False) -> int:
        data = self._read_block(
            field.address, field.size, f"READ of {field.name}({field.address})", allow_alert=allow_alert
        )
        return ct.decode_value(field, data)

    def _write_value(self, field: ct.Field, value: int, *, allow_alert: bool = False) -> None:
        data = list(ct.encode_value(field, value))

        def transaction() -> None:
            result, error = self._sdk(self._ph.writeTxRx, self._port, self.servo_id, field.address, field.size, data)
            self._check(result, error, f"WRITE of {field.name}({field.address}) = {value}", allow_alert=allow_alert)

        self._retried(transaction)

    def _check(self, result: int, error: int, what: str, *, allow_alert: bool = False, reply_length: int = 0) -> None:
        """Turn the SDK's status code and the status packet's error byte into an exception."""
        sid = self.servo_id
        if result != COMM_SUCCESS:
            if self._port is not None:
                self._port.is_using = False
            if result == COMM_RX_TIMEOUT:
                timeout = self._port.timeout_ms(reply_length + 11) if self._port is not None else float("nan")
                raise DriverTimeout(f"{self.describe()}: servo {sid} did not answer the {what} within {timeout:.1f} ms")
            if result == COMM_RX_CORRUPT:
                self.stats.rejected += 1
                raise ProtocolError(
                    f"{self.describe()}: the answer of servo {sid} to the {what} was corrupted (bad CRC or cut short)"
                )
            raise DriverError(f"{self.describe()}: {what} failed: {self._ph.getTxRxResult(result)}")
        number = error & 0x7F
        if number:
            kind = DeviceFault if number == ErrorNumber.RESULT_FAIL else ProtocolError
            raise kind(f"{self.describe()}: servo {sid} refused the {what}: {describe_error(number)}")
        if error & ALERT and not allow_alert:
            raise DeviceFault(f"{self.describe()}: servo {sid} reports a hardware error: {self._hardware_error_text()}")

    def _hardware_error_text(self) -> str:
        try:
            bits = self._read_value(ct.HARDWARE_ERROR_STATUS, allow_alert=True)
        except DriverError as exc:
            return f"Hardware Error Status could not be read ({exc})"
        return (
            f"{HardwareError(bits).describe()} (Hardware Error Status {bits}); the servo switched its torque off. "
            f"Remove the cause, then power-cycle it or reopen with reboot=1"
        )
