"""The simulated servo: the sampled plant's timing rules, the sim:// driver's options, twins behind it."""

from __future__ import annotations

import numpy as np
import pytest

from servoid.drivers import driver_from_url
from servoid.drivers.clock import VirtualClock
from servoid.drivers.model_plant import MODEL_PLANT
from servoid.drivers.sampled import SampledPlant
from servoid.drivers.sim import SimDriver, reference_output_std
from servoid.drivers.twin import Twin, TwinPlant, preset
from servoid.errors import ConfigError, DeviceFault, DriverError
from servoid.ident import PAPER_PLANT, Plant

MS = 1_000_000


def test_each_command_is_one_sample_and_silence_holds_the_last_one():
    sampled, ref = SampledPlant(MODEL_PLANT, period_ns=MS), Plant(MODEL_PLANT)
    sampled.enable()
    # commands at 0, 1.3, 2.2 ms are one sample each (jitter < half a period); at 4.6 ms
    # two periods passed (nearest): one sample on the held command first
    for t, u in ((0, 0.1), (1.3, 0.2), (2.2, -0.1)):
        assert sampled.command(u, int(t * MS)).position == ref.step(u)
    got = sampled.command(0.3, int(4.6 * MS))
    ref.step(-0.1)
    assert got.position == ref.step(0.3) and got.index == 4
    # the host's own count of periods wins over the clock
    got = sampled.command(0.0, int(4.7 * MS), periods=3)
    ref.step(0.3), ref.step(0.3)
    assert got.position == ref.step(0.0) and got.index == 7
    # a read runs the held samples due up to its time
    assert sampled.read(int(7.8 * MS)).index == 10


def test_slot_numbers_and_a_wrapping_counter_say_how_many_samples_passed():
    by_slot, by_counter = SampledPlant(MODEL_PLANT), SampledPlant(MODEL_PLANT, period_ns=MS, slot_modulus=4)
    ref, ref_u = Plant(MODEL_PLANT), 0.0
    for plant in (by_slot, by_counter):
        plant.enable()
    # slots 0, 1, 4, 13 at times that say nothing (all at 0 ns, or one period apart): the slots decide;
    # the counter (slot mod 4) wraps, and its 9-period gap 1 -> 1 is told from 1 or 5 by the time
    for slot, u in ((0, 0.1), (1, 0.2), (4, -0.1), (13, 0.15)):
        held = {0: 0, 1: 0, 4: 2, 13: 8}[slot]
        for _ in range(held):
            ref.step(ref_u)
        expected = ref.step(u)
        ref_u = u
        assert by_slot.command(u, 0, slot=slot).position == expected
        assert by_counter.command(u, slot * MS + 200_000, slot=slot % 4).position == expected
    assert by_slot.index == by_counter.index == 13
    assert by_slot.command(0.0, 0, slot=13).index == 14  # a device cannot refuse a sample: a repeat is the next
    by_slot.disable(), by_slot.enable()
    assert by_slot.command(0.0, 0, slot=3).index == 15  # the count starts afresh when the torque comes back


def test_torque_off_freezes_the_plant_and_refuses_commands():
    sampled = SampledPlant(MODEL_PLANT, period_ns=MS)
    with pytest.raises(DriverError, match="torque is off"):
        sampled.command(0.1, 0)
    sampled.enable()
    sampled.command(0.2, 0)
    sampled.command(0.2, MS)
    sampled.disable()
    assert sampled.read(50 * MS).index == 1


def test_latency_moves_the_virtual_clock_and_the_run_repeats_exactly():
    def run() -> tuple[list[float], int]:
        servo = SimDriver(servo="model", clock=VirtualClock(), latency=200e-6, jitter=100e-6, noise=0.001, seed=4)
        with servo:
            servo.enable()
            ys = [servo.exchange(u).position for u in np.linspace(-0.2, 0.2, 50)]
            return ys, servo.clock.now_ns()

    (ys1, t1), (ys2, t2) = run(), run()
    assert ys1 == ys2 and t1 == t2
    assert 50 * 200_000 < t1 < 50 * 600_000  # latency + mean jitter per exchange


