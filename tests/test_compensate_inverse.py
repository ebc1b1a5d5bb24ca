"""The backlash inverse, above all at reversals: exact where it should be, smooth where it must be."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from servoid.errors import ConfigError, ModelError
from servoid.ident import PAPER_PLANT
from servoid.ident.control.compensate import BacklashInverse, InverseParams, backlash_inverse, default_band
from servoid.ident.models.kernels import backlash_step

M2, C1, C2 = PAPER_PLANT.m2, PAPER_PLANT.c1, PAPER_PLANT.c2


def _through_backlash(x_d: np.ndarray, *, x0: float, y0: float) -> np.ndarray:
    """The backlash of the model driven by x_d (what the servo's output does)."""
    y, x_prev, out = y0, x0, []
    for x in x_d:
        y, _ = backlash_step(float(x), x_prev, y, M2, C1, C2)
        out.append(y)
        x_prev = float(x)
    return np.array(out)


def test_naive_inverse_is_tao_kokotovic():
    inv = BacklashInverse(InverseParams.from_model(PAPER_PLANT, band=0.0), y0=0.0)
    assert inv.step(0.4) == pytest.approx(0.4 + C1)  # rising: up line
    assert inv.step(0.4) == pytest.approx(0.4 + C1)  # standing: held
    assert inv.step(0.3) == pytest.approx(0.3 / M2 - C2)  # falling: down line, across the whole gap
    assert inv.weight == 1.0
    assert inv.step(0.31) == pytest.approx(0.31 + C1)  # the smallest reversal jumps the gap back


def test_exact_inverse_cancels_the_backlash_on_monotone_stretches():
    y_d = np.concatenate([np.linspace(0, 1.2, 50), np.full(10, 1.2), np.linspace(1.2, -0.8, 80),
                          np.linspace(-0.8, 0.5, 60)])  # fmt: skip
    x_d = backlash_inverse(InverseParams.from_model(PAPER_PLANT, band=0.0), y_d, y0=0.0, x0=C1)
    y = _through_backlash(x_d, x0=C1, y0=0.0)
    np.testing.assert_allclose(y, y_d, atol=1e-12)  # every sample, reversals included


def test_band_crosses_the_gap_in_proportion_and_lands_exactly():
    band = 0.1
    params = InverseParams.from_model(PAPER_PLANT, band=band)
    inv = BacklashInverse(params, y0=0.0)
    for v in np.linspace(0, 1.0, 21)[1:]:
        inv.step(v)
    assert inv.weight == 0.0
    up, down = 0.98 + C1, 0.98 / M2 - C2
    x_small = inv.step(0.98)  # a reversal of 0.02 = band / 5
    assert inv.weight == pytest.approx(0.2)
    assert x_small == pytest.approx(0.8 * up + 0.2 * down)  # a fifth of the way across, not all of it
    inv.step(1.0)  # back up: the weight returns, no jump
    assert inv.weight == pytest.approx(0.0)
    falling = np.linspace(1.0, 0.5, 26)[1:]
    x_d = [inv.step(v) for v in falling]
    assert inv.weight == 1.0
    assert x_d[-1] == pytest.approx(0.5 / M2 - C2)  # past the band: exactly on the down line


def test_small_reversals_move_the_command_by_a_fraction_of_the_naive_jump():
    rng = np.random.default_rng(4)
    y_d = 0.3 + rng.normal(0, 0.005, 400)  # a held position seen through noise
    naive = backlash_inverse(InverseParams.from_model(PAPER_PLANT, band=0.0), y_d)
    smooth = backlash_inverse(InverseParams.from_model(PAPER_PLANT, band=0.05), y_d)
    travel_naive = np.sum(np.abs(np.diff(naive)))
    travel_smooth = np.sum(np.abs(np.diff(smooth)))
    gap = (0.3 + C1) - (0.3 / M2 - C2)
    assert travel_naive > 100 * gap  # the naive inverse throws the motor across the play again and again
    assert travel_smooth < travel_naive / 5


def test_output_error_after_a_reversal_is_bounded_by_the_band():
    band = 0.08
    k = np.arange(400)
    y_d = 0.9 * np.sin(2 * np.pi * k / 200)
    x_d = backlash_inverse(InverseParams.from_model(PAPER_PLANT, band=band), y_d, y0=0.0, x0=C1)
    y = _through_backlash(x_d, x0=C1, y0=0.0)
    err = np.abs(y - y_d)
    assert err.max() <= band * 1.05
    assert err.max() > band / 4  # the band does cost something at the turns...
    turns = np.flatnonzero(np.diff(np.sign(np.diff(y_d)))) + 1
    far = np.ones(k.size, bool)
    for t in turns:
        far[t : t + 25] = False
    assert err[far].max() < 1e-12  # ...and nothing away from them


@settings(max_examples=60, deadline=None)
@given(
    steps=st.lists(st.floats(-0.3, 0.3, allow_nan=False), min_size=2, max_size=60),
    band=st.floats(0.01, 0.5),
)
def test_command_is_continuous_in_the_wanted_output(steps, band):
    """|dx_d| <= |dy_d| (1 + gap / band) / min(1, m2): no jumps with a band, however y_d moves."""
    y_d = np.cumsum(steps)
    x_d = backlash_inverse(InverseParams.from_model(PAPER_PLANT, band=band), y_d)
    gap = np.abs((y_d + C1) - (y_d / M2 - C2)).max()
    dy = np.abs(np.diff(y_d))
    assert np.all(np.abs(np.diff(x_d)) <= dy * (1 + gap / band) / min(1.0, M2) + 1e-12)


def test_online_equals_batch_and_reset_from_a_known_motor_position():
    rng = np.random.default_rng(1)
    y_d = np.cumsum(rng.normal(0, 0.05, 300))
    params = InverseParams.from_model(PAPER_PLANT, band=0.04)
    inv = BacklashInverse(params, y0=0.2, x0=0.0)
    assert inv.weight == pytest.approx(params.weight_for(0.2, 0.0))
    # x0 = 0 with y = 0.2 lies inside the play: between the lines, so 0 < s < 1
    assert 0.0 < inv.weight < 1.0
    online = np.array([inv.step(v) for v in y_d])
    np.testing.assert_array_equal(online, backlash_inverse(params, y_d, y0=0.2, x0=0.0))
    assert params.weight_for(0.2, 0.2 + C1) == 0.0 and params.weight_for(0.2, 0.2 / M2 - C2) == 1.0


def test_bad_input_names_the_value():
    with pytest.raises(ModelError, match=r"c1 \(=-0.1\) must be > 0"):
        InverseParams(m2=1.0, c1=-0.1, c2=0.1, band=0.0)
    with pytest.raises(ModelError, match=r"band \(=-0.01\) must be >= 0"):
        InverseParams(m2=1.0, c1=0.1, c2=0.1, band=-0.01)
    inv = BacklashInverse(InverseParams(m2=1.0, c1=0.1, c2=0.1, band=0.0))
    with pytest.raises(ConfigError, match=r"y_d \(=nan\) must be finite"):
        inv.step(float("nan"))
    with pytest.raises(ConfigError, match=r"y_d\[2\]"):
        backlash_inverse(inv.params, [0.0, 1.0, float("inf")])


def test_default_band():
    assert default_band(PAPER_PLANT) == pytest.approx(0.03)
    assert default_band(PAPER_PLANT, noise_std=0.05) == pytest.approx(0.1)
    assert default_band(PAPER_PLANT, noise_std=0.001) == pytest.approx(0.03)
