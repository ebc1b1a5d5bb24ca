"""What every driver promises, run over every transport of ``contract.TRANSPORTS``.

The serial entries run the real pyserial driver against the compiled firmware
on a pseudo-terminal, in real time; the simulated servo runs in virtual time.
Every device runs a physical twin; every reading is held against the same
twin stepped here on the recorded commands. Fault tests skip a transport
that cannot inject the fault.
"""

from __future__ import annotations

import math
import time

import numpy as np
import pytest

from servoid.drivers import Limits, driver_from_url
from servoid.drivers.clock import MonotonicClock
from servoid.errors import ConfigError, DeviceRestarted, DriverError, DriverTimeout
from servoid.recording import read_recording
from servoid.session import SessionConfig, run_session

from .contract import RATE_HZ, TRANSPORTS, Faults, Transport


@pytest.fixture(params=TRANSPORTS, ids=lambda t: t.name)
def transport(request: pytest.FixtureRequest) -> Transport:
    return request.param


def needs(transport: Transport, fault: str) -> None:
    if fault not in transport.faults:
        pytest.skip(f"{transport.name}: {transport.cannot.get(fault, f'cannot inject {fault}')}")


def excitation(n: int, amplitude: float = 0.1, seed: int = 0) -> np.ndarray:
    return np.random.default_rng(seed).uniform(-amplitude, amplitude, n)


def stall_at(driver, slot: int, periods: float):
    """A command filter that stalls the host for ``periods`` at one slot (forcing missed slots)."""
    clock = getattr(driver, "clock", None) or MonotonicClock()
    calls = iter(range(10**9))

    def command(reference: float) -> float:
        if next(calls) == slot:
            clock.sleep_ns(int(periods / RATE_HZ * 1e9))
        return reference

    return command


def assert_follows_plant(transport: Transport, result, *, after: int | None = None) -> None:
    """Every measured position equals the twin driven by the recorded commands (up to the encoder)."""
    y_plant = transport.expected(result.u)
    measured = np.isfinite(result.y)
    if after is not None:
        measured[after:] = False
    tolerance = 2 * transport.resolution + 1e-12
    worst = np.max(np.abs(result.y[measured] - y_plant[measured]))
    assert worst <= tolerance, f"a reading differs from the plant by {worst:.3g}"


def test_life_cycle_and_torque(transport):
    with transport.open_servo(Faults(), None) as servo:
        with pytest.raises(DriverError, match="not open"):
            servo.exchange(0.0)
        servo.open()
        assert servo.identity.get("driver") == servo.scheme
        with pytest.raises(DriverError):
            servo.exchange(0.01)  # torque off: refused, never silently ignored
        servo.enable()
        m = servo.exchange(0.01)
        assert math.isfinite(m.position) and servo.torque_enabled
        servo.close()
        servo.close()  # idempotent
        assert not servo.is_open and not servo.torque_enabled


def test_readings_follow_the_plant_sample_by_sample_through_missed_slots(transport):
    with transport.open_servo(Faults(), None) as servo:
        servo.open()
        result = run_session(servo, excitation(400), SessionConfig(period_s=1 / RATE_HZ),
                             command_filter=stall_at(servo, 150, 3.3))  # fmt: skip
    counts = result.counts
    assert counts["missed"] >= 2, counts  # the stall skipped slots rather than bursting them out
    assert len(result) == 400 and not servo.torque_enabled
    t, t_actual = result.t, result.t_actual
    on_time = result.status == "ok"
    assert np.all(t_actual[on_time] >= t[on_time] - 1e-9) and np.all(t_actual[on_time] - t[on_time] < 0.5 / RATE_HZ)
    assert_follows_plant(transport, result)
    if transport.virtual_time:
        # slot 150 stalls 3.3 periods: it is late, 151 and 152 are skipped, 153 is late by 0.3 periods
        assert counts == {"ok": 396, "late": 2, "missed": 2, "timeout": 0}
        assert list(result.status[150:154]) == ["late", "missed", "missed", "late"]


