"""The Dynamixel emulator: X-series servos on a pseudo-terminal that the official SDK talks to unmodified.

:class:`DynamixelEmulator` opens a pseudo-terminal, serves Protocol 2.0 on it
for one or more :class:`~servoid.drivers.dynamixel.emulated_servo.EmulatedServo`
(several IDs on one bus), and gives the slave's name (``/dev/pts/N``) to hand
to the SDK's ``PortHandler`` or to ``dxl:///dev/pts/N?id=1``.

Instructions: PING (also broadcast), READ, WRITE, REG_WRITE / ACTION,
FACTORY_RESET, REBOOT, SYNC_READ, SYNC_WRITE, BULK_READ, BULK_WRITE. Status
packets carry the error byte (error number, and the alert bit while a hardware
error is pending), honour Status Return Level (PING always answered, reads
from level 1, everything at level 2) and are sent after each servo's Return
Delay Time; for SYNC_READ and BULK_READ the servos answer one after the other
in the order of the request. Instructions addressed to the broadcast ID are
executed by every servo and answered only for PING. A frame with a bad CRC
addressed to a servo is answered with the CRC error number. FAST_SYNC_READ,
FAST_BULK_READ and CLEAR are answered with an Instruction Error.

Faults for tests (:class:`LinkFaults`, :meth:`DynamixelEmulator.unplug`,
:meth:`EmulatedServo.inject_hardware_error`, and ``flip`` on the whole line):
a servo that stops answering (at once or after some replies), a servo gone
from the bus, lost replies, corrupted replies, corrupted requests, random bit
flips in both directions, a hardware error. ``trace`` writes every reading
of the present values a servo sends, before any corruption, so that a test
can check that nothing else was ever accepted.

Samples: see :mod:`~servoid.drivers.dynamixel.emulated_servo` (one per goal,
or on the servo's own clock with ``period_s``).

Two ways to run it: :meth:`DynamixelEmulator.start` serves from a thread of
the calling process (deterministic logic tests, with an injected clock);
:class:`EmulatorProcess` serves from a child process, which timing
measurements need, because an emulator thread shares the interpreter lock
with the code being measured.
"""

from __future__ import annotations

import errno
import fcntl
import os
import pickle
import select
import subprocess
import sys
import threading
import tty
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

import numpy as np

from servoid import validation
from servoid.drivers.clock import NS_PER_S, Clock, MonotonicClock
from servoid.drivers.dynamixel import control_table as ct
from servoid.drivers.dynamixel.emulated_servo import EmulatedServo
from servoid.drivers.dynamixel.protocol import (
    ALERT,
    BROADCAST_ID,
    CorruptPacket,
    ErrorNumber,
    Frame,
    Instruction,
    Packet,
    PacketReader,
    status_packet,
    unstuff,
)
from servoid.drivers.servos import Servo, parse_servo
from servoid.drivers.twin import Twin
from servoid.errors import ConfigError, DriverError
from servoid.ident.models.plant import Plant

__all__ = ["LinkFaults", "DynamixelBus", "DynamixelEmulator", "EmulatorProcess", "EmulatorStats", "dxl_url"]

#: A partial frame is dropped when the line stays quiet this long (s), as a servo's packet timeout does.
IDLE_DISCARD_S = 0.05


def dxl_url(port: str, servo_id: int, *, baud: int = 1_000_000, **options: Any) -> str:
    """The driver URL for a servo on ``port``: ``dxl:///dev/pts/7?id=1&baud=1000000``."""
    extra = "".join(f"&{k}={v}" for k, v in options.items())
    return f"dxl://{port}?id={servo_id}&baud={baud}{extra}"


