"""The Feetech emulator: STS servos on a pseudo-terminal that the official SDK (``scservo_sdk``) talks to unmodified.

:class:`FeetechEmulator` serves the SCS/STS protocol
(:mod:`~servoid.drivers.feetech.protocol`) for one or more
:class:`~servoid.drivers.feetech.emulated_servo.EmulatedServo` on one bus, on
the pty loop every serial-bus emulator shares (:mod:`servoid.drivers._pty_bus`:
the pty, bit flips, lost, corrupted and stale replies, muted and unplugged
servos, a child process for timing).

Instructions: PING, READ, WRITE, REG_WRITE / ACTION, RESET, SYNC_READ (the
servos answer one after the other in the order of the request), SYNC_WRITE.
A packet to the broadcast ID is executed by every servo and answered by
none. Response Status Level 0 answers only PING and READ. A packet with a
bad checksum is dropped unanswered (an STS has no error number for it), so a
lost goal shows only in a read-back. Every status packet carries the
servo's active protections in its error byte. Faults beyond the link's:
:meth:`FeetechEmulator.restart` (a brown-out), :meth:`EmulatedServo.inject_fault`
(a protection trips).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from pathlib import Path
from typing import Any

from servoid.drivers import _pty_bus
from servoid.drivers._pty_bus import PtyBusEmulator, ServoBus, bus_servos, serve_child
from servoid.drivers.clock import Clock, MonotonicClock
from servoid.drivers.feetech import control_table as ct
from servoid.drivers.feetech.emulated_servo import EmulatedServo
from servoid.drivers.feetech.protocol import (
    BROADCAST_ID,
    CorruptPacket,
    Frame,
    Instruction,
    Packet,
    PacketReader,
    packet,
)
from servoid.drivers.servos import Servo

__all__ = ["FeetechBus", "FeetechEmulator", "EmulatorProcess", "feetech_url"]

Replies = list[tuple[EmulatedServo, bytes]]


def feetech_url(port: str, servo_id: int | Iterable[int], *, baud: int = 1_000_000, **options: Any) -> str:
    """The driver URL for servos on ``port``: ``feetech:///dev/pts/7?id=1&baud=1000000`` (``id=1,2,3`` for several)."""
    ids = str(servo_id) if isinstance(servo_id, int) else ",".join(str(i) for i in servo_id)
    extra = "".join(f"&{k}={v}" for k, v in options.items())
    return f"feetech://{port}?id={ids}&baud={baud}{extra}"


