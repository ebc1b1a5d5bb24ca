"""The persistent-excitation report: the regressor is the MRGIA's, the numbers mean what they say, the verdicts are right."""

import json

import numpy as np
import pytest

from servoid.excitation import MultisineSpec, sample
from servoid.excitation.regressor import regressor
from servoid.excitation.report import assess, input_stats
from servoid.ident import PAPER_PLANT, BacklashModel, simulate
from servoid.ident.models.kernels import ZONE_MEMORY
from servoid.ident.paper import PAPER_INPUT_AMPLITUDE


def test_the_regressor_reproduces_the_output_on_every_updated_sample():
    # eq. (40): on the lines y(k) = h(k)^T theta exactly, with the true theta
    model = BacklashModel(a=(0.3, -0.2), b=(0.6, 0.3), delay=2, m2=0.7, c1=0.3, c2=0.2)
    sim = simulate(model, np.random.default_rng(4).uniform(-2, 2, 3000))
    reg = regressor(model, sim)
    assert reg.h.shape == (3000, model.n_params) and reg.names == model.names
    assert 0.3 < reg.phi.mean() < 0.95
    np.testing.assert_allclose(reg.h[reg.phi] @ model.theta, sim.y_clean[reg.phi], atol=1e-12)
    # Phi marks exactly the samples the simulator put on a line (the first one is never used)
    np.testing.assert_array_equal(reg.phi[1:], sim.zone[1:] != ZONE_MEMORY)


@pytest.mark.parametrize("lines, order", [((100,), 2), ((100, 250), 4), ((100, 250, 400), 6)])
def test_the_order_of_a_multisine_is_twice_its_lines(lines, order):
    # each sine spans two dimensions of the covariance matrix, no more (well-separated
    # frequencies: slow sines are nearly collinear with their own delays and read as lower orders)
    bands = tuple((line / 1000 - 1e-4, line / 1000 + 1e-4) for line in lines)
    spec = MultisineSpec(amplitude=1.0, bands=bands, period=1000)
    assert spec.harmonics == lines
    stats = input_stats(sample(spec, 4000), max_order=10)
    assert stats.pe_order == order
    assert stats.pe_condition[order] > 1e10  # the next order is singular, not merely poor


def test_white_noise_is_exciting_of_every_order_and_a_constant_of_none():
    white = input_stats(np.random.default_rng(0).uniform(-1, 1, 5000), max_order=12)
    assert white.pe_order == white.pe_max_order == 12
    assert max(white.pe_condition) < 1.5
    constant = input_stats(np.full(100, 3.0))
    assert constant.pe_order == 0 and constant.std == 0.0
    report = assess(np.full(100, 3.0), model=PAPER_PLANT)
    assert not report.sufficient and "constant" in report.verdicts[0].message


def test_input_statistics():
    u = np.array([0.0, 1.0, 3.0, 2.0, 2.0, 4.0, -1.0] * 10)
    stats = input_stats(u, max_order=3)
    assert (stats.minimum, stats.maximum, stats.max_step) == (-1.0, 4.0, 5.0)
    assert stats.reversals == 4 * 10 - 1  # up, down, (hold), up, down: four turns per period, joined
    assert stats.crest_factor == pytest.approx(np.max(np.abs(u - u.mean())) / u.std())


def test_the_papers_input_is_sufficient_and_the_lemma_numbers_are_consistent():
    u = np.random.default_rng(1).uniform(-PAPER_INPUT_AMPLITUDE, PAPER_INPUT_AMPLITUDE, 5000)
    report = assess(u, model=PAPER_PLANT)
    assert report.sufficient and report.needed_order == 3
    tm = report.through_model
    assert 0 < tm.gamma < tm.beta and tm.condition == pytest.approx(tm.beta / tm.gamma)
    info = regressor(PAPER_PLANT, tm.simulation).information()
    assert tm.trace == pytest.approx(np.trace(info))
    np.testing.assert_allclose([tm.gamma, tm.beta], np.linalg.eigvalsh(info)[[0, -1]])
    assert tm.share_up + tm.share_down + tm.share_memory == pytest.approx(1.0)
    assert tm.update_share == pytest.approx(tm.share_up + tm.share_down, abs=1e-3)
    assert tm.line_switches > 1000 and tm.collinearity < 250
    json.dumps(report.to_dict())  # JSON-ready


def test_an_input_inside_the_play_is_insufficient_with_the_reason():
    report = assess(sample("uniform:amplitude=0.3", 4000, seed=2), model=PAPER_PLANT)
    assert not report.sufficient and report.level == "insufficient"
    first = report.verdicts[0]
    assert first.level == "insufficient" and "never leaves the memory zone" in first.message
    assert "raise the amplitude" in first.message and "c1 + c2 = 1.5" in first.message


def test_a_ramp_crosses_the_play_once_and_is_flagged():
    report = assess(np.linspace(-3, 3, 2000), model=PAPER_PLANT)
    messages = " ".join(v.message for v in report.verdicts if v.level == "insufficient")
    assert "order 1 only" in messages and "only 1 time(s)" in messages


def test_one_sine_cannot_identify_three_linear_parameters():
    spec = MultisineSpec(amplitude=2.4, bands=((0.0999, 0.1001),), period=1000)
    report = assess(sample(spec, 4000), model=PAPER_PLANT)
    order = [v for v in report.verdicts if v.topic == "excitation order"][0]
    assert order.level == "insufficient" and "order 2 only" in order.message and "needs order >= 3" in order.message


def test_a_large_input_is_warned_about_the_crossing_of_the_lines():
    report = assess(sample("uniform:amplitude=5", 3000), model=PAPER_PLANT)
    assert report.sufficient and report.level == "warning"
    assert any(v.topic == "range" and "x = -4" in v.message for v in report.verdicts)


def test_without_a_model_only_the_signal_is_judged():
    report = assess(sample("prbs:amplitude=1,hold=2", 2000))
    assert report.through_model is None and report.needed_order is None
    assert report.sufficient and report.verdicts[0].topic == "excitation order"
    assert "through_model" not in report.to_dict()
