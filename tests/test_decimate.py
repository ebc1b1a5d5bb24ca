"""The decimating estimator: the slow stream it feeds, the factor it picks, and that it converges where the fast MRGIA cannot."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.signal import cont2discrete

from servoid.ident.models.pseudo_wiener import BacklashModel
from servoid.ident.models.simulate import free_run
from servoid.ident.online.decimate import DecimatingEstimator, decimate_record, decimation_factor, slow_denominator
from servoid.ident.online.mrgia import MRGIA, MRGIAConfig, convergence_margin, run_mrgia


def _loop(ratio: float, bw: float = 5.0, zeta: float = 0.7) -> tuple[np.ndarray, np.ndarray]:
    """A position loop of bandwidth ``bw`` Hz sampled at ``ratio`` times it (ZOH): the exact linear block."""
    w = 2 * np.pi * bw
    num, den, _ = cont2discrete(([w * w], [1, 2 * zeta * w, w * w]), 1.0 / (ratio * bw))
    return np.asarray(den[1:]), np.asarray(num[0][1:])


class _Log:
    """An estimator that records what it was handed (the plumbing under test, no estimation)."""

    def __init__(self) -> None:
        self.calls: list[tuple[float, float | None]] = []

    def update(self, u: float, y: float) -> None:
        self.calls.append((u, y))

    def skip(self, u: float) -> None:
        self.calls.append((u, None))

    def warm_up(self) -> None:
        pass

    def current(self) -> dict[str, float]:
        return {}


def test_slow_denominator_raises_the_poles_to_the_factor() -> None:
    a, _ = _loop(50)
    poles = np.roots(np.r_[1.0, a])
    slow = np.roots(np.r_[1.0, slow_denominator(a, 7)])
    assert np.allclose(np.sort_complex(slow), np.sort_complex(poles**7))
    a_direct, _ = _loop(50 / 7)  # sampling 7x more slowly in the first place
    assert np.allclose(slow_denominator(a, 7), a_direct)


@pytest.mark.parametrize("ratio", [20, 100])
def test_factor_is_the_smallest_that_meets_the_condition(ratio: float) -> None:
    a, _ = _loop(ratio)
    assert convergence_margin(a) < 0  # the fast rate fails the condition (Q6)
    k = decimation_factor(a, target_margin=0.05)
    assert convergence_margin(slow_denominator(a, k)) >= 0.05
    assert convergence_margin(slow_denominator(a, k - 1)) < 0.05


def test_streaming_and_batch_decimation_agree() -> None:
    rng = np.random.default_rng(3)
    u = np.repeat(rng.uniform(-1, 1, 40), 6)
    u[50:53] += 0.3  # a group whose set point changes inside it
    y = rng.normal(size=u.size)
    valid = rng.random(u.size) > 0.2
    log = _Log()
    est = DecimatingEstimator(log, 4)
    for uk, yk, ok in zip(u, y, valid):
        est.update(uk, yk) if ok else est.skip(uk)
    us, ys, vs, held = decimate_record(u, y, 4, valid)
    assert len(log.calls) == us.size == est.stats.groups
    assert np.allclose([c[0] for c in log.calls], us)
    assert [c[1] is not None for c in log.calls] == vs.tolist()
    assert np.allclose([c[1] for c in log.calls if c[1] is not None], ys[vs])
    assert est.stats.unheld == int((~held).sum()) > 0
    assert est.stats.skipped == int((~vs).sum())


def test_decimated_mrgia_converges_where_the_fast_one_cannot() -> None:
    """The exact plant at 50x its loop's bandwidth, set point held for 3 groups (an exact-recovery test)."""
    a, b = _loop(50)
    plant = BacklashModel(a=tuple(a), b=tuple(b), delay=1, m2=1.0, c1=0.004, c2=0.004)
    k = decimation_factor(a)
    rng = np.random.default_rng(0)
    u = np.repeat(rng.uniform(-0.05, 0.05, 900), 3 * k)
    y = free_run(plant, u)
    config = MRGIAConfig(na=2, nb=1, delay=1)
    fast = run_mrgia(u, y, config)
    est = DecimatingEstimator(MRGIA(config), k, record_every=10)
    for uk, yk in zip(u, y):
        est.update(uk, yk)
    slow = est.mrgia_result()
    assert slow is not None and slow.samples == u.size // k
    gap_fast = fast.model.dead_zone if fast.settled else np.inf
    assert abs(slow.model.dead_zone / plant.dead_zone - 1) < 0.03
    assert not abs(gap_fast / plant.dead_zone - 1) < 0.03
    assert abs(slow.model.m2 - 1) < 0.03
