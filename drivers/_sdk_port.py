"""What the drivers on a vendor's serial-bus SDK share (ROBOTIS, Feetech): the fixed port handler, transactions, URL options.

``dynamixel_sdk.PortHandler`` and ``scservo_sdk.PortHandler`` (Feetech's SDK
is a port of ROBOTIS's) share their method names and their faults: timeouts
measured with the wall clock, a fixed 16 ms USB latency timer (a missing
answer costs 34 ms), and a reply awaited by spinning a core. :class:`SelectPort`
is mixed in front of either (``class _Port(SelectPort, PortHandler)``) and
fixes all three; :func:`default_latency_ms` says what latency to allow for a
port. :class:`SdkTransactions` is mixed into both drivers: patient,
retried transactions outside the per-sample exchange, the SDK's busy flag
reset after a failure, the owner thread checked. The URL options both take
(``return_delay_us``, ``latency_ms``) are parsed here.
"""

from __future__ import annotations

import contextlib
import dataclasses
import logging
import os
import select
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from typing import TYPE_CHECKING, Any, TypeVar

from servoid.errors import ConfigError, DriverError, DriverTimeout, ProtocolError

if TYPE_CHECKING:  # pragma: no cover
    from servoid.drivers.base import Limits

__all__ = ["SelectPort", "SdkTransactions", "default_latency_ms", "parse_return_delay", "parse_latency", "checked",
           "PTY_LATENCY_MS", "SETUP_LATENCY_MS", "SETUP_ATTEMPTS"]  # fmt: skip

T = TypeVar("T")

log = logging.getLogger("servoid.drivers")

#: Latency timer (ms) assumed for a pseudo-terminal (an emulator) when the URL does not say.
PTY_LATENCY_MS = 10.0

#: Latency timer (ms) at least assumed outside the per-sample exchange (opening, torque, reboot):
#: nothing there is timed, and a servo just powered up or a loaded host may be slow to answer.
SETUP_LATENCY_MS = 25.0


#: Tries of a transaction outside the per-sample exchange (opening, torque, reboot) before giving
#: up: a noisy line costs a retry there, never the run; a goal is never sent twice.
SETUP_ATTEMPTS = 3


def parse_return_delay(value: Any) -> int | None:
    """URL ``return_delay_us``: even microseconds 0..508, or ``keep`` (None).

    Parameters
    ----------
    value : str or int or None
        The option's text.
    """
    if value is None or str(value).lower() == "keep":
        return None
    number = int(value)
    if not 0 <= number <= 508 or number % 2:
        raise ValueError("the Return Delay Time is an even number of microseconds in 0..508, or 'keep'")
    return number


def parse_latency(value: Any) -> float | None:
    """URL ``latency_ms``: a positive number of milliseconds, or ``auto`` (None).

    Parameters
    ----------
    value : str or float or None
        The option's text.
    """
    if value is None or str(value).lower() == "auto":
        return None
    number = float(value)
    if not number > 0:
        raise ValueError("the latency timer is a positive number of milliseconds, or 'auto'")
    return number


def checked(name: str, value: Any, parse: Callable[[Any], Any]) -> Any:
    """``parse(value)``, a ValueError turned into a :class:`~servoid.errors.ConfigError` naming ``name``.

    Parameters
    ----------
    name : str
        The argument's name.
    value : object
        Its value.
    parse : callable
        The option's parser.
    """
    try:
        return parse(value)
    except (TypeError, ValueError) as exc:
        raise ConfigError(f"{name} (={value!r}) is invalid: {exc}") from None


def default_latency_ms(port: str) -> float:
    """The latency to allow for ``port`` when the URL does not say (``latency_ms=auto``).

    A USB serial adapter (U2D2, USB2Dynamixel, Feetech's URT-1: FTDI or CH340
    chips) holds received bytes up to its latency timer, read from sysfs. A
    pseudo-terminal's other end is a program (the emulator), which a loaded
    machine may not schedule for several milliseconds: :data:`PTY_LATENCY_MS`.
    Anything else (a native UART): 1 ms.

    Parameters
    ----------
    port : str
        The serial port's path.
    """
    real = os.path.realpath(port)
    try:
        with open(f"/sys/bus/usb-serial/devices/{os.path.basename(real)}/latency_timer", encoding="ascii") as fh:
            latency = float(fh.read().strip())
    except (OSError, ValueError):
        return PTY_LATENCY_MS if real.startswith("/dev/pts/") else 1.0
    if latency > 2:
        log.warning(
            "%s: the USB adapter's latency timer is %g ms, which delays every reply; set it to 1 ms: "
            "echo 1 | sudo tee /sys/bus/usb-serial/devices/%s/latency_timer", port, latency, os.path.basename(real),
        )  # fmt: skip
    return latency


