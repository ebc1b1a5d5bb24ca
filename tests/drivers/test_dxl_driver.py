"""The dxl:// driver against the emulator: URL, opening, units, modes, limits and the SDK's pitfalls."""

from __future__ import annotations

import math
import threading
import time

import pytest

from servoid.drivers import driver_from_url
from servoid.drivers._sdk_port import PTY_LATENCY_MS, default_latency_ms
from servoid.drivers.dynamixel import DynamixelDriver
from servoid.drivers.dynamixel import control_table as ct
from servoid.drivers.dynamixel.emulator import DynamixelEmulator
from servoid.errors import CommandUnconfirmed, ConfigError, DeviceFault, DriverError, DriverTimeout, ProtocolError

from .dxl_helpers import TEST_LATENCY_MS, clock, emulator, url  # noqa: F401 - fixtures

RAD = ct.RAD_PER_COUNT


def test_url_options_and_defaults():
    d = driver_from_url("dxl:///dev/ttyUSB0?id=3&baud=1000000&mode=current&return_delay_us=keep&max=0.5")
    assert isinstance(d, DynamixelDriver)
    assert (d.port, d.servo_id, d.baud, d.mode, d.return_delay_us) == ("/dev/ttyUSB0", 3, 1_000_000, "current", None)
    assert d.command_unit.unit == "A" and d.position_unit.unit == "rad" and d.limits.maximum == 0.5
    d = driver_from_url("dxl:///dev/ttyUSB1")
    assert (d.servo_id, d.baud, d.mode, d.return_delay_us, d.latency_ms) == (1, 57600, "position", 0, None)
    assert driver_from_url("dxl://COM3?id=2").port == "COM3"


@pytest.mark.parametrize(
    "bad, message",
    [
        ("dxl:///dev/ttyUSB0?baud=4500000", "refuses 4.5 Mbps"),
        ("dxl:///dev/ttyUSB0?baud=12345", "expected one of 9600, 57600"),
        ("dxl:///dev/ttyUSB0?id=253", "servo ID is 0..252"),
        ("dxl:///dev/ttyUSB0?mode=velocity", "position, current, pwm"),
        ("dxl:///dev/ttyUSB0?return_delay_us=3", "even number"),
        ("dxl:///dev/ttyUSB0?latency_ms=0", "positive"),
        ("dxl:///dev/ttyUSB0?speed=1", "unknown option.*speed"),
        ("dxl://?id=1", "must name the serial port"),
    ],
)
def test_bad_urls_are_refused_by_name(bad, message):
    with pytest.raises(ConfigError, match=message):
        driver_from_url(bad)


def test_reply_timeouts_follow_the_port(emulator):  # noqa: F811
    assert default_latency_ms(emulator.port) == PTY_LATENCY_MS  # an emulator: a program at the other end
    assert default_latency_ms("/dev/ttyS99") == 1.0  # no USB adapter in between
    with driver_from_url(emulator.url(1)) as d:
        assert d._port.latency_ms == PTY_LATENCY_MS
        assert d._port.timeout_ms(27) == pytest.approx(27 * 0.01 + 2 * PTY_LATENCY_MS + 2.0)


def test_opening_reads_the_servo_and_leaves_the_torque_off(emulator):  # noqa: F811
    servo = emulator.servo(1)
    servo.write(ct.TORQUE_ENABLE.address, b"\x01")  # left on by a previous program
    servo.write(ct.MAX_POSITION_LIMIT.address, b"")  # no-op: refused, nothing changes
    with driver_from_url(url(emulator, mode="current")) as d:
        assert d.identity == {
            "driver": "dxl", "vendor": "ROBOTIS", "protocol": "2.0", "model_number": 1020, "model": "XM430-W350",
            "firmware_version": 48, "id": 1, "baud": 1_000_000, "port": emulator.port,
            "operating_mode": "current", "return_delay_us": 0, "readings": "output",
        }  # fmt: skip
        # the EEPROM write of the mode succeeded, so the torque went off first
        assert not servo.torque and servo.value(ct.OPERATING_MODE) == ct.OperatingMode.CURRENT
        assert d.limits.maximum == pytest.approx(1193 * 2.69e-3) and d.limits.minimum == pytest.approx(-1193 * 2.69e-3)


def test_return_delay_and_status_return_level_are_set_up_at_open(clock):  # noqa: F811
    with DynamixelEmulator(ids=[1], clock=clock, servo="model") as emu:  # factory Return Delay Time: 500 us
        emu.servo(1).write(ct.STATUS_RETURN_LEVEL.address, b"\x01")
        with driver_from_url(url(emu, return_delay_us="keep")) as d:
            assert d.identity["return_delay_us"] == 500 and emu.servo(1).status_return_level == 2
        with driver_from_url(url(emu)):
            assert emu.servo(1).value(ct.RETURN_DELAY_TIME) == 0
        emu.servo(1).write(ct.STATUS_RETURN_LEVEL.address, b"\x00")  # only PING answered
        with driver_from_url(url(emu)) as d:
            d.enable()
            assert d.exchange(0.1).position == 0.0 and emu.servo(1).status_return_level == 2


