"""The CiA 402 driver against the simulated drive, both on python-can's virtual bus, through canopen.

Known truth: the drive is sample-synchronous, so the positions the driver
reads must equal the bench plant simulated directly on the same inputs, to
within the encoder's increments.
"""

from __future__ import annotations

import math
import time

import numpy as np
import pytest

from servoid.drivers import driver_from_url
from servoid.drivers.can._sim_axis import TORQUE_GAIN
from servoid.drivers.can.cia402 import Cia402Driver
from servoid.drivers.can.sim_cia402 import SIM_COUNTS_PER_REV, SIM_RATED_TORQUE_MNM, SimCia402Drive
from servoid.drivers.model_plant import MODEL_PLANT
from servoid.errors import ConfigError, DeviceFault, DriverTimeout, ProtocolError
from servoid.ident.models.simulate import simulate
from servoid.recording import read_recording

from .can_helpers import (
    PATIENT_S,
    bench_input,
    buses_closed,  # noqa: F401 - autouse fixture
    private_bus,
    recorded_run,
)

COUNT = 2 * math.pi / SIM_COUNTS_PER_REV


@pytest.fixture
def drive():
    with SimCia402Drive(node=1, bus=private_bus(), servo="model") as sim:
        yield sim


def test_positions_follow_the_bench_plant_to_within_an_increment(drive):
    u = bench_input(400, seed=1)
    with driver_from_url(drive.url(timeout=PATIENT_S)) as servo:
        assert isinstance(servo, Cia402Driver) and not drive.power_on
        servo.enable()
        assert drive.nmt_state == "OPERATIONAL" and drive.state == "OPERATION ENABLED" and drive.mode == 8
        y = np.array([servo.exchange(v).position for v in u])
        assert servo.identity["counts_per_rev"] == SIM_COUNTS_PER_REV  # read from 0x608F
        assert servo.identity["device_name"] == "servoid simulated CiA 402 drive"
    # target and actual position are both whole increments: at most an increment apart from the plant
    assert np.max(np.abs(y - simulate(MODEL_PLANT, u).y)) < 2 * COUNT
    assert np.ptp(y) > 0.1
    assert not drive.power_on and drive.state == "SWITCH ON DISABLED" and drive.nmt_state == "PRE-OPERATIONAL"


def test_torque_mode_scales_nm_by_the_rated_torque(drive):
    u = bench_input(300, seed=2)  # Nm
    with driver_from_url(drive.url(mode="torque", timeout=PATIENT_S)) as servo:
        servo.enable()
        assert drive.mode == 10
        assert servo.command_unit.unit == "Nm" and servo.identity["rated_torque_mNm"] == SIM_RATED_TORQUE_MNM
        y = np.array([servo.exchange(v).position for v in u])
    per_mille = np.round(u / (SIM_RATED_TORQUE_MNM / 1e6))  # what 0x6071 carries
    torque = per_mille * SIM_RATED_TORQUE_MNM / 1e6
    assert np.max(np.abs(y - simulate(MODEL_PLANT, TORQUE_GAIN * torque).y)) < COUNT


