"""Keeping a signal safe: the amplitude bound, then the rate limit, in an order that cannot break the bound.

Targets are first clipped to ``[low, high]``; then each sample moves from
the previous output towards its target by at most ``rate``. Because the
previous output and the target both lie in the interval, so does every point
between them: the rate limit can never push a sample out of the bound. The
limited sample is clipped once more only to absorb floating-point rounding,
and nudged back by one unit in the last place when rounding would make the
step exceed ``rate``, so that both limits hold exactly in floating point.
"""

from __future__ import annotations

import numpy as np

from servoid.ident._jit import jit

__all__ = ["clip_and_limit", "rate_limit_kernel"]


@jit
def rate_limit_kernel(target: np.ndarray, last: float, rate: float, low: float, high: float, out: np.ndarray) -> float:
    """Rate-limit ``target`` (already inside ``[low, high]``) into ``out``; return the last output.

    Parameters
    ----------
    target : ndarray
        Values inside the bound.
    last : float
        Output before ``target[0]`` (inside the bound).
    rate : float
        Largest ``|out[k] - out[k-1]|``, ``> 0``.
    low, high : float
        The bound.
    out : ndarray
        Filled in place.
    """
    for k in range(target.shape[0]):
        goal = target[k]
        if goal - last > rate:
            value = last + rate
            while value - last > rate:  # rounding of last + rate went one ulp too far
                value = np.nextafter(value, last)
        elif last - goal > rate:
            value = last - rate
            while last - value > rate:
                value = np.nextafter(value, last)
        else:
            value = goal
        value = min(max(value, low), high)
        out[k] = value
        last = value
    return last


def clip_and_limit(
    target: np.ndarray, *, low: float, high: float, rate: float, last: float
) -> tuple[np.ndarray, float]:
    """Clip ``target`` to ``[low, high]`` and rate-limit it from ``last``.

    Parameters
    ----------
    target : ndarray
        Wanted values, unit of ``u``.
    low, high : float
        The bound.
    rate : float
        Largest change per sample; ``inf`` for none.
    last : float
        Output before the first sample (inside the bound).

    Returns
    -------
    values : ndarray
        Inside ``[low, high]``, steps at most ``rate``.
    last : float
        The last value (``last`` unchanged when ``target`` is empty).
    """
    clipped = np.clip(target, low, high)
    if not np.isfinite(rate):
        return clipped, float(clipped[-1]) if clipped.size else last
    out = np.empty_like(clipped)
    last = rate_limit_kernel(clipped, float(last), float(rate), float(low), float(high), out)
    return out, float(last)