@dataclass
class LinkFaults:
    """Faults injected on one servo's link; change the fields while the emulator runs.

    Attributes
    ----------
    mute : bool
        The servo still executes instructions but never answers (a broken
        return line): every read times out, yet a torque-off write still
        reaches it.
    corrupt_replies : int
        Corrupt the CRC of this many of the servo's next status packets.
    corrupt_requests : int
        Treat this many of the next instruction packets addressed to the servo
        as received with a bad CRC (it answers with the CRC error number).
    stale_replies : int
        Answer this many of the next READs with an empty status packet, as a
        late answer to an earlier WRITE would look to the SDK (success, but no
        data).
    mute_after : int, optional
        Set ``mute`` after the servo sent this many more status packets (counts down).
    drop : float
        Probability that a status packet is lost on the way back.
    corrupt_goals : int
        Treat this many of the next SYNC_WRITE packets on the bus as received
        with a bad CRC: every servo drops them, unanswered (a goal lost on its
        way, which only a read-back of the goal shows).
    corrupt_lengths : int
        Send this many of the servo's next status packets with their LENGTH
        field cut to 3 (fewer bytes than the packet's own header holds), the
        rest of the packet unchanged.
    """

    mute: bool = False
    corrupt_replies: int = 0
    corrupt_requests: int = 0
    corrupt_goals: int = 0
    corrupt_lengths: int = 0
    stale_replies: int = 0
    mute_after: int | None = None
    drop: float = 0.0


