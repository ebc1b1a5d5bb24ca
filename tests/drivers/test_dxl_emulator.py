"""The Dynamixel emulator, driven by the official SDK unmodified over a pseudo-terminal.

Only the SDK's own PortHandler and PacketHandler are used here, so every test
shows how a program written against the real servo sees the emulator.
"""

from __future__ import annotations

import time

import dynamixel_sdk as sdk
import pytest

from servoid.drivers.dynamixel import control_table as ct
from servoid.drivers.dynamixel.control_table import HardwareError
from servoid.drivers.dynamixel.emulator import DynamixelEmulator
from servoid.drivers.dynamixel.protocol import Instruction
from servoid.drivers.model_plant import MODEL_PLANT
from servoid.ident.models.plant import Plant

from .dxl_helpers import TEST_LATENCY_MS, clock, emulator  # noqa: F401 - fixtures

ACCESS, DATA_RANGE, DATA_LENGTH, DATA_LIMIT, INSTRUCTION, CRC, RESULT_FAIL = 7, 4, 5, 6, 2, 3, 1


@pytest.fixture(autouse=True)
def patient_sdk(monkeypatch):
    # the SDK's own setting for its reply timeouts (module-wide): see TEST_LATENCY_MS
    monkeypatch.setattr(sdk.port_handler, "LATENCY_TIMER", TEST_LATENCY_MS)


@pytest.fixture
def bus(emulator):  # noqa: F811
    port = sdk.PortHandler(emulator.port)
    assert port.openPort() and port.setBaudRate(1_000_000)
    yield port, sdk.PacketHandler(2.0)
    port.closePort()


def test_ping_finds_every_servo_on_the_bus(bus):
    port, ph = bus
    assert ph.ping(port, 1) == (1020, sdk.COMM_SUCCESS, 0)
    assert ph.ping(port, 2)[:2] == (1020, sdk.COMM_SUCCESS)
    assert ph.ping(port, 3)[1] == sdk.COMM_RX_TIMEOUT
    found, result = ph.broadcastPing(port)
    assert result == sdk.COMM_SUCCESS and found == {1: [1020, 48], 2: [1020, 48]}


def test_read_write_and_the_refusals_of_the_e_manual(bus, emulator):  # noqa: F811
    port, ph = bus
    assert ph.read4ByteTxRx(port, 1, ct.PRESENT_POSITION.address) == (2048, sdk.COMM_SUCCESS, 0)
    assert ph.write1ByteTxRx(port, 1, ct.LED.address, 1) == (sdk.COMM_SUCCESS, 0)
    assert ph.read1ByteTxRx(port, 1, ct.LED.address)[0] == 1
    assert ph.readTxRx(port, 1, 140, 20)[1:] == (sdk.COMM_SUCCESS, ACCESS)  # beyond the emulated table
    assert ph.write4ByteTxRx(port, 1, ct.PRESENT_POSITION.address, 7)[1] == ACCESS  # read-only
    assert ph.write2ByteTxRx(port, 1, ct.GOAL_POSITION.address, 7)[1] == DATA_LENGTH  # half an entry
    assert ph.write1ByteTxRx(port, 1, ct.OPERATING_MODE.address, 2)[1] == DATA_RANGE  # no mode 2
    assert ph.write4ByteTxRx(port, 1, ct.GOAL_POSITION.address, 5000)[1] == DATA_LIMIT  # beyond Max Position Limit
    assert ph.write2ByteTxRx(port, 1, ct.GOAL_CURRENT.address, 2000)[1] == DATA_LIMIT  # beyond Current Limit
    assert ph.clearMultiTurn(port, 1) == (sdk.COMM_SUCCESS, INSTRUCTION)  # CLEAR is not emulated
    assert emulator.servo(1).value(ct.GOAL_POSITION) == 2048  # nothing refused was written


