"""When an estimate's mean has crossed a bound: Page's CUSUM with its reference at the bound, its threshold from a false-alarm rate.

The alarm rule of :mod:`~servoid.ident.monitoring.alarms` asks ``persist``
estimates in a row to lie beyond a bound by ``z`` standard deviations; for an
estimate that scatters by 7 % of its value (the play of a short window) and a
bound at +10 %, a +20 % step then rarely raises it. A CUSUM adds up the
evidence instead. With the bound ``high`` half-way between the mean the
estimate had (``m0``) and the mean to detect (``m0 + 2 (high - m0)``: a bound
at +10 % detects a +20 % step best), Page's optimal statistic is::

    S(k) = max(0, S(k-1) + (x(k) - high) / sigma)        raise when S(k) > h

(and its mirror below ``low``). In control each check takes ``kappa = (high -
m0) / sigma`` from ``S`` on average; after the step it adds as much.

The threshold ``h`` comes from the mean number of checks between false alarms
(``arl``) by Siegmund's approximation for independent normal checks,
``ARL0 = (exp(2 kappa b) - 2 kappa b - 1) / (2 kappa^2)`` with ``b = h + 1.166``.
Estimates on overlapping windows are correlated: a run of ``tau`` correlated
checks counts as one (``tau`` the integrated autocorrelation, 1 for
independent checks), so ``h = tau h1`` where ``h1`` gives ``ARL0 = arl / tau``.
An alarm is cleared by the mirror statistic: the sum of ``(high - x) / sigma``
(of ``(x - low) / sigma`` below) from the alarm on, above the same ``h``: the
evidence that the mean is back inside is asked as much as the evidence that it
left (a rule of a few estimates in a row back inside cleared and raised again
on a noisy estimate that sat just past the bound). Clearing restarts the sums.
An event's ``since`` is the check after the sum last stood at 0: the CUSUM's
estimate of when the change began (it may precede the change by a few checks).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np
from scipy.optimize import brentq

from servoid import validation
from servoid.errors import ConfigError
from servoid.ident.monitoring.alarms import AlarmEvent, Bound

__all__ = ["Cusum", "threshold", "false_alarm_checks", "correlation_time"]

#: Siegmund's correction of the threshold for the overshoot of a normal walk.
_OVERSHOOT = 1.166


def false_alarm_checks(kappa: float, h: float, tau: float = 1.0) -> float:
    """Mean checks between false alarms of :class:`Cusum` (Siegmund's approximation; the module's text).

    Parameters
    ----------
    kappa : float
        Distance from the in-control mean to the bound, in standard deviations, > 0.
    h : float
        The threshold.
    tau : float
        Correlated checks that count as one, >= 1.

    Returns
    -------
    float
        The in-control average run length, checks.
    """
    k = validation.positive("kappa", kappa)
    t = max(1.0, validation.positive("tau", tau))
    x = 2.0 * k * (validation.non_negative("h", h) / t + _OVERSHOOT)
    return t * (math.expm1(x) - x) / (2.0 * k * k) if x < 700.0 else math.inf


def threshold(kappa: float, arl: float, tau: float = 1.0) -> float:
    """The threshold ``h`` whose mean number of checks between false alarms is ``arl``.

    Parameters
    ----------
    kappa : float
        Distance from the in-control mean to the bound, in standard deviations, > 0.
    arl : float
        Mean checks between false alarms wanted, > 1.
    tau : float
        Correlated checks that count as one, >= 1.

    Returns
    -------
    float
        ``h >= 0`` (0 when even ``h = 0`` gives ``arl``).
    """
    target = validation.positive("arl", arl)
    if false_alarm_checks(kappa, 0.0, tau) >= target:
        return 0.0
    hi = 1.0
    while false_alarm_checks(kappa, hi, tau) < target:
        hi *= 2.0
    return float(brentq(lambda h: math.log(false_alarm_checks(kappa, h, tau)) - math.log(target), 0.0, hi))


def correlation_time(x: Sequence[float] | np.ndarray, lags: int) -> float:
    """The integrated autocorrelation ``1 + 2 sum rho(j)``, ``j = 1..lags``, at least 1.

    Parameters
    ----------
    x : array_like
        The in-control estimates, in order.
    lags : int
        Largest lag summed (the checks a window overlaps).
    """
    a = np.asarray(x, dtype=np.float64)
    a = a - a.mean()
    var = float(np.dot(a, a))
    if a.size < 3 or var <= 0.0:
        return 1.0
    n = min(validation.integer("lags", lags, minimum=0), a.size - 2)
    rho = [float(np.dot(a[:-j], a[j:])) / var for j in range(1, n + 1)]
    return max(1.0, 1.0 + 2.0 * sum(rho))


class Cusum:
    """The CUSUM alarm over a set of bounds, fed one check at a time (the module's rule).

    Parameters
    ----------
    bounds : sequence of Bound
        One per quantity.
    h : float
        The threshold (:func:`threshold`); ``inf`` never raises.
    """

    def __init__(self, bounds: Sequence[Bound], h: float) -> None:
        names = [b.quantity for b in bounds]
        if len(set(names)) != len(names):
            raise ConfigError(f"one bound per quantity, got {', '.join(names)}")
        self.bounds = tuple(bounds)
        self.h = math.inf if h == math.inf else validation.non_negative("h", h)
        self._sum = {b.quantity: [0.0, 0.0] for b in self.bounds}  # above, below
        self._since = {b.quantity: [0, 0] for b in self.bounds}
        self._back = {b.quantity: [0.0, 0] for b in self.bounds}  # the clearing sum, since
        self._active: dict[str, AlarmEvent] = {}

    @property
    def active(self) -> dict[str, AlarmEvent]:
        """The alarms raised and not cleared, by quantity."""
        return dict(self._active)

    def statistic(self, quantity: str) -> float:
        """The larger of the two sums of ``quantity`` (above and below), in standard deviations.

        Parameters
        ----------
        quantity : str
            A bound's quantity.
        """
        return max(self._sum[quantity])

    def check(self, sample: int, readings: Mapping[str, tuple[float, float]]) -> list[AlarmEvent]:
        """Add one check to the sums; return the alarms it raised or cleared.

        Parameters
        ----------
        sample : int
            Sample index of the check.
        readings : mapping
            ``{quantity: (value, std)}``, ``std > 0``; a NaN value or std changes nothing.
        """
        events = []
        for bound in self.bounds:
            if bound.quantity not in readings:
                continue
            value, std = readings[bound.quantity]
            if math.isnan(value) or not std > 0.0:
                continue
            q = bound.quantity
            sums, since = self._sum[q], self._since[q]
            for i, step in enumerate(((value - bound.high) / std, (bound.low - value) / std)):
                if math.isinf(step):  # an open side
                    continue
                if sums[i] == 0.0:
                    since[i] = sample
                sums[i] = max(0.0, sums[i] + step)
            if q not in self._active:
                if max(sums) > self.h:
                    i = 0 if sums[0] >= sums[1] else 1
                    self._active[q] = AlarmEvent(bound, True, sample, value, std, ("above", "below")[i], since[i])
                    self._back[q] = [0.0, sample]
                    events.append(self._active[q])
                continue
            back = self._back[q]
            step = (bound.high - value if self._active[q].side == "above" else value - bound.low) / std
            if back[0] == 0.0:
                back[1] = sample
            back[0] = max(0.0, back[0] + step)
            if back[0] > self.h:
                events.append(AlarmEvent(bound, False, sample, value, std, self._active.pop(q).side, int(back[1])))
                sums[0] = sums[1] = 0.0
        return events
