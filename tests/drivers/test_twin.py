"""The physical servo twins: presets against the vendors' figures, the physics, the firmware, the interface."""

from __future__ import annotations

import dataclasses
import importlib
import inspect
import math
import re

import numpy as np
import pytest

from servoid.drivers.twin import Twin, TwinParams, TwinPlant, preset, preset_names
from servoid.drivers.twin.figures import measure, no_load_speed
from servoid.drivers.twin.presets import PUBLISHED
from servoid.errors import ConfigError

RPM = 2.0 * math.pi / 60.0


def frictionless(name: str, **more) -> TwinParams:
    """A preset with every friction, damping and gear loss removed (for conservation checks)."""
    return preset(
        name,
        load_coulomb_nm=0,
        load_breakaway_nm=0,
        load_viscous_nms=0,
        gear_damping_nms=0,
        gear_efficiency=1.0,
        motor_coulomb_nm=0,
        motor_breakaway_nm=0,
        motor_viscous_nms=0,
        **more,
    )


def steady_speed(twin: Twin, settle_s: float, window_s: float) -> float:
    """Mean true load speed over a window after settling, rad/s."""
    twin.advance(settle_s)
    start, t0 = twin.physics().load_rad, twin.time_s
    twin.advance(window_s)
    return (twin.physics().load_rad - start) / (twin.time_s - t0)


# --- the vendors' published figures ------------------------------------------------------------


@pytest.mark.parametrize("name", ["xm430", "sts3215"])
def test_no_load_speed_stall_torque_and_resolution_match_the_datasheet(name):
    # XM430-W350: 46 rpm, 4.1 N m at 2.3 A, 4096 pulse/rev (e-manual); STS3215: 0.192 s/60 deg,
    # 19.5 kg cm, 4096 steps (7.4 V). The speed follows from back-EMF, resistance and friction,
    # the torque from the torque constant, the current and the gear's efficiency.
    published = PUBLISHED[name]
    figures = measure(preset(name))
    assert figures.no_load_speed_rpm == pytest.approx(published.no_load_speed_rpm, rel=0.03)
    assert figures.stall_torque_nm == pytest.approx(published.stall_torque_nm, rel=0.05)
    if published.stall_current_a is not None:
        assert figures.stall_current_a == pytest.approx(published.stall_current_a, rel=0.01)
    assert figures.output_cpr == published.output_cpr


def test_the_no_load_speed_runs_at_the_pwm_limit_and_a_wrong_motor_misses_the_datasheet():
    twin = Twin(preset("xm430"))
    twin.enable()
    twin.command(3.0)
    twin.advance(0.3)
    assert twin.counters.saturated_share > 0.9
    weak = preset("xm430", back_emf_v_s=1.1 * preset("xm430").back_emf_v_s)
    assert no_load_speed(weak) * 60 / (2 * math.pi) < 0.95 * PUBLISHED["xm430"].no_load_speed_rpm


@pytest.mark.parametrize("name", preset_names())
def test_output_resolution_is_the_encoders(name):
    twin = Twin(preset(name))
    twin.enable()
    twin.command(0.03)
    twin.advance(0.2)
    r = twin.read()
    step = twin.truth.output_rad_per_count
    assert step == pytest.approx(2 * math.pi / {"xm430": 4096, "sts3215": 4096, "cia402": 2**20, "odrive": 16384}[name])
    assert r.position_rad / step == pytest.approx(round(r.position_rad / step), abs=1e-9)
    # without noise the reading is within half a count of the true angle
    assert abs(r.position_rad - twin.physics().load_rad) <= 0.5 * step + 1e-12 or r.time_s < twin.time_s


def test_odrive_runs_at_its_velocity_limit_and_cia402_at_its_current_limit():
    # ODrive: vel_limit 2 turn/s of the motor (controller.hpp); 8:1 reducer
    odrive = Twin(preset("odrive"))
    odrive.enable()
    odrive.command(1.0)
    assert steady_speed(odrive, 0.15, 0.2) == pytest.approx(2 * 2 * math.pi / 8, rel=0.02)
    assert odrive.read().fault is None
    # EPOS4 50/5: 15 A peak; a large step asks for more and gets exactly the limit
    drive = Twin(preset("cia402"))
    drive.enable()
    drive.command(1.0)
    peak = 0.0
    for _ in range(40):
        drive.advance(0.001)
        peak = max(peak, abs(drive.physics().current_a))
    assert peak == pytest.approx(15.0, rel=0.05)
    assert drive.counters.current_limited_ticks > 10
    # the drives' own position estimates: the ODrive's PLL near its encoder, the EPOS4 its encoder
    r = odrive.read()
    assert r.position_estimate_rad == pytest.approx(r.motor_rad / 8, abs=2 * 2 * math.pi / 8192 / 8)
    r = drive.read()
    assert r.position_estimate_rad == r.motor_rad / 10


