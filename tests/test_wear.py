"""Simulated wear: the dead zones of a simulated servo ramp and step with its age, deterministically."""

from __future__ import annotations

import numpy as np
import pytest

from servoid.drivers import driver_from_url
from servoid.drivers.sampled import SampledPlant
from servoid.errors import ConfigError
from servoid.ident import Plant
from servoid.ident.models.wear import GEAR_PLANT, WEAR_RESOLUTION, Wear, WearingPlant
from servoid.session import SessionConfig, run_session


def test_the_factor_ramps_then_holds_and_a_swap_multiplies_it():
    wear = Wear(drift=1.5, drift_samples=1000, drift_start=200, swap_at=5000, swap_factor=1.2)
    assert wear.factor(0) == wear.factor(200) == 1.0
    assert wear.factor(700) == pytest.approx(1.25)
    assert wear.factor(1200) == wear.factor(4999) == 1.5
    assert wear.factor(5000) == pytest.approx(1.8)
    m = wear.model(GEAR_PLANT, 700)
    assert (m.c1, m.c2) == pytest.approx((0.5, 0.75)) and (m.a, m.b, m.m2) == (
        GEAR_PLANT.a,
        GEAR_PLANT.b,
        GEAR_PLANT.m2,
    )
    assert not Wear().active and Wear(drift=2.0, drift_samples=10).active
    assert GEAR_PLANT.dead_zone == pytest.approx(1.0)


@pytest.mark.parametrize(
    "kwargs, fragment",
    [
        ({"drift": 1.5}, "drift (=1.5) needs drift_samples"),
        ({"swap_factor": 1.2}, "needs swap_at"),
        ({"drift": -1.0, "drift_samples": 10}, "drift"),
        ({"drift": 1.5, "drift_samples": 0}, "drift_samples"),
    ],
)
def test_bad_wear_is_named(kwargs, fragment):
    with pytest.raises(ConfigError, match=fragment.replace("(", r"\(").replace(")", r"\)")):
        Wear(**kwargs)


def test_a_wearing_plant_follows_the_wear_in_small_steps_and_a_swap_exactly():
    wear = Wear(drift=1.5, drift_samples=10_000, swap_at=15_000, swap_factor=0.8)
    plant = WearingPlant(GEAR_PLANT, wear)
    u = np.random.default_rng(0).uniform(-2.4, 2.4, 20_000)
    for j, v in enumerate(u):
        plant.step(v)
        assert abs(plant.model.c1 / GEAR_PLANT.c1 - wear.factor(j)) <= WEAR_RESOLUTION * 1.5 + 1e-12
    assert plant.model.c1 == pytest.approx(GEAR_PLANT.c1 * 1.5 * 0.8, rel=1e-12)
    plant.reset()  # a power cycle does not mend the gear
    assert plant.age == 20_000 and plant.model.c2 == pytest.approx(GEAR_PLANT.c2 * 1.2, rel=1e-12)


def test_a_plant_without_wear_gives_the_same_numbers():
    u = np.random.default_rng(1).uniform(-2.4, 2.4, 3000)
    worn, plain = WearingPlant(GEAR_PLANT, Wear()), Plant(GEAR_PLANT)
    assert [worn.step(v) for v in u] == [plain.step(v) for v in u]
    assert type(SampledPlant(GEAR_PLANT, wear=Wear()).plant) is Plant


def test_the_simulated_servo_wears_on_its_own_sample_grid():
    url = "sim://gear?clock=virtual&drift=1.5&drift_samples=2000&drift_start=500&swap_at=3000&swap_factor=1.2"
    with driver_from_url(url) as servo:
        assert servo.identity["wear"] == {"drift": 1.5, "drift_samples": 2000, "drift_start": 500, "swap_at": 3000,
                                          "swap_factor": 1.2}  # fmt: skip
        u = np.random.default_rng(2).uniform(-2.4, 2.4, 2800)
        run_session(servo, u, SessionConfig(period_s=1e-3))
        plant = servo.device.plant
        assert plant.model.dead_zone == pytest.approx(1.5, rel=1e-12) and plant.index == 2799
        servo.enable()
        servo.exchange(0.0)
        # the periods the host stays silent still age the gear: 300 of them, then one command
        servo.clock.sleep_ns(300_000_000)
        servo.exchange(0.0)
        assert plant.index == 2800 + 300
        assert plant.model.dead_zone == pytest.approx(1.8, rel=1e-12)
    assert servo.truth_at(1500).dead_zone == pytest.approx(1.25) and servo.truth.dead_zone == pytest.approx(1.0)
    for bad, fragment in [("sim://?drift=1.5", "needs drift_samples"), ("sim://?drift=0", "drift='0' is invalid"),
                          ("sim://?swap_factor=2", "needs swap_at")]:  # fmt: skip
        with pytest.raises(ConfigError, match=fragment):
            driver_from_url(bad)