class SelectPort:
    """Mixed in front of a vendor SDK's PortHandler: monotonic timeouts, the real latency timer, no busy-polling.

    Parameters
    ----------
    port_name : str
        The serial port.
    latency_ms : float
        The adapter's latency timer, ms: reply timeouts are 2 x it + 2 ms plus the wire time.
    """

    # the attributes the SDKs' PortHandler sets
    ser: Any
    packet_start_time: float
    packet_timeout: float
    tx_time_per_byte: float

    def __init__(self, port_name: str, *, latency_ms: float) -> None:
        super().__init__(port_name)  # type: ignore[call-arg]
        self.latency_ms = latency_ms
        #: "select" waits for the reply's bytes; "spin" is the SDK's own busy-polling (for comparison).
        self.poll = "select"

    def getCurrentTime(self) -> float:  # noqa: N802 - the SDK's name; ms, like the SDK's
        return time.monotonic_ns() / 1e6

    def getTimeSinceStart(self) -> float:  # noqa: N802
        return self.getCurrentTime() - self.packet_start_time

    def setPacketTimeout(self, packet_length: int) -> None:  # noqa: N802
        # the SDK's formula, with the adapter's latency instead of its fixed 16 ms
        self.packet_start_time = self.getCurrentTime()
        self.packet_timeout = self.tx_time_per_byte * packet_length + self.latency_ms * 2.0 + 2.0

    def readPort(self, length: int) -> bytes:  # noqa: N802
        # The SDK calls this in a tight loop until the reply is complete or the
        # timeout expires; waiting in select() instead frees the core for the
        # servo emulator or the estimator, and wakes as soon as bytes arrive.
        if length <= 0:
            # the SDK's own arithmetic on a corrupted LENGTH field (it waits for LENGTH + 7 bytes and has
            # more already): nothing to read, and the CRC over the bytes it has then refuses the packet
            return b""
        fd = getattr(self.ser, "fd", None)
        if fd is None or self.poll == "spin":
            return super().readPort(length)  # type: ignore[misc, no-any-return]
        remaining_ms = self.packet_timeout - self.getTimeSinceStart()
        ready, _, _ = select.select([fd], [], [], max(remaining_ms, 0.0) / 1000.0)
        if not ready:
            return b""
        try:
            return os.read(fd, length)
        except BlockingIOError:
            return b""

    @contextlib.contextmanager
    def patience(self, latency_ms: float) -> Iterator[None]:
        """Use at least ``latency_ms`` for the timeouts inside the ``with`` block.

        Parameters
        ----------
        latency_ms : float
            The least latency to allow, ms.
        """
        saved = self.latency_ms
        self.latency_ms = max(saved, latency_ms)
        try:
            yield
        finally:
            self.latency_ms = saved

    def timeout_ms(self, packet_length: int) -> float:
        """The reply timeout the SDK will use for a reply of ``packet_length`` bytes.

        Parameters
        ----------
        packet_length : int
            Bytes of the reply.
        """
        return float(self.tx_time_per_byte * packet_length + self.latency_ms * 2.0 + 2.0)


