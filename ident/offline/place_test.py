"""Whether a record rejects one place of the play against the other: a Diebold-Mariano test of their validation errors.

The validation margin (``val_other / val_best - 1``) says how much better one place of the play
predicts the validation blocks; it does not say whether that is more than the record's noise lets
two models differ by. Two models that both fit at the floor differ by a few per cent and may do so
by chance, or on every reversal. The test (Diebold & Mariano 1995, "Comparing predictive accuracy",
J. Business & Economic Statistics 13(3)) reads the loss differential ``d_t = e_other,t^2 - e_best,t^2``
of the two free runs on the validation samples: its mean over its standard error, with the
Newey-West (Bartlett) long-run variance, since free-run errors are correlated over many samples.
Large and positive: the record prefers the winner's place at every part of the record, not in one
stretch; near 0: the two places explain the record alike.

Measured on the twins (issue 12 horn search session, gentle sines, 10/20/50x, seeds 1-2): the
XM430 (play in the loop) wins by 1.3-7.4 % with both places within 1.0-1.7 times the floor, which the
margin rule calls undetermined; the statistic is +0.9 (10x s1), +2.4 ... +6.9 on the other five. The
CiA 402's motor-side winners (margins 0.3-1.8 %) score +1.4 ... +4.8 against the play in the loop, but so do
the horn twins' wrong motor-side winners on held steps and with four times the friction (+2.6 ... +5.5,
issue 12 DM session): a model that misses an effect can lose everywhere in the right place, so only a
play-in-loop answer is read (:data:`~servoid.ident.offline.intervals.PLACE_Z`).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["place_z"]


def place_z(e_best: np.ndarray, e_other: np.ndarray) -> float:
    """The Diebold-Mariano statistic of the winner's squared errors against the other's (positive: the winner's better).

    Parameters
    ----------
    e_best, e_other : ndarray
        The two models' free-run errors on the same validation samples, in time order.

    Returns
    -------
    float
        ``mean(d) / se(mean(d))`` with ``d = e_other^2 - e_best^2`` and the Bartlett long-run variance
        (``sqrt(n)`` lags, as :func:`~servoid.ident.offline.intervals.hac_stderr` takes); NaN with fewer
        than 2 samples or a non-finite error, +-inf where the differential does not vary but its mean does not vanish.
    """
    a = np.asarray(e_best, dtype=np.float64)
    b = np.asarray(e_other, dtype=np.float64)
    if a.shape != b.shape or a.ndim != 1 or a.size < 2 or not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))):
        return math.nan
    d = b * b - a * a
    n = d.size
    mean = float(np.mean(d))
    c = d - mean
    lags = max(1, int(math.sqrt(n)))
    var = float(c @ c) / n
    for lag in range(1, min(lags, n - 1) + 1):
        var += 2.0 * (1.0 - lag / (lags + 1)) * float(c[lag:] @ c[:-lag]) / n
    if var <= 0.0:
        return math.nan if mean == 0.0 else math.copysign(math.inf, mean)
    return mean / math.sqrt(var / n)
