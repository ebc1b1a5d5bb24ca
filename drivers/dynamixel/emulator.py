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

from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

from servoid.drivers import _pty_bus
from servoid.drivers._pty_bus import EmulatorStats, LinkFaults, PtyBusEmulator, ServoBus, bus_servos, serve_child
from servoid.drivers.clock import Clock, MonotonicClock
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
from servoid.drivers.servos import Servo

__all__ = ["LinkFaults", "DynamixelBus", "DynamixelEmulator", "EmulatorProcess", "EmulatorStats", "dxl_url"]


def dxl_url(port: str, servo_id: int, *, baud: int = 1_000_000, **options: Any) -> str:
    """The driver URL for a servo on ``port``: ``dxl:///dev/pts/7?id=1&baud=1000000``."""
    extra = "".join(f"&{k}={v}" for k, v in options.items())
    return f"dxl://{port}?id={servo_id}&baud={baud}{extra}"


class DynamixelBus(ServoBus[EmulatedServo]):
    """Several servos on one half-duplex bus: which instruction reaches whom, and who answers.

    Parameters
    ----------
    servos : iterable of EmulatedServo
        The servos on the bus (looked up by their current ID, which a WRITE
        of ID can change).
    """

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


class DynamixelEmulator(PtyBusEmulator[EmulatedServo]):
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
        own_clock: Clock = clock if clock is not None else MonotonicClock()
        servos = bus_servos(ids, servo, lambda i, spec: EmulatedServo(
            i, servo=spec, model_number=model_number, firmware=firmware, return_delay_us=return_delay_us,
            clock=own_clock, period_s=period_s))  # fmt: skip
        super().__init__(servos, PacketReader(), clock=own_clock, flip=flip, flip_rx=flip_rx, flip_tx=flip_tx,
                         seed=seed, trace=trace)  # fmt: skip
        self.bus: DynamixelBus = DynamixelBus(servos)
        for emulated in servos:
            emulated.on_event = on_event

    def url(self, servo_id: int | None = None, *, baud: int = 1_000_000, **options: Any) -> str:
        """The ``dxl://`` URL that reaches a servo of this bus (default: the first)."""
        return dxl_url(self.port, self.bus.servos[0].id if servo_id is None else servo_id, baud=baud, **options)

    # ---- Protocol 2.0 on the shared pty loop ---------------------------------------------------
    def _handle(self, frame: Frame) -> list[tuple[EmulatedServo, bytes]]:
        return self.bus.handle(frame)

    def _timers(self, now_ns: int) -> int | None:
        """Run the Bus Watchdogs; the next one's deadline."""
        for servo in self.bus.connected():
            servo.check_watchdog(now_ns)
        deadlines = [d for d in (s.watchdog_deadline_ns() for s in self.bus.servos) if d is not None]
        return min(deadlines) if deadlines else None

    def _received(self, frame: Frame, received_ns: int) -> None:
        assert isinstance(frame, Packet)
        for servo in self.bus.connected():  # an intact instruction packet feeds the Bus Watchdog of its servos
            if frame.id in (servo.id, BROADCAST_ID):
                servo.heard(received_ns)

    def _as_corrupt(self, frame: Frame) -> Frame:
        assert isinstance(frame, Packet)
        return CorruptPacket(frame.id, frame.encode())

    def _is_corrupt(self, frame: Frame) -> bool:
        return isinstance(frame, CorruptPacket)

    def _is_instruction(self, frame: Frame) -> bool:
        return isinstance(frame, Packet) and not frame.is_status

    def _is_read(self, frame: Frame) -> bool:
        return isinstance(frame, Packet) and frame.instruction == Instruction.READ

    def _is_sync_write(self, frame: Frame) -> bool:
        return isinstance(frame, Packet) and frame.instruction == Instruction.SYNC_WRITE

    def _empty_reply(self, servo: EmulatedServo) -> bytes:
        return status_packet(servo.id, 0)

    def _cut_length(self, reply: bytes) -> bytes:
        return reply[:5] + bytes((3, 0)) + reply[7:]  # LEN (5, 6): 3, where the header alone has 4

    def _trace_line(self, servo: EmulatedServo, frame: Frame, reply: bytes) -> str | None:
        """``<id> <tick ms> <position counts>`` for a READ of the present values."""
        if not isinstance(frame, Packet) or frame.instruction != Instruction.READ or len(frame.params) != 4:
            return None
        address, length = _u16(frame.params, 0), _u16(frame.params, 2)
        if not (address <= ct.REALTIME_TICK.address and address + length >= ct.PRESENT_POSITION.end):
            return None
        data = unstuff(reply[7:-2])[2:]  # after header (4), ID, LEN (2): instruction, error, then the data
        tick = ct.decode_value(ct.REALTIME_TICK, data, ct.REALTIME_TICK.address - address)
        position = ct.decode_value(ct.PRESENT_POSITION, data, ct.PRESENT_POSITION.address - address)
        return f"{servo.id} {tick} {position}"


class EmulatorProcess(_pty_bus.EmulatorProcess):
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

    module = __name__ if __name__ != "__main__" else "servoid.drivers.dynamixel.emulator"
    kind = "Dynamixel"

    def url(self, servo_id: int | None = None, *, baud: int = 1_000_000, **options: Any) -> str:
        """The ``dxl://`` URL of a servo of the child's bus (default: the first)."""
        return dxl_url(self.port, self.ids[0] if servo_id is None else servo_id, baud=baud, **options)


if __name__ == "__main__":
    serve_child(DynamixelEmulator)
