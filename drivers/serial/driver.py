"""The serial bench servo driver on pyserial (``serial://``), speaking docs/serial-protocol.md.

URL::

    serial:///dev/ttyUSB0?baud=1000000&timeout=0.05
    serial://COM3?unit=counts

Positions and commands travel as encoder counts; the driver converts them to
rad with the counts per revolution the firmware reports (``unit=counts``
keeps counts). Every reply is checked (CRC, framing, field count, sequence
number, boot id) before anything in it is used: a corrupted frame is thrown
away and counted in ``stats.rejected``, a reply to an earlier request that had
timed out in ``stats.stale``, a change of boot id raises
:class:`~servoid.errors.DeviceRestarted`.
"""

from __future__ import annotations

import math
import select
import time
from collections import deque
from collections.abc import Mapping
from typing import Any, ClassVar

import serial

from servoid.drivers import options as opt
from servoid.drivers.base import Driver, DriverURL, Measurement, Option, Reading, UnitConversion
from servoid.drivers.serial.protocol import (
    ERROR_CODES,
    PROTOCOL_VERSION,
    SEQ_MODULUS,
    FrameSplitter,
    Reply,
    encode,
    parse_reply,
)
from servoid.errors import ConfigError, DeviceFault, DeviceRestarted, DriverError, DriverTimeout, ProtocolError

__all__ = ["SerialDriver"]

#: After a corrupted frame, wait at most this long for a good reply before
#: giving the sample up: the corrupted frame was most likely the reply.
CORRUPT_GRACE_S = 0.002

#: User units the driver offers.
UNITS = ("rad", "counts")

#: Configuration requests (identity, torque, period) are retried this often;
#: set points never are (a repeated set point would be a second sample).
CONFIG_ATTEMPTS = 3


