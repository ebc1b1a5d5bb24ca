"""The Protocol 2.0 codec against the ROBOTIS e-manual's worked examples, the SDK, and properties.

Every vector below is copied from the e-manual page "Protocol 2.0",
https://emanual.robotis.com/docs/en/dxl/protocol2/ (source:
github.com/ROBOTIS-GIT/emanual, docs/en/dxl/protocol2.md), section
"Instruction Details"; the comment on each names its subsection.
"""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from servoid.drivers.dynamixel.protocol import (
    BROADCAST_ID,
    CorruptPacket,
    Instruction,
    Packet,
    PacketReader,
    crc16,
    decode,
    describe_error,
    instruction_packet,
    status_packet,
    stuff,
    unstuff,
)
from servoid.errors import ProtocolError


def h(text: str) -> bytes:
    return bytes.fromhex(text)


# (subsection, packet id, instruction, params, bytes on the wire)
INSTRUCTION_VECTORS = [
    ("Ping, example 1", 0x01, Instruction.PING, "", "FF FF FD 00 01 03 00 01 19 4E"),
    ("Ping, example 2 (broadcast)", BROADCAST_ID, Instruction.PING, "", "FF FF FD 00 FE 03 00 01 31 42"),
    ("Read: Present Position(132) of ID 1", 0x01, Instruction.READ, "84 00 04 00", "FF FF FD 00 01 07 00 02 84 00 04 00 1D 15"),
    ("Write: 512 to Goal Position(116)", 0x01, Instruction.WRITE, "74 00 00 02 00 00", "FF FF FD 00 01 09 00 03 74 00 00 02 00 00 CA 89"),
    ("Reg Write: 200 to Goal Velocity(104)", 0x01, Instruction.REG_WRITE, "68 00 C8 00 00 00", "FF FF FD 00 01 09 00 04 68 00 C8 00 00 00 AE 8E"),
    ("Action", 0x01, Instruction.ACTION, "", "FF FF FD 00 01 03 00 05 02 CE"),
    ("Factory Reset, option 0x01", 0x01, Instruction.FACTORY_RESET, "01", "FF FF FD 00 01 04 00 06 01 A1 E6"),
    ("Reboot", 0x01, Instruction.REBOOT, "", "FF FF FD 00 01 03 00 08 2F 4E"),
    ("Clear: multi-turn", 0x01, Instruction.CLEAR, "01 44 58 4C 22", "FF FF FD 00 01 08 00 10 01 44 58 4C 22 B1 DC"),
    ("Sync Read: Present Position of IDs 1, 2", BROADCAST_ID, Instruction.SYNC_READ, "84 00 04 00 01 02",
     "FF FF FD 00 FE 09 00 82 84 00 04 00 01 02 CE FA"),
    ("Sync Write: Goal Position 150 to ID 1, 170 to ID 2", BROADCAST_ID, Instruction.SYNC_WRITE,
     "74 00 04 00 01 96 00 00 00 02 AA 00 00 00",
     "FF FF FD 00 FE 11 00 83 74 00 04 00 01 96 00 00 00 02 AA 00 00 00 82 87"),
    ("Bulk Read: Present Voltage of ID 1, Present Temperature of ID 2", BROADCAST_ID, Instruction.BULK_READ,
     "01 90 00 02 00 02 92 00 01 00", "FF FF FD 00 FE 0D 00 92 01 90 00 02 00 02 92 00 01 00 1A 05"),
    ("Bulk Write: Max Voltage Limit of ID 1, Temperature Limit of ID 2", BROADCAST_ID, Instruction.BULK_WRITE,
     "01 20 00 02 00 A0 00 02 1F 00 01 00 50", "FF FF FD 00 FE 10 00 93 01 20 00 02 00 A0 00 02 1F 00 01 00 50 B7 68"),
]  # fmt: skip

# (subsection, packet id, error byte, params after the error byte, bytes on the wire)
STATUS_VECTORS = [
    ("Ping: ID 1, model 1030, firmware 38", 0x01, 0, "06 04 26", "FF FF FD 00 01 07 00 55 00 06 04 26 65 5D"),
    ("Ping, example 2: ID 2", 0x02, 0, "06 04 26", "FF FF FD 00 02 07 00 55 00 06 04 26 6F 6D"),
    ("Read / Sync Read: ID 1, position 166", 0x01, 0, "A6 00 00 00", "FF FF FD 00 01 08 00 55 00 A6 00 00 00 8C C0"),
    ("Sync Read: ID 2, position 2079", 0x02, 0, "1F 08 00 00", "FF FF FD 00 02 08 00 55 00 1F 08 00 00 BA BE"),
    ("Write / Reg Write / Action / Reboot: ID 1, no error", 0x01, 0, "", "FF FF FD 00 01 04 00 55 00 A1 0C"),
    ("Bulk Read: ID 1, voltage 119", 0x01, 0, "77 00", "FF FF FD 00 01 06 00 55 00 77 00 C3 69"),
    ("Bulk Read: ID 2, temperature 36", 0x02, 0, "24", "FF FF FD 00 02 05 00 55 00 24 8B A9"),
]  # fmt: skip


@pytest.mark.parametrize("name, pid, inst, params, wire", INSTRUCTION_VECTORS, ids=[v[0] for v in INSTRUCTION_VECTORS])
def test_instruction_packets_match_the_e_manual(name, pid, inst, params, wire):
    assert instruction_packet(pid, inst, h(params)) == h(wire)
    assert decode(h(wire)) == Packet(pid, inst, h(params))


