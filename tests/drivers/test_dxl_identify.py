"""Live identification through the real SDK: the emulated Dynamixel against the plant simulated directly.

The emulator's only departure from the simulated plant is the 12-bit encoder
(and the goal rounded to whole counts): the first test shows the two agree
sample by sample once that is accounted for; the others identify the servo
from a live run and compare the parameter errors with the same plant
simulated directly.
"""

from __future__ import annotations

import numpy as np
import pytest

from servoid.drivers import driver_from_url
from servoid.drivers.dynamixel import control_table as ct
from servoid.drivers.dynamixel.emulated_servo import CURRENT_GAIN
from servoid.drivers.dynamixel.emulator import DynamixelEmulator, EmulatorProcess
from servoid.drivers.model_plant import MODEL_AMPLITUDE, MODEL_PLANT
from servoid.ident import MRGIAConfig, identify, simulate

from .dxl_helpers import TEST_LATENCY_MS, url

CONFIG = MRGIAConfig(na=2, nb=0, delay=1, rho_exponent=0.75)
NAMES = ("a1", "a2", "b0", "m2", "c1", "c2")


def parameters(model) -> np.ndarray:
    return np.array([*model.a, *model.b, model.m2, model.c1, model.c2])


def relative_errors(model, truth=MODEL_PLANT) -> np.ndarray:
    return np.abs(parameters(model) - parameters(truth)) / np.abs(parameters(truth))


def live_run(driver_url: str, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    with driver_from_url(driver_url) as servo:
        servo.enable()
        ms = [servo.exchange(u_k) for u_k in u]
    return np.array([m.command for m in ms]), np.array([m.position for m in ms])


def quantised(x: np.ndarray) -> np.ndarray:
    """``x`` (rad) rounded to whole encoder counts."""
    return np.round(x / ct.RAD_PER_COUNT) * ct.RAD_PER_COUNT


def test_the_emulated_servo_is_the_bench_plant_seen_through_a_12_bit_encoder():
    u = np.random.default_rng(11).uniform(-MODEL_AMPLITUDE, MODEL_AMPLITUDE, 500)
    with DynamixelEmulator(ids=[1], return_delay_us=0, servo="model") as emu:
        command, y = live_run(url(emu), u)
    np.testing.assert_allclose(command, quantised(u), rtol=0, atol=1e-12)
    np.testing.assert_allclose(y, quantised(simulate(MODEL_PLANT, command).y), rtol=0, atol=1e-12)


def test_live_identification_matches_direct_simulation():
    u = np.random.default_rng(3).uniform(-MODEL_AMPLITUDE, MODEL_AMPLITUDE, 3000)
    with DynamixelEmulator(ids=[1], return_delay_us=0, servo="model") as emu:
        command, y = live_run(url(emu), u)
    live = identify(command, y, CONFIG)
    direct = identify(u, simulate(MODEL_PLANT, u).y, CONFIG)
    through_encoder = identify(command, quantised(simulate(MODEL_PLANT, command).y), CONFIG)
    live_err, direct_err = relative_errors(live.model), relative_errors(direct.model)
    assert not live.warnings
    # noise-free simulation identifies exactly; the live run is limited by the encoder's
    # 1.5 mrad resolution (7 % of c1) alone: exactly as good as the simulation through the encoder
    assert direct_err.max() < 1e-6
    assert live_err.max() < 0.002, dict(zip(NAMES, live_err.round(5)))
    np.testing.assert_allclose(parameters(live.model), parameters(through_encoder.model), rtol=1e-9)


def test_current_mode_identifies_the_spring_of_the_emulated_servo():
    """In current mode the emulated joint settles at CURRENT_GAIN rad per A: the DC gain found."""
    amplitude_a = MODEL_AMPLITUDE / CURRENT_GAIN
    u = np.random.default_rng(4).uniform(-amplitude_a, amplitude_a, 3000)
    with DynamixelEmulator(ids=[1], return_delay_us=0, servo="model") as emu:
        command, y = live_run(url(emu, mode="current"), u)
    model = identify(command, y, CONFIG).model
    dc_gain = sum(model.b) / (1 + sum(model.a))
    assert dc_gain == pytest.approx(CURRENT_GAIN, rel=0.01)
    assert (model.c1, model.c2) == pytest.approx((MODEL_PLANT.c1, MODEL_PLANT.c2), rel=0.05)


@pytest.mark.slow
def test_the_emulator_in_another_process_serves_the_driver():
    u = np.random.default_rng(9).uniform(-MODEL_AMPLITUDE, MODEL_AMPLITUDE, 1500)
    with EmulatorProcess([1, 2], servo="model") as emu:
        command, y = live_run(emu.url(2, latency_ms=TEST_LATENCY_MS), u)
    assert relative_errors(identify(command, y, CONFIG).model).max() < 0.02
