"""The Feetech STS driver (STS3215: LeRobot's SO-100/SO-101 and Koch arms) on the official SDK ``scservo_sdk``.

URL::

    feetech:///dev/ttyUSB0?id=1&baud=1000000

The SDK is ``feetech-servo-sdk`` (module ``scservo_sdk``, what LeRobot
installs): ``PortHandler``, ``PacketHandler(0)`` (0: the STS's little-endian
numbers), ``GroupSyncWrite`` and ``GroupSyncRead``.

Per sample, :meth:`FeetechDriver.exchange` writes Goal Position with a
GroupSyncWrite (a broadcast, never answered) and then READs Torque Enable
(40) to Present Current (70) in one transaction: the torque, the goal
itself, Lock, Present Position, Speed, Load, Voltage, Temperature, Status,
Moving and Current. The goal read back confirms the write: an STS drops a
packet whose checksum fails without a word, and only the read-back shows
it (:class:`~servoid.errors.CommandUnconfirmed`, counted in
``stats.unconfirmed``; the session leaves that sample and a guard window
out). Torque Enable read back 0 while the driver has it on means the servo
restarted (a brown-out: :class:`~servoid.errors.DeviceRestarted`) or a
protection unloaded it (the status error byte says which:
:class:`~servoid.errors.DeviceFault`).

Units
-----
position, command   rad, ``(count - 2048) * 2 pi / 4096`` (0 rad at the middle of the range); goals whole counts
velocity            rad/s (Present Speed, counts per second, sign in bit 15)
current             A (Present Current, 6.5 mA a unit)
device_time         none: the STS has no clock to read

The sign-magnitude entries (Present Position, Present Speed, Goal Position:
bit 15; Homing Offset: bit 11; Present Load: bit 10) are decoded by
:mod:`~servoid.drivers.feetech.control_table`.

What opening does
-----------------
PING the servo (a clear :class:`~servoid.errors.DriverTimeout` naming the ID,
port and baud rate if nothing answers), read the memory table 0..70 in one
READ, refuse a servo whose protections are active (Status, 65), switch the
torque off, make it answer every instruction (Response Status Level 1), and
set Return Delay Time (``return_delay_us``, default 0; the EEPROM is unlocked
for the write and locked again). The command limits default to the servo's
own Min/Max Position Limit, narrowed by ``min``/``max``. Switching the
torque on first sets the goal to the present position, so the servo does not
jump.

No watchdog
-----------
The STS memory table has no communication timeout (nothing like the
Dynamixel's Bus Watchdog): a servo whose host died holds its last goal with
the torque on. servoid switches the torque off on every way out that software
can catch -- close, every error, Ctrl-C, SIGTERM, SIGHUP; a SIGKILL or a cut
cable cannot be caught, and ``watchdog_s`` stays None so that nothing pretends
otherwise (docs/feetech.md).

Pitfalls of the SDK handled here
--------------------------------
The SDK is a port of ROBOTIS's and shares its faults, fixed the same way
(:mod:`servoid.drivers._sdk_port`: monotonic timeouts, the adapter's real
latency, ``select`` instead of a spinning core); status codes and the error
byte become exceptions; the busy flag is reset after every failure; every
READ's length is checked (the SDK slices whatever arrived). Not thread-safe.
"""

from __future__ import annotations

import logging
import math
import time
from typing import Any, TypeVar