def test_eeprom_is_locked_while_the_torque_is_on(bus, emulator):  # noqa: F811
    port, ph = bus
    assert ph.write1ByteTxRx(port, 1, ct.TORQUE_ENABLE.address, 1) == (sdk.COMM_SUCCESS, 0)
    assert ph.write1ByteTxRx(port, 1, ct.OPERATING_MODE.address, 0) == (sdk.COMM_SUCCESS, ACCESS)
    assert ph.write1ByteTxRx(port, 1, ct.RETURN_DELAY_TIME.address, 0)[1] == ACCESS
    assert emulator.servo(1).value(ct.OPERATING_MODE) == 3
    assert ph.write1ByteTxRx(port, 1, ct.TORQUE_ENABLE.address, 0) == (sdk.COMM_SUCCESS, 0)
    assert ph.write1ByteTxRx(port, 1, ct.OPERATING_MODE.address, 0) == (sdk.COMM_SUCCESS, 0)
    assert emulator.servo(1).value(ct.OPERATING_MODE) == 0


def test_a_new_id_takes_effect_at_once(bus):
    port, ph = bus
    assert ph.write1ByteTxRx(port, 2, ct.ID.address, 7) == (sdk.COMM_SUCCESS, 0)
    assert ph.ping(port, 7)[1] == sdk.COMM_SUCCESS and ph.ping(port, 2)[1] == sdk.COMM_RX_TIMEOUT


def test_reg_write_waits_for_action(bus, emulator):  # noqa: F811
    port, ph = bus
    assert ph.regWriteTxRx(port, 1, ct.LED.address, 1, [1]) == (sdk.COMM_SUCCESS, 0)
    assert ph.read1ByteTxRx(port, 1, ct.REGISTERED_INSTRUCTION.address)[0] == 1
    assert ph.read1ByteTxRx(port, 1, ct.LED.address)[0] == 0
    assert ph.action(port, 1) == sdk.COMM_SUCCESS
    # the SDK's action() leaves the ACTION's answer unread: let it arrive and drop it, or the
    # next READ takes it for its own (the stray-reply pitfall)
    time.sleep(0.05)
    port.clearPort()
    assert ph.read1ByteTxRx(port, 1, ct.LED.address)[0] == 1
    assert ph.read1ByteTxRx(port, 1, ct.REGISTERED_INSTRUCTION.address)[0] == 0
    # ACTION with nothing registered is an Instruction Error (the SDK's action() does not wait
    # for the answer, so send and receive by hand)
    assert ph.txPacket(port, [0xFF, 0xFF, 0xFD, 0, 1, 3, 0, Instruction.ACTION, 0, 0]) == sdk.COMM_SUCCESS
    port.setPacketTimeout(11)
    reply, result = ph.rxPacket(port, False)
    assert result == sdk.COMM_SUCCESS and reply[8] == INSTRUCTION


def test_sync_and_bulk_read_answer_in_turn(bus, emulator):  # noqa: F811
    port, ph = bus
    ph.write4ByteTxRx(port, 2, ct.PROFILE_VELOCITY.address, 1234)
    group = sdk.GroupSyncRead(port, ph, ct.PRESENT_POSITION.address, 4)
    assert group.addParam(1) and group.addParam(2)
    assert group.txRxPacket() == sdk.COMM_SUCCESS
    assert group.getData(1, ct.PRESENT_POSITION.address, 4) == group.getData(2, ct.PRESENT_POSITION.address, 4) == 2048
    bulk = sdk.GroupBulkRead(port, ph)
    assert bulk.addParam(1, ct.PRESENT_TEMPERATURE.address, 1) and bulk.addParam(2, ct.PROFILE_VELOCITY.address, 4)
    assert bulk.txRxPacket() == sdk.COMM_SUCCESS
    assert bulk.getData(1, ct.PRESENT_TEMPERATURE.address, 1) == 36
    assert bulk.getData(2, ct.PROFILE_VELOCITY.address, 4) == 1234


def test_the_plant_advances_one_step_per_goal_written(bus, emulator, clock):  # noqa: F811
    port, ph = bus
    writer = sdk.GroupSyncWrite(port, ph, ct.GOAL_POSITION.address, 4)
    goals = [2048 + 120, 2048 - 80, 2048 + 40, 2048 + 40, 2048 - 130]
    writer.addParam(1, list(ct.encode_value(ct.GOAL_POSITION, goals[0])))
    writer.txPacket()  # torque off: the goal is stored, nothing moves
    assert emulator.servo(1).steps == 0
    ph.write1ByteTxRx(port, 1, ct.TORQUE_ENABLE.address, 1)
    reference = Plant(MODEL_PLANT)
    for goal in goals:
        writer.changeParam(1, list(ct.encode_value(ct.GOAL_POSITION, goal)))
        assert writer.txPacket() == sdk.COMM_SUCCESS
        clock.advance(0.002)
        expected = round(reference.step((goal - 2048) * ct.RAD_PER_COUNT) / ct.RAD_PER_COUNT) + 2048
        position, result, _ = ph.read4ByteTxRx(port, 1, ct.PRESENT_POSITION.address)
        assert (result, position) == (sdk.COMM_SUCCESS, expected)
        assert ph.read4ByteTxRx(port, 1, ct.PRESENT_POSITION.address)[0] == expected  # reads do not step
    assert emulator.servo(1).steps == len(goals) and emulator.servo(2).steps == 0


