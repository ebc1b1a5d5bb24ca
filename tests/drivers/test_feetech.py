"""The Feetech STS driver, its codec and emulator: the SDK's bytes, sign-magnitude, open, faults, a bus of several."""

from __future__ import annotations

import math
import subprocess
import sys
import textwrap

import numpy as np
import pytest
from scservo_sdk import SCS_TOHOST, SCS_TOSCS, GroupSyncWrite, PacketHandler

from servoid.drivers import driver_from_url
from servoid.drivers.bus import BusDriver
from servoid.drivers.feetech import control_table as ct
from servoid.drivers.feetech.emulator import FeetechEmulator
from servoid.drivers.feetech.protocol import CorruptPacket, ErrorBit, Instruction, Packet, PacketReader, decode, packet
from servoid.errors import CommandUnconfirmed, ConfigError, DeviceFault, DriverTimeout, ProtocolError
from servoid.recording import read_recording
from servoid.session import SessionConfig, run_session
from servoid.session.joints import bus_excitation, joint_columns, joint_result

from .dxl_helpers import TEST_LATENCY_MS


@pytest.fixture
def emulator():
    """Servos 1, 2, 3 on one bus, served from a thread; the model plant (one sample per goal)."""
    with FeetechEmulator(ids=[1, 2, 3], servo="model") as emu:
        yield emu


def url(emu: FeetechEmulator, ids=1, **options: object) -> str:
    options.setdefault("latency_ms", TEST_LATENCY_MS)
    return emu.url(ids, **options)


class _Capture:
    """What the SDK's packet handler needs of a port, keeping what it writes."""

    def __init__(self) -> None:
        self.is_using, self.written = False, b""

    def clearPort(self) -> None:  # noqa: N802 - the SDK's name
        pass

    def writePort(self, data) -> int:  # noqa: N802
        self.written += bytes(data)
        return len(data)


def test_the_sdk_builds_the_same_bytes_and_a_manual_example_checks():
    # the manual's PING of ID 1: FF FF 01 02 01 FB
    assert packet(1, Instruction.PING) == bytes.fromhex("ffff010201fb")
    port, ph = _Capture(), PacketHandler(0)
    writer = GroupSyncWrite(port, ph, ct.GOAL_POSITION.address, 2)
    for servo_id, goal in ((1, 2048), (2, -300), (6, 4095)):
        writer.addParam(servo_id, list(ct.encode_value(ct.GOAL_POSITION, goal)))
    writer.txPacket()
    params = bytes([42, 2, 1, 0, 8, 2, 0x2C, 0x81, 6, 0xFF, 0x0F])
    assert port.written == packet(0xFE, Instruction.SYNC_WRITE, params)
    assert decode(port.written) == Packet(0xFE, Instruction.SYNC_WRITE, params)


def test_sign_magnitude_entries_agree_with_the_sdk_and_round_trip():
    for field, bit in ((ct.PRESENT_POSITION, 15), (ct.HOMING_OFFSET, 11), (ct.PRESENT_LOAD, 10)):
        for value in (0, 1, -1, 5, -5, field.maximum, field.minimum):
            raw = int.from_bytes(ct.encode_value(field, value), "little")
            assert raw == SCS_TOSCS(value, bit) and SCS_TOHOST(raw, bit) == value
            assert ct.decode_value(field, ct.encode_value(field, value)) == value
    with pytest.raises(ValueError, match="Homing Offset"):
        ct.encode_value(ct.HOMING_OFFSET, 2048)  # past bit 11


def test_the_reader_resynchronises_after_garbage_and_a_corrupted_frame():
    good = packet(3, Instruction.READ, bytes([56, 2]))
    bad = bytearray(packet(4, Instruction.PING))
    bad[-1] ^= 0x10
    frames = PacketReader().feed(b"\x00\xff" + bytes(bad) + good[:4])
    assert len(frames) == 1 and isinstance(frames[0], CorruptPacket) and frames[0].id == 4
    reader = PacketReader()
    reader.feed(b"\x00\xff" + bytes(bad) + good[:4])
    assert reader.feed(good[4:]) == [Packet(3, Instruction.READ, bytes([56, 2]))]


def test_open_reads_the_servo_sets_it_up_and_narrows_the_limits(emulator):
    servo = emulator.servo(2)
    servo.write(ct.LOCK.address, b"\x00")
    servo.write(ct.MIN_POSITION_LIMIT.address, bytes(ct.encode_value(ct.MIN_POSITION_LIMIT, 1024)))
    servo.write(ct.RETURN_DELAY_TIME.address, b"\xfa")  # 500 us
    servo.write(ct.LOCK.address, b"\x01")
    with driver_from_url(url(emulator, 2, min=-3.0, max=0.5)) as d:
        assert d.identity["model"] == "STS3215" and d.identity["return_delay_us"] == 0
        assert d.limits.minimum == pytest.approx((1024 - 2048) * ct.RAD_PER_COUNT) and d.limits.maximum == 0.5
        assert d.watchdog_s is None  # the STS has none, and nothing pretends otherwise
    servo.restart()
    assert servo.value(ct.RETURN_DELAY_TIME) == 0  # written unlocked: kept over a power cycle
    with pytest.raises(ConfigError, match="id"):
        driver_from_url(emulator.url(1) + "&id=2")
    with pytest.raises(ConfigError, match="baud"):
        driver_from_url(emulator.url(1, baud=4_000_000))


def test_a_missing_servo_is_named(emulator):
    with pytest.raises(DriverTimeout, match="no Feetech servo with ID 9"):
        driver_from_url(url(emulator, 9, latency_ms=5)).open()