from scservo_sdk import (
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
from servoid.drivers.feetech import control_table as ct
from servoid.drivers.feetech.protocol import MAX_ID, Instruction, describe_error
from servoid.errors import (
    CommandUnconfirmed,
    ConfigError,
    DeviceFault,
    DeviceRestarted,
    DriverError,
    DriverTimeout,
    ProtocolError,
)

__all__ = ["FeetechDriver", "POSITION_UNIT", "SUPPORTED_BAUD_RATES", "present"]

log = logging.getLogger("servoid.drivers.feetech")

T = TypeVar("T")

#: Baud rates an STS servo and the SDK both accept.
SUPPORTED_BAUD_RATES = (38_400, 57_600, 115_200, 128_000, 250_000, 500_000, 1_000_000)
#: Factory baud rate of an STS3215.
DEFAULT_BAUD = 1_000_000
#: The SDK's protocol_end for the STS/SMS series (little-endian numbers).
STS_END = 0
POSITION_UNIT = UnitConversion("rad", ct.RAD_PER_COUNT, ct.POSITION_CENTRE)

#: The per-sample READ: Torque Enable (40) to the end of Present Current (71).
_BLOCK_START = ct.TORQUE_ENABLE.address
_BLOCK_LENGTH = ct.PRESENT_CURRENT.end - _BLOCK_START


def _servo_id(value: Any) -> int:
    number = int(value)
    if not 0 <= number <= MAX_ID:
        raise ValueError(f"a servo ID is 0..{MAX_ID}")
    return number


def _baud(value: Any) -> int:
    number = int(value)
    if number not in SUPPORTED_BAUD_RATES:
        raise ValueError(f"expected one of {', '.join(map(str, SUPPORTED_BAUD_RATES))}")
    return number


class _Port(SelectPort, PortHandler):  # type: ignore[misc]
    """The SDK's PortHandler with monotonic timeouts, the real latency timer, and no busy-polling."""


def present(data: bytes | bytearray | list[int]) -> tuple[Reading, int, int, int]:
    """The per-sample block (40..70) as ``(reading, goal, torque, status)``.

    Parameters
    ----------
    data : bytes
        The block's bytes, from Torque Enable (40).
    """

    def value(field: ct.Field) -> int:
        return ct.decode_value(field, data, field.address - _BLOCK_START)

    reading = Reading(
        position=float(value(ct.PRESENT_POSITION)),
        velocity=value(ct.PRESENT_SPEED) * ct.RAD_PER_S_PER_SPEED_UNIT,
        current=value(ct.PRESENT_CURRENT) * ct.AMPERE_PER_CURRENT_UNIT,
    )
    return reading, value(ct.GOAL_POSITION), value(ct.TORQUE_ENABLE), value(ct.STATUS)


class FeetechDriver(SdkTransactions, Driver):
    """A Feetech STS servo (see the module docstring).

    Parameters
    ----------
    port : str
        Serial port (``/dev/ttyUSB0``, ``/dev/ttyACM0``, ``/dev/pts/7``, ``COM3``).
    servo_id : int
        The servo's ID, 0..253 (URL ``id``, default 1).
    baud : int
        Baud rate of the port and the servo (default 1000000, the factory setting).
    return_delay_us : int or None
        Return Delay Time to set at open, even microseconds 0..508 (default 0);
        None keeps the servo's.
    latency_ms : float or None
        Latency timer for reply timeouts, which are 2 x it + 2 ms plus the wire
        time (default: the USB adapter's from sysfs, 10 ms for a pseudo-terminal,
        else 1 ms).
    limits : Limits, optional
        Command limits in rad; narrowed to the servo's own at open.
    """

    scheme = "feetech"
    vendor = "Feetech"
    _group_classes = (GroupSyncWrite, GroupSyncRead)
    options = {
        "id": Option(_servo_id, f"servo ID 0..{MAX_ID} (default 1)", "servo_id"),
        "baud": Option(_baud, f"baud rate of port and servo, bit/s (default {DEFAULT_BAUD}, the factory setting)"),
        "return_delay_us": Option(
            parse_return_delay, "Return Delay Time set at open, us, even, 0..508, or keep (default 0)"
        ),
        "latency_ms": Option(
            parse_latency, "reply timeout is 2 x this + 2 ms; ms, or auto: the adapter's, 10 on a pty (default)"
        ),
    }

    def __init__(
        self,
        port: str,
        *,
        servo_id: int = 1,
        baud: int = DEFAULT_BAUD,
        return_delay_us: int | None = 0,
        latency_ms: float | None = None,
        limits: Limits | None = None,
    ) -> None:
        if not isinstance(port, str) or not port:
            raise ConfigError(f"port (={port!r}) must name a serial port, e.g. /dev/ttyUSB0")
        self.port = port
        self.servo_id = checked("servo_id", servo_id, _servo_id)
        self.baud = checked("baud", baud, _baud)
        self.return_delay_us = checked("return_delay_us", return_delay_us, parse_return_delay)
        self.latency_ms = checked("latency_ms", latency_ms, parse_latency)
        super().__init__(limits=limits, position_unit=POSITION_UNIT)
        self.command_step = 1.0  # goals are whole counts
        self._port: _Port | None = None
        self._ph: Any = None
        self._goal_writer: Any = None
        self._owner = 0
        self._attempts = 1
        self._info: dict[str, Any] = {}
        self._position_range = (0, ct.COUNTS_PER_REV - 1)

    _port_class = _Port

    def _packet_handler(self) -> Any:
        return PacketHandler(STS_END)

    # ---- primitives (opening and closing: SdkTransactions) ------------------------------
    def _set_torque(self, enabled: bool) -> None:
        with self._setup():
            if enabled:
                low, high = self._position_range
                start = min(max(self._read_value(ct.PRESENT_POSITION), low), high)
                self._write_value(ct.GOAL_POSITION, start)  # start from where the servo is: no jump
                self._write_value(ct.TORQUE_ENABLE, 1)
            else:
                # switching off matters most when the line is bad: retried (SETUP_ATTEMPTS) before giving up
                self._write_value(ct.TORQUE_ENABLE, 0, allow_error=True)  # a servo with a protection active obeys

    def _exchange(self, command: float, slot: int | None) -> Reading:  # noqa: ARG002 - runs on its own clock
        self._require_owner()
        if not self.torque_enabled:
            raise DriverError(f"{self.describe()}: the torque is off; call enable() first")
        value = int(round(command))
        self.drop_stale()
        writer = self._goal_writer
        writer.changeParam(self.servo_id, list(ct.encode_value(ct.GOAL_POSITION, value)))
        self._check(self._sdk(writer.txPacket), 0, "SYNC_WRITE of the goal")
        data = self._read_block(_BLOCK_START, _BLOCK_LENGTH, "READ of the present values")
        return self.confirm_block(data, value)

    def _read(self) -> Reading:
        self._require_owner()
        return present(self._read_block(_BLOCK_START, _BLOCK_LENGTH, "READ of the present values"))[0]

    def _identity(self) -> dict[str, Any]:
        return dict(self._info)

    # ---- for a bus of several (servoid.drivers.bus) -------------------------------------------
    def present_block(self) -> tuple[int, int]:
        """``(address, length)`` of the per-sample READ: Torque Enable (40) to Present Current's end."""
        return _BLOCK_START, _BLOCK_LENGTH

    def goal_entry(self) -> tuple[int, int]:
        """``(address, size)`` of Goal Position."""
        return ct.GOAL_POSITION.address, ct.GOAL_POSITION.size

    def encode_goal(self, value: int) -> list[int]:
        """A goal's bytes (sign-magnitude, bit 15).

        Parameters
        ----------
        value : int
            The goal, counts.
        """
        return list(ct.encode_value(ct.GOAL_POSITION, value))

    def confirm_block(self, data: bytes, written: int) -> Reading:
        """The reading in the per-sample block ``data``, the goal ``written`` confirmed (:meth:`confirm`).

        Parameters
        ----------
        data : bytes
            The block (:meth:`present_block`).
        written : int
            The goal just written.
        """
        return self.confirm(data, written)

    def confirm(self, data: bytes | bytearray | list[int], written: int) -> Reading:
        """The reading in ``data`` (the per-sample block), after checking the servo holds the goal ``written``.

        Parameters
        ----------
        data : bytes
            The block read back, from Torque Enable (40).
        written : int
            The goal just written, counts.

        Raises
        ------
        DeviceFault
            A protection unloaded the servo.
        DeviceRestarted
            The torque is off though the driver switched it on (a brown-out).
        CommandUnconfirmed
            The goal differs from the one written (the SYNC_WRITE was lost).
        """
        reading, goal, torque, status = present(data)
        if status and torque:
            raise DeviceFault(
                f"{self.describe()}: servo {self.servo_id} reports {describe_error(status)} (Status {status})"
            )
        if not torque:
            if status:
                raise DeviceFault(
                    f"{self.describe()}: servo {self.servo_id} unloaded itself: {describe_error(status)} "
                    f"(Status {status}); remove the cause, then reopen"
                )
            raise DeviceRestarted(
                f"{self.describe()}: servo {self.servo_id} has its torque off though it was switched on: it restarted "
                f"(a brown-out of its supply?); the run stops"
            )
        if goal != written:
            self.stats.unconfirmed += 1
            raise CommandUnconfirmed(
                f"{self.describe()}: servo {self.servo_id} holds Goal Position {goal}, not the {written} just written: "
                f"the goal was lost on its way (a corrupted SYNC_WRITE is dropped unanswered)"
            )
        return reading

    # ---- configuration at open -------------------------------------------------------------------
    def _configure(self) -> None:
        model = self._retried(self._ping)
        state = self._read_block(0, ct.PRESENT_CURRENT.end, "READ of the memory table")

        def value(field: ct.Field) -> int:
            return ct.decode_value(field, state, field.address)

        status = value(ct.STATUS)
        if status:
            raise DeviceFault(
                f"{self.describe()}: servo {self.servo_id} reports {describe_error(status)} (Status {status}); "
                f"remove the cause, then power-cycle it"
            )
        if value(ct.TORQUE_ENABLE):
            self._write_value(ct.TORQUE_ENABLE, 0)
        if value(ct.STATUS_RETURN_LEVEL) != 1:
            self._answer_everything()
        return_delay = value(ct.RETURN_DELAY_TIME)
        if self.return_delay_us is not None and return_delay != self.return_delay_us // 2:
            self._write_eeprom(ct.RETURN_DELAY_TIME, self.return_delay_us // 2)
            return_delay = self.return_delay_us // 2
        number = value(ct.MODEL_NUMBER) or model
        self._info = {
            "driver": "feetech",
            "vendor": "Feetech",
            "protocol": "SCS/STS",
            "model_number": number,
            "model": ct.MODEL_NAMES.get(number, f"model {number}"),
            "firmware_version": f"{value(ct.FIRMWARE_MAJOR)}.{value(ct.FIRMWARE_MINOR)}",
            "id": self.servo_id,
            "baud": self.baud,
            "port": self.port,
            "return_delay_us": 2 * return_delay,
            "watchdog": "none (the STS has no communication timeout)",
        }
        self._position_range = (value(ct.MIN_POSITION_LIMIT), value(ct.MAX_POSITION_LIMIT))
        self.limits = self._servo_limits()
        self._goal_writer = GroupSyncWrite(self._port, self._ph, ct.GOAL_POSITION.address, ct.GOAL_POSITION.size)
        self._goal_writer.addParam(self.servo_id, list(ct.encode_value(ct.GOAL_POSITION, 0)))

    def _ping(self) -> int:
        model, result, error = self._sdk(self._ph.ping, self._port, self.servo_id)
        if result == COMM_RX_TIMEOUT:
            raise DriverTimeout(
                f"{self.describe()}: no Feetech servo with ID {self.servo_id} answers on {self.port} at {self.baud} "
                f"bit/s (check the ID, the baud rate (factory setting 1000000), power and wiring)"
            )
        self._check(result, 0, "PING")
        return int(model)

    def _answer_everything(self) -> None:
        """Response Status Level 1: at 0 a WRITE is not answered, so the new level is written without waiting."""
        port = self._open_port()
        self._sdk(self._ph.write1ByteTxOnly, port, self.servo_id, ct.STATUS_RETURN_LEVEL.address, 1)
        time.sleep(port.timeout_ms(6) / 1000.0)
        port.clearPort()
        port.ser.reset_input_buffer()
        if self._read_value(ct.STATUS_RETURN_LEVEL) != 1:
            raise DriverError(f"{self.describe()}: servo {self.servo_id} keeps its Response Status Level at 0")

    def _write_eeprom(self, field: ct.Field, value: int) -> None:
        """Unlock the EEPROM, write, lock it again (so that the value survives a power cycle)."""
        self._write_value(ct.LOCK, 0)
        try:
            self._write_value(field, value)
        finally:
            self._write_value(ct.LOCK, 1)

    def _servo_limits(self) -> Limits:
        """The limits set on the driver, narrowed to the servo's own (it clips goals beyond them)."""
        low, high = self._position_range
        return self._narrowed_limits(low, high)

    # ---- transactions ----------------------------------------------------------------------------
    def _read_block(self, address: int, length: int, what: str) -> bytes:
        # the READ as the SDK's readTxRx builds it, through txRxPacket so that the reply's own length
        # can be checked: readTxRx slices the data out of whatever arrived
        request = [0] * 8
        request[2], request[3], request[4] = self.servo_id, 4, Instruction.READ
        request[5], request[6] = address, length

        def transaction() -> bytes:
            reply, result, error = self._sdk(self._ph.txRxPacket, self._port, request)
            self._check(result, error, what, reply_length=length)
            received = reply[3] - 2  # LEN counts the error byte and the checksum too
            if received != length:
                raise ProtocolError(
                    f"{self.describe()}: the reply to the {what} has {received} data bytes, expected {length}"
                )
            return bytes(reply[5 : 5 + length])

        return self._retried(transaction)

    def _read_value(self, field: ct.Field) -> int:
        return ct.decode_value(field, self._read_block(field.address, field.size, f"READ of {field.name}"))

    def _write_value(self, field: ct.Field, value: int, *, allow_error: bool = False) -> None:
        data = list(ct.encode_value(field, value))

        def transaction() -> None:
            result, error = self._sdk(self._ph.writeTxRx, self._port, self.servo_id, field.address, field.size, data)
            self._check(result, 0 if allow_error else error, f"WRITE of {field.name}({field.address}) = {value}")

        self._retried(transaction)

    def _check(self, result: int, error: int, what: str, *, reply_length: int = 0) -> None:
        """Turn the SDK's status code and the status packet's error byte into an exception."""
        sid = self.servo_id
        if result != COMM_SUCCESS:
            if self._port is not None:
                self._port.is_using = False
            if result == COMM_RX_TIMEOUT:
                timeout = self._port.timeout_ms(reply_length + 6) if self._port is not None else math.nan
                raise DriverTimeout(f"{self.describe()}: servo {sid} did not answer the {what} within {timeout:.1f} ms")
            if result == COMM_RX_CORRUPT:
                self.stats.rejected += 1
                raise ProtocolError(
                    f"{self.describe()}: the answer of servo {sid} to the {what} was corrupted (bad checksum or cut short)"
                )
            raise DriverError(f"{self.describe()}: {what} failed: {self._ph.getTxRxResult(result)}")
        if error:
            raise DeviceFault(
                f"{self.describe()}: servo {sid} reports {describe_error(error)} (in its answer to the {what})"
            )
