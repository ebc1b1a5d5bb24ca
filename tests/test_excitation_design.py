"""The design helper, and the claim the report makes: a signal it flags identifies poorly, the one it proposes well."""

import math

import numpy as np
import pytest

from servoid.errors import ConfigError
from servoid.excitation import StepsSpec, UniformSpec, sample
from servoid.excitation.design import Prior, ServoLimits, design
from servoid.excitation.report import assess
from servoid.ident import PAPER_PLANT, MRGIAConfig, identify, noise_epsilon, simulate
from servoid.ident.paper import RECOMMENDED_RHO_EXPONENT

ROUGH = Prior(dead_zone=1.5, gain=0.4)  # the paper's plant as an engineer would guess it


def identification_errors(u_of_seed, seeds, snr=43.0):
    errors = []
    for seed in seeds:
        u = u_of_seed(seed)
        sim = simulate(PAPER_PLANT, u, snr=snr, rng=1000 + seed)
        config = MRGIAConfig(rho_exponent=RECOMMENDED_RHO_EXPONENT, epsilon=noise_epsilon(sim.noise_std))
        # the paper's plant has no loop: the black box's errors are the question, not the servo-loop model's
        errors.append(identify(u, sim.y, config, servo_loop=False).model.max_relative_error(PAPER_PLANT))
    return np.array(errors)


def test_a_flagged_input_identifies_poorly_and_the_proposed_one_well():
    seeds = range(4)
    weak = UniformSpec(amplitude=0.5)  # inside the play: x hardly ever reaches a line
    assert not assess(sample(weak, 5000), model=PAPER_PLANT).sufficient
    weak_errors = identification_errors(lambda s: sample(weak, 5000, seed=s), seeds)

    proposal = design(ROUGH, ServoLimits(position_min=-3.0, position_max=3.0))
    assert proposal.sufficient
    good_errors = identification_errors(lambda s: sample(proposal.spec, proposal.samples, seed=s), seeds)

    assert np.min(weak_errors) > 0.1  # every seed: more than 10% off somewhere
    assert np.max(good_errors) < 0.02  # every seed: within 2%
    assert assess(sample(proposal.spec, proposal.samples), model=PAPER_PLANT).sufficient  # also on the true plant


def test_the_proposal_respects_the_limits():
    limits = ServoLimits(position_min=1.0, position_max=7.0, max_step=0.8, sample_period_s=0.01, settle_s=0.05)
    proposal = design(ROUGH, limits)
    spec = proposal.spec
    assert isinstance(spec, StepsSpec)
    assert spec.offset == 4.0 and spec.low >= 1.0 and spec.high <= 7.0 and spec.rate == 0.8
    assert spec.hold >= 5  # the servo settles in 5 samples
    u = sample(spec, proposal.samples)
    assert u.min() >= 1.0 and u.max() <= 7.0 and np.max(np.abs(np.diff(u))) <= 0.8
    assert proposal.duration_s == pytest.approx(proposal.samples * 0.01)
    assert any("settles in 5 samples" in r for r in proposal.reasons)


def test_with_a_whole_prior_model_the_proposal_is_small_as_remark_2_asks():
    wide = design(Prior(model=PAPER_PLANT), ServoLimits(position_min=-10.0, position_max=10.0))
    assert isinstance(wide.spec, UniformSpec)
    assert 1.0 < wide.spec.amplitude < 4.0  # far below the 10 the range allows
    assert wide.report.sufficient


def test_a_range_too_narrow_for_the_play_is_a_clear_error():
    with pytest.raises(ConfigError, match=r"allows an amplitude of 0.5.*needs more than 1.875.*widen the range"):
        design(ROUGH, ServoLimits(position_min=-0.5, position_max=0.5))


def test_a_step_limit_too_tight_is_a_clear_error():
    with pytest.raises(ConfigError, match=r"no signal inside the position range \[-2.5, 2.5\].*max step 0.01"):
        design(ROUGH, ServoLimits(position_min=-2.5, position_max=2.5, max_step=0.01))


@pytest.mark.parametrize(
    "kwargs, fragment",
    [
        (dict(position_min=1.0, position_max=1.0), "range [1, 1] is empty"),
        (dict(position_min=0.0, position_max=1.0, max_step=0.0), "max_step (=0.0) must be > 0"),
        (dict(position_min=0.0, position_max=1.0, settle_s=0.1), "settle_s needs sample_period_s"),
    ],
)
def test_bad_limits_are_named(kwargs, fragment):
    with pytest.raises(ConfigError) as info:
        ServoLimits(**kwargs)
    assert fragment in str(info.value)


def test_bad_priors_are_named():
    with pytest.raises(ConfigError, match="gain"):
        Prior(dead_zone=1.0, gain=0.0)
    with pytest.raises(ConfigError, match="dead_zone"):
        Prior(dead_zone=-1.0, gain=1.0)
    assert ServoLimits(position_min=0, position_max=1).max_step == math.inf


def test_a_servo_with_its_encoder_on_the_load_gets_gentle_sines_and_the_reason():
    limits = ServoLimits(position_min=-0.5, position_max=0.5, sample_period_s=1 / 70)
    d = design(Prior(dead_zone=0.004, structure="play_in_loop", load_decel=20.0), limits)
    assert d.spec.kind == "gentle"
    assert d.spec.accel == pytest.approx(0.4 * 20.0 / 70**2)
    assert any("encoder sits on the load" in r for r in d.reasons)
    u = sample(d.spec, d.samples, seed=0)
    assert np.all(np.abs(u) <= 0.5)
    # many reversals far beyond the play, none steeper than the acceleration asked for
    assert np.sum(np.diff(np.sign(np.diff(u))) != 0) >= 100
    assert np.quantile(np.abs(np.diff(u, 2)), 0.99) <= d.spec.accel * 1.01
    with pytest.raises(ConfigError, match="structure"):
        Prior(dead_zone=0.004, structure="inside")
