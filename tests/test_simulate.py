"""Simulation of the pseudo-Wiener model: the backlash zones, the direction rule, the stepped plant."""

import numpy as np
import pytest

from servoid.errors import ConfigError, ModelError
from servoid.ident import PAPER_PLANT, BacklashModel, Plant, free_run, simulate
from servoid.ident.models.kernels import ZONE_DOWN, ZONE_MEMORY, ZONE_UP, backlash_step, schur_stable

M2, C1, C2 = 1.5, 0.5, 1.0


def test_backlash_step_three_zones():
    # rising past y + c1: up line y = x - c1
    assert backlash_step(2.0, 1.0, 0.0, M2, C1, C2) == (1.5, ZONE_UP)
    # rising but inside the play: hold
    assert backlash_step(0.4, 0.1, 0.0, M2, C1, C2) == (0.0, ZONE_MEMORY)
    # falling below y/m2 - c2: down line y = m2 (x + c2)
    assert backlash_step(-2.0, -1.0, 0.0, M2, C1, C2) == (pytest.approx(-1.5), ZONE_DOWN)
    # standing still: hold, whatever the position
    assert backlash_step(5.0, 5.0, 0.0, M2, C1, C2) == (0.0, ZONE_MEMORY)


def test_direction_rule_beyond_the_crossing():
    # Beyond x* = -4 both switching conditions of eqs (6)-(7) hold; the direction decides.
    x, y_prev = -6.0, -7.0  # y_prev + c1 = -6.5 < x and y_prev/m2 - c2 = -5.67 > x
    assert y_prev + C1 < x and y_prev / M2 - C2 > x
    assert backlash_step(x, -6.5, y_prev, M2, C1, C2) == (pytest.approx(x - C1), ZONE_UP)
    assert backlash_step(x, -5.5, y_prev, M2, C1, C2) == (pytest.approx(M2 * (x + C2)), ZONE_DOWN)


def test_simulation_follows_lines_and_play():
    model = BacklashModel(a=(0.0,), b=(1.0,), delay=1, m2=1.0, c1=0.5, c2=0.5)  # x(k) = u(k-1)
    u = np.array([0.0, 1.0, 2.0, 1.5, 1.0, 0.0, 0.5, 0.0])
    sim = simulate(model, u)
    assert np.allclose(sim.x, [0, 0, 1, 2, 1.5, 1.0, 0.0, 0.5])
    # up line x - 0.5, then the play of width 1 holds y = 1.5 until x falls below
    # y/m2 - c2 = 1.0; at x = 0 the down line gives m2 (x + c2) = 0.5, held on the way back up
    assert np.allclose(sim.y, [0, 0, 0.5, 1.5, 1.5, 1.5, 0.5, 0.5])
    assert sim.zone.tolist() == [0, 0, 1, 1, 0, 0, -1, 0]


def test_plant_matches_simulate_and_drift_keeps_state():
    rng = np.random.default_rng(3)
    u = rng.uniform(-2.4, 2.4, 500)
    expected = simulate(PAPER_PLANT, u).y
    plant = Plant(PAPER_PLANT)
    assert np.array_equal([plant.step(v) for v in u], expected)
    y_before = plant.y
    plant.model = BacklashModel(a=(0.45, 0.55), b=(0.8,), delay=1, m2=1.5, c1=0.6, c2=1.2)
    assert plant.y == y_before
    with pytest.raises(ModelError, match="keeps its orders"):
        plant.model = BacklashModel(a=(0.5,), b=(1.0,), delay=1, m2=1.0, c1=0.1, c2=0.1)


def test_snr_is_the_papers_definition():
    rng = np.random.default_rng(5)
    u = rng.uniform(-2.4, 2.4, 20_000)
    sim = simulate(PAPER_PLANT, u, snr=43.0, rng=rng)
    noise = sim.y - sim.y_clean
    assert np.sqrt(np.var(sim.y_clean) / np.var(noise)) == pytest.approx(43.0, rel=0.03)
    assert sim.noise_std == pytest.approx(np.std(sim.y_clean) / 43.0)


def test_noise_needs_a_seeded_generator():
    with pytest.raises(ConfigError, match="rng"):
        simulate(PAPER_PLANT, np.ones(10), noise_std=0.1)
    a = simulate(PAPER_PLANT, np.linspace(-2, 2, 50), noise_std=0.1, rng=11).y
    b = simulate(PAPER_PLANT, np.linspace(-2, 2, 50), noise_std=0.1, rng=np.random.default_rng(11)).y
    assert np.array_equal(a, b)


def test_bad_inputs_are_named():
    with pytest.raises(ConfigError, match=r"u\[2\] \(=nan\) is not finite"):
        free_run(PAPER_PLANT, [0.0, 1.0, float("nan")])
    with pytest.raises(ConfigError, match="one-dimensional"):
        free_run(PAPER_PLANT, np.zeros((3, 2)))
    with pytest.raises(ConfigError, match="snr"):
        simulate(PAPER_PLANT, np.ones(5), snr=-1.0, rng=1)


def test_zone_shares_and_crossing_count():
    sim = simulate(PAPER_PLANT, np.random.default_rng(0).uniform(-2.4, 2.4, 5000))
    shares = sim.zone_shares
    assert sum(shares.values()) == pytest.approx(1.0)
    assert min(shares.values()) > 0.2  # the paper's input visits all three zones
    assert sim.beyond_crossing == int(np.sum(sim.x < -4.0))
    big = simulate(PAPER_PLANT, np.random.default_rng(0).uniform(-12, 12, 2000))
    assert big.beyond_crossing > 0


@pytest.mark.parametrize(
    "a, stable",
    [
        ((0.45, 0.55), True),
        ((-1.9, 0.95), True),
        ((-2.0, 1.0), False),
        ((0.5,), True),
        ((1.0,), False),
        ((0.1, 0.2, 1.2), False),
    ],
)
def test_schur_stable_agrees_with_roots(a, stable):
    arr = np.array(a, dtype=float)
    assert schur_stable(arr) == stable
    assert (np.max(np.abs(np.roots(np.r_[1.0, arr]))) < 1) == stable