def test_counts_per_rev_from_the_url_override_the_drive(drive):
    with driver_from_url(drive.url(counts_per_rev=SIM_COUNTS_PER_REV // 2)) as servo:
        servo.enable()
        m = [servo.exchange(0.15) for _ in range(30)][-1]
    # the driver believes in half the increments per turn: the drive turns half as far (less the
    # backlash c1 on the way up), and the driver reads its increments as twice the angle
    assert drive.axis.position == pytest.approx(0.15 / 2 - MODEL_PLANT.c1, abs=1e-4)
    assert m.position == pytest.approx(2 * drive.axis.position, abs=2 * COUNT)


def test_emcy_becomes_a_device_fault_and_the_recording_is_kept(drive, tmp_path):
    path = tmp_path / "run.csv"
    with driver_from_url(drive.url()) as servo:
        servo.enable()
        with pytest.raises(DeviceFault, match=r"node 1 .*reported EMCY 0x2310 \(current\).*state FAULT"):
            recorded_run(servo, bench_input(100, seed=3), path, at=40, event=drive.inject_fault)
    assert drive.state == "FAULT" and not drive.power_on
    assert len(read_recording(path)) == 40


def test_enabling_a_faulted_drive_needs_a_fault_reset(drive):
    with driver_from_url(drive.url()) as servo:
        servo.enable()
        drive.inject_fault(code=0x4310)  # over-temperature
        with pytest.raises(DeviceFault):
            servo.exchange(0.0)
    with driver_from_url(drive.url()) as servo:
        with pytest.raises(DeviceFault, match=r"in FAULT \(error code 0x603F = 0x4310.*temperature.*fault_reset=1"):
            servo.enable()
    with driver_from_url(drive.url(fault_reset=1)) as servo:
        servo.enable()
        assert drive.state == "OPERATION ENABLED" and drive.error_code == 0
        servo.exchange(0.01)


@pytest.mark.parametrize("state", ["SWITCH ON DISABLED", "QUICK STOP ACTIVE"])
def test_leaving_operation_enabled_is_a_device_fault_and_torque_ends_off(drive, tmp_path, state):
    path = tmp_path / "run.csv"
    with driver_from_url(drive.url()) as servo:
        servo.enable()
        with pytest.raises(DeviceFault, match=f"left Operation Enabled: statusword 0x[0-9A-F]{{4}} = {state}"):
            recorded_run(servo, bench_input(60, seed=4), path, at=25, event=lambda: drive.drop_out(state))
    assert not drive.power_on and drive.state == "SWITCH ON DISABLED"
    assert len(read_recording(path)) == 25


def test_a_missing_node_is_a_timeout_naming_it(drive):
    url = drive.bus.url("cia402", 5)
    with pytest.raises(DriverTimeout, match=r"node 5 on virtual test-\w+ does not answer .*node=5"):
        driver_from_url(url).open()


def test_a_device_of_another_profile_is_refused():
    with SimCia402Drive(node=2, bus=private_bus(), device_type=0x191) as sim:  # CiA 401, I/O module
        with pytest.raises(ProtocolError, match=r"not a CiA 402 drive: device type 0x00000191"):
            driver_from_url(sim.url()).open()


def test_commands_outside_the_drive_range_are_refused_before_sending(drive):
    with driver_from_url(drive.url()) as servo:
        servo.enable()
        with pytest.raises(ConfigError, match="outside the drive's range.*min/max"):
            servo.exchange(1e6)  # rad: ~2e10 increments, beyond INTEGER32
        assert drive.power_on  # nothing was sent


def test_the_sync_counter_tells_the_drive_how_many_cycles_passed(drive):
    """Slots the host skipped are SYNCs that never came: the drive runs them on the held target.

    The counter (0x1019 = 240) wraps; a gap of 299 slots is told from 59 by the
    cycle period (0x1006) the driver wrote and the time that passed.
    """
    slots = [0, 1, 4, 5, 304, 305]
    u = bench_input(len(slots), seed=5)
    with driver_from_url(drive.url(timeout=PATIENT_S)) as servo:
        assert drive.counter_overflow == 240
        servo.set_sample_period(0.001)
        assert drive.axis.sampled.period_ns == 1_000_000
        servo.enable()
        y = []
        for slot, value in zip(slots, u):
            if slot == 304:
                time.sleep(0.299)  # 299 cycles of 1 ms since slot 5, give or take the host's timing
            y.append(servo.exchange(value, slot=slot).position)
    held = np.repeat(u, np.diff(slots, append=slots[-1] + 1))  # the target each cycle had
    expected = simulate(MODEL_PLANT, held).y[np.array(slots) - slots[0]]
    assert np.max(np.abs(np.array(y) - expected)) < 2 * COUNT
    assert drive.axis.steps == 1 + slots[-1] + 1  # the enable cycle, then one per slot 0..305


def test_the_drive_switches_off_when_the_host_heartbeat_stops(drive):
    events: list[str] = []
    drive.on_event = events.append
    with driver_from_url(drive.url(timeout=PATIENT_S, watchdog=0.1)) as servo:
        servo.enable()
        servo.exchange(0.01)
        time.sleep(0.3)  # the heartbeat keeps it on while the host is alive, whatever the sample rate
        assert drive.power_on and not events and drive.abort_option == 2
        servo._heartbeat.stop()  # the host dies (its heartbeat thread with it)
        stopped = time.monotonic()
        while drive.power_on and time.monotonic() - stopped < 2.0:
            time.sleep(0.002)
        assert not drive.power_on and time.monotonic() - stopped < 0.1 + 0.1
        assert events[0] == "node 1: power stage off (SWITCH ON DISABLED)"
        assert events[1].startswith("node 1: heartbeat of node 127 lost (none for 1")
        servo._heartbeat = None
    with driver_from_url(drive.url(timeout=PATIENT_S, watchdog=0.1)) as servo:
        servo.enable()  # no fault to reset: 0x6007 was "disable voltage"
        servo.exchange(0.01)
    time.sleep(0.3)  # an orderly close switched the consumer off first: no loss reported
    assert not any("lost" in e for e in events[2:])


def test_the_watchdog_options_are_checked():
    with pytest.raises(ConfigError, match=r"host_node \(=1\) must differ from the drive's node"):
        driver_from_url("can://virtual/x?protocol=cia402&node=1&host_node=1")
    with pytest.raises(ConfigError, match=r"option watchdog='70' is invalid"):
        driver_from_url("can://virtual/x?protocol=cia402&watchdog=70")
    assert driver_from_url("can://virtual/x?protocol=cia402&watchdog=0").watchdog_s is None


@pytest.mark.parametrize(("options", "side"), [({}, "output"), ({"readings": "motor"}, "motor")])
def test_the_url_says_which_shaft_the_position_is_of_and_the_identity_records_it(drive, options, side):
    # the emulator reads its output (as a load encoder would); a drive whose 0x6064 is the motor's is told by the URL
    with driver_from_url(drive.url(**options)) as servo:
        assert servo.readings_side == side
        assert servo.identity["readings"] == side
        assert servo.identity["device_name"] == "servoid simulated CiA 402 drive"  # the drive's own, read at open


def test_another_side_is_refused_in_one_line_naming_it():
    with pytest.raises(ConfigError, match=r"^readings \(='load'\) must be one of output, motor$"):
        driver_from_url("can://virtual/x?protocol=cia402&node=1&readings=load")