def test_snr_sets_the_noise_against_the_reference_input():
    servo = SimDriver(servo="model", clock=VirtualClock(), snr=20.0, seed=1)
    assert servo.noise_std == pytest.approx(reference_output_std(servo.servo) / 20.0)
    with servo:
        servo.enable()
        ys = np.array([servo.exchange(0.0).position for _ in range(4000)])  # at rest: only the noise moves
        assert servo.identity["noise_std"] == servo.noise_std
    assert np.std(ys) == pytest.approx(servo.noise_std, rel=0.05)


def test_url_options():
    servo = driver_from_url("sim://paper?clock=virtual&latency=0.001")
    assert isinstance(servo, SimDriver) and servo.truth == PAPER_PLANT and servo.position_unit.unit == "unit"
    assert isinstance(servo.clock, VirtualClock) and servo.reference_amplitude > 2
    with servo:
        assert servo.identity["model"] == PAPER_PLANT.to_dict()
    for url, fragment in [
        ("sim://?drop=2", "drop='2' is invalid"),
        ("sim://rotor", "unknown servo 'rotor'; valid: xm430, sts3215, cia402, odrive, model, paper, gear"),
        ("sim://?plant=gear", r"plant= is gone: the servo is the URL's host, sim://gear\?"),
        ("sim://?plant=bench", r"sim://model\?"),
        ("sim://model?play_deg=1", "unknown option.*play_deg; sim:// accepts"),
        (
            "sim://xm430?play_degs=1",
            "unknown option.*play_degs; sim:// accepts .*; and a twin's parameters: .*play_deg",
        ),
        ("sim://xm430?play_deg=lots", r"play_deg \(='lots'\) must be a number"),
        ("sim://?clock=wall", "choose one of real, virtual"),
        ("sim://?snr=40&noise=0.1", "not both"),
        ("sim://?seed=-1", "seed='-1' is invalid"),
    ]:
        with pytest.raises(ConfigError, match=fragment):
            driver_from_url(url)


def test_the_simulated_servo_declares_its_extra_members_and_a_real_driver_does_not_have_them():
    from servoid.drivers.serial.driver import SerialDriver
    from servoid.drivers.simulated import SimulatedServo

    sim = SimDriver(servo="paper", snr=40, clock="virtual", drift=1.5, drift_samples=100)
    assert isinstance(sim, SimulatedServo)
    assert sim.truth == PAPER_PLANT and sim.truth_at(100).dead_zone == pytest.approx(1.5 * PAPER_PLANT.dead_zone)
    assert sim.twin_truth is None and sim.twin_truth_at(5) is None
    assert isinstance(sim.clock, VirtualClock) and sim.noise_std > 0 and sim.reference_amplitude > 0
    assert not isinstance(SerialDriver(port="/dev/null"), SimulatedServo)


# --- a physical twin behind sim:// ------------------------------------------------------------------


def twin_run(url: str, u: np.ndarray, period_s: float = 0.005) -> list[float]:
    with driver_from_url(url) as sim:
        sim.set_sample_period(period_s)
        sim.enable()
        return [sim.exchange(v).position for v in u]


def test_sim_url_opens_a_twin_preset_with_overrides_and_declares_its_ground_truth():
    sim = driver_from_url("sim://xm430?play_deg=0.8&load_inertia_kgm2=1e-3&clock=virtual&seed=2")
    assert isinstance(sim, SimDriver) and sim.truth is None and sim.reference_amplitude == 0.1
    truth = sim.twin_truth
    assert truth.play_rad == pytest.approx(np.radians(0.8)) and truth.gear_ratio == 353.5
    assert (truth.loop_encoder, truth.output_encoder) == ("load", "load") and "Dynamixel" in truth.structure
    with sim:
        identity = sim.identity
    assert identity["servo"] == "xm430" and identity["twin"]["play_rad"] == truth.play_rad
    assert identity["overrides"] == {"play_deg": "0.8", "load_inertia_kgm2": "1e-3"}
    default = driver_from_url("sim://?clock=virtual")
    assert default.servo.name == "xm430" and default.twin_truth == Twin(preset("xm430")).truth
    assert driver_from_url("sim://cia402").twin_truth.loop_encoder == "motor"


