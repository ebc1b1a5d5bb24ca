"""Whether a record rejects one place of the play against the other: a test of their errors after the reversals.

The validation margin (``val_other / val_best - 1``) says how much better one place of the play
predicts the validation blocks; it does not say whether that is more than the record's noise lets
two models differ by. Two models that both fit at the floor differ by a few per cent and may do so
by chance, or on every reversal. The test reads the loss differential ``d_t = e_other,t^2 - e_best,t^2``
of the two free runs (Diebold & Mariano 1995, "Comparing predictive accuracy", J. Business & Economic
Statistics 13(3)). Until the issue 12 xmname session it was their test over the whole validation record
(the mean over its Newey-West standard error); what it measured then follows.

Measured on the twins (issue 12 horn search session, gentle sines, 10/20/50x, seeds 1-2): the
XM430 (play in the loop) wins by 1.3-7.4 % with both places within 1.0-1.7 times the floor, which the
margin rule calls undetermined; the statistic is +0.9 (10x s1), +2.4 ... +6.9 on the other five. The
CiA 402's motor-side winners (margins 0.3-1.8 %) score +1.4 ... +4.8 against the play in the loop, but so do
the horn twins' wrong motor-side winners on held steps and with four times the friction (+2.6 ... +5.5,
issue 12 DM session): a model that misses an effect can lose everywhere in the right place, so only a
play-in-loop answer is read (:data:`~servoid.ident.offline.intervals.PLACE_Z`).

The statistic :func:`~servoid.ident.offline.loop_fit.fit_loop` reads is :func:`reversal_z` (issue 12 xmname
session): the same loss differential, on the catch-ups after the reversals only (:func:`catch_up_groups`), one
observation a reversal. Where both places fit near the floor, the whole record's differential is mostly made
mid-stroke, where both places are the same linear loop and the fits differ by how each traded gains, friction
and play; that trade named wrong places: the CiA 402 twin with no encoder noise (50x s4) at +2.47 and with a
1024-count encoder (20x s3) at +2.77, both play-in-loop winners over 2.33 (``benchmarks/variants.py``). On the
catch-ups they score -0.35 and +0.15, the XM430's gentle sines (10/20/50x, seeds 1-2) +0.6 ... +6.6 (was
+1.0 ... +5.1), and on seeds 3-6 the four XM430 winners under the 5 % margin +2.7 ... +4.5 (was +1.9 ... +3.1).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["reversal_z", "catch_up_groups"]


def catch_up_groups(y_hat: np.ndarray, play: float, span: int, scored: np.ndarray) -> list[np.ndarray]:
    """The scored samples of each catch-up after a reversal of ``y_hat``: from the turn's confirmation, ``span`` more.

    A turn is confirmed where ``y_hat`` has come back by more than ``play`` from its extreme
    (:func:`~servoid.ident.offline.intervals.reversal_indices`): the play has been crossed and the output moves
    again. The group is that sample and the ``span`` after it, those of ``scored`` only (empty ones dropped).

    Parameters
    ----------
    y_hat : ndarray
        The winner's free run.
    play : float
        Its play (the turn's threshold).
    span : int
        Samples after the confirmation (>= 0).
    scored : ndarray of bool
        The samples that count (the validation blocks), ``y_hat``'s length.

    Returns
    -------
    list of ndarray of int
    """
    from servoid.ident.offline.intervals import reversal_indices

    scored = np.asarray(scored, dtype=np.bool_)
    groups = []
    for t in reversal_indices(y_hat, play):
        g = np.arange(int(t), min(int(t) + span + 1, scored.size))
        g = g[scored[g]]
        if g.size:
            groups.append(g)
    return groups


def reversal_z(e_best: np.ndarray, e_other: np.ndarray, groups: list[np.ndarray]) -> float:
    """The winner's place against the other's on the catch-ups after reversals: a t statistic over the reversals.

    Where the two places of the play differ physically: after a reversal the output has crossed the play,
    and a loop closed on it (play in the loop) has been driving the motor through the play all the while,
    so the output catches up; a loop closed on the motor (play outside it) has moved the motor at its own
    pace, and the output lags by the play. Mid-stroke both are the same linear loop, and there the two fits
    differ only by how each traded its gains, friction and play against the record's other effects: the
    whole-record statistic (the Diebold-Mariano test before) reads that trade as evidence too. Each reversal's summed loss
    differential ``sum(e_other^2 - e_best^2)`` over its group (:func:`catch_up_groups`) is one observation
    (the reversals are far apart against the noise's and the loop's memory); the statistic is their mean
    over its standard error (positive: the winner's place better).

    Parameters
    ----------
    e_best, e_other : ndarray
        The two models' free-run errors over the same samples.
    groups : list of ndarray of int
        The samples of each reversal's catch-up.

    Returns
    -------
    float
        NaN with fewer than 3 groups or a non-finite error in them; +-inf where the sums do not vary but
        their mean does not vanish.
    """
    a = np.asarray(e_best, dtype=np.float64)
    b = np.asarray(e_other, dtype=np.float64)
    if a.shape != b.shape or len(groups) < 3:
        return math.nan
    d = b * b - a * a
    sums = np.array([float(np.sum(d[g])) for g in groups])
    if not np.all(np.isfinite(sums)):
        return math.nan
    mean = float(np.mean(sums))
    sd = float(np.std(sums, ddof=1))
    if sd <= 0.0:
        return math.nan if mean == 0.0 else math.copysign(math.inf, mean)
    return mean / (sd / math.sqrt(sums.size))
