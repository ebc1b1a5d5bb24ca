"""Output-error refinement and the identification pipeline: better fits, honest standard errors, bad records named."""

import numpy as np
import pytest
from conftest import paper_record

from servoid.errors import ConfigError, DataError
from servoid.ident import PAPER_PLANT, BacklashModel, MRGIAConfig, check_record, identify, noise_epsilon, refine
from servoid.ident.paper import PAPER_RHO_EXPONENT


def test_refinement_improves_the_online_estimate_and_its_errors_are_honest(paper_noisy):
    cfg = MRGIAConfig(rho_exponent=0.75, epsilon=noise_epsilon(paper_noisy.noise_std))
    result = identify(paper_noisy.u, paper_noisy.y, cfg)
    assert result.method == "mrgia+oe"
    online_err = result.mrgia_model.max_relative_error(PAPER_PLANT)
    refined_err = result.model.max_relative_error(PAPER_PLANT)
    assert refined_err < online_err
    assert refined_err < 5e-3
    # standard errors: each true value within 4 standard errors of its estimate
    stderr = np.array(result.refinement.stderr)
    assert np.all(stderr > 0)
    assert np.all(np.abs(result.model.values() - PAPER_PLANT.values()) < 4 * stderr)
    # the fit reaches the noise floor: NRMSE ~ 1/SNR
    assert result.fit_nrmse == pytest.approx(1 / 43, rel=0.1)
    assert result.refinement.residual_std == pytest.approx(paper_noisy.noise_std, rel=0.1)


def test_refinement_from_a_distant_start_on_clean_data(paper_clean):
    far = BacklashModel(a=(0.2, 0.3), b=(1.0,), delay=1, m2=1.2, c1=0.3, c2=0.7)
    ref = refine(paper_clean.u, paper_clean.y, far)
    assert ref.success
    assert ref.initial_nrmse > 0.1
    assert ref.model.max_relative_error(PAPER_PLANT) < 1e-8


def test_refine_rejects_mismatched_records():
    with pytest.raises(ConfigError, match="differ in length"):
        refine(np.ones(50), np.ones(40), PAPER_PLANT)


@pytest.mark.parametrize(
    "u, y, fragment",
    [
        (np.ones(500), np.arange(500.0), "input u is constant"),
        (np.arange(500.0), np.zeros(500), "output y is constant"),
        (np.arange(30.0), np.arange(30.0), "too few"),
        (np.r_[np.arange(499.0), np.inf], np.arange(500.0), r"u\[499\] \(=inf\) is not finite"),
    ],
)
def test_records_that_cannot_be_identified(u, y, fragment):
    with pytest.raises(DataError, match=fragment):
        check_record(u, y, MRGIAConfig())


def test_identify_reports_an_unsettled_run():
    rec = paper_record(3000, seed=1)  # stuck with the paper's rho exponent (test_mrgia.py)
    result = identify(rec.u, rec.y, MRGIAConfig(rho_exponent=PAPER_RHO_EXPONENT, recover=False))
    assert not result.mrgia.settled
    assert any("did not settle" in w for w in result.warnings)


@pytest.mark.parametrize("a, margin", [((0.45, 0.55), 0.0), ((-1.2, 0.36), -0.56), ((-0.5, 0.06), 0.44)])
def test_convergence_margin(a, margin):
    from servoid.ident import convergence_margin

    assert convergence_margin(a) == pytest.approx(margin, abs=1e-3)


def test_a_slow_plant_is_identified_from_the_arx_start_and_the_user_is_told():
    """Double pole at 0.8: the MRGIA's convergence condition fails (margin -1.24) and its estimate is useless."""
    from servoid.ident import simulate

    plant = BacklashModel(a=(-1.6, 0.64), b=(0.04,), delay=1, m2=1.2, c1=0.1, c2=0.15)
    rng = np.random.default_rng(0)
    u = rng.uniform(-1, 1, 5000)
    sim = simulate(plant, u, snr=40, rng=rng)
    result = identify(u, sim.y, MRGIAConfig(rho_exponent=0.75, epsilon=noise_epsilon(sim.noise_std)))
    assert result.refined_from == "arx"
    assert result.start_nrmse["arx"] < result.start_nrmse["mrgia"]
    assert result.model.max_relative_error(plant) < 1e-2
    assert any("convergence condition" in w for w in result.warnings)
    arx = __import__("servoid.ident", fromlist=["arx_start"]).arx_start(u, sim.y, na=2, nb=0, delay=1)
    assert arx.max_relative_error(plant) > 0.1  # the start alone is not the answer: refinement is


