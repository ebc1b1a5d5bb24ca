"""Live identification through the CAN drivers: the simulated drives identify as well as the plant itself.

A small sampling loop (what the sampling session will do at a fixed rate):
open the driver on the simulated drive, exchange a seeded uniform input, and
identify the backlash model from what came back; then identify the same
plant simulated directly on the same input. Known truth: MODEL_PLANT.
"""

from __future__ import annotations

import numpy as np
import pytest

from servoid.drivers import driver_from_url
from servoid.drivers.can.simulated import simulated_drive
from servoid.drivers.model_plant import MODEL_PLANT
from servoid.ident import MRGIAConfig, identify, simulate

from .can_helpers import (
    PATIENT_S,
    bench_input,
    buses_closed,  # noqa: F401 - autouse fixture
    private_bus,
)

SAMPLES = 2500


@pytest.mark.parametrize(("protocol", "mode"), [("cia402", "position"), ("odrive", "position"), ("cia402", "torque")])
def test_a_simulated_drive_identifies_like_the_plant_itself(protocol, mode):
    u = bench_input(SAMPLES, seed=31)
    with simulated_drive(protocol, bus=private_bus(), servo="model") as drive:
        with driver_from_url(drive.url(mode=mode, timeout=PATIENT_S)) as servo:
            servo.enable()
            y = np.array([servo.exchange(v).position for v in u])
    config = MRGIAConfig(rho_exponent=0.75)
    live = identify(u, y, config).model
    direct = identify(u, simulate(MODEL_PLANT, u).y, config).model
    # quantisation (17-bit encoder, 0.1 % torque steps) is the only difference from the plant itself
    assert live.max_relative_error(MODEL_PLANT) < 0.005, live
    assert direct.max_relative_error(MODEL_PLANT) < 1e-6, direct
