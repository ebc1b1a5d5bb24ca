"""Twins behind the emulators: each protocol reports the twin in its vendor's units, and says what the twin did.

Every emulator defaults to the twin of its transport (Dynamixel: xm430,
CiA 402: cia402, ODrive: odrive); the contract tests hold their readings
against the Python twin sample for sample. Here: the units and registers
of each protocol, the encoders a CiA 402 drive reports, the modes a twin can
and cannot run, and the faults it raises.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from servoid.drivers import driver_from_url
from servoid.drivers.can.sim_cia402 import SimCia402Drive
from servoid.drivers.can.sim_odrive import SimOdriveAxis
from servoid.drivers.dynamixel import control_table as ct
from servoid.drivers.dynamixel.emulator import DynamixelEmulator
from servoid.drivers.twin import preset
from servoid.errors import ConfigError, DeviceFault, ProtocolError

from .can_helpers import (
    PATIENT_S,
    buses_closed,  # noqa: F401 - autouse fixture
    private_bus,
)

PERIOD_S = 0.005


def run(url: str, u, *, period_s: float = PERIOD_S) -> tuple[dict, list[float]]:
    """The driver's identity and the positions it read for the commands ``u``."""
    with driver_from_url(url) as servo:
        servo.set_sample_period(period_s)
        servo.enable()
        return servo.identity, [servo.exchange(v).position for v in u]


def test_the_cia402_twin_reports_its_load_encoder_in_0x60e4_and_its_motor_encoder_in_0x6064():
    twin = preset("cia402")
    with SimCia402Drive(node=1, bus=private_bus()) as drive:
        load, y = run(drive.url(timeout=PATIENT_S), [0.05] * 60)
        reading = drive.axis.reading
        assert load["encoder"].startswith("additional") and load["gear_ratio"] == 10.0
        assert y[-1] == pytest.approx(reading.load_counts * 2 * math.pi / twin.load_encoder_cpr, abs=1e-12)
        main, y_main = run(drive.url(timeout=PATIENT_S, encoder="main"), [0.05] * 60)
        reading = drive.axis.reading
        motor_rad = reading.motor_counts * 2 * math.pi / twin.motor_encoder_cpr
        assert y_main[-1] == pytest.approx(motor_rad / twin.gear_ratio, abs=1e-12)  # both in output rad
        assert main["encoder"] == "position actual value (0x6064)"
    # the loop closes on the motor: the motor side is where it was told, the load short of it inside the play
    assert y_main[-1] == pytest.approx(0.05, abs=2e-5) and 0 < y_main[-1] - y[-1] < twin.play_rad


def test_a_drive_without_a_second_encoder_is_read_on_its_main_one_and_asking_for_one_is_an_error():
    with SimCia402Drive(node=1, bus=private_bus(), servo="model") as drive:
        with pytest.raises(ConfigError, match=r"has no additional position actual value \(0x60E4\).*encoder=main"):
            driver_from_url(drive.url(encoder="additional")).open()
    with pytest.raises(ConfigError, match="counts_per_rev .* the twin 'cia402' has its own"):
        SimCia402Drive(node=1, bus=private_bus(), counts_per_rev=4096)


def test_torque_mode_runs_a_cascade_twins_current_loop_and_a_pid_twin_refuses_it():
    with SimCia402Drive(node=1, bus=private_bus()) as drive:
        _, y = run(drive.url(timeout=PATIENT_S, mode="torque"), [0.5] * 40)
        assert drive.axis.twin.twin.mode == "torque" and drive.axis.reading.current_a > 0 and y[-1] > 0.01
    with SimCia402Drive(node=1, bus=private_bus(), servo="xm430") as drive:
        with pytest.raises(ConfigError, match="does not support cyclic synchronous torque mode"):
            driver_from_url(drive.url(mode="torque")).open()
    with SimOdriveAxis(node=3, bus=private_bus(), servo="xm430") as axis:
        with pytest.raises(DeviceFault, match="BAD_CONFIG"):
            run(axis.url(timeout=PATIENT_S, mode="torque"), [0.1])


