"""The simulated servo: the sampled plant's timing rules and the sim:// driver's options."""

from __future__ import annotations

import numpy as np
import pytest

from servoid.drivers import driver_from_url
from servoid.drivers.clock import VirtualClock
from servoid.drivers.model_plant import MODEL_PLANT
from servoid.drivers.sampled import SampledPlant
from servoid.drivers.sim import SIM_PLANTS, SimDriver, reference_output_std
from servoid.errors import ConfigError, DriverError
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
        servo = SimDriver(clock=VirtualClock(), latency=200e-6, jitter=100e-6, noise=0.001, seed=4)
        with servo:
            servo.enable()
            ys = [servo.exchange(u).position for u in np.linspace(-0.2, 0.2, 50)]
            return ys, servo.clock.now_ns()

    (ys1, t1), (ys2, t2) = run(), run()
    assert ys1 == ys2 and t1 == t2
    assert 50 * 200_000 < t1 < 50 * 600_000  # latency + mean jitter per exchange


def test_snr_sets_the_noise_against_the_reference_input():
    servo = SimDriver(clock=VirtualClock(), snr=20.0, seed=1)
    assert servo.noise_std == pytest.approx(reference_output_std(SIM_PLANTS["bench"]) / 20.0)
    with servo:
        servo.enable()
        ys = np.array([servo.exchange(0.0).position for _ in range(4000)])  # at rest: only the noise moves
        assert servo.identity["noise_std"] == servo.noise_std
    assert np.std(ys) == pytest.approx(servo.noise_std, rel=0.05)


def test_url_options():
    servo = driver_from_url("sim://?plant=paper&clock=virtual&latency=0.001")
    assert isinstance(servo, SimDriver) and servo.truth == PAPER_PLANT and servo.position_unit.unit == "unit"
    assert isinstance(servo.clock, VirtualClock) and servo.reference_amplitude > 2
    with servo:
        assert servo.identity["model"] == PAPER_PLANT.to_dict()
    for url, fragment in [
        ("sim://?drop=2", "drop='2' is invalid"),
        ("sim://?plant=rotor", "choose one of bench, paper"),
        ("sim://?clock=wall", "choose one of real, virtual"),
        ("sim://?snr=40&noise=0.1", "not both"),
        ("sim://?seed=-1", "seed='-1' is invalid"),
    ]:
        with pytest.raises(ConfigError, match=fragment):
            driver_from_url(url)


def test_the_simulated_servo_declares_its_extra_members_and_a_real_driver_does_not_have_them():
    from servoid.drivers.serial.driver import SerialDriver
    from servoid.drivers.simulated import SimulatedServo

    sim = SimDriver(plant="paper", snr=40, clock="virtual", drift=1.5, drift_samples=100)
    assert isinstance(sim, SimulatedServo)
    assert sim.truth == PAPER_PLANT and sim.truth_at(100).dead_zone == pytest.approx(1.5 * PAPER_PLANT.dead_zone)
    assert isinstance(sim.clock, VirtualClock) and sim.noise_std > 0 and sim.reference_amplitude > 0
    assert not isinstance(SerialDriver(port="/dev/null"), SimulatedServo)