# --- physics -----------------------------------------------------------------------------------


def test_a_free_load_coasts_through_the_play_with_its_momentum():
    twin = Twin(frictionless("xm430"))  # torque off: the motor is free too
    twin.place(load_rad=0.0, gear_side_rad=0.0, load_rad_s=0.4)
    half = twin.truth.play_rad / 2
    speeds = []
    while True:
        twin.advance(5e-4)
        ph = twin.physics()
        if ph.load_rad - ph.gear_side_rad >= half:
            break
        speeds.append(ph.load_rad_s)
    assert len(speeds) > 5
    assert np.all(np.array(speeds) == 0.4)  # no torque inside the play: the speed is exactly kept
    twin.advance(0.02)
    ph = twin.physics()
    params = twin.params
    assert ph.motor_rad_s > 0.0  # contact passed momentum to the motor, and none was lost
    momentum = params.load_inertia_kgm2 * ph.load_rad_s + params.motor_inertia_kgm2 * params.gear_ratio * ph.motor_rad_s
    assert momentum == pytest.approx(params.load_inertia_kgm2 * 0.4, rel=1e-9)


def test_contact_keeps_the_energy_without_losses():
    params = frictionless("xm430")
    twin = Twin(params)
    twin.place(load_rad_s=1.0)

    def energy() -> float:
        ph = twin.physics()
        pen = max(0.0, abs(ph.gear_side_rad - ph.load_rad) - params.play_rad / 2)
        return (
            0.5 * params.motor_inertia_kgm2 * ph.motor_rad_s**2
            + 0.5 * params.load_inertia_kgm2 * ph.load_rad_s**2
            + 0.5 * params.gear_stiffness_nm_rad * pen**2
        )

    e0 = energy()
    values = []
    for _ in range(400):
        twin.advance(5e-4)
        values.append(energy())
    assert twin.counters.contact_s > 0.05  # it did bounce against the flanks
    assert np.max(np.abs(np.array(values) / e0 - 1.0)) < 0.02  # symplectic: bounded, no drift


def test_a_stuck_motor_stays_stuck_below_break_away_and_an_integrator_frees_it():
    step = 3 * 2 * math.pi / 4096  # three counts: 2 % duty, below the motor's break-away torque
    factory = Twin(preset("xm430"))
    factory.enable()
    start = factory.physics().motor_rad
    factory.command(step)
    factory.advance(1.0)
    assert factory.physics().motor_rad == start and factory.physics().motor_stuck
    assert factory.read().setpoint_rad == step
    # the same step with an integral gain: the duty grows until the break-away level is passed
    with_i = Twin(preset("xm430", pos_i=400))
    with_i.enable()
    with_i.command(step)
    with_i.advance(1.0)
    assert with_i.physics().motor_rad != start
    # and a larger step (20 counts) moves even the factory gains
    bigger = Twin(preset("xm430"))
    bigger.enable()
    bigger.command(20 * 2 * math.pi / 4096)
    bigger.advance(0.3)
    assert bigger.physics().motor_rad > 0.0


@pytest.mark.parametrize("name", ["xm430", "sts3215"])
def test_reversal_waits_until_the_motor_side_has_crossed_the_play(name):
    twin = Twin(preset(name))
    twin.enable()
    speed = 0.3  # rad/s at the output, a triangle of 0.2 rad
    u = np.r_[np.linspace(0, 0.2, 400), np.linspace(0.2, 0.0, 400)]
    rec = twin.sample(u, 0.2 / speed / 400)
    gear, load = rec.true_gear_side_rad, rec.true_load_rad
    top = int(np.argmax(load))
    leaves = top + int(np.argmax(load[top:] < load[top] - 1e-5))
    crossed = (gear.max() - gear[leaves]) / twin.truth.play_rad
    assert 0.9 < crossed < 1.3
    # so the output stands still for about play / speed after the motor side turns
    dead = rec.t_s[leaves] - rec.t_s[int(np.argmax(gear))]
    assert dead > 0.8 * twin.truth.play_rad / speed