@pytest.mark.parametrize(
    "mode, command, goal, expected",
    [
        ("position", 0.1, ct.GOAL_POSITION, round(0.1 / RAD) + 2048),
        ("position", -1.0, ct.GOAL_POSITION, round(-1.0 / RAD) + 2048),
        ("current", 0.05, ct.GOAL_CURRENT, round(0.05 / 2.69e-3)),
        ("current", -0.2, ct.GOAL_CURRENT, round(-0.2 / 2.69e-3)),
        ("pwm", 12.0, ct.GOAL_PWM, round(12.0 * 885 / 100)),
        ("pwm", -30.0, ct.GOAL_PWM, round(-30.0 * 885 / 100)),
    ],
)
def test_commands_reach_the_servo_in_its_units(emulator, mode, command, goal, expected):  # noqa: F811
    with driver_from_url(url(emulator, mode=mode)) as d:
        d.enable()
        m = d.exchange(command)
        assert emulator.servo(1).value(goal) == expected and emulator.servo(1).steps == 1
        # the command reported is the goal the servo got, in the user's unit
        assert m.command == pytest.approx(d.command_unit.to_user(expected), abs=1e-12)
        assert m.requested == command and not m.clamped


def test_present_values_come_back_signed_in_user_units(emulator, clock):  # noqa: F811
    with driver_from_url(url(emulator)) as d:
        d.enable()
        clock.advance(0.01)
        first = d.exchange(-0.5)
        clock.advance(0.01)
        second = d.exchange(-0.5)
    servo = emulator.servo(1)
    assert second.position == pytest.approx((servo.value(ct.PRESENT_POSITION) - 2048) * RAD)
    assert second.position < -0.1 and first.position == 0.0  # one sample of delay, then down
    assert (
        second.velocity == pytest.approx(servo.value(ct.PRESENT_VELOCITY) * 0.229 * 2 * math.pi / 60)
        and second.velocity < 0
    )
    assert second.current == pytest.approx(servo.value(ct.PRESENT_CURRENT) * 2.69e-3) and second.current < 0
    assert (first.device_time, second.device_time) == pytest.approx((0.01, 0.02))


def test_the_realtime_tick_is_unwrapped(emulator, clock):  # noqa: F811
    with driver_from_url(url(emulator)) as d:
        d.enable()
        times = []
        for _ in range(5):
            clock.advance(12.0)
            times.append(d.exchange(0.0).device_time)
    assert times == pytest.approx([12.0, 24.0, 36.0, 48.0, 60.0])


def test_limits_are_narrowed_to_the_servo_s_own(emulator):  # noqa: F811
    emulator.servo(1).write(ct.MAX_POSITION_LIMIT.address, ct.encode_value(ct.MAX_POSITION_LIMIT, 3000))
    with driver_from_url(url(emulator, min=-0.3, max=5)) as d:
        assert d.limits.minimum == -0.3 and d.limits.maximum == pytest.approx((3000 - 2048) * RAD)
        d.enable()
        m = d.exchange(4.0)
        assert m.clamped and emulator.servo(1).value(ct.GOAL_POSITION) == 3000
    with pytest.raises(ConfigError, match="do not overlap the servo's own range"):
        driver_from_url(url(emulator, min=2, max=3)).open()


def test_enabling_holds_the_present_position(emulator):  # noqa: F811
    with driver_from_url(url(emulator)) as d:
        d.enable()
        for _ in range(5):
            d.exchange(0.4)
    servo = emulator.servo(1)
    steps, present = servo.steps, servo.value(ct.PRESENT_POSITION)
    assert present > 2048 + 100
    with driver_from_url(url(emulator)) as d:
        d.enable()
        assert servo.value(ct.GOAL_POSITION) == present and servo.steps == steps and servo.torque
        assert d.read().position == pytest.approx((present - 2048) * RAD)


def test_a_missing_servo_or_port_is_named(emulator):  # noqa: F811
    with pytest.raises(DriverTimeout, match="no Dynamixel with ID 5 answers on .* at 1000000 bit/s"):
        driver_from_url(url(emulator, 5)).open()
    with pytest.raises(DriverError, match="cannot open the serial port /dev/nonexistent"):
        driver_from_url("dxl:///dev/nonexistent?id=1").open()


def test_a_stray_reply_is_caught_by_its_length(emulator):  # noqa: F811
    with driver_from_url(url(emulator)) as d:
        d.enable()
        emulator.faults(1).stale_replies = 1
        with pytest.raises(ProtocolError, match="present values has 0 data bytes, expected 20"):
            d.exchange(0.1)
        assert d.exchange(0.1).position is not None  # and the next sample is fine


def test_an_answer_left_in_the_input_is_dropped_not_taken_for_the_next_one(emulator):  # noqa: F811
    with driver_from_url(url(emulator)) as d:
        d.enable()
        emulator.faults(1).late_replies = 1
        d.exchange(0.1)  # answered twice: the copy waits in the input like an answer that came too late
        time.sleep(0.05)
        for goal in (0.2, 0.3):  # taken for the answer, the copy would read back the goal 0.1: unconfirmed
            m = d.exchange(goal)
            assert m.position is not None
        assert d.stats.stale == 1 and d.stats.unconfirmed == 0