def test_an_online_estimate_that_did_not_converge_is_named_even_when_the_refined_model_is_right():
    """Held PRBS (hold 3), noise-free: the MRGIA settles on a wrong model; the ARX start rescues the fit."""
    from servoid.excitation import sample
    from servoid.ident import simulate

    u = sample("prbs:amplitude=2.406,hold=3", 5000, seed=0)
    y = simulate(PAPER_PLANT, u).y
    result = identify(u, y, MRGIAConfig(rho_exponent=0.75))
    assert result.mrgia.settled and result.mrgia_model.max_relative_error(PAPER_PLANT) > 0.1
    assert result.refined_from == "arx" and result.model.max_relative_error(PAPER_PLANT) < 1e-9
    assert any("did not converge here" in w and "whiter input" in w for w in result.warnings)


def test_the_streamed_arx_start_is_the_whole_least_squares_problem():
    # the ARX regression is reduced chunk by chunk (a streaming QR); over more than one chunk and with
    # lost samples it must solve the same least squares as lstsq on the whole regressor matrix
    from servoid.ident import simulate
    from servoid.ident.offline.refine import ARX_CHUNK, arx_start

    rng = np.random.default_rng(11)
    n = ARX_CHUNK + 5000
    u = rng.uniform(-2.4, 2.4, n)
    sim = simulate(PAPER_PLANT, u, snr=30.0, rng=rng)
    valid = rng.random(n) > 0.01
    y = np.where(valid, sim.y, np.nan)
    na, nb, d = 2, 1, 1
    start = arx_start(u, y, na=na, nb=nb, delay=d, valid=valid)
    yy = np.where(valid, y, 0.0)
    k0 = max(na, d + nb)
    usable = valid[k0:].copy()
    for i in range(1, na + 1):
        usable &= valid[k0 - i : n - i]
    cols = [-yy[k0 - i : n - i] for i in range(1, na + 1)]
    cols += [u[k0 - d - j : n - d - j] for j in range(nb + 1)] + [np.ones(n - k0)]
    whole = np.linalg.lstsq(np.column_stack(cols)[usable], yy[k0:][usable], rcond=None)[0]
    np.testing.assert_allclose(np.r_[start.a, start.b], whole[: na + nb + 1], rtol=1e-9, atol=1e-12)


def test_identification_inside_a_stop_keeps_what_it_made_and_says_so(paper_noisy, monkeypatch):
    """A live run's wall budget (identify inside ``_threads.stopping``): the black box's refinement stops at its first
    evaluation, in memory or streamed; the MRGIA's estimate answers, withheld with the reason; a stop that never
    comes changes nothing."""
    from servoid.ident.offline import _oefit, _threads

    cfg = MRGIAConfig(rho_exponent=0.75, epsilon=noise_epsilon(paper_noisy.noise_std))
    u, y = paper_noisy.u[:2000], paper_noisy.y[:2000]
    whole = identify(u, y, cfg)
    with _threads.stopping(_threads.Stop()):
        same = identify(u, y, cfg)
    assert same.method == whole.method == "mrgia+oe" and np.array_equal(same.model.values(), whole.model.values())
    stop = _threads.Stop(why="the test")
    stop.now()
    with _threads.stopping(stop):
        cut = identify(u, y, cfg)
    assert stop.fired and cut.refinement is None and cut.method == "mrgia"
    assert np.array_equal(cut.model.values(), whole.mrgia_model.values())
    assert not cut.identifiable and any("stopped by the test" in r for r in cut.verdict.reasons)
    assert any("refinement from the mrgia start stopped by the test" in w for w in cut.warnings)
    monkeypatch.setattr(_oefit, "STREAM_FROM_ROWS", 100)  # the long record's path checks the stop too
    with _threads.stopping(stop), pytest.raises(_threads.Stopped):
        refine(u, y, whole.mrgia_model)


def test_no_model_names_the_stop_that_cut_the_refinement_not_a_missing_request():
    """A record whose MRGIA estimate is not a valid model (a doubly integrated walk: an unstable linear block) and a
    wall budget already spent: the error names the cut refinement and the budget, not ``--no-refine``; without the
    stop and with ``refine_model=False`` it names the request."""
    from servoid.errors import ModelError
    from servoid.ident.offline import _threads

    rng = np.random.default_rng(1)
    u, y = rng.uniform(-1.0, 1.0, 400), 1e-3 * np.cumsum(np.cumsum(rng.normal(0.0, 1.0, 400)))
    with pytest.raises(ModelError, match="refinement was not requested"):
        identify(u, y, MRGIAConfig(), refine_model=False)
    stop = _threads.Stop(why="the test")
    stop.now()
    with _threads.stopping(stop), pytest.raises(ModelError, match="stopped by the test before any start") as cut:
        identify(u, y, MRGIAConfig())
    assert "--budget" in str(cut.value) and "not requested" not in str(cut.value)
