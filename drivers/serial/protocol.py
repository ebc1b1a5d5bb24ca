"""The servoid bench protocol on the host side: framing, CRC, replies (docs/serial-protocol.md).

A frame is one line of printable ASCII, ``BODY*CRC\\n``, with the CRC-16/CCITT-FALSE
of ``BODY`` (``binascii.crc_hqx(body, 0xFFFF)``) as four upper-case hex digits.
Requests are ``<seq> <verb> [<arg>]``; replies ``<seq> <kind> <boot> [fields]``.
The reference firmware (``firmware/protocol.c``) implements the same rules in C.
"""

from __future__ import annotations

import binascii
from dataclasses import dataclass

from servoid.errors import ProtocolError

__all__ = [
    "MAX_FRAME",
    "PROTOCOL_VERSION",
    "crc16",
    "encode",
    "check",
    "Reply",
    "parse_reply",
    "FrameSplitter",
    "ERROR_CODES",
]

#: Longest frame in bytes, ``*``, CRC and ``\n`` included.
MAX_FRAME = 80

#: Version of the protocol this host speaks (the firmware reports its own in ``I``).
PROTOCOL_VERSION = 1

#: Sequence numbers run 0..65535 and wrap.
SEQ_MODULUS = 65536

#: Meaning of the code of an ``X`` reply.
ERROR_CODES = {
    1: "unknown request or malformed arguments",
    2: "the torque is off",
    3: "an argument is out of range",
    4: "streaming needs a control period (send C first)",
    5: "the set point's slot is not after the previous one",
    6: "the output stage turned itself off (a fault of the drive, e.g. an overspeed); the torque is off",
}

#: Reply kinds and how many fields follow the boot id.
_FIELDS = {"I": 3, "K": 0, "P": 3, "D": 3, "Q": 5, "X": 1}


def crc16(data: bytes) -> int:
    """CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF), as the firmware computes it."""
    return binascii.crc_hqx(data, 0xFFFF)


def encode(body: str) -> bytes:
    """The frame for ``body``: ``body*CRC\\n``."""
    raw = body.encode("ascii")
    frame = raw + b"*%04X\n" % crc16(raw)
    if len(frame) > MAX_FRAME:
        raise ProtocolError(f"frame {body!r} is {len(frame)} bytes, the protocol allows {MAX_FRAME}")
    return frame


def check(line: bytes) -> bytes | None:
    """``BODY`` of a received line (without ``\\n``) when it is a well-formed frame with a matching CRC, else None."""
    if len(line) < 6 or len(line) >= MAX_FRAME or line[-5:-4] != b"*":
        return None
    body, digits = line[:-5], line[-4:]
    if any(c < 0x20 or c > 0x7E or c == 0x2A for c in body):
        return None
    if any(c not in b"0123456789ABCDEF" for c in digits):
        return None
    return body if crc16(body) == int(digits, 16) else None


@dataclass(frozen=True)
class Reply:
    """One reply or stream frame from the device.

    Attributes
    ----------
    seq : int
        Echo of the request's sequence number (a stream counter for ``D``).
    kind : str
        ``I`` identity, ``K`` ok, ``P`` position, ``D`` streamed position,
        ``Q`` status, ``X`` error.
    boot : int
        The device's boot id.
    fields : tuple of str
        The rest, as text.
    """

    seq: int
    kind: str
    boot: int
    fields: tuple[str, ...]

    def ints(self) -> tuple[int, ...]:
        """The fields as integers (for P, D, Q, X)."""
        return tuple(int(f) for f in self.fields)


def parse_reply(line: bytes) -> Reply:
    """Check and split one received line (without ``\\n``).

    Raises
    ------
    ProtocolError
        Bad CRC or framing, an unknown kind, a wrong number of fields, or a
        field that is not a number where one is expected.
    """
    body = check(line)
    if body is None:
        raise ProtocolError(f"corrupted frame {line[:MAX_FRAME]!r} (framing or CRC)")
    tokens = body.decode("ascii").split(" ")
    if len(tokens) < 3 or tokens[1] not in _FIELDS or len(tokens) != 3 + _FIELDS[tokens[1]]:
        raise ProtocolError(f"malformed reply {body!r}")
    seq, kind, boot, *fields = tokens
    try:
        parsed = Reply(_decimal(seq, 0, SEQ_MODULUS - 1), kind, int(boot, 16), tuple(fields))
        if len(boot) != 4:
            raise ValueError(boot)
        if kind in "PDQX":
            parsed.ints()
        if kind == "I":
            _decimal(fields[0], 0, 255)
            _decimal(fields[1], 1, 1 << 24)
    except ValueError:
        raise ProtocolError(f"malformed reply {body!r}") from None
    return parsed


def _decimal(text: str, low: int, high: int) -> int:
    if not text.lstrip("-").isdigit():
        raise ValueError(text)
    value = int(text)
    if not low <= value <= high:
        raise ValueError(text)
    return value


class FrameSplitter:
    """Cut a byte stream into lines; over-long garbage is dropped and counted.

    Read whatever is waiting on the port and :meth:`feed` it: ``readline()``
    costs a system call per byte (HARDWARE.md), this costs one per read.
    """

    def __init__(self) -> None:
        self._buffer = bytearray()
        self.overflows = 0

    def feed(self, data: bytes) -> list[bytes]:
        """Add received bytes; return the complete lines (without ``\\n``)."""
        self._buffer += data
        lines = []
        while True:
            end = self._buffer.find(b"\n")
            if end < 0:
                break
            lines.append(bytes(self._buffer[:end]))
            del self._buffer[: end + 1]
        if len(self._buffer) >= MAX_FRAME:
            # no newline in a frame's length: line noise or a lost '\n'; resynchronise at the next one
            self._buffer.clear()
            self.overflows += 1
        return lines

    def clear(self) -> None:
        self._buffer.clear()