def test_commands_outside_the_limits_are_clamped_before_they_reach_the_servo(transport):
    limits = Limits(minimum=-0.05, maximum=0.05, max_step=0.02)
    with transport.open_servo(Faults(), limits) as servo:
        servo.open()
        result = run_session(servo, excitation(200), SessionConfig(period_s=1 / RATE_HZ))
        assert servo.stats.clamped > 50
    assert np.max(np.abs(result.u)) <= 0.05 + 1e-12
    assert np.max(np.abs(np.diff(result.u[np.isfinite(result.t_actual)]))) <= 0.04 + 1e-12
    # the servo moved as the clamped commands say: the requested ones never reached it
    assert_follows_plant(transport, result)


def test_unknown_url_options_are_rejected_by_name(transport):
    with pytest.raises(ConfigError, match="unknown option.*bogus"):
        driver_from_url(transport.bad_url)


def test_a_servo_that_stops_answering_times_out_and_keeps_the_recording(transport, tmp_path):
    needs(transport, "mute_after")
    path = tmp_path / "rec.csv"
    with transport.open_servo(Faults(mute_after=60, timeout=0.02), None) as servo:
        servo.open()
        with pytest.raises(DriverTimeout, match="stopped answering") as info:
            run_session(servo, excitation(1000), SessionConfig(period_s=1 / RATE_HZ, give_up_after_s=0.15),
                        recording=path)  # fmt: skip
    partial = info.value.partial
    assert str(path) in str(info.value)
    rec = read_recording(path)
    assert len(rec) == len(partial) >= 50
    assert np.isfinite(rec.y).sum() >= 45 and rec.status[-1] == "timeout"
    np.testing.assert_array_equal(rec.y, partial.y)
    assert_follows_plant(transport, partial)


def test_a_restart_mid_run_is_detected(transport, tmp_path):
    needs(transport, "restart_after")
    path = tmp_path / "rec.csv"
    with transport.open_servo(Faults(restart_after=80), None) as servo:
        servo.open()
        with pytest.raises(DeviceRestarted, match="restarted") as info:
            run_session(servo, excitation(1000), SessionConfig(period_s=1 / RATE_HZ), recording=path)
    rec = read_recording(path)
    sent = int(np.sum(rec.status != "missed"))
    assert 60 <= sent <= 80 and len(rec) == len(info.value.partial)
    assert_follows_plant(transport, info.value.partial)


def test_lost_replies_are_timeouts_and_the_run_goes_on(transport):
    needs(transport, "drop")
    with transport.open_servo(Faults(drop=0.03, seed=2, timeout=0.02), None) as servo:
        servo.open()
        result = run_session(servo, excitation(600), SessionConfig(period_s=1 / RATE_HZ))
        assert servo.stats.timeouts == result.counts["timeout"]
    assert 3 <= result.counts["timeout"] <= 100 and len(result) == 600
    assert_follows_plant(transport, result)  # a lost reply's command still reached the servo


def test_corrupted_bytes_are_rejected_and_counted_never_accepted(transport, tmp_path):
    needs(transport, "flip")
    trace = tmp_path / "sent.txt"
    with transport.open_servo(Faults(flip=0.004, seed=5, trace=trace, timeout=0.01), None) as servo:
        servo.open()
        to_native = servo.position_unit.to_native
        result = run_session(servo, excitation(1500), SessionConfig(period_s=1 / RATE_HZ, give_up_after_s=2.0))
        rejected = servo.stats.rejected
    time.sleep(0.05)
    sent = transport.sent_readings(trace)
    measured = np.isfinite(result.y)
    # a device without a clock (Feetech) traces its readings with time 0
    accepted = {(round(t * 1e6) if math.isfinite(t) else 0, round(to_native(y)))
                for t, y in zip(result.device_time[measured], result.y[measured])}  # fmt: skip
    assert rejected > 0 and result.counts["timeout"] > 0
    assert accepted <= sent, f"{len(accepted - sent)} readings were accepted that the firmware never sent"
    # without a device clock only the positions tell readings apart: fewer distinct ones, as many measured
    assert len(accepted) > 300 or (np.all(np.isnan(result.device_time)) and measured.sum() > 300)