def test_a_held_pendulum_presses_on_the_gear_with_m_g_l_sin_theta():
    # 0.1 kg at 0.1 m, held horizontal by the XM430: the gear carries the link's weight
    twin = Twin(preset("xm430", load_mass_kg=0.1, load_arm_m=0.1))
    twin.enable()
    twin.command(math.pi / 2)
    twin.advance(1.5)
    ph = twin.physics()
    assert ph.load_stuck and abs(ph.load_rad - math.pi / 2) < 0.1
    weight = 0.1 * 9.80665 * 0.1 * math.sin(ph.load_rad)
    assert ph.contact_torque_nm == pytest.approx(weight, abs=preset("xm430").load_breakaway_nm)
    # torque off: back-driven through 353.5:1 at 79 % efficiency, 0.1 N m stays under the motor's
    # break-away and the gear holds the link; ten times the weight back-drives it and it falls
    twin.disable()
    twin.advance(0.3)
    assert twin.physics().load_rad == ph.load_rad
    heavy = Twin(preset("xm430", load_mass_kg=1.0, load_arm_m=0.1))
    heavy.enable()
    heavy.command(math.pi / 2)
    heavy.advance(1.5)
    heavy.disable()
    heavy.advance(0.5)
    assert heavy.physics().load_rad < 1.0


def test_torque_off_cuts_the_current_and_the_motor_coasts():
    twin = Twin(preset("xm430"))
    twin.enable()
    twin.command(1.0)
    twin.advance(0.1)
    moving = twin.physics()
    assert abs(moving.current_a) > 0.1 and moving.motor_rad_s > 0
    twin.disable()
    twin.advance(1e-4)
    ph = twin.physics()
    assert ph.current_a == 0.0 and twin.read().duty == 0.0
    assert ph.motor_rad > moving.motor_rad  # still turning on its own momentum


# --- firmware and host timing ------------------------------------------------------------------


def test_a_command_waits_for_the_next_tick_and_readings_belong_to_ticks():
    twin = Twin(preset("sts3215"))  # 1 kHz firmware
    twin.enable()
    twin.advance(0.0004)
    twin.command(0.1)
    twin.advance(0.0005)  # t = 0.9 ms: no tick since the command
    assert twin.read().setpoint_rad == 0.0 and twin.read().time_s == 0.0
    twin.advance(0.0001)  # t = 1 ms: the tick latches it
    r = twin.read()
    assert r.setpoint_rad == 0.1 and r.time_s == pytest.approx(0.001)
    assert r.duty > 0.0


def test_clipped_set_points_and_the_pwm_limit():
    twin = Twin(preset("xm430"))
    twin.enable()
    twin.command(10.0)  # beyond the Max Position Limit: clipped to half a turn
    twin.advance(0.01)
    assert twin.read().setpoint_rad == pytest.approx(math.pi)
    assert twin.read().duty == 1.0
    limited = Twin(preset("xm430", output_limit=442))  # PWM Limit 442 = 50 %
    limited.enable()
    limited.command(1.0)
    limited.advance(0.05)
    assert limited.read().duty == pytest.approx(442 / 885)
    assert limited.counters.saturated_share > 0.95


def test_odrive_faults_on_overspeed_and_turns_its_output_off():
    # Factory gains, a heavy load behind the play and quick reversals: crossing the play the motor
    # carries none of the load's inertia and overshoots vel_limit x 1.2 (ODrive: ERROR_OVERSPEED).
    twin = Twin(preset("odrive"))
    twin.enable()
    fastest = 0.0
    for u in np.random.default_rng(1).uniform(-0.1, 0.1, 100):
        twin.command(u)
        for _ in range(40):
            twin.advance(0.00025)
            fastest = max(fastest, abs(twin.physics().motor_rad_s))
        if twin.read().fault:
            break
    r = twin.read()
    assert r.fault == "overspeed" and not r.enabled and r.duty == 0.0
    assert fastest > 1.2 * twin.params.vel_limit_rad_s  # a real overspeed, not an estimator's artefact
    twin.advance(0.01)
    assert twin.physics().current_a == 0.0
    twin.enable()  # re-arming clears the error
    assert twin.read().fault is None and twin.read().enabled


def test_noise_is_seeded_and_chunked_runs_equal_one_shot_runs():
    params = preset("xm430", encoder_noise_counts=0.7)
    u = np.random.default_rng(3).uniform(-0.1, 0.1, 60)
    one = Twin(params, seed=5)
    one.enable()
    rec = one.sample(u, 0.003)
    again = Twin(params, seed=5)
    again.enable()
    ys = []
    for v in u:
        ys.append(again.read().position_rad)
        again.command(v)
        again.advance(0.003)
    np.testing.assert_array_equal(rec.y, np.array(ys))
    assert again.physics() == one.physics()
    other = Twin(params, seed=6)
    other.enable()
    assert not np.array_equal(other.sample(u, 0.003).y, rec.y)
    # the plant adapter gives the same outputs, y(k) before u(k) takes effect
    plant = TwinPlant(Twin(params, seed=5), 0.003)
    np.testing.assert_array_equal([plant.step(v) for v in u], rec.y)