def test_on_its_own_clock_the_servo_holds_the_goal_between_samples(clock):  # noqa: F811
    """With a period, the servo's loop runs on: silence is samples on the held goal, counted by its clock."""
    period = 0.01
    with DynamixelEmulator(ids=[1], clock=clock, return_delay_us=0, period_s=period, servo="model") as emu:
        port = sdk.PortHandler(emu.port)
        assert port.openPort() and port.setBaudRate(1_000_000)
        ph = sdk.PacketHandler(2.0)
        writer = sdk.GroupSyncWrite(port, ph, ct.GOAL_POSITION.address, 4)
        writer.addParam(1, list(ct.encode_value(ct.GOAL_POSITION, 2048)))
        ph.write1ByteTxRx(port, 1, ct.TORQUE_ENABLE.address, 1)
        reference, held, latest = Plant(MODEL_PLANT), 0.0, 2048
        # goals 1.3, 3.2 and 3.6 periods apart (nearest: 1, 3 and 4 samples); a READ 2.6 periods after the
        # third goal reports the latest sample (held samples are counted when the next goal comes)
        for gap, goal in ((0.0, 2048 + 150), (1.3, 2048 - 90), (3.2, 2048 + 60), (3.6, 2048 - 20)):
            if gap == 3.6:
                clock.advance(2.6 * period)
                assert ph.read4ByteTxRx(port, 1, ct.PRESENT_POSITION.address)[0] == latest
                clock.advance(1.0 * period)
            else:
                clock.advance(gap * period)
            for _ in range(max(round(gap), 1) - 1):
                reference.step(held)
            held = (goal - 2048) * ct.RAD_PER_COUNT
            expected = round(reference.step(held) / ct.RAD_PER_COUNT) + 2048
            writer.changeParam(1, list(ct.encode_value(ct.GOAL_POSITION, goal)))
            assert writer.txPacket() == sdk.COMM_SUCCESS
            latest = ph.read4ByteTxRx(port, 1, ct.PRESENT_POSITION.address)[0]
            assert latest == expected
        assert emu.servo(1).steps == 1 + 1 + 3 + 4
        port.closePort()


def test_negative_values_and_the_header_pattern_survive_the_wire(bus, emulator):  # noqa: F811
    port, ph = bus
    # 0x00FDFFFF is FF FF FD 00 on the wire: the SDK stuffs it, the emulator must unstuff, and back
    assert ph.write4ByteTxRx(port, 1, ct.PROFILE_ACCELERATION.address, 0x00FDFFFF) == (sdk.COMM_SUCCESS, 0)
    assert emulator.servo(1).value(ct.PROFILE_ACCELERATION) == 0x00FDFFFF
    assert ph.read4ByteTxRx(port, 1, ct.PROFILE_ACCELERATION.address) == (0x00FDFFFF, sdk.COMM_SUCCESS, 0)
    ph.write2ByteTxRx(port, 1, ct.GOAL_PWM.address, (-300) & 0xFFFF)
    assert emulator.servo(1).value(ct.GOAL_PWM) == -300


def test_realtime_tick_counts_milliseconds_of_the_clock_and_wraps(bus, clock):  # noqa: F811
    port, ph = bus
    clock.advance(1.2345)
    assert ph.read2ByteTxRx(port, 1, ct.REALTIME_TICK.address)[0] == 1234
    clock.advance(40.0)
    assert ph.read2ByteTxRx(port, 1, ct.REALTIME_TICK.address)[0] == 41234 - 32768


