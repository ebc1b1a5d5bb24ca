"""Shared fixtures. Randomness is always seeded: np.random.default_rng(seed)."""

from __future__ import annotations

import numpy as np
import pytest

from servoid.ident.models.simulate import Simulation, simulate
from servoid.ident.paper import PAPER_INPUT_AMPLITUDE, PAPER_PLANT


def paper_record(n: int, seed: int, snr: float | None = None) -> Simulation:
    """The paper's Section 4 experiment: uniform input of variance 1.93 into the paper's plant."""
    rng = np.random.default_rng(seed)
    u = rng.uniform(-PAPER_INPUT_AMPLITUDE, PAPER_INPUT_AMPLITUDE, size=n)
    return simulate(PAPER_PLANT, u, snr=snr, rng=rng)


@pytest.fixture(scope="session")
def paper_clean() -> Simulation:
    return paper_record(3000, seed=0)


@pytest.fixture(scope="session")
def paper_noisy() -> Simulation:
    return paper_record(5000, seed=7, snr=43.0)
