"""The place test of two places' validation errors on the catch-ups after reversals (:mod:`servoid.ident.offline.place_test`)."""

from __future__ import annotations

import math

import numpy as np

from servoid.drivers.twin import Twin, preset
from servoid.excitation.generate import sample
from servoid.excitation.specs import GentleSpec
from servoid.ident.offline.loop_fit import block_mask
from servoid.ident.offline.place_test import catch_up_groups, reversal_z


def _xm430(u: np.ndarray, period: float, noise_counts: float, **over: object) -> tuple[np.ndarray, float]:
    """The XM430 twin's readings of ``u`` (4096-count horn encoder) and its play; ``over``: twin fields."""
    twin = Twin(preset("xm430", load_encoder_cpr=4096, encoder_noise_counts=noise_counts, **over), seed=5)
    twin.enable()
    return np.asarray(twin.sample(u, period).y, dtype=np.float64), twin.truth.play_rad


def test_the_catch_ups_after_reversals_name_the_place_and_ignore_the_strokes_between() -> None:
    # 10 s of gentle sines at 20x the XM430's loop bandwidth (the play in the loop, 2.8 counts): its own
    # noise-free response (the right place) against the same servo's with the loop closed on the motor
    period = 1.0 / 70.0
    u = sample(GentleSpec(amplitude=0.1, accel=8.0 * period**2, spread=8.0), 700, seed=5)
    y, play = _xm430(u, period, 0.3)
    right, _ = _xm430(u, period, 0.0)
    wrong, _ = _xm430(u, period, 0.0, loop_encoder="motor", motor_encoder_cpr=2**22)
    val = ~block_mask(u.size)
    groups = catch_up_groups(right, play, 2, val)
    assert len(groups) >= 10 and all(val[g].all() for g in groups)
    assert reversal_z(right - y, wrong - y, groups) > 3.0
    assert reversal_z(wrong - y, right - y, groups) < -3.0
    # the right place's fit off by two counts between the catch-ups (what a fit trades mid-stroke): the
    # whole record's mean loss differential turns against it, the catch-ups' statistic does not move
    between = np.ones(u.size, dtype=bool)
    for g in groups:
        between[g] = False
    traded = right + np.where(between, 2.0 * 2.0 * math.pi / 4096, 0.0)

    def whole(e_best: np.ndarray) -> float:
        return float(np.mean((wrong - y)[val] ** 2 - e_best[val] ** 2))

    assert whole(traded - y) < whole(right - y)
    assert reversal_z(traded - y, wrong - y, groups) == reversal_z(right - y, wrong - y, groups)


def test_reversal_z_needs_three_reversals_and_finite_errors() -> None:
    e = np.ones(10)
    groups = [np.array([0, 1]), np.array([4]), np.array([7, 8])]
    assert math.isnan(reversal_z(e, 2.0 * e, groups[:2]))
    assert reversal_z(e, 2.0 * e, [np.array([0]), np.array([4]), np.array([7])]) == math.inf
    assert math.isnan(reversal_z(e, np.where(np.arange(10) == 4, np.nan, 1.0), groups))
    assert math.isnan(reversal_z(e, np.ones(9), groups))
