"""Dynamixel Protocol 2.0 packets: framing, CRC-16, byte stuffing and the status error byte.

A packet on the wire is::

    FF FF FD 00 | ID | LEN_L LEN_H | INST | params ... | CRC_L CRC_H

``LEN`` counts the bytes after it (instruction, parameters, CRC); a status
packet (``INST = 0x55``) carries the error byte as its first parameter. The
body (instruction and parameters) is byte-stuffed: wherever ``FF FF FD``
occurs, an extra ``FD`` follows, so that the header never appears inside a
packet. The CRC-16 (polynomial 0x8005, initial value 0, not reflected) covers
the whole stuffed packet from the first header byte up to the CRC.

Reference: ROBOTIS e-manual, Protocol 2.0
(https://emanual.robotis.com/docs/en/dxl/protocol2/) and CRC calculation
(https://emanual.robotis.com/docs/en/dxl/crc/). The emulator uses this codec;
the driver lets the official SDK do its own framing, and the tests check both
agree byte for byte.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass

from servoid.errors import ProtocolError

__all__ = [
    "HEADER",
    "BROADCAST_ID",
    "MAX_ID",
    "ALERT",
    "MAX_LENGTH",
    "Instruction",
    "ErrorNumber",
    "Packet",
    "CorruptPacket",
    "PacketReader",
    "Frame",
    "crc16",
    "stuff",
    "unstuff",
    "instruction_packet",
    "status_packet",
    "decode",
    "describe_error",
]

#: Header and reserved byte that start every packet.
HEADER = b"\xff\xff\xfd\x00"
_PATTERN = b"\xff\xff\xfd"
#: Packet ID that addresses every servo on the bus.
BROADCAST_ID = 0xFE
#: Highest ID a servo can have.
MAX_ID = 0xFC
#: Bit 7 of the status error byte: the servo has a hardware error (see Hardware Error Status).
ALERT = 0x80
#: Longest LEN accepted when receiving (the SDK's buffer size).
MAX_LENGTH = 1024


class Instruction(enum.IntEnum):
    """The instruction byte."""

    PING = 0x01
    READ = 0x02
    WRITE = 0x03
    REG_WRITE = 0x04
    ACTION = 0x05
    FACTORY_RESET = 0x06
    REBOOT = 0x08
    CLEAR = 0x10
    STATUS = 0x55
    SYNC_READ = 0x82
    SYNC_WRITE = 0x83
    FAST_SYNC_READ = 0x8A
    BULK_READ = 0x92
    BULK_WRITE = 0x93
    FAST_BULK_READ = 0x9A


class ErrorNumber(enum.IntEnum):
    """Bits 0-6 of the status error byte: why the servo refused an instruction."""

    NONE = 0
    RESULT_FAIL = 1
    INSTRUCTION = 2
    CRC = 3
    DATA_RANGE = 4
    DATA_LENGTH = 5
    DATA_LIMIT = 6
    ACCESS = 7


_ERROR_TEXT = {
    ErrorNumber.RESULT_FAIL: "result fail: the servo could not process the instruction",
    ErrorNumber.INSTRUCTION: "instruction error: undefined instruction, or ACTION without REG_WRITE",
    ErrorNumber.CRC: "CRC error: the servo received a corrupted packet",
    ErrorNumber.DATA_RANGE: "data range error: the value is outside the entry's range",
    ErrorNumber.DATA_LENGTH: "data length error: the write covers only part of an entry",
    ErrorNumber.DATA_LIMIT: "data limit error: the value is beyond the servo's limit (position/current/PWM limit)",
    ErrorNumber.ACCESS: "access error: read-only or undefined address, or EEPROM written while the torque is on",
}


def describe_error(error: int) -> str:
    """The status error byte in words (``"ok"`` when it is 0)."""
    parts = []
    number = error & 0x7F
    if number:
        try:
            parts.append(_ERROR_TEXT[ErrorNumber(number)])
        except ValueError:
            parts.append(f"unknown error number {number}")
    if error & ALERT:
        parts.append("alert: hardware error (see Hardware Error Status)")
    return "; ".join(parts) if parts else "ok"


def _crc_table() -> tuple[int, ...]:
    table = []
    for i in range(256):
        crc = i << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x8005) if crc & 0x8000 else (crc << 1)
        table.append(crc & 0xFFFF)
    return tuple(table)


_CRC_TABLE = _crc_table()


def crc16(data: bytes | bytearray, crc: int = 0) -> int:
    """CRC-16 of ``data`` (polynomial 0x8005, not reflected), continuing from ``crc``."""
    table = _CRC_TABLE
    for byte in data:
        crc = ((crc << 8) & 0xFFFF) ^ table[((crc >> 8) ^ byte) & 0xFF]
    return crc


def stuff(body: bytes | bytearray) -> bytes:
    """Insert ``FD`` after every ``FF FF FD`` of ``body`` (instruction and parameters)."""
    if _PATTERN not in body:  # the common case: nothing to do
        return bytes(body)
    out = bytearray()
    for byte in body:
        out.append(byte)
        # a stuffing byte can never be part of a later pattern (it follows FD, not FF FF)
        if byte == 0xFD and out[-3:] == _PATTERN:
            out.append(0xFD)
    return bytes(out)


def unstuff(body: bytes | bytearray) -> bytes:
    """Remove the ``FD`` that :func:`stuff` inserted after every ``FF FF FD``."""
    if _PATTERN not in body:
        return bytes(body)
    out = bytearray()
    i, n = 0, len(body)
    while i < n:
        out.append(body[i])
        if body[i] == 0xFD and out[-3:] == _PATTERN and i + 1 < n and body[i + 1] == 0xFD:
            i += 2
        else:
            i += 1
    return bytes(out)


def _frame(packet_id: int, body: bytes) -> bytes:
    stuffed = stuff(body)
    length = len(stuffed) + 2
    head = HEADER + bytes((packet_id, length & 0xFF, length >> 8))
    crc = crc16(head + stuffed)
    return head + stuffed + bytes((crc & 0xFF, crc >> 8))


def instruction_packet(packet_id: int, instruction: int, params: bytes | bytearray = b"") -> bytes:
    """An instruction packet as it goes on the wire (stuffed, with CRC)."""
    _check_byte("packet_id", packet_id, BROADCAST_ID)
    _check_byte("instruction", instruction, 0xFF)
    return _frame(packet_id, bytes((instruction,)) + bytes(params))


def status_packet(packet_id: int, error: int, params: bytes | bytearray = b"") -> bytes:
    """A status packet (instruction 0x55, then the error byte, then ``params``)."""
    _check_byte("packet_id", packet_id, MAX_ID)
    _check_byte("error", error, 0xFF)
    return _frame(packet_id, bytes((Instruction.STATUS, error)) + bytes(params))


def _check_byte(name: str, value: int, maximum: int) -> None:
    if not isinstance(value, int) or not 0 <= value <= maximum:
        raise ProtocolError(f"{name} (={value!r}) must be an integer in 0..{maximum}")


@dataclass(frozen=True)
class Packet:
    """A decoded packet (parameters unstuffed).

    Attributes
    ----------
    id : int
        Packet ID (254 is broadcast).
    instruction : int
        Instruction byte (0x55 for a status packet).
    params : bytes
        Parameters; for a status packet, those after the error byte.
    error : int or None
        The status packet's error byte; None for an instruction packet.
    """

    id: int
    instruction: int
    params: bytes = b""
    error: int | None = None

    @property
    def is_status(self) -> bool:
        return self.instruction == Instruction.STATUS

    def encode(self) -> bytes:
        """The packet as it goes on the wire."""
        if self.is_status:
            return status_packet(self.id, self.error or 0, self.params)
        return instruction_packet(self.id, self.instruction, self.params)


@dataclass(frozen=True)
class CorruptPacket:
    """A frame whose CRC did not match (what a servo answers with a CRC error).

    Attributes
    ----------
    id : int
        The packet ID as received (it may itself be corrupted).
    raw : bytes
        The whole frame.
    """

    id: int
    raw: bytes


def decode(frame: bytes | bytearray) -> Packet:
    """Decode one complete frame.

    Raises
    ------
    ProtocolError
        A wrong header, a LEN that does not match the frame, a CRC mismatch,
        or a status packet without its error byte.
    """
    frame = bytes(frame)
    if len(frame) < 10 or not frame.startswith(HEADER):
        raise ProtocolError(f"not a Protocol 2.0 packet: {frame[:12].hex(' ')}")
    length = frame[5] | frame[6] << 8
    if len(frame) != 7 + length:
        raise ProtocolError(f"packet length field says {length} bytes after it, the frame has {len(frame) - 7}")
    crc = frame[-2] | frame[-1] << 8
    expected = crc16(frame[:-2])
    if crc != expected:
        raise ProtocolError(f"CRC mismatch: packet says 0x{crc:04X}, content gives 0x{expected:04X}")
    body = unstuff(frame[7:-2])
    instruction = body[0]
    if instruction == Instruction.STATUS:
        if len(body) < 2:
            raise ProtocolError("status packet without its error byte")
        return Packet(frame[4], instruction, body[2:], body[1])
    return Packet(frame[4], instruction, body[1:])


class PacketReader:
    """Split a byte stream into packets, resynchronising after garbage or corruption.

    :meth:`feed` returns, in order, every complete frame found so far: a
    :class:`Packet` when its CRC matches, a :class:`CorruptPacket` when not.
    Bytes before a header are skipped; after a corrupt frame the search
    resumes right after its header, so that a packet hidden behind a
    corrupted length field is not lost.
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

    def feed(self, data: bytes | bytearray) -> list[Packet | CorruptPacket]:
        buf = self._buffer
        buf += data
        out: list[Packet | CorruptPacket] = []
        while True:
            start = buf.find(HEADER)
            if start < 0:
                # keep a possible header prefix (FF, FF FF, FF FF FD) for the next read
                keep = next((k for k in (3, 2, 1) if buf.endswith(HEADER[:k])), 0)
                del buf[: len(buf) - keep]
                return out
            del buf[:start]
            if len(buf) < 7:
                return out
            length = buf[5] | buf[6] << 8
            if not 3 <= length <= MAX_LENGTH:
                del buf[:1]  # not a real header: keep looking
                continue
            if len(buf) < 7 + length:
                return out
            frame = bytes(buf[: 7 + length])
            try:
                out.append(decode(frame))
            except ProtocolError:
                out.append(CorruptPacket(frame[4], frame))
                del buf[: len(HEADER)]
                continue
            del buf[: 7 + length]


#: What :meth:`PacketReader.feed` yields.
Frame = Packet | CorruptPacket