class SerialDriver(Driver):
    """A bench controller running the servoid firmware, on a serial port.

    Parameters
    ----------
    port : str
        Device name (``/dev/ttyUSB0``, ``COM3``, a pseudo-terminal).
    baud : int
        Line rate (a 50-byte reply at 1 kHz needs >= 500000 on a real UART;
        ignored on a pseudo-terminal).
    timeout : float
        Seconds to wait for a reply.
    unit : {"rad", "counts"}
        User unit of commands and positions.
    watchdog : float
        Seconds without a request after which the firmware switches the
        torque off by itself (0: off); covers a host that crashed.
    **kwargs
        Limits for :class:`~servoid.drivers.base.Driver`.
    """

    scheme: ClassVar[str] = "serial"
    carries_slots: ClassVar[bool] = True  # the set-input request carries the slot: S <counts> <slot>
    options: ClassVar[Mapping[str, Option]] = {
        "baud": Option(opt.integer(minimum=1), "line rate in bit/s (default 1000000)"),
        "timeout": Option(opt.number(low=0, low_open=True), "seconds to wait for a reply (default 0.1)"),
        "unit": Option(opt.choice(*UNITS), "user unit: rad or counts (default rad)"),
        "watchdog": Option(
            opt.number(low=0, high=600),
            "seconds without a request before the firmware drops the torque (0: off, default 0.5)",
        ),
    }
    clock_wrap_s: ClassVar[float | None] = 2**32 / 1e6  # u32 microsecond counter

    def __init__(
        self,
        *,
        port: str,
        baud: int = 1_000_000,
        timeout: float = 0.1,
        unit: str = "rad",
        watchdog: float = 0.5,
        **kwargs: Any,
    ) -> None:
        if not port:
            raise ConfigError("port (='') must name a serial device, e.g. serial:///dev/ttyUSB0")
        super().__init__(**kwargs)
        self.port_name = port
        if unit not in UNITS:
            raise ConfigError(f"unit (={unit!r}) must be one of {', '.join(UNITS)}")
        self.baud, self.timeout, self.unit, self.watchdog = baud, timeout, unit, watchdog
        self._port: serial.Serial | None = None
        self._splitter = FrameSplitter()
        self._seq = 0
        self._boot: int | None = None
        self._tick: int | None = None
        self._info: dict[str, Any] = {}
        self._stream: deque[Reply] = deque()
        #: When the latest request was sent (``perf_counter``), and how long after the one before it, s.
        self._sent_at: float | None = None
        self._silent_s = 0.0
        self.command_step = 1.0  # set points travel as whole encoder counts
        self.watchdog_s = watchdog or None

    @classmethod
    def from_url(cls, url: DriverURL) -> SerialDriver:
        driver = cls(port=url.host + url.path, **cls.parse_options(url))
        driver.url = url.raw
        return driver

    # ---- primitives -------------------------------------------------------------------
    def _open(self) -> None:
        try:
            # writing only blocks when the line is jammed: give it longer than a reply
            self._port = serial.Serial(self.port_name, self.baud, timeout=0, write_timeout=max(1.0, self.timeout))
        except serial.SerialException as exc:
            raise DriverError(f"{self.describe()}: cannot open {self.port_name}: {exc}") from exc
        self._port.reset_input_buffer()
        self._splitter.clear()
        self._boot, self._tick, self._sent_at = None, None, None
        try:
            hello = self._config("H", None, "I")
            version, cpr, firmware = int(hello.fields[0]), int(hello.fields[1]), hello.fields[2]
            if version != PROTOCOL_VERSION:
                raise ProtocolError(
                    f"{self.describe()}: firmware speaks protocol {version}, this driver {PROTOCOL_VERSION}"
                )
            self._boot = hello.boot
            self._info = {
                "firmware": firmware,
                "protocol": version,
                "counts_per_rev": cpr,
                "boot_id": f"{hello.boot:04x}",
            }
            if self.unit == "rad":
                self.position_unit = self.command_unit = UnitConversion("rad", scale=2 * math.pi / cpr)
            else:
                self.position_unit = self.command_unit = UnitConversion("counts")
            self._config("W", int(round(self.watchdog * 1000)), "K")
        except BaseException:
            self._port.close()
            self._port = None
            raise

    def _close(self) -> None:
        if self._port is not None:
            self._port.close()
            self._port = None

    def _set_torque(self, enabled: bool) -> None:
        self._config("E", int(enabled), "K")

    def _set_period(self, period_s: float) -> None:
        period_us = int(round(period_s * 1e6))
        if not 1 <= period_us <= 1_000_000:
            raise ConfigError(f"period_s (={period_s!r}) must lie in [1e-6, 1] s for the firmware")
        self._config("C", period_us, "K")

    def _exchange(self, command: float, slot: int | None) -> Reading:
        counts = int(round(command))  # whole already (command_step): the base rounded it inside the limits
        if slot is None:
            return self._position(self._transact("S", counts, "P"))
        # the slot number tells the firmware how many periods passed since the last set point
        return self._position(self._transact("S", f"{counts} {slot % 2**32}", "P"))

    def _read(self) -> Reading:
        # a read outside the sample sequence (at enable the loop's sample index may not have started):
        # its tick is not compared with the exchanges' ticks
        tick = self._tick
        try:
            return self._position(self._transact("G", None, "P"), check_tick=False)
        finally:
            self._tick = tick

    def _identity(self) -> dict[str, Any]:
        return {"driver": "serial", "port": self.port_name, **self._info}

    # ---- serial-specific ----------------------------------------------------------------
    def status(self) -> dict[str, int]:
        """The firmware's status: torque, period (us) and its frame counters (``Q``)."""
        torque, period, rx_ok, rx_bad, tx = self._call(self._config, "Q", None, "Q").ints()
        return {"torque": torque, "period_us": period, "rx_ok": rx_ok, "rx_bad": rx_bad, "tx": tx}

    def start_stream(self) -> None:
        """Let the device send its reading every control period (set by :meth:`set_sample_period`)."""
        self._call(self._config, "R", 1, "K")

    def stop_stream(self) -> None:
        """Stop streaming; frames already on their way are dropped."""
        self._call(self._config, "R", 0, "K")
        self._stream.clear()

    def read_stream(self) -> Measurement:
        """The next streamed reading, device-timed (see :meth:`start_stream`), in the user's unit.

        Raises
        ------
        DriverTimeout
            If none comes within the timeout.
        """
        tick, t_us, counts = self._call(self._next_stream_frame).ints()
        last = self.last_command if self.last_command is not None else math.nan
        return self._measurement(Reading(position=float(counts), device_time=t_us * 1e-6), last, last, False)

    # ---- the link -----------------------------------------------------------------------
    def _require_port(self) -> serial.Serial:
        if self._port is None:
            raise DriverError(f"{self.describe()} is not open")
        return self._port

    def _config(self, verb: str, arg: int | str | None, expect: str) -> Reply:
        for attempt in range(1, CONFIG_ATTEMPTS + 1):
            try:
                return self._transact(verb, arg, expect)
            except (DriverTimeout, ProtocolError):
                if attempt == CONFIG_ATTEMPTS:
                    raise
        raise AssertionError("unreachable")

    def _transact(self, verb: str, arg: int | str | None, expect: str) -> Reply:
        port = self._require_port()
        seq = self._seq
        self._seq = (self._seq + 1) % SEQ_MODULUS
        try:
            port.write(encode(f"{seq} {verb}" if arg is None else f"{seq} {verb} {arg}"))
        except serial.SerialTimeoutException as exc:
            raise DriverTimeout(f"{self.describe()}: could not send {verb} (seq {seq}): {exc}") from exc
        sent = time.perf_counter()
        self._silent_s = 0.0 if self._sent_at is None else sent - self._sent_at
        self._sent_at = sent
        deadline = sent + self.timeout
        corrupted = False
        while True:
            for line in self._lines(deadline):
                try:
                    reply = parse_reply(line)
                except ProtocolError:
                    self.stats.rejected += 1
                    corrupted = True
                    deadline = min(deadline, time.perf_counter() + CORRUPT_GRACE_S)
                    continue
                if reply.kind == "D":
                    self._stream.append(reply)
                    continue
                if reply.seq != seq:
                    self.stats.stale += 1
                    continue
                return self._accept(reply, verb, expect)
            if time.perf_counter() >= deadline:
                if corrupted:
                    raise ProtocolError(f"{self.describe()}: the reply to {verb} (seq {seq}) was corrupted")
                raise DriverTimeout(f"{self.describe()}: no reply to {verb} (seq {seq}) within {self.timeout:g} s")

    def _accept(self, reply: Reply, verb: str, expect: str) -> Reply:
        self._check_boot(reply)
        if reply.kind == "X":
            code = reply.ints()[0]
            what = ERROR_CODES.get(code, f"error code {code}")
            if code == 2 and self.watchdog_s is not None and self._silent_s > self.watchdog_s:
                # the firmware says only that the torque is off; the host knows it was silent past the watchdog
                what += (f": the servo's watchdog switched it off, no request for {self._silent_s:.3g} s before this "
                         f"one (watchdog {self.watchdog_s:g} s: the host stalled)")  # fmt: skip
            if code in (2, 6):
                raise DeviceFault(f"{self.describe()}: {verb} refused: {what}")
            raise DriverError(f"{self.describe()}: {verb} refused: {what}")
        if reply.kind != expect:
            raise ProtocolError(f"{self.describe()}: {verb} answered with {reply.kind}, expected {expect}")
        return reply

    def _check_boot(self, reply: Reply) -> None:
        if self._boot is not None and reply.boot != self._boot:
            old, self._boot = self._boot, reply.boot
            raise DeviceRestarted(
                f"{self.describe()}: the servo restarted (boot id {old:04x} -> {reply.boot:04x}); "
                "its torque is off and its configuration is lost"
            )

    def _lines(self, deadline: float) -> list[bytes]:
        """Complete lines received before ``deadline`` (waits for the first bytes, then takes what is there)."""
        port = self._require_port()
        remaining = deadline - time.perf_counter()
        if remaining > 0 and not port.in_waiting:
            select.select([port.fileno()], [], [], remaining)
        waiting = port.in_waiting
        return self._splitter.feed(port.read(waiting)) if waiting else []

    def _next_stream_frame(self) -> Reply:
        deadline = time.perf_counter() + self.timeout
        while not self._stream:
            for line in self._lines(deadline):
                try:
                    reply = parse_reply(line)
                except ProtocolError:
                    self.stats.rejected += 1
                    continue
                if reply.kind == "D":
                    self._stream.append(reply)
                else:
                    self.stats.stale += 1
            if not self._stream and time.perf_counter() >= deadline:
                raise DriverTimeout(f"{self.describe()}: no streamed reading within {self.timeout:g} s")
        reply = self._stream.popleft()
        self._check_boot(reply)
        return reply

    def _position(self, reply: Reply, *, check_tick: bool = True) -> Reading:
        tick, t_us, counts = reply.ints()
        if check_tick and self._tick is not None and tick < self._tick:
            raise DeviceRestarted(f"{self.describe()}: the servo's sample counter went back ({self._tick} -> {tick})")
        self._tick = tick
        return Reading(position=float(counts), device_time=t_us * 1e-6)