class FeetechBus(ServoBus[EmulatedServo]):
    """STS servos on one half-duplex bus: which instruction reaches whom, and who answers."""

    def handle(self, frame: Frame) -> Replies:
        """Execute one received frame; the status packets to send, in order.

        Parameters
        ----------
        frame : Packet or CorruptPacket
            The frame as received.
        """
        if isinstance(frame, CorruptPacket):
            return []  # an STS drops a packet whose checksum fails, unanswered
        handler = _HANDLERS.get(frame.instruction)
        if handler is None:
            return []
        return handler(self, frame)

    @staticmethod
    def _status(servo: EmulatedServo, params: bytes = b"") -> bytes:
        return packet(servo.id, servo.error, params)

    def _targets(self, p: Packet) -> list[EmulatedServo]:
        if p.id == BROADCAST_ID:
            return self.connected()
        servo = self.find(p.id)
        return [] if servo is None else [servo]

    def _answer(self, p: Packet, servo: EmulatedServo, params: bytes = b"", *, always: bool = False) -> Replies:
        """The status packet, unless broadcast, or Response Status Level 0 and not a READ or PING."""
        if p.id == BROADCAST_ID or not (always or servo.status_return_level >= 1):
            return []
        return [(servo, self._status(servo, params))]

    def _ping(self, p: Packet) -> Replies:
        out: Replies = []
        for servo in self._targets(p):
            out += self._answer(p, servo, always=True)
        return out

    def _read(self, p: Packet) -> Replies:
        servo = self.find(p.id)
        if servo is None or p.id == BROADCAST_ID or len(p.params) != 2:
            return []
        data = servo.read(p.params[0], p.params[1])
        return [] if data is None else self._answer(p, servo, data, always=True)

    def _write(self, p: Packet) -> Replies:
        out: Replies = []
        if len(p.params) < 2:
            return out
        for servo in self._targets(p):
            if p.instruction == Instruction.REG_WRITE:
                servo.reg_write(p.params[0], p.params[1:])
            else:
                servo.write(p.params[0], p.params[1:])
            out += self._answer(p, servo)
        return out

    def _action(self, p: Packet) -> Replies:
        out: Replies = []
        for servo in self._targets(p):
            servo.action()
            out += self._answer(p, servo)
        return out

    def _reset(self, p: Packet) -> Replies:
        out: Replies = []
        for servo in self._targets(p):
            servo.reset()
            out += self._answer(p, servo)
        return out

    def _sync_read(self, p: Packet) -> Replies:
        if p.id != BROADCAST_ID or len(p.params) < 3:
            return []
        address, length = p.params[0], p.params[1]
        out: Replies = []
        for servo_id in p.params[2:]:
            servo = self.find(servo_id)
            data = None if servo is None else servo.read(address, length)
            if servo is not None and data is not None:
                out.append((servo, self._status(servo, data)))
        return out

    def _sync_write(self, p: Packet) -> Replies:
        if p.id != BROADCAST_ID or len(p.params) < 2:
            return []
        address, length = p.params[0], p.params[1]
        body = p.params[2:]
        for i in range(0, len(body) - length, length + 1):
            servo = self.find(body[i])
            if servo is not None:
                servo.write(address, body[i + 1 : i + 1 + length])  # never answered
        return []


_HANDLERS: dict[int, Callable[[FeetechBus, Packet], Replies]] = {
    Instruction.PING: FeetechBus._ping,
    Instruction.READ: FeetechBus._read,
    Instruction.WRITE: FeetechBus._write,
    Instruction.REG_WRITE: FeetechBus._write,
    Instruction.ACTION: FeetechBus._action,
    Instruction.RESET: FeetechBus._reset,
    Instruction.SYNC_READ: FeetechBus._sync_read,
    Instruction.SYNC_WRITE: FeetechBus._sync_write,
}