def test_the_plain_servo_facts_name_the_presets_and_plants_they_stand_for():
    from servoid.drivers import servo_facts, servos
    from servoid.drivers.twin import preset_names

    assert servo_facts.TWIN_NAMES == preset_names()
    assert servo_facts.MODEL_PLANT_NAMES == tuple(servos.MODEL_PLANTS)
    assert servo_facts.SERVO_NAMES == servos.servo_names()
    assert servo_facts.DEFAULT_SERVO in servo_facts.TWIN_NAMES


def test_the_twin_behind_sim_is_the_twin_itself_sample_by_sample():
    u = np.random.default_rng(5).uniform(-0.1, 0.1, 300)
    got = twin_run("sim://sts3215?clock=virtual&seed=3", u, period_s=0.004)
    reference = TwinPlant(Twin(preset("sts3215"), seed=3), 0.004)
    assert got == [reference.step(v) for v in u]


def test_noise_on_a_twin_is_its_output_encoders_and_enters_its_loop():
    sim = SimDriver(servo="xm430", noise=0.003, clock="virtual")
    resolution = 2 * np.pi / 4096
    assert sim.noise_std == pytest.approx(0.003) and sim._twin_params.load_encoder_noise_counts == pytest.approx(
        0.003 / resolution
    )
    assert SimDriver(servo="xm430", snr=10).noise_std == pytest.approx(0.1 / np.sqrt(3) / 10)
    with pytest.raises(ConfigError, match="not both"):
        driver_from_url("sim://xm430?noise=0.01&encoder_noise_counts=1")


def test_wear_on_a_twin_widens_its_play_on_its_own_clock():
    url = "sim://xm430?clock=virtual&drift=3&drift_samples=100&swap_at=300&swap_factor=0.5"
    sim = driver_from_url(url)
    play = sim.twin_truth.play_rad
    assert sim.twin_truth_at(50).play_rad == pytest.approx(2 * play)
    assert sim.twin_truth_at(200).play_rad == pytest.approx(3 * play)
    assert sim.twin_truth_at(300).play_rad == pytest.approx(1.5 * play)
    with sim:
        sim.set_sample_period(0.005)
        sim.enable()
        for _ in range(150):
            sim.exchange(0.05)
        assert sim.device.plant.twin.truth.play_rad == pytest.approx(3 * play)


def test_torque_off_opens_the_twins_drive_stage_and_it_coasts():
    with driver_from_url("sim://odrive?clock=virtual") as sim:
        sim.set_sample_period(0.005)
        sim.enable()
        for _ in range(40):
            sim.exchange(2.0)  # moving at its velocity limit
        twin = sim.device.plant.twin.twin
        moving, at = twin.physics().load_rad_s, twin.physics().load_rad
        sim.disable()
        assert not twin.read().enabled
        sim.read()  # time passes with the stage open
        sim.clock.sleep_ns(20_000_000)
        sim.read()
        coasting = twin.physics()
        assert moving > 1.0 and coasting.current_a == 0.0 and twin.read().duty == 0.0
        assert coasting.load_rad > at and abs(coasting.load_rad_s) < moving  # it ran on, and friction slows it
        with pytest.raises(DriverError, match="torque is off"):
            sim.exchange(0.0)


def test_an_odrive_twin_that_overspeeds_is_a_device_fault_and_can_be_rearmed():
    # the ODrive's default gains and velocity limit: quick reversals let the motor cross the play
    # without the load and overshoot 1.2 x vel_limit (docs/twins.md)
    with driver_from_url("sim://odrive?clock=virtual&seed=1") as sim:
        sim.set_sample_period(0.005)
        sim.enable()
        with pytest.raises(DeviceFault, match="turned its output stage off by itself \\(overspeed error\\)"):
            for v in np.random.default_rng(1).uniform(-0.2, 0.2, 200):
                sim.exchange(v)
        assert not sim.device.plant.twin.enabled  # the drive's own doing: the host still thinks it on
        sim.disable()
        sim.enable()  # re-arms it, as an ODrive's closed-loop request does
        sim.exchange(0.0)
        assert sim.device.plant.twin.enabled