@pytest.mark.parametrize("name, pid, error, params, wire", STATUS_VECTORS, ids=[v[0] for v in STATUS_VECTORS])
def test_status_packets_match_the_e_manual(name, pid, error, params, wire):
    assert status_packet(pid, error, h(params)) == h(wire)
    packet = decode(h(wire))
    assert packet.is_status and (packet.id, packet.error, packet.params) == (pid, error, h(params))


def test_crc_is_the_manual_s_crc16_over_the_header_and_body():
    # the Ping example's CRC bytes 19 4E (low byte first) over everything before them
    assert crc16(h("FF FF FD 00 01 03 00 01")) == 0x4E19
    # CRC-16/BUYPASS (poly 0x8005, init 0, no reflection): check value over ASCII "123456789"
    assert crc16(b"123456789") == 0xFEE8


def test_a_stuffed_body_and_its_length():
    # a body with the header pattern: FF FF FD becomes FF FF FD FD, and LEN counts the extra byte
    packet = instruction_packet(1, Instruction.WRITE, h("6C 00 FF FF FD 00"))
    assert packet[5] == 10 and h("FF FF FD FD 00") in packet
    assert decode(packet).params == h("6C 00 FF FF FD 00")


def test_errors_are_described_in_words():
    assert describe_error(0) == "ok"
    assert "CRC error" in describe_error(3)
    assert "access error" in describe_error(7) and "EEPROM" in describe_error(7)
    assert "alert" in describe_error(0x80) and "data limit" in describe_error(0x86)


def test_decode_rejects_bad_frames_by_name():
    good = h("FF FF FD 00 01 03 00 01 19 4E")
    with pytest.raises(ProtocolError, match="CRC mismatch"):
        decode(good[:-1] + b"\x00")
    with pytest.raises(ProtocolError, match="length field"):
        decode(good + b"\x00")
    with pytest.raises(ProtocolError, match="not a Protocol 2.0 packet"):
        decode(b"\xff\xff\xff\x00" + good[4:])
    with pytest.raises(ProtocolError, match="packet_id"):
        instruction_packet(300, 1)


# ---- properties ---------------------------------------------------------------------------
bodies = st.binary(max_size=64) | st.lists(st.sampled_from([0xFF, 0xFD, 0x00]), max_size=64).map(bytes)
ids = st.integers(0, 0xFC)


@given(bodies)
def test_stuffing_round_trips_and_never_leaves_a_header_in_the_body(body):
    stuffed = stuff(body)
    assert unstuff(stuffed) == body
    at = stuffed.find(b"\xff\xff\xfd")
    while at >= 0:  # every FF FF FD is followed by the stuffing FD, so never by the reserved 00
        assert stuffed[at + 3 : at + 4] == b"\xfd"
        at = stuffed.find(b"\xff\xff\xfd", at + 1)


@given(ids, st.integers(1, 0x54), bodies)
def test_encode_decode_round_trip(pid, inst, params):
    assert decode(instruction_packet(pid, inst, params)) == Packet(pid, inst, params)
    assert decode(status_packet(pid, inst, params)) == Packet(pid, Instruction.STATUS, params, inst)


@given(ids, bodies, st.data())
def test_every_single_bit_flip_is_detected(pid, params, data):
    wire = bytearray(instruction_packet(pid, Instruction.WRITE, params))
    bit = data.draw(st.integers(0, 8 * len(wire) - 1))
    wire[bit // 8] ^= 1 << (bit % 8)
    with pytest.raises(ProtocolError):
        decode(wire)


@given(ids, bodies)
def test_the_sdk_builds_the_same_bytes(pid, params):
    """The official SDK's own stuffing and CRC agree with this codec byte for byte."""
    from dynamixel_sdk import Protocol2PacketHandler

    handler = Protocol2PacketHandler()
    length = len(params) + 3
    packet = [0xFF, 0xFF, 0xFD, 0x00, pid, length & 0xFF, length >> 8, Instruction.WRITE, *params, 0, 0]
    packet = handler.addStuffing(packet)
    total = (packet[5] | packet[6] << 8) + 7
    crc = handler.updateCRC(0, packet, total - 2)
    packet[total - 2 : total] = [crc & 0xFF, crc >> 8]
    assert bytes(packet[:total]) == instruction_packet(pid, Instruction.WRITE, params)


@settings(max_examples=50)
@given(st.lists(st.tuples(ids, bodies), min_size=1, max_size=5), st.binary(max_size=8), st.data())
def test_the_reader_finds_every_packet_however_the_stream_is_cut(packets, garbage, data):
    wires = [instruction_packet(pid, Instruction.WRITE, params) for pid, params in packets]
    garbage = garbage.replace(b"\xff", b"")  # garbage without a header prefix cannot swallow a packet
    stream = garbage + b"".join(wires)
    cuts = sorted(data.draw(st.lists(st.integers(0, len(stream)), max_size=6)))
    reader, found = PacketReader(), []
    for start, end in zip([0, *cuts], [*cuts, len(stream)]):
        found += reader.feed(stream[start:end])
    assert found == [Packet(pid, Instruction.WRITE, params) for pid, params in packets]
    assert reader.pending == 0


def test_the_reader_reports_a_corrupt_frame_and_finds_the_next_one():
    good = instruction_packet(2, Instruction.PING)
    bad = bytearray(instruction_packet(1, Instruction.READ, h("84 00 04 00")))
    bad[9] ^= 0x10
    found = PacketReader().feed(bytes(bad) + good)
    assert isinstance(found[0], CorruptPacket) and found[0].id == 1
    assert found[1:] == [Packet(2, Instruction.PING)]