def test_a_lost_goal_is_unconfirmed_and_counted_and_the_next_sample_is_fine(emulator):
    with driver_from_url(url(emulator)) as d:
        d.enable()
        d.exchange(0.1)
        emulator.faults(1).corrupt_goals = 1
        with pytest.raises(CommandUnconfirmed, match="lost on its way"):
            d.exchange(0.2)
        assert d.stats.unconfirmed == 1
        assert d.exchange(0.2).command == pytest.approx(0.2, abs=ct.RAD_PER_COUNT)
        emulator.faults(1).stale_replies = 1
        with pytest.raises(ProtocolError, match="data bytes"):
            d.exchange(0.1)  # an empty answer is never taken for the readings
        d.exchange(0.1)


def test_a_protection_is_named_and_the_torque_ends_off(emulator):
    with driver_from_url(url(emulator)) as d:
        d.enable()
        d.exchange(0.05)
        emulator.servo(1).inject_fault(ErrorBit.OVERLOAD)
        with pytest.raises(DeviceFault, match="overload"):
            d.exchange(0.05)
    assert not emulator.servo(1).torque
    with pytest.raises(DeviceFault, match="overload"):
        driver_from_url(url(emulator)).open()  # refused while the protection is active


def test_a_bus_commands_and_reads_every_joint_in_one_transaction_with_its_own_limits(emulator, tmp_path):
    bus = driver_from_url(url(emulator, [1, 2, 3], min="-0.5,-0.02,-0.5", max="0.5,0.02,0.5", guard=0.6))
    assert isinstance(bus, BusDriver) and bus.ids == (1, 2, 3)
    assert [(j.limits.minimum, j.limits.maximum, j.limits.guard) for j in bus.joints] == [
        (-0.5, 0.5, 0.6), (-0.02, 0.02, 0.6), (-0.5, 0.5, 0.6)]  # fmt: skip
    with bus:
        before = emulator.stats.received
        u, blocks = bus_excitation(lambda i, n: np.random.default_rng(i).uniform(-0.1, 0.1, n), 3, 40,
                                   mode="together")  # fmt: skip
        path = tmp_path / "bus.csv"
        result = run_session(bus, u, SessionConfig(period_s=0.01), recording=path)
        sent = int(np.sum(result.status != "missed"))
        # per joint 3 packets to switch on (read, goal, torque) and 1 to switch off; one SYNC_WRITE + one SYNC_READ a sample
        assert emulator.stats.received - before == 3 * 4 + 2 * sent
    assert not any(s.torque for s in emulator.bus.servos)
    assert result.u.shape == (40, 3) and np.all(np.abs(result.u[:, 1]) <= 0.02 + 1e-12)
    assert np.max(np.abs(result.u[:, 0])) > 0.05 and blocks == [slice(0, 40)] * 3
    rec = read_recording(path, u_column="u_3", y_column="y_3")
    np.testing.assert_array_equal(rec.y, result.y[:, 2])
    assert open(path).read().count(",".join(joint_columns((1, 2, 3)))) == 1
    one = joint_result(result, 2)
    np.testing.assert_array_equal(one.y, result.y[:, 2])
    steps = [emulator.servo(i).steps for i in (1, 2, 3)]
    assert steps == [sent] * 3


@pytest.mark.parametrize(
    ("options", "message"),
    [({"min": "-1,-1"}, r"min=-1,-1 has 2 values for 3 joints \(ids 1,2,3\)"),
     ({"baud": "1000000,500000"}, r"baud=1000000,500000 has several values; only the limits")],
)  # fmt: skip
def test_per_joint_options_name_what_is_wrong(emulator, options, message):
    with pytest.raises(ConfigError, match=message):
        driver_from_url(url(emulator, [1, 2, 3], **options))


def test_a_silent_joint_fails_the_group_read_by_name_and_every_torque_ends_off(emulator):
    with driver_from_url(url(emulator, [1, 2, 3], latency_ms=3)) as bus:
        bus.enable()
        bus.exchange([0.0, 0.0, 0.0])
        emulator.faults(2).mute = True
        with pytest.raises(DriverTimeout, match="servo 2"):
            bus.exchange([0.01, 0.01, 0.01])
        emulator.faults(2).mute = False
    assert not any(s.torque for s in emulator.bus.servos)


def test_sequential_excitation_moves_one_joint_at_a_time():
    u, blocks = bus_excitation(lambda i, n: np.full(n, i + 1.0), 3, 5)
    assert u.shape == (15, 3) and blocks[1] == slice(5, 10)
    assert np.all(u[5:10, 1] == 2.0) and np.all(u[5:10, [0, 2]] == 0.0)
    with pytest.raises(ConfigError, match="mode"):
        bus_excitation(lambda i, n: np.zeros(n), 2, 3, mode="random")
    assert math.isfinite(float(u.sum()))


def test_without_the_sdk_the_driver_names_its_extra_and_the_emulator_still_runs():
    code = textwrap.dedent("""
        import sys
        sys.modules["scservo_sdk"] = None  # as if feetech-servo-sdk were not installed
        from servoid.drivers.feetech.emulator import FeetechEmulator
        FeetechEmulator([1]).close()  # written from the protocol: no SDK needed
        from servoid.drivers import driver_from_url
        driver_from_url("feetech:///dev/ttyUSB0?id=1")
    """)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert "MissingDependency" in out.stderr and "pip install 'servoid[feetech]'" in out.stderr