class DynamixelBus:
    """Several servos on one half-duplex bus: which instruction reaches whom, and who answers.

    Parameters
    ----------
    servos : iterable of EmulatedServo
        The servos on the bus (looked up by their current ID, which a WRITE
        of ID can change).
    """

    def __init__(self, servos: Iterable[EmulatedServo]) -> None:
        self.servos = list(servos)
        self._detached: set[int] = set()  # id() of unplugged servos

    def find(self, servo_id: int) -> EmulatedServo | None:
        """The connected servo that currently has ``servo_id``."""
        for servo in self.servos:
            if id(servo) not in self._detached and servo.id == servo_id:
                return servo
        return None

    def connected(self) -> list[EmulatedServo]:
        return sorted((s for s in self.servos if id(s) not in self._detached), key=lambda s: s.id)

    def detach(self, servo: EmulatedServo) -> None:
        self._detached.add(id(servo))

    def attach(self, servo: EmulatedServo) -> None:
        self._detached.discard(id(servo))

    def handle(self, frame: Frame) -> list[tuple[EmulatedServo, bytes]]:
        """Execute one received frame; return the status packets to send, in order."""
        if isinstance(frame, CorruptPacket):
            servo = self.find(frame.id)
            if servo is None or servo.status_return_level < 1:
                return []
            return [(servo, self._status(servo, ErrorNumber.CRC))]
        if frame.is_status:
            return []  # another device's answer: not for us
        handler = _HANDLERS.get(frame.instruction)
        if handler is None:
            servo = self.find(frame.id)
            return [] if servo is None else [(servo, self._status(servo, ErrorNumber.INSTRUCTION))]
        return handler(self, frame)

    # ---- helpers -------------------------------------------------------------------------
    @staticmethod
    def _status(servo: EmulatedServo, error: int, params: bytes = b"", *, as_id: int | None = None) -> bytes:
        # a servo whose ID was just rewritten still answers as the ID it was asked by
        packet_id = servo.id if as_id is None else as_id
        return status_packet(packet_id, error | (ALERT if servo.alert else 0), params)

    def _targets(self, packet: Packet) -> list[EmulatedServo]:
        if packet.id == BROADCAST_ID:
            return self.connected()
        servo = self.find(packet.id)
        return [] if servo is None else [servo]

    def _answer(
        self, packet: Packet, servo: EmulatedServo, error: int, params: bytes = b"", *, level: int = 2
    ) -> list[tuple[EmulatedServo, bytes]]:
        """The status packet, unless the packet was broadcast or Status Return Level is below ``level``."""
        if packet.id == BROADCAST_ID or servo.status_return_level < level:
            return []
        return [(servo, self._status(servo, error, params, as_id=packet.id))]

    # ---- instructions ------------------------------------------------------------------------
    def _ping(self, packet: Packet) -> list[tuple[EmulatedServo, bytes]]:
        out = []
        for servo in self._targets(packet):  # PING is answered whatever the Status Return Level
            info = ct.encode_value(ct.MODEL_NUMBER, servo.value(ct.MODEL_NUMBER)) + bytes(
                (servo.value(ct.FIRMWARE_VERSION),)
            )
            out.append((servo, self._status(servo, ErrorNumber.NONE, info)))
        return out

    def _read(self, packet: Packet) -> list[tuple[EmulatedServo, bytes]]:
        servo = self.find(packet.id)
        if servo is None or packet.id == BROADCAST_ID:
            return []
        if len(packet.params) != 4:
            return self._answer(packet, servo, ErrorNumber.DATA_LENGTH, level=1)
        address, length = _u16(packet.params, 0), _u16(packet.params, 2)
        error, data = servo.read(address, length)
        return self._answer(packet, servo, error, data, level=1)

    def _write(self, packet: Packet) -> list[tuple[EmulatedServo, bytes]]:
        out = []
        for servo in self._targets(packet):
            if len(packet.params) < 3:
                error = ErrorNumber.DATA_LENGTH
            elif packet.instruction == Instruction.REG_WRITE:
                error = servo.reg_write(_u16(packet.params, 0), packet.params[2:])
            else:
                error = servo.write(_u16(packet.params, 0), packet.params[2:])
            out += self._answer(packet, servo, error)
        return out

    def _action(self, packet: Packet) -> list[tuple[EmulatedServo, bytes]]:
        out = []
        for servo in self._targets(packet):
            out += self._answer(packet, servo, servo.action())
        return out

    def _reboot(self, packet: Packet) -> list[tuple[EmulatedServo, bytes]]:
        out = []
        for servo in self._targets(packet):
            out += self._answer(packet, servo, ErrorNumber.NONE)  # answered before restarting
            servo.reboot()
        return out

    def _factory_reset(self, packet: Packet) -> list[tuple[EmulatedServo, bytes]]:
        option = packet.params[0] if len(packet.params) == 1 else -1
        if packet.id == BROADCAST_ID and option == 0xFF:
            return []  # refused by design: it would give every servo ID 1
        out = []
        for servo in self._targets(packet):
            answer = self._answer(
                packet, servo, servo.factory_reset(option) if option >= 0 else ErrorNumber.DATA_LENGTH
            )
            out += answer
        return out

    def _sync_read(self, packet: Packet) -> list[tuple[EmulatedServo, bytes]]:
        if packet.id != BROADCAST_ID or len(packet.params) < 5:
            return []
        address, length = _u16(packet.params, 0), _u16(packet.params, 2)
        out = []
        for servo_id in packet.params[4:]:
            servo = self.find(servo_id)
            if servo is not None and servo.status_return_level >= 1:
                error, data = servo.read(address, length)
                out.append((servo, self._status(servo, error, data)))
        return out

    def _sync_write(self, packet: Packet) -> list[tuple[EmulatedServo, bytes]]:
        if packet.id != BROADCAST_ID or len(packet.params) < 4:
            return []
        address, length = _u16(packet.params, 0), _u16(packet.params, 2)
        body = packet.params[4:]
        for i in range(0, len(body) - length, length + 1):
            servo = self.find(body[i])
            if servo is not None:
                servo.write(address, body[i + 1 : i + 1 + length])  # never answered, errors included
        return []

    def _bulk_read(self, packet: Packet) -> list[tuple[EmulatedServo, bytes]]:
        if packet.id != BROADCAST_ID:
            return []
        out = []
        params = packet.params
        for i in range(0, len(params) - 4, 5):
            servo = self.find(params[i])
            if servo is not None and servo.status_return_level >= 1:
                error, data = servo.read(_u16(params, i + 1), _u16(params, i + 3))
                out.append((servo, self._status(servo, error, data)))
        return out

    def _bulk_write(self, packet: Packet) -> list[tuple[EmulatedServo, bytes]]:
        if packet.id != BROADCAST_ID:
            return []
        params, i = packet.params, 0
        while i + 5 <= len(params):
            length = _u16(params, i + 3)
            servo = self.find(params[i])
            if servo is not None:
                servo.write(_u16(params, i + 1), params[i + 5 : i + 5 + length])
            i += 5 + length
        return []


def _u16(data: bytes, offset: int) -> int:
    return data[offset] | data[offset + 1] << 8