def test_the_odrive_twin_counts_motor_turns_from_its_pll_and_an_overspeed_disarms_it():
    twin = preset("odrive")
    with SimOdriveAxis(node=3, bus=private_bus(), period_s=PERIOD_S) as axis:
        _, y = run(axis.url(timeout=PATIENT_S), [0.4] * 100)  # motor rad: 0.05 rad at the output
        reading = axis.axis.reading
        assert y[-1] == pytest.approx(reading.position_estimate_rad * twin.gear_ratio, abs=1e-6)
        assert reading.load_rad == pytest.approx(0.05, abs=twin.play_rad)
    with SimOdriveAxis(node=3, bus=private_bus(), period_s=PERIOD_S) as axis:
        events: list[str] = []
        axis.on_event = events.append
        # the ODrive's default gains: quick reversals of 1.6 rad at the output spin the motor past 1.2 x vel_limit
        with pytest.raises(DeviceFault, match=r"VELOCITY_LIMIT_VIOLATION"):
            run(axis.url(timeout=PATIENT_S), np.random.default_rng(1).uniform(-1.6, 1.6, 200))
        assert not axis.power_on
        # the board says so as it says a watchdog's disarming: the cause, then the power stage going off
        assert "overspeed" in events[0] and events[1] == "node 3: power stage off (IDLE)"


def test_the_dynamixel_twin_shows_its_registers_in_control_table_units():
    with DynamixelEmulator(ids=[1], return_delay_us=0, period_s=PERIOD_S) as emu:
        _, y = run(emu.url(1), [0.5] * 12)  # on its way, at full PWM
        servo = emu.servo(1)
        r = servo.plant.twin.reading
        assert servo.value(ct.PRESENT_POSITION) == r.load_counts + 2048
        assert servo.value(ct.PRESENT_VELOCITY) == round(r.velocity_rad_s / ct.RAD_PER_S_PER_VELOCITY_UNIT) > 100
        assert servo.value(ct.PRESENT_CURRENT) == round(r.current_a / ct.AMPERE_PER_UNIT) > 0
        assert servo.value(ct.PRESENT_PWM) == round(r.duty * 885) == 885
        assert servo.value(ct.MOVING) == 1
        with pytest.raises(ProtocolError, match=r"refused the WRITE of Operating Mode\(11\) = 16: data range"):
            driver_from_url(emu.url(1, mode="pwm")).open()


@pytest.mark.parametrize("kind", ["serial", "can", "dxl"])
@pytest.mark.parametrize(
    ("servo", "message"),
    [
        ("xm431", "unknown servo 'xm431'; valid: xm430, sts3215, cia402, odrive, model, paper, gear"),
        ("xm430?play_degs=1", "unknown twin parameter(s) play_degs for servo 'xm430'; valid: "),
        ("model?play_deg=1", "servo 'model' is the pseudo-Wiener plant and takes no parameters"),
        ("xm430?play_deg=400", "play_rad (=6.98"),
    ],
)
def test_every_emulator_refuses_a_bad_servo_in_one_line(kind, servo, message, capsys):
    from servoid.cli import main

    argv = ["emulate", kind, "--servo", servo] + (["--interface", "udp_multicast"] if kind == "can" else [])
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1 and "Traceback" not in err


def test_a_twin_that_faults_behind_the_dynamixel_protocol_raises_its_hardware_error():
    events: list[str] = []
    with DynamixelEmulator(
        ids=[1], return_delay_us=0, period_s=PERIOD_S, servo="odrive", on_event=events.append
    ) as emu:
        with pytest.raises(DeviceFault, match="overload"):
            run(emu.url(1), np.random.default_rng(1).uniform(-1.6, 1.6, 200))
        assert not emu.servo(1).torque and emu.servo(1).value(ct.HARDWARE_ERROR_STATUS) == ct.HardwareError.OVERLOAD
    assert "Overload Error" in events[0] and events[1] == "servo 1: torque off"  # reported as the watchdog's are