def test_a_goal_lost_on_its_way_is_seen_in_the_read_back_and_never_taken_as_applied(emulator):  # noqa: F811
    with driver_from_url(url(emulator)) as d:
        d.enable()
        held = emulator.servo(1).value(ct.GOAL_POSITION)
        emulator.faults(1).corrupt_goals = 1
        with pytest.raises(CommandUnconfirmed, match=r"holds Goal Position \d+, not the \d+ just written"):
            d.exchange(0.2)
        assert emulator.servo(1).value(ct.GOAL_POSITION) == held and d.stats.unconfirmed == 1
        # the SYNC_WRITE that arrives intact is confirmed
        d.exchange(0.2)
        assert emulator.servo(1).value(ct.GOAL_POSITION) == round(0.2 / RAD) + ct.POSITION_CENTRE
        assert d.stats.unconfirmed == 1


def test_a_corrupted_length_field_is_a_rejected_frame_not_a_driver_error(emulator):  # noqa: F811
    with driver_from_url(url(emulator)) as d:
        d.enable()
        emulator.faults(1).corrupt_lengths = 1
        with pytest.raises(ProtocolError, match="was corrupted") as caught:
            d.exchange(0.1)  # the SDK asked the port for a negative count (Errno 22) before the fix
        assert type(caught.value) is ProtocolError and d.stats.rejected == 1
        assert d.exchange(0.1).position is not None  # the next sample is fine


def test_the_bus_watchdog_stops_a_servo_whose_host_went_silent(emulator, clock):  # noqa: F811
    events: list[str] = []
    emulator.servo(1).on_event = events.append
    with driver_from_url(url(emulator, watchdog=0.1)) as d:
        d.enable()
        d.exchange(0.1)
        assert emulator.servo(1).value(ct.BUS_WATCHDOG) == 5  # 5 x 20 ms, armed with the torque
        clock.advance(0.05)
        d.exchange(0.1)  # a packet feeds it
        clock.advance(0.15)  # then the host is silent (killed): the emulator stops the servo on its own
        deadline = time.monotonic() + 2.0
        while not events and time.monotonic() < deadline:
            time.sleep(0.01)
        assert events == ["servo 1: bus watchdog expired after 150 ms without an instruction: stopped, goals locked"]
        assert emulator.servo(1).value(ct.BUS_WATCHDOG) == -1
        with pytest.raises(DeviceFault, match="Bus Watchdog expired .* locks its goals"):
            d.exchange(0.3)  # the goal is refused (read-only), and the read-back says why
    assert events[-1] == "servo 1: torque off"
    with driver_from_url(url(emulator, watchdog=0)) as d:  # opening clears the expired watchdog
        assert emulator.servo(1).value(ct.BUS_WATCHDOG) == 0
        d.enable()
        d.exchange(0.2)
        assert emulator.servo(1).value(ct.GOAL_POSITION) == round(0.2 / RAD) + ct.POSITION_CENTRE


def test_a_sample_period_the_watchdog_would_outlast_is_refused(emulator):  # noqa: F811
    with driver_from_url(url(emulator, watchdog=0.1)) as d:
        with pytest.raises(ConfigError, match=r"below half the device's watchdog \(0.1 s\)"):
            d.set_sample_period(0.06)
        d.set_sample_period(0.04)


def test_the_busy_flag_is_reset_after_the_sdk_raises(emulator, monkeypatch):  # noqa: F811
    with driver_from_url(url(emulator)) as d:
        d.enable()
        port = d._port
        original = port.readPort

        def fail_once(length):
            monkeypatch.setattr(port, "readPort", original)
            raise OSError(5, "Input/output error")

        monkeypatch.setattr(port, "readPort", fail_once)
        with pytest.raises(DriverError, match="Input/output error"):
            d.exchange(0.1)
        assert not port.is_using
        d.exchange(0.1)  # would return COMM_PORT_BUSY forever if the flag had stayed set


@pytest.mark.timeout(20)
def test_timeouts_do_not_trust_the_wall_clock(emulator, monkeypatch):  # noqa: F811
    with driver_from_url(url(emulator)) as d:
        d.enable()
        emulator.unplug(1)
        frozen = time.time()
        monkeypatch.setattr(time, "time", lambda: frozen)  # with the SDK's own clock this would hang
        with pytest.raises(DriverTimeout, match=f"did not answer .* within {2 * TEST_LATENCY_MS + 2}"):
            d.exchange(0.1)
        monkeypatch.undo()
        emulator.plug(1)


def test_the_driver_refuses_a_second_thread(emulator):  # noqa: F811
    errors = []
    with driver_from_url(url(emulator)) as d:
        d.enable()

        def other():
            try:
                d.exchange(0.1)
            except DriverError as exc:
                errors.append(str(exc))

        thread = threading.Thread(target=other)
        thread.start()
        thread.join()
    assert errors and "not thread-safe" in errors[0]