_HANDLERS: dict[int, Callable[[DynamixelBus, Packet], list[tuple[EmulatedServo, bytes]]]] = {
    Instruction.PING: DynamixelBus._ping,
    Instruction.READ: DynamixelBus._read,
    Instruction.WRITE: DynamixelBus._write,
    Instruction.REG_WRITE: DynamixelBus._write,
    Instruction.ACTION: DynamixelBus._action,
    Instruction.REBOOT: DynamixelBus._reboot,
    Instruction.FACTORY_RESET: DynamixelBus._factory_reset,
    Instruction.SYNC_READ: DynamixelBus._sync_read,
    Instruction.SYNC_WRITE: DynamixelBus._sync_write,
    Instruction.BULK_READ: DynamixelBus._bulk_read,
    Instruction.BULK_WRITE: DynamixelBus._bulk_write,
}


@dataclass
class EmulatorStats:
    """What the emulator saw: packets received, status packets sent, frames with a bad CRC."""

    received: int = 0
    replies: int = 0
    corrupt_received: int = 0
    dropped_replies: int = 0
    flipped_bits: int = 0


class DynamixelEmulator:
    """X-series servos on a pseudo-terminal (see the module docstring).

    Parameters
    ----------
    ids : iterable of int
        IDs of the servos on the bus.
    servo : Servo or str
        The mechanics behind each servo (:mod:`servoid.drivers.servos`);
        default the ``xm430`` twin, ``"model"`` the bench plant.
    model_number, firmware : int
        What the servos report (default XM430-W350, firmware 48).
    return_delay_us : int
        Initial Return Delay Time of each servo, microseconds (factory: 500).
    clock : Clock, optional
        The servos' time (Realtime Tick, own sample clock) and the Return
        Delay Time's wait; default the real clock (inject a
        :class:`~servoid.drivers.clock.VirtualClock` for deterministic tests).
    period_s : float, optional
        Each servo's own sample period (see
        :mod:`~servoid.drivers.dynamixel.emulated_servo`); None: one sample per goal.
    flip : float
        Probability per byte of one flipped bit, in both directions (a noisy line).
    flip_rx, flip_tx : float, optional
        The same for the instruction packets the servos receive (a corrupted
        command: a goal lost on its way) and for the status packets they
        send; each defaults to ``flip``.
    seed : int
        Seed of the flipped bits and lost replies.
    trace : path, optional
        File to which every reading of the present values is written as it
        is sent, before any corruption: ``<id> <tick ms> <position counts>``.
    on_event : callable, optional
        Called with one line (``"servo 1: bus watchdog expired ..."``,
        ``"servo 1: torque off"``) when a servo's Bus Watchdog expires or its
        torque goes off, from the serving thread.

    Examples
    --------
    >>> with DynamixelEmulator(ids=[1]) as emu:        # doctest: +SKIP
    ...     with driver_from_url(emu.url(1)) as servo:
    ...         servo.enable(); servo.exchange(0.1)
    """

    def __init__(
        self,
        ids: Iterable[int] = (1,),
        *,
        servo: Servo | str = "xm430",
        model_number: int = 1020,
        firmware: int = 48,
        return_delay_us: int = 500,
        clock: Clock | None = None,
        period_s: float | None = None,
        flip: float = 0.0,
        flip_rx: float | None = None,
        flip_tx: float | None = None,
        seed: int = 0,
        trace: str | Path | None = None,
        on_event: Callable[[str], None] | None = None,
    ) -> None:
        id_list = [int(i) for i in ids]
        if not id_list or len(set(id_list)) != len(id_list):
            raise ConfigError(f"ids (={id_list}) must be one or more distinct servo IDs")
        self.clock: Clock = clock if clock is not None else MonotonicClock()
        spec = servo if isinstance(servo, Servo) else parse_servo(servo)
        servos = [
            EmulatedServo(i, servo=spec, model_number=model_number, firmware=firmware, return_delay_us=return_delay_us,
                          clock=self.clock, period_s=period_s)
            for i in id_list
        ]  # fmt: skip
        self.flip = validation.in_unit_interval("flip", flip, open_low=False, open_high=False)
        # None: follow ``flip`` (which tests may change while the emulator runs)
        self._flip_rx = None if flip_rx is None else validation.in_unit_interval("flip_rx", flip_rx, open_low=False,
                                                                                  open_high=False)  # fmt: skip
        self._flip_tx = None if flip_tx is None else validation.in_unit_interval("flip_tx", flip_tx, open_low=False,
                                                                                  open_high=False)  # fmt: skip
        self._rng = np.random.default_rng(seed)
        self._trace: IO[str] | None = open(trace, "w", encoding="ascii") if trace is not None else None  # noqa: SIM115
        self.bus = DynamixelBus(servos)
        for emulated in servos:
            emulated.on_event = on_event
        # compile (or load) the kernels now, not while a reply is awaited
        if spec.model is not None:
            Plant(spec.model).step(0.0)
        else:
            Twin(spec.twin).advance(1e-3)  # type: ignore[arg-type]
        self._faults = {id(s): LinkFaults() for s in servos}
        self.stats = EmulatorStats()
        self._reader = PacketReader()
        self._master, self._slave = os.openpty()
        tty.setraw(self._slave)
        # the emulator must never block on a full pty when nobody reads the other side
        fcntl.fcntl(self._master, fcntl.F_SETFL, fcntl.fcntl(self._master, fcntl.F_GETFL) | os.O_NONBLOCK)
        self.port = os.ttyname(self._slave)
        self._wake_r, self._wake_w = os.pipe()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._closed = False

    @property
    def flip_rx(self) -> float:
        """Bit-flip probability per byte of the instruction packets received."""
        return self.flip if self._flip_rx is None else self._flip_rx

    @property
    def flip_tx(self) -> float:
        """Bit-flip probability per byte of the status packets sent."""
        return self.flip if self._flip_tx is None else self._flip_tx

    # ---- access for tests and users -----------------------------------------------------
    def servo(self, servo_id: int) -> EmulatedServo:
        """The servo that has ``servo_id`` now (also when unplugged)."""
        for s in self.bus.servos:
            if s.id == servo_id:
                return s
        raise ConfigError(f"servo_id (={servo_id}) is not on this bus; IDs: {[s.id for s in self.bus.servos]}")

    def faults(self, servo_id: int) -> LinkFaults:
        """The faults injected on a servo's link (mutable)."""
        return self._faults[id(self.servo(servo_id))]

    def unplug(self, servo_id: int) -> None:
        """Take a servo off the bus: it neither executes nor answers anything."""
        self.bus.detach(self.servo(servo_id))

    def plug(self, servo_id: int) -> None:
        """Put an unplugged servo back on the bus."""
        self.bus.attach(self.servo(servo_id))

    def url(self, servo_id: int | None = None, *, baud: int = 1_000_000, **options: Any) -> str:
        """The ``dxl://`` URL that reaches a servo of this bus (default: the first)."""
        return dxl_url(self.port, self.bus.servos[0].id if servo_id is None else servo_id, baud=baud, **options)

    # ---- serving ------------------------------------------------------------------------------
    def start(self) -> DynamixelEmulator:
        """Serve from a daemon thread (for logic tests; timing needs :class:`EmulatorProcess`)."""
        if self._thread is None:
            self._stop.clear()
            self._thread = threading.Thread(target=self.serve_forever, name=f"dxl-emulator {self.port}", daemon=True)
            self._thread.start()
        return self

    def stop(self) -> None:
        """Stop serving (the pty stays open until :meth:`close`)."""
        self._stop.set()
        try:
            os.write(self._wake_w, b"x")
        except OSError:
            pass
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(timeout=5.0)
        self._thread = None

    def close(self) -> None:
        """Stop and close the pseudo-terminal; safe to call twice."""
        if self._closed:
            return
        self.stop()
        self._closed = True
        if self._trace is not None:
            self._trace.close()
        for fd in (self._master, self._slave, self._wake_r, self._wake_w):
            try:
                os.close(fd)
            except OSError:
                pass

    def __enter__(self) -> DynamixelEmulator:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.close()

    def serve_forever(self) -> None:
        """Answer packets until :meth:`stop` (or Ctrl-C when run in the foreground); run the Bus Watchdogs."""
        while not self._stop.is_set():
            ready, _, _ = select.select([self._master, self._wake_r], [], [], self._quiet_for_s())
            self._check_watchdogs()
            if self._wake_r in ready:
                os.read(self._wake_r, 64)
                continue
            if not ready:
                self._reader.discard()
                continue
            try:
                data = os.read(self._master, 4096)
            except BlockingIOError:
                continue
            except OSError as exc:  # the pty went away
                if exc.errno == errno.EIO:
                    break
                raise
            received = self.clock.now_ns()
            for frame in self._reader.feed(self._flipped(data, self.flip_rx)):
                self._serve_frame(frame, received)

    def _quiet_for_s(self) -> float:
        """How long to wait for bytes: until a partial frame is stale, or the next Bus Watchdog expires."""
        deadlines = [d for d in (s.watchdog_deadline_ns() for s in self.bus.servos) if d is not None]
        if not deadlines:
            return IDLE_DISCARD_S
        return min(IDLE_DISCARD_S, max(0.0, (min(deadlines) - self.clock.now_ns()) / NS_PER_S))

    def _check_watchdogs(self) -> None:
        now = self.clock.now_ns()
        for servo in self.bus.connected():
            servo.check_watchdog(now)

    def _flipped(self, data: bytes, probability: float) -> bytes:
        """``data`` with one random bit flipped in each byte hit (``probability`` per byte)."""
        if not probability:
            return data
        hit = np.flatnonzero(self._rng.random(len(data)) < probability)
        if not hit.size:
            return data
        out = bytearray(data)
        for i in hit:
            out[i] ^= 1 << int(self._rng.integers(8))
        self.stats.flipped_bits += int(hit.size)
        return bytes(out)

    def _write_trace(self, servo: EmulatedServo, frame: Frame, reply: bytes) -> None:
        """Note the reading of the present values (tick and position) in ``reply``, about to be sent."""
        if not isinstance(frame, Packet) or frame.instruction != Instruction.READ or len(frame.params) != 4:
            return
        address, length = _u16(frame.params, 0), _u16(frame.params, 2)
        if address <= ct.REALTIME_TICK.address and address + length >= ct.PRESENT_POSITION.end:
            data = unstuff(reply[7:-2])[2:]  # after header (4), ID, LEN (2): instruction, error, then the data
            tick = ct.decode_value(ct.REALTIME_TICK, data, ct.REALTIME_TICK.address - address)
            position = ct.decode_value(ct.PRESENT_POSITION, data, ct.PRESENT_POSITION.address - address)
            assert self._trace is not None
            self._trace.write(f"{servo.id} {tick} {position}\n")
            self._trace.flush()

    def _serve_frame(self, frame: Frame, received: int) -> None:
        self.stats.received += 1
        if isinstance(frame, Packet):
            target = self.bus.find(frame.id)
            if target is not None and self._faults[id(target)].corrupt_requests > 0:
                self._faults[id(target)].corrupt_requests -= 1
                frame = CorruptPacket(frame.id, frame.encode())
            elif frame.instruction == Instruction.SYNC_WRITE:
                losing = next((f for f in self._faults.values() if f.corrupt_goals > 0), None)
                if losing is not None:
                    losing.corrupt_goals -= 1
                    frame = CorruptPacket(frame.id, frame.encode())
        if isinstance(frame, CorruptPacket):
            self.stats.corrupt_received += 1
        elif isinstance(frame, Packet) and not frame.is_status:
            for servo in self.bus.connected():  # an intact instruction packet feeds the Bus Watchdog of its servos
                if frame.id in (servo.id, BROADCAST_ID):
                    servo.heard(received)
        last = received
        for servo, reply in self.bus.handle(frame):
            faults = self._faults[id(servo)]
            if faults.mute_after is not None and faults.mute_after <= 0:
                faults.mute = True
            if faults.mute:
                continue
            if faults.mute_after is not None:
                faults.mute_after -= 1
            if faults.drop and self._rng.random() < faults.drop:
                self.stats.dropped_replies += 1
                continue
            if faults.stale_replies > 0 and isinstance(frame, Packet) and frame.instruction == Instruction.READ:
                faults.stale_replies -= 1
                reply = status_packet(servo.id, 0)
            elif self._trace is not None:
                self._write_trace(servo, frame, reply)
            if faults.corrupt_replies > 0:
                faults.corrupt_replies -= 1
                reply = reply[:-1] + bytes((reply[-1] ^ 0xFF,))
            if faults.corrupt_lengths > 0:
                faults.corrupt_lengths -= 1
                reply = reply[:5] + bytes((3, 0)) + reply[7:]  # LEN (5, 6): 3, where the header alone has 4
            # each servo waits its Return Delay Time after the bus went quiet
            self.clock.sleep_until_ns(last + round(servo.return_delay_s * NS_PER_S))
            try:
                os.write(self._master, self._flipped(reply, self.flip_tx))
                self.stats.replies += 1
            except BlockingIOError:
                self.stats.dropped_replies += 1
            last = self.clock.now_ns()