class FeetechEmulator(PtyBusEmulator[EmulatedServo]):
    """STS servos on a pseudo-terminal (see the module docstring).

    Parameters
    ----------
    ids : iterable of int
        IDs of the servos on the bus.
    servo : Servo or str
        The mechanics behind each servo (default the ``sts3215`` twin).
    return_delay_us : int
        Initial Return Delay Time of each servo, microseconds (factory: 0).
    clock : Clock, optional
        The servos' time and the Return Delay Time's wait (default the real clock).
    period_s : float, optional
        Each servo's own sample period; None: one sample per goal.
    flip : float
        Probability per byte of one flipped bit, in both directions.
    flip_rx, flip_tx : float, optional
        The same for the instruction packets received and the status packets sent.
    seed : int
        Seed of the flipped bits and lost replies.
    trace : path, optional
        File to which every reading of the present values is written as it
        is sent, before any corruption: ``<id> <position counts>``.
    restart_after : int, optional
        Every servo restarts (a brown-out) after this many SYNC_WRITE packets
        (a host's per-sample goals) received.
    on_event : callable, optional
        Called with one line when a servo's torque goes off or it restarts.
    """

    kind = "Feetech"

    def __init__(
        self,
        ids: Iterable[int] = (1,),
        *,
        servo: Servo | str = "sts3215",
        return_delay_us: int = 0,
        clock: Clock | None = None,
        period_s: float | None = None,
        flip: float = 0.0,
        flip_rx: float | None = None,
        flip_tx: float | None = None,
        seed: int = 0,
        trace: str | Path | None = None,
        restart_after: int | None = None,
        on_event: Callable[[str], None] | None = None,
    ) -> None:
        own_clock: Clock = clock if clock is not None else MonotonicClock()
        servos = bus_servos(ids, servo, lambda i, spec: EmulatedServo(
            i, servo=spec, return_delay_us=return_delay_us, clock=own_clock, period_s=period_s))  # fmt: skip
        super().__init__(servos, PacketReader(), clock=own_clock, flip=flip, flip_rx=flip_rx, flip_tx=flip_tx,
                         seed=seed, trace=trace)  # fmt: skip
        self.bus: FeetechBus = FeetechBus(servos)
        self.restart_after = restart_after
        for emulated in servos:
            emulated.on_event = on_event

    def url(self, servo_id: int | Iterable[int] | None = None, *, baud: int = 1_000_000, **options: Any) -> str:
        """The ``feetech://`` URL of servos of this bus (default: the first)."""
        return feetech_url(self.port, self.bus.servos[0].id if servo_id is None else servo_id, baud=baud, **options)

    def restart(self, servo_id: int | None = None) -> None:
        """A brown-out of one servo (or of all: the bus's supply dipped).

        Parameters
        ----------
        servo_id : int, optional
            The servo; None: every servo.
        """
        for servo in self.bus.servos if servo_id is None else [self.servo(servo_id)]:
            servo.restart()

    # ---- the SCS/STS protocol on the shared pty loop ---------------------------------------------
    def _handle(self, frame: Frame) -> Replies:
        return self.bus.handle(frame)

    def _received(self, frame: Frame, received_ns: int) -> None:
        if self.restart_after is not None and self._is_sync_write(frame):
            self.restart_after -= 1
            if self.restart_after < 0:
                self.restart_after = None
                self.restart()

    def _as_corrupt(self, frame: Frame) -> Frame:
        assert isinstance(frame, Packet)
        return CorruptPacket(frame.id, frame.encode())

    def _is_corrupt(self, frame: Frame) -> bool:
        return isinstance(frame, CorruptPacket)

    def _is_read(self, frame: Frame) -> bool:
        return isinstance(frame, Packet) and frame.instruction == Instruction.READ

    def _is_sync_write(self, frame: Frame) -> bool:
        return isinstance(frame, Packet) and frame.instruction == Instruction.SYNC_WRITE

    def _empty_reply(self, servo: EmulatedServo) -> bytes:
        return packet(servo.id, servo.error)

    def _cut_length(self, reply: bytes) -> bytes:
        return reply[:3] + b"\x01" + reply[4:]  # LEN 1: less than the error byte and checksum it must count

    def _trace_line(self, servo: EmulatedServo, frame: Frame, reply: bytes) -> str | None:
        """``<id> <position counts>`` for a reading of Present Position (READ or SYNC_READ)."""
        if not isinstance(frame, Packet) or frame.instruction not in (Instruction.READ, Instruction.SYNC_READ):
            return None
        address, length = frame.params[0], frame.params[1]
        if not address <= ct.PRESENT_POSITION.address < ct.PRESENT_POSITION.end <= address + length:
            return None
        position = ct.decode_value(ct.PRESENT_POSITION, reply, 5 + ct.PRESENT_POSITION.address - address)
        return f"{servo.id} {position}"


class EmulatorProcess(_pty_bus.EmulatorProcess):
    """A :class:`FeetechEmulator` in a child process, for timing measurements.

    Parameters
    ----------
    ids : iterable of int
        Servo IDs on the bus.
    **options
        Passed to :class:`FeetechEmulator` (all but ``clock``).
    """

    module = __name__ if __name__ != "__main__" else "servoid.drivers.feetech.emulator"
    kind = "Feetech"

    def url(self, servo_id: int | Iterable[int] | None = None, *, baud: int = 1_000_000, **options: Any) -> str:
        """The ``feetech://`` URL of servos of the child's bus (default: the first)."""
        return feetech_url(self.port, self.ids[0] if servo_id is None else servo_id, baud=baud, **options)


if __name__ == "__main__":
    serve_child(FeetechEmulator)
