"""The ODrive CAN Simple driver against the simulated axis, both on python-can's virtual bus.

Known truth: the axis is sample-synchronous, so the positions read back must
equal the bench plant simulated directly (to float32 precision of turns).
"""

from __future__ import annotations

import json
import math
import time

import numpy as np
import pytest

from servoid.drivers import driver_from_url
from servoid.drivers.can import odrive_protocol as proto
from servoid.drivers.can._sim_axis import TORQUE_GAIN
from servoid.drivers.can.odrive import OdriveDriver
from servoid.drivers.can.sim_odrive import SimOdriveAxis
from servoid.drivers.model_plant import MODEL_PLANT
from servoid.errors import ConfigError, DeviceFault, DriverTimeout
from servoid.ident.models.simulate import simulate
from servoid.recording import read_recording

from .can_helpers import (
    PATIENT_S,
    bench_input,
    buses_closed,  # noqa: F401 - autouse fixture
    private_bus,
    recorded_run,
)

FLOAT32_TURN = 2 * math.pi * 2.0**-22  # resolution of a float32 position near one turn, rad


@pytest.fixture
def axis():
    with SimOdriveAxis(node=3, bus=private_bus(), servo="model") as sim:
        yield sim


@pytest.mark.parametrize("mode", ["position", "torque"])
def test_positions_follow_the_bench_plant(axis, mode):
    u = bench_input(400, seed=11)
    with driver_from_url(axis.url(mode=mode, timeout=PATIENT_S)) as servo:
        assert isinstance(servo, OdriveDriver) and not axis.power_on
        servo.enable()
        assert axis.power_on and axis.control_mode == proto.CONTROL_MODES[mode]
        y = np.array([servo.exchange(v).position for v in u])
        assert servo.identity["firmware_version"] == "0.6.10"
    gain = TORQUE_GAIN if mode == "torque" else 1.0
    assert np.max(np.abs(y - simulate(MODEL_PLANT, gain * u).y)) < FLOAT32_TURN
    assert np.ptp(y) > 0.1
    assert axis.axis_state == proto.IDLE


def test_an_axis_error_is_a_device_fault_naming_it_and_the_recording_is_kept(axis, tmp_path):
    path = tmp_path / "run.csv"
    with driver_from_url(axis.url()) as servo:
        servo.enable()
        with pytest.raises(DeviceFault, match=r"ODrive node 3 .*axis error 0x00001000 \(CURRENT_LIMIT_VIOLATION\), "
                                              r"axis state IDLE; active errors 0x00001000"):  # fmt: skip
            recorded_run(servo, bench_input(80, seed=12), path, at=35, event=axis.inject_axis_error)
        with pytest.raises(DeviceFault, match="CURRENT_LIMIT_VIOLATION"):  # and it stays an error
            servo.exchange(0.0)
    assert not axis.power_on and axis.axis_error == 0x1000
    assert len(read_recording(path)) == 35


def test_enable_refuses_an_axis_with_an_error(axis):
    axis.inject_axis_error(0x200)  # DC_BUS_UNDER_VOLTAGE, taken with the next input (enable sends one)
    with driver_from_url(axis.url()) as servo:
        for _ in range(2):  # the second time from the heartbeat already seen, before sending anything
            with pytest.raises(DeviceFault, match="DC_BUS_UNDER_VOLTAGE"):
                servo.enable()
            assert not axis.power_on


def test_a_missing_node_is_a_timeout_naming_it(axis):
    with pytest.raises(DriverTimeout, match=r"ODrive node 4 on virtual test-\w+ does not answer.*node=4"):
        driver_from_url(axis.bus.url("odrive", 4)).open()


def test_velocity_is_reported_in_rad_per_second(axis):
    with driver_from_url(axis.url()) as servo:
        servo.enable()
        ms = [servo.exchange(0.1) for _ in range(3)]
    # the simulated axis differentiates over wall-clock time: the sign and the unit are what can be checked
    assert ms[-1].velocity == pytest.approx(axis.axis.velocity, rel=1e-6) and ms[-1].velocity > 0