def test_wear_changes_the_play_while_running():
    twin = Twin(preset("xm430"))
    twin.enable()
    twin.advance(0.01)
    twin.set_play(math.radians(1.0))
    assert twin.truth.play_rad == pytest.approx(math.radians(1.0))
    assert twin.params.play_rad == pytest.approx(math.radians(0.25))  # as built
    with pytest.raises(ConfigError, match=r"play_rad \(=-0\.1\)"):
        twin.set_play(-0.1)


# --- parameters and presets --------------------------------------------------------------------


def test_every_preset_knows_its_ground_truth():
    for name in preset_names():
        truth = Twin(preset(name)).truth
        assert truth.name == name and truth.play_rad > 0 and truth.gear_ratio > 1
        assert truth.loop_encoder in ("motor", "load") and truth.output_encoder == "load"
        assert "closed on the" in truth.structure
    assert Twin(preset("cia402")).truth.loop_encoder == "motor"
    assert Twin(preset("xm430")).truth.loop_encoder == "load"


def test_overrides_by_human_names_and_text():
    p = preset("xm430", play_deg="0.8", load_inertia_kgm2=1e-3, encoder_noise_counts="0.5", motor_encoder_cpr="0")
    assert p.play_rad == pytest.approx(math.radians(0.8))
    assert p.load_inertia_kgm2 == 1e-3 and p.load_encoder_noise_counts == 0.5
    assert preset("cia402", play_arcmin=3).play_rad == pytest.approx(math.radians(3 / 60))
    assert preset("XM430") is preset("xm430")


@pytest.mark.parametrize(
    "call, message",
    [
        (lambda: preset("xm431"), r"unknown twin preset 'xm431'; valid: xm430, sts3215, cia402, odrive"),
        (lambda: preset("xm430", frobnicate=1), r"unknown twin parameter 'frobnicate'"),
        (lambda: preset("xm430", load_inertia_kgm2=-1e-4), r"load_inertia_kgm2 \(=-0\.0001\) must be > 0"),
        (lambda: preset("xm430", play_deg=400), r"play_rad \(=6\.98.*\) must be smaller than the range range_rad"),
        (lambda: preset("xm430", play_deg="lots"), r"play_deg \(='lots'\) must be a number"),
        (lambda: preset("xm430", gear_efficiency=1.5), r"gear_efficiency \(=1\.5\) must lie in \(0, 1\]"),
        (lambda: preset("xm430", load_encoder_cpr=0), r"loop_encoder \(='load'\) needs a load encoder"),
        (lambda: preset("xm430", firmware="magic"), r"firmware \(='magic'\) must be one of"),
        (lambda: preset("xm430", motor_breakaway_nm=0.0), r"motor_breakaway_nm \(=0\.0\) must be >= motor_coulomb_nm"),
        (
            lambda: preset("xm430", gear_stiffness_nm_rad=1e9),
            r"gear_stiffness_nm_rad \(=1000000000\.0\).*raise substeps",
        ),
        (lambda: preset("cia402", current_rate_hz=3000), r"current_rate_hz \(=3000\.0\) must be a whole multiple"),
    ],
)
def test_bad_parameters_get_one_line_naming_the_value(call, message):
    with pytest.raises(ConfigError, match=message) as info:
        call()
    assert "\n" not in str(info.value)


def test_bad_run_arguments():
    twin = Twin(preset("xm430"))
    with pytest.raises(ConfigError, match=r"dt_s \(=-1\.0\) must be >= 0"):
        twin.advance(-1.0)
    with pytest.raises(ConfigError, match=r"u \(=nan\) must be finite"):
        twin.command(float("nan"))
    with pytest.raises(ConfigError, match=r"period_s \(=0\.0\) must be > 0"):
        twin.sample([0.0, 0.1], 0.0)
    with pytest.raises(ConfigError, match=r"params must be TwinParams"):
        Twin({"name": "xm430"})  # type: ignore[arg-type]


def test_every_public_argument_is_documented():
    mod = importlib.import_module("servoid.drivers.twin")
    for name in mod.__all__:
        obj = getattr(mod, name)
        doc = (
            "\n".join(inspect.getdoc(c) or "" for c in obj.__mro__ if c is not object)
            if inspect.isclass(obj)
            else inspect.getdoc(obj)
        )
        if inspect.isclass(obj):
            params = (
                [f.name for f in dataclasses.fields(obj)]
                if dataclasses.is_dataclass(obj)
                else list(inspect.signature(obj.__init__).parameters)[1:]
            )
        else:
            params = list(inspect.signature(obj).parameters)
        missing = [
            p
            for p in params
            if p not in ("self", "overrides")
            and not re.search(rf"(^|[\s,`(]){re.escape(p)}([\s,`:)]|$)", doc or "", re.M)
        ]
        assert not missing, f"{name}: undocumented {missing}"