def test_a_hardware_error_raises_the_alert_until_a_reboot(bus, emulator, clock):  # noqa: F811
    port, ph = bus
    ph.write1ByteTxRx(port, 1, ct.TORQUE_ENABLE.address, 1)
    clock.advance(5.0)
    emulator.servo(1).inject_hardware_error(HardwareError.OVERLOAD)
    value, result, error = ph.read1ByteTxRx(port, 1, ct.HARDWARE_ERROR_STATUS.address)
    assert (value, result, error) == (HardwareError.OVERLOAD, sdk.COMM_SUCCESS, 0x80)
    assert ph.read1ByteTxRx(port, 1, ct.TORQUE_ENABLE.address)[0] == 0  # overload is a Shutdown bit
    assert ph.write1ByteTxRx(port, 1, ct.TORQUE_ENABLE.address, 1)[1] == 0x80 | RESULT_FAIL
    assert ph.ping(port, 2)[2] == 0  # the other servo is fine
    assert ph.reboot(port, 1)[0] == sdk.COMM_SUCCESS
    assert ph.read1ByteTxRx(port, 1, ct.HARDWARE_ERROR_STATUS.address) == (0, sdk.COMM_SUCCESS, 0)
    assert ph.read2ByteTxRx(port, 1, ct.REALTIME_TICK.address)[0] == 0  # the tick restarted
    assert ph.write1ByteTxRx(port, 1, ct.TORQUE_ENABLE.address, 1) == (sdk.COMM_SUCCESS, 0)


def test_status_return_level_decides_what_is_answered(bus, emulator):  # noqa: F811
    port, ph = bus
    ph.write1ByteTxRx(port, 1, ct.STATUS_RETURN_LEVEL.address, 1)
    assert ph.write1ByteTxRx(port, 1, ct.LED.address, 1)[0] == sdk.COMM_RX_TIMEOUT  # not answered ...
    assert emulator.servo(1).value(ct.LED) == 1  # ... but done
    assert ph.read1ByteTxRx(port, 1, ct.LED.address)[:2] == (1, sdk.COMM_SUCCESS)
    ph.write1ByteTxOnly(port, 1, ct.STATUS_RETURN_LEVEL.address, 0)
    assert ph.read1ByteTxRx(port, 1, ct.LED.address)[1] == sdk.COMM_RX_TIMEOUT
    assert ph.ping(port, 1)[1] == sdk.COMM_SUCCESS  # PING is always answered


def test_a_corrupted_request_is_answered_with_the_crc_error(bus, emulator):  # noqa: F811
    port, ph = bus
    emulator.faults(1).corrupt_requests = 1
    assert ph.read1ByteTxRx(port, 1, ct.LED.address)[1:] == (sdk.COMM_SUCCESS, CRC)
    emulator.faults(1).corrupt_replies = 1
    assert ph.read1ByteTxRx(port, 1, ct.LED.address)[1] == sdk.COMM_RX_CORRUPT
    assert ph.read1ByteTxRx(port, 1, ct.LED.address) == (0, sdk.COMM_SUCCESS, 0)
    assert emulator.stats.corrupt_received == 1


def test_return_delay_time_is_honoured():
    with DynamixelEmulator(ids=[1], return_delay_us=508) as emu:
        port = sdk.PortHandler(emu.port)
        port.openPort()
        ph = sdk.PacketHandler(2.0)
        fastest = min(_timed_ping(port, ph) for _ in range(20))
        ph.write1ByteTxRx(port, 1, ct.RETURN_DELAY_TIME.address, 0)
        port.closePort()
    # a lower bound only: the reply cannot come before the delay, however loaded the machine is
    assert fastest >= 508e-6


def _timed_ping(port, ph) -> float:
    start = time.perf_counter()
    assert ph.ping(port, 1)[1] == sdk.COMM_SUCCESS
    return time.perf_counter() - start


def test_factory_reset_restores_the_eeprom_but_keeps_the_id_on_request(bus, emulator):  # noqa: F811
    port, ph = bus
    ph.write1ByteTxRx(port, 2, ct.OPERATING_MODE.address, 16)
    assert ph.factoryReset(port, 2, 0x01) == (sdk.COMM_SUCCESS, 0)
    assert emulator.servo(2).value(ct.OPERATING_MODE) == 3 and emulator.servo(2).value(ct.RETURN_DELAY_TIME) == 250
    assert ph.ping(port, 2)[1] == sdk.COMM_SUCCESS