def test_on_its_own_clock_the_axis_holds_the_input_between_samples():
    """With a period, silence is samples on the held input, counted by the axis's clock (CAN Simple has no count)."""
    period = 0.05  # long, so that the host's timing is far inside half a period
    u = bench_input(4, seed=13)
    with SimOdriveAxis(node=3, bus=private_bus(), period_s=period, servo="model") as axis:
        with driver_from_url(axis.url(timeout=PATIENT_S)) as servo:
            servo.enable()
            start = time.perf_counter()
            y = []
            for k, at in enumerate((0.0, 1.0, 4.0, 5.0)):  # periods after the first input
                time.sleep(max(start + at * period - time.perf_counter(), 0.0))
                y.append(servo.exchange(u[k]).position)
            assert axis.axis.steps == 6
    held = np.repeat(u, [1, 3, 1, 1])  # 2 samples on u[1] held before u[2]
    expected = simulate(MODEL_PLANT, held).y
    assert np.max(np.abs(np.array(y) - expected[[0, 1, 4, 5]])) < FLOAT32_TURN


def test_the_axis_watchdog_disarms_an_axis_whose_host_went_silent(tmp_path):
    endpoints = tmp_path / "flat_endpoints.json"
    endpoints.write_text(json.dumps(SimOdriveAxis.flat_endpoints()))
    with SimOdriveAxis(node=3, bus=private_bus()) as axis:
        events: list[str] = []
        axis.on_event = events.append
        url = axis.url(timeout=PATIENT_S, watchdog=0.1, endpoints=str(endpoints))
        with driver_from_url(url) as servo:
            assert axis.enable_watchdog and axis.watchdog_timeout == pytest.approx(0.1) and servo.watchdog_s == 0.1
            servo.enable()
            for _ in range(5):  # every frame feeds it: an exchange every 50 ms keeps the axis armed
                servo.exchange(0.01)
                time.sleep(0.05)
            assert axis.power_on and not events
            silent = time.monotonic()  # then the host dies
            while axis.power_on and time.monotonic() - silent < 2.0:
                time.sleep(0.002)
            assert not axis.power_on and time.monotonic() - silent < 0.1 + 0.1
            assert events[0].startswith("node 3: axis watchdog expired") and "power stage off" in events[1]
            with pytest.raises(DeviceFault, match="WATCHDOG_TIMER_EXPIRED"):
                servo.exchange(0.01)
        with driver_from_url(axis.url(timeout=PATIENT_S)) as servo:
            servo.enable()  # what the dead host left, the watchdog's own error, is cleared
            servo.exchange(0.01)
            assert axis.power_on and not axis.axis_error


def test_the_watchdog_needs_the_board_s_endpoints(tmp_path):
    with pytest.raises(ConfigError, match=r"watchdog \(=0.5\) needs endpoints="):
        driver_from_url("can://virtual/x?protocol=odrive&node=3&watchdog=0.5")
    wrong = tmp_path / "e.json"
    wrong.write_text(json.dumps({"fw_version": "0.5.6", "endpoints": {}}))
    with pytest.raises(ConfigError, match=r"must be an ODrive flat_endpoints.json"):
        driver_from_url(f"can://virtual/x?protocol=odrive&node=3&watchdog=0.5&endpoints={wrong}")


@pytest.mark.parametrize(("servo", "side"), [("odrive", "motor"), ("odrive?loop_encoder=load", "output"),
                                             ("model", "output")])  # fmt: skip
def test_the_axis_url_says_which_shaft_its_estimates_are_of_and_the_driver_records_it(servo, side):
    # a twin's loop on its motor encoder: Get_Encoder_Estimates is the motor's, the play lies beyond it
    with SimOdriveAxis(node=3, bus=private_bus(), servo=servo) as sim, driver_from_url(sim.url()) as driver:
        assert f"readings={side}" in sim.url()
        assert driver.readings_side == side and driver.identity["readings"] == side


def test_the_driver_reads_the_motor_unless_told_and_refuses_another_side():
    assert OdriveDriver(interface="virtual", channel="x").readings_side == "motor"
    assert OdriveDriver(interface="virtual", channel="x", readings="output").readings_side == "output"
    with pytest.raises(ConfigError, match=r"readings \(='load'\) must be one of output, motor"):
        OdriveDriver(interface="virtual", channel="x", readings="load")