def _serve_child() -> None:
    """Entry of the child process of :class:`EmulatorProcess` (``python -m servoid.drivers.dynamixel.emulator``).

    Reads the pickled ``(ids, options)`` from stdin, prints the port on stdout,
    and serves until stdin closes (the parent stopped it, or went away).
    """
    ids, options = pickle.load(sys.stdin.buffer)
    with DynamixelEmulator(ids, **options) as emulator:
        print(emulator.port, flush=True)
        sys.stdin.buffer.read()


class EmulatorProcess:
    """A :class:`DynamixelEmulator` in a child process, for timing measurements.

    The child is a fresh interpreter (``python -m servoid.drivers.dynamixel.emulator``),
    so this works from any script, with or without an ``if __name__ == "__main__"`` guard.

    Parameters
    ----------
    ids : iterable of int
        Servo IDs on the bus.
    **options
        Passed to :class:`DynamixelEmulator` (all but ``clock``: ``servo``,
        ``model_number``, ``firmware``, ``return_delay_us``, ``period_s``,
        ``flip``, ``flip_rx``, ``flip_tx``, ``seed``, ``trace``).

    Examples
    --------
    >>> with EmulatorProcess([1]) as emu:              # doctest: +SKIP
    ...     print(emu.url(1))
    dxl:///dev/pts/7?id=1&baud=1000000
    """

    def __init__(self, ids: Iterable[int] = (1,), **options: Any) -> None:
        if "clock" in options:
            raise ConfigError("clock cannot be given to an emulator in another process; use DynamixelEmulator")
        self.ids = [int(i) for i in ids]
        self._options = options
        self._process: subprocess.Popen[bytes] | None = None
        self.port = ""

    def start(self, timeout: float = 60.0) -> EmulatorProcess:
        """Start the child and wait for its port; returns self."""
        self._process = subprocess.Popen(
            [sys.executable, "-m", __name__], stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE
        )
        assert self._process.stdin is not None and self._process.stdout is not None
        pickle.dump((self.ids, self._options), self._process.stdin)
        self._process.stdin.flush()
        ready, _, _ = select.select([self._process.stdout], [], [], timeout)
        line = self._process.stdout.readline().decode().strip() if ready else ""
        if not line:
            error = b"" if self._process.poll() is None else self._process.stderr.read()  # type: ignore[union-attr]
            self.stop()
            raise DriverError(
                f"the Dynamixel emulator process did not start within {timeout} s: {error.decode().strip()}"
            )
        self.port = line
        return self

    def stop(self, timeout: float = 5.0) -> None:
        """Stop the child process; safe to call twice."""
        process, self._process = self._process, None
        if process is None:
            return
        try:
            process.stdin.close()  # type: ignore[union-attr]
            process.wait(timeout)
        except (OSError, subprocess.TimeoutExpired):
            process.kill()
            process.wait(timeout)
        finally:
            for stream in (process.stdout, process.stderr):
                if stream is not None:
                    stream.close()

    def url(self, servo_id: int | None = None, *, baud: int = 1_000_000, **options: Any) -> str:
        return dxl_url(self.port, self.ids[0] if servo_id is None else servo_id, baud=baud, **options)

    def __enter__(self) -> EmulatorProcess:
        return self.start()

    def __exit__(self, *exc: object) -> None:
        self.stop()


if __name__ == "__main__":
    _serve_child()
