"""Long records' refinement: normal equations summed as the simulations run give scipy's fit without its memory."""

from dataclasses import replace

import numpy as np
import pytest
from conftest import paper_record

from servoid.ident import PAPER_PLANT, refine
from servoid.ident.models.kernels import normal_equations_kernel, simulate_kernel
from servoid.ident.offline import _oefit


def test_the_streamed_cost_and_normal_equations_are_the_simulations_and_their_jacobian():
    sim = paper_record(3000, seed=5, snr=30.0)
    keep = np.random.default_rng(5).random(sim.u.size) > 0.1
    m = PAPER_PLANT
    p = np.array([*m.a, *m.b, m.m2, m.c1, m.c2])
    h = 1e-6 * np.maximum(1.0, np.abs(p))

    def y_hat(q):
        x, yh, zone = np.empty_like(sim.u), np.empty_like(sim.u), np.empty(sim.u.shape, dtype=np.int8)
        simulate_kernel(q[:2].copy(), q[2:3].copy(), 1, q[3], q[4], q[5], sim.u, 0.0, x, yh, zone)
        return yh

    ps = [p] + [p + h[j] * np.eye(6)[j] for j in range(6)]
    a, b = np.array([q[:2] for q in ps]), np.array([q[2:3] for q in ps])
    m2, c1, c2 = (np.array([q[i] for q in ps]) for i in (3, 4, 5))
    jtj, jtr = np.zeros((6, 6)), np.zeros(6)
    cost = normal_equations_kernel(a, b, m2, c1, c2, h, 1, sim.u, sim.y, keep, 0.0, jtj, jtr)
    r = (y_hat(p) - sim.y)[keep]
    jac = np.column_stack([(y_hat(q) - y_hat(p))[keep] / h[j] for j, q in enumerate(ps[1:])])
    assert cost == pytest.approx(r @ r, rel=1e-12)
    np.testing.assert_allclose(jtj, jac.T @ jac, rtol=1e-9, atol=1e-9 * np.abs(jtj).max())
    np.testing.assert_allclose(jtr, jac.T @ r, rtol=1e-9, atol=1e-9 * np.abs(jtr).max())


@pytest.mark.parametrize("masked", [False, True])
def test_streamed_refinement_finds_scipys_optimum_and_errors(monkeypatch, masked):
    sim = paper_record(20_000, seed=7, snr=40.0)
    valid = (np.arange(sim.u.size) % 53 != 0) if masked else None
    start = replace(PAPER_PLANT, a=(0.4, 0.5), m2=1.35, c1=0.6, c2=0.85)
    monkeypatch.setattr(_oefit, "STREAM_FROM_ROWS", 10**12)
    scipy_fit = refine(sim.u, sim.y, start, valid=valid)
    monkeypatch.setattr(_oefit, "STREAM_FROM_ROWS", 1)
    streamed = refine(sim.u, sim.y, start, valid=valid)
    assert streamed.success and ("ftol" in streamed.message or "xtol" in streamed.message)
    se = np.array(scipy_fit.stderr)
    assert np.all(np.abs(streamed.model.values() - scipy_fit.model.values()) < 0.05 * se)
    np.testing.assert_allclose(streamed.stderr, scipy_fit.stderr, rtol=1e-3)
    assert streamed.nrmse == pytest.approx(scipy_fit.nrmse, rel=1e-6)


def test_a_streamed_identification_gives_the_same_play_and_interval_without_a_jacobian(monkeypatch):
    from servoid.ident import MRGIAConfig, identify

    sim = paper_record(10_000, seed=7, snr=40.0)
    monkeypatch.setattr(_oefit, "STREAM_FROM_ROWS", 10**12)
    held = identify(sim.u, sim.y, MRGIAConfig())
    monkeypatch.setattr(_oefit, "STREAM_FROM_ROWS", 1)
    streamed = identify(sim.u, sim.y, MRGIAConfig())
    width = held.play_interval[1] - held.play_interval[0]
    assert np.isfinite(width) and streamed.identifiable == held.identifiable
    assert streamed.play == pytest.approx(held.play, abs=0.05 * width)
    assert streamed.play_interval[1] - streamed.play_interval[0] == pytest.approx(width, rel=0.25)
