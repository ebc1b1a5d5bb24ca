"""Feetech SCS/STS packets: framing, the checksum and the status error byte.

A packet on the wire is::

    FF FF | ID | LEN | INST | params ... | CHK

``LEN`` counts the bytes after it (instruction, parameters and the
checksum): ``len(params) + 2``. ``CHK = ~(ID + LEN + INST + sum(params)) &
0xFF``. A status packet has the same form, with the servo's error byte where
an instruction packet has its instruction. Numbers of two bytes are
little-endian on the STS/SMS series (the SCS series is big-endian; servoid
speaks STS). There is no byte stuffing: a receiver finds the next packet by
its header and checks the checksum.

Reference: Feetech's SCS/STS communication protocol manual and the official
SDK (``scservo_sdk``, ``protocol_packet_handler.py``: ``txPacket``,
``rxPacket``; ``scservo_def.py``: the instructions and ``ERRBIT_*``); the
emulator uses this codec, the driver lets the SDK do its own framing, and
the tests check both agree byte for byte.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass

from servoid.errors import ProtocolError

__all__ = [
    "HEADER",
    "BROADCAST_ID",
    "MAX_ID",
    "Instruction",
    "ErrorBit",
    "Packet",
    "CorruptPacket",
    "Frame",
    "PacketReader",
    "checksum",
    "packet",
    "decode",
    "describe_error",
]

#: The two bytes that start every packet.
HEADER = b"\xff\xff"
#: Packet ID that addresses every servo on the bus (never answered, except by nobody).
BROADCAST_ID = 0xFE
#: Highest ID a servo can have.
MAX_ID = 0xFD


class Instruction(enum.IntEnum):
    """The instruction byte (``scservo_def.py``)."""

    PING = 0x01
    READ = 0x02
    WRITE = 0x03
    REG_WRITE = 0x04
    ACTION = 0x05
    RESET = 0x06  # back to the factory's memory table (the ID kept)
    SYNC_READ = 0x82
    SYNC_WRITE = 0x83


class ErrorBit(enum.IntFlag):
    """The status packet's error byte: which of the servo's protections is active (``ERRBIT_*``)."""

    VOLTAGE = 1
    ANGLE = 2  # the magnetic encoder (sensor) fault
    OVERHEAT = 4
    OVERELE = 8  # over current
    OVERLOAD = 32

    def describe(self) -> str:
        """The bits in words."""
        return ", ".join(_ERROR_TEXT[bit] for bit in ErrorBit if bit in self) or "no error"


_ERROR_TEXT = {
    ErrorBit.VOLTAGE: "input voltage out of range",
    ErrorBit.ANGLE: "magnetic encoder (angle sensor) fault",
    ErrorBit.OVERHEAT: "overheating",
    ErrorBit.OVERELE: "over current",
    ErrorBit.OVERLOAD: "overload",
}


def describe_error(error: int) -> str:
    """The status error byte in words (``"ok"`` when it is 0)."""
    if not error:
        return "ok"
    text = ErrorBit(error & 0x2F).describe()
    unknown = error & ~0x2F & 0xFF
    return text if not unknown else f"{text}; unknown bits 0x{unknown:02X}"


def checksum(body: bytes | bytearray) -> int:
    """``~sum(body) & 0xFF`` over ID, LEN, INST (or error) and the parameters."""
    return ~sum(body) & 0xFF


def _check_byte(name: str, value: int, maximum: int) -> None:
    if not isinstance(value, int) or not 0 <= value <= maximum:
        raise ProtocolError(f"{name} (={value!r}) must be an integer in 0..{maximum}")


def packet(packet_id: int, instruction: int, params: bytes | bytearray = b"") -> bytes:
    """An instruction packet, or a status packet with the error byte as ``instruction``."""
    _check_byte("packet_id", packet_id, 0xFE)
    _check_byte("instruction", instruction, 0xFF)
    if len(params) > 250:
        raise ProtocolError(f"params ({len(params)} bytes) must be at most 250 bytes")
    body = bytes((packet_id, len(params) + 2, instruction)) + bytes(params)
    return HEADER + body + bytes((checksum(body),))


@dataclass(frozen=True)
class Packet:
    """A decoded packet.

    Attributes
    ----------
    id : int
        Packet ID (254 is broadcast).
    instruction : int
        The byte after LEN: the instruction, or a status packet's error byte
        (the wire does not tell them apart; the direction does).
    params : bytes
        The parameters.
    """

    id: int
    instruction: int
    params: bytes = b""

    def encode(self) -> bytes:
        """The packet as it goes on the wire."""
        return packet(self.id, self.instruction, self.params)


@dataclass(frozen=True)
class CorruptPacket:
    """A frame whose checksum did not match (a servo drops it unanswered).

    Attributes
    ----------
    id : int
        The packet ID as received (it may itself be corrupted).
    raw : bytes
        The whole frame.
    """

    id: int
    raw: bytes


#: What :meth:`PacketReader.feed` yields.
Frame = Packet | CorruptPacket


def decode(frame: bytes | bytearray) -> Packet:
    """Decode one complete frame.

    Raises
    ------
    ProtocolError
        A wrong header, a LEN that does not match the frame, or a checksum mismatch.
    """
    frame = bytes(frame)
    if len(frame) < 6 or not frame.startswith(HEADER):
        raise ProtocolError(f"not an SCS/STS packet: {frame[:8].hex(' ')}")
    length = frame[3]
    if len(frame) != 4 + length:
        raise ProtocolError(f"packet length field says {length} bytes after it, the frame has {len(frame) - 4}")
    expected = checksum(frame[2:-1])
    if frame[-1] != expected:
        raise ProtocolError(f"checksum mismatch: packet says 0x{frame[-1]:02X}, content gives 0x{expected:02X}")
    return Packet(frame[2], frame[4], frame[5:-1])


class PacketReader:
    """Split a byte stream into packets, resynchronising after garbage or corruption.

    :meth:`feed` returns, in order, every complete frame found so far: a
    :class:`Packet` when its checksum matches, a :class:`CorruptPacket` when
    not. After a corrupt frame the search resumes one byte after its header,
    so that a packet hidden behind a corrupted length byte is not lost.
    """

    def __init__(self) -> None:
        self._buffer = bytearray()

    @property
    def pending(self) -> int:
        """Bytes held back waiting for the rest of a frame."""
        return len(self._buffer)

    def discard(self) -> None:
        """Drop a partial frame (the line went quiet in the middle of a packet)."""
        self._buffer.clear()

    def feed(self, data: bytes | bytearray) -> list[Frame]:
        """The frames completed by ``data`` (see the class docstring).

        Parameters
        ----------
        data : bytes
            Bytes as they came off the line.
        """
        buf = self._buffer
        buf += data
        out: list[Frame] = []
        while True:
            start = buf.find(HEADER)
            if start < 0:
                keep = 1 if buf.endswith(b"\xff") else 0
                del buf[: len(buf) - keep]
                return out
            del buf[:start]
            if len(buf) >= 3 and buf[2] == 0xFF:
                del buf[:1]  # FF FF FF: the header is the last two of them (an ID is never FF)
                continue
            if len(buf) < 4:
                return out
            length = buf[3]
            if length < 2:
                del buf[:1]  # not a real header: keep looking
                continue
            if len(buf) < 4 + length:
                return out
            frame = bytes(buf[: 4 + length])
            try:
                out.append(decode(frame))
            except ProtocolError:
                out.append(CorruptPacket(frame[2], frame))
                del buf[:1]
                continue
            del buf[: 4 + length]