class SdkTransactions:
    """Mixed into a driver on a vendor SDK: transactions outside the per-sample exchange, the SDK's busy flag, the owner thread.

    The driver sets ``_port`` (a :class:`SelectPort`, None while closed),
    ``_attempts`` (1) and ``_owner`` (the opening thread's id).
    """

    _port: Any
    _attempts: int
    _owner: int
    #: The vendor's name in messages.
    vendor = ""

    describe: Callable[[], str]  # Driver's
    _check: Callable[..., None]  # the vendor's: status code and error byte -> exception
    goal_entry: Callable[[], tuple[int, int]]  # the vendor's: (address, size) of the per-sample goal
    servo_id: int
    _ph: Any
    #: The SDK's GroupSyncWrite and GroupSyncRead classes (the vendor driver sets them).
    _group_classes: tuple[Any, Any]
    _shared: Any = None  # the joint whose port this one uses, on a bus of several
    _group: Any = None  # (ids, writer, reader) of the group transaction, on the joint that owns the port

    port: str
    baud: int
    latency_ms: float | None
    _configure: Callable[[], None]  # the vendor's: read the servo's facts, set it up for sampling
    #: The vendor's port class (:class:`SelectPort` mixed in front of the SDK's ``PortHandler``).
    _port_class: Any

    def _packet_handler(self) -> Any:
        """The SDK's packet handler for this vendor's protocol."""
        raise NotImplementedError

    # ---- the URL, opening and closing (the same on both SDKs) -------------------------------
    @classmethod
    def from_url(cls, url: Any) -> Any:
        """``SCHEME:///dev/ttyUSB0?id=1&baud=1000000`` (the port is the URL's path; ``SCHEME://COM3?...`` on Windows)."""
        vendor: Any = cls  # a Driver: its scheme and options
        port = url.path or url.host
        if not port or port == "/":
            raise ConfigError(
                f"{url.raw}: the URL must name the serial port, e.g. {vendor.scheme}:///dev/ttyUSB0?id=1&baud=1000000"
            )
        driver = vendor(port, **vendor.parse_options(url))
        driver.url = url.raw
        return driver

    def _open(self) -> None:
        if self._open_on_shared_port(self._configure):  # a joint on a bus another joint opened
            return
        latency = self.latency_ms if self.latency_ms is not None else default_latency_ms(self.port)
        port = self._port_class(self.port, latency_ms=latency)
        try:
            port.openPort()
        except Exception as exc:  # noqa: BLE001 - pyserial raises SerialException, OSError, ValueError
            raise DriverError(f"{self.describe()}: cannot open the serial port {self.port}: {exc}") from exc
        if not port.setBaudRate(self.baud):
            port.closePort()
            raise ConfigError(f"{self.describe()}: the port refused baud (={self.baud})")
        self._port, self._ph = port, self._packet_handler()
        self._owner = threading.get_ident()
        try:
            with self._setup():
                self._configure()
        except BaseException:
            port.closePort()
            self._port = None
            raise

    def _close(self) -> None:
        if self._port is not None and self._shared is None:
            self._port.closePort()
        self._port = None

    def _narrowed_limits(self, low: float, high: float) -> Limits:
        """The limits set on the driver, narrowed to the servo's own range ``low .. high`` (native unit).

        The servo ignores or clips goals beyond its own range; limits that do
        not overlap it are a one-line error naming both.
        """
        driver: Any = self  # a Driver: its command unit and limits
        unit = driver.command_unit
        servo_low, servo_high = unit.to_user(low), unit.to_user(high)
        asked = driver.limits
        minimum, maximum = max(asked.minimum, servo_low), min(asked.maximum, servo_high)
        if not minimum < maximum:
            raise ConfigError(
                f"{self.describe()}: the limits min={asked.minimum}, max={asked.maximum} {unit.unit} do not overlap "
                f"the servo's own range {servo_low:.4g} .. {servo_high:.4g} {unit.unit}"
            )
        limits: Limits = dataclasses.replace(asked, minimum=minimum, maximum=maximum)
        return limits

    # ---- several servos on one bus (servoid.drivers.bus) ------------------------------------
    def share_port(self, owner: Any) -> None:
        """Use ``owner``'s port and SDK handles (opened by it) instead of opening one: a joint of the same bus.

        Parameters
        ----------
        owner : driver
            The joint that opens the port (it is opened first and closed last).
        """
        self._shared = owner

    def _open_on_shared_port(self, configure: Callable[[], None]) -> bool:
        """Open on the owner's port (True), when this joint shares one; configure the servo there."""
        owner = self._shared
        if owner is None:
            return False
        self._port, self._ph, self._owner = owner._open_port(), owner._ph, owner._owner
        try:
            with self._setup():
                configure()
        except BaseException:
            self._port = None
            raise
        return True

    def group_exchange(self, joints: Sequence[Any], values: Sequence[int]) -> list[Any]:
        """Every joint's goal in one SYNC_WRITE, every joint's per-sample block in one SYNC_READ; their readings.

        Called on the joint that owns the port. Each reading is confirmed by its
        joint (the goal read back, the torque, the protections), in order.

        Parameters
        ----------
        joints : sequence of driver
            The joints of the bus (this one first), open, torque on.
        values : sequence of int
            Each joint's goal, native units.
        """
        self._require_owner()
        ids = tuple(j.servo_id for j in joints)
        address, length = joints[0].present_block()
        if self._group is None or self._group[0] != ids:
            write_class, read_class = self._group_classes
            goal_address, goal_size = self.goal_entry()
            writer = write_class(self._open_port(), self._ph, goal_address, goal_size)
            reader = read_class(self._open_port(), self._ph, address, length)
            for j in joints:
                writer.addParam(j.servo_id, j.encode_goal(0))
                reader.addParam(j.servo_id)
            self._group = (ids, writer, reader)
        _, writer, reader = self._group
        self.drop_stale()
        for j, value in zip(joints, values):
            writer.changeParam(j.servo_id, j.encode_goal(value))
        self._check(self._sdk(writer.txPacket), 0, "SYNC_WRITE of the goals")
        for j in joints:
            reader.data_dict[j.servo_id] = []
        result = self._sdk(reader.txRxPacket)
        missing = [j for j in joints if len(reader.data_dict.get(j.servo_id) or ()) != length]
        if result != 0 or missing:
            culprit = missing[0] if missing else joints[0]
            culprit._check(result if result != 0 else -7, 0, f"SYNC_READ of servos {', '.join(map(str, ids))}",
                           reply_length=length)  # fmt: skip
            raise ProtocolError(
                f"{self.describe()}: the SYNC_READ answer of servo {culprit.servo_id} has the wrong length"
            )
        return [j.confirm_block(bytes(reader.data_dict[j.servo_id]), value) for j, value in zip(joints, values)]

    @contextlib.contextmanager
    def _setup(self) -> Iterator[None]:
        """Outside the per-sample exchange: patient timeouts, and a failed transaction tried again."""
        with self._open_port().patience(SETUP_LATENCY_MS):
            self._attempts = SETUP_ATTEMPTS
            try:
                yield
            finally:
                self._attempts = 1

    def _retried(self, transaction: Callable[[], T]) -> T:
        """``transaction()``, tried again after a timeout or a corrupted answer inside :meth:`_setup`."""
        for attempt in range(1, self._attempts + 1):
            try:
                return transaction()
            except (DriverTimeout, ProtocolError) as exc:
                if attempt == self._attempts:
                    raise
                log.debug("%s: attempt %d failed (%s), trying again", self.describe(), attempt, exc)
        raise AssertionError("unreachable")

    def _sdk(self, func: Callable[..., Any], *args: Any) -> Any:
        try:
            return func(*args)
        except BaseException:
            # the SDK leaves its busy flag set when a call raises: every later call would fail
            if self._port is not None:
                self._port.is_using = False
            raise

    def drop_stale(self) -> None:
        """Drop answers that came after their request timed out, before a new request (counted in ``stats.stale``).

        The SDKs never clear their input (their ``clearPort`` flushes the
        output): a late answer left there passes for the answer to the next
        request of the same length -- a SYNC_READ's answers would then always
        be one sample old, and every goal read back unconfirmed.
        """
        ser = self._open_port().ser
        if ser.in_waiting:
            ser.reset_input_buffer()
            self.stats.stale += 1  # type: ignore[attr-defined]

    def _open_port(self) -> Any:
        if self._port is None:
            raise DriverError(f"{self.describe()} is not open")
        return self._port

    def _require_owner(self) -> None:
        if threading.get_ident() != self._owner:
            raise DriverError(
                f"{self.describe()}: a {self.vendor} driver is not thread-safe; use it from the thread that opened it"
            )
