"""Run an online estimator on a decimated stream, at a rate where the MRGIA's convergence condition holds.

Hosts sample a servo at 10-200 times its position loop's bandwidth. There the
linear block's poles crowd towards 1 and the condition under which the MRGIA
converges -- ``|A(e^jw) - 1| < 1`` at every frequency, i.e. ``1/A(q) - 1/2``
strictly positive real, the condition of Ljung (1977b) on which the paper's
Theorem 1 rests (:func:`~servoid.ident.online.mrgia.convergence_margin`) --
fails from about 10x on. Sampling ``k`` times more slowly raises each pole to
the power ``k`` (:func:`slow_denominator`), which restores it:
:func:`decimation_factor` picks the smallest ``k`` that does.

The session still samples as fast as the device allows (the recording keeps
every sample); :class:`DecimatingEstimator` hands its inner estimator one
sample per group of ``k``. The slow record is a zero-order-hold record of the
same plant only when the set point is held for whole groups
(``/work/notes/proto12`` Q6: box-averaging a changing set point gave 6-14x
the noise floor), so:

* ``y_slow(j) = y(j k)``, the first sample of group ``j``: it depends on the
  commands up to group ``j - 1`` only. Picking, not averaging, keeps the
  backlash a static map of the sampled ``x`` (an average of ``y`` over a
  reversal is no backlash of anything); the fast noise is white, so picking
  aliases nothing that a model would have to explain.
* ``u_slow(j)`` is the set point held over group ``j``. Where the set point
  changed inside the group the command is anti-aliased by its mean over the
  group, and the group is counted as *not held* (:attr:`DecimationStats.unheld`):
  a designed excitation holds for multiples of ``k`` and has none.
* a group whose picked sample is not usable (lost, late, in a guard window)
  is skipped with its command (:meth:`Estimator.skip`).

The slow sample of group ``j`` is complete only at the group's end, so the
inner estimator sees it ``k - 1`` fast samples late; :func:`decimate_record`
builds the same slow record from arrays, for the offline stage to refine on
the same time base.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from servoid import validation
from servoid.errors import ConfigError
from servoid.ident.online.estimator import Estimator
from servoid.ident.online.mrgia import MRGIA, MRGIAResult, convergence_margin

__all__ = [
    "DecimatingEstimator",
    "DecimationStats",
    "decimate_record",
    "decimation_factor",
    "slow_denominator",
    "MAX_FACTOR",
    "TARGET_MARGIN",
]

#: The largest decimation :func:`decimation_factor` proposes: beyond it a 1 kHz host would
#: estimate at under 20 Hz, too slow for any servo's loop.
MAX_FACTOR = 50

#: The convergence margin :func:`decimation_factor` asks for. 0 is the boundary (the paper's
#: own plant sits on it); a little inside leaves room for the probe's model being rough.
TARGET_MARGIN = 0.05

#: Relative tolerance under which a group's commands count as one held set point.
_HELD_RTOL = 1e-9


def slow_denominator(a: Sequence[float] | np.ndarray, factor: int) -> np.ndarray:
    """The denominator ``a_1 .. a_na`` of the same linear block sampled ``factor`` times more slowly.

    A zero-order-hold discretisation maps a continuous pole ``s`` to
    ``exp(s T)``; at ``factor T`` it is ``exp(s T)^factor``.

    Parameters
    ----------
    a : array_like
        Denominator coefficients of eq. (1) at the fast rate, ``A(q) = 1 + a_1 q^-1 + ...``.
    factor : int
        Decimation factor ``k >= 1``.
    """
    arr = validation.signal("a", a)
    k = validation.integer("factor", factor, minimum=1)
    poles = np.roots(np.concatenate(([1.0], arr)))
    slow: np.ndarray = np.real(np.poly(poles**k))[1:]
    return slow


def decimation_factor(
    a: Sequence[float] | np.ndarray, *, max_factor: int = MAX_FACTOR, target_margin: float = TARGET_MARGIN
) -> int:
    """The smallest decimation at which the MRGIA's convergence condition holds for the linear block ``a``.

    Parameters
    ----------
    a : array_like
        Denominator ``a_1 .. a_na`` at the session's rate (the probe's model).
    max_factor : int
        Largest factor tried; it is returned when none reaches the margin.
    target_margin : float
        Margin of :func:`~servoid.ident.online.mrgia.convergence_margin` to reach.

    Returns
    -------
    int
        ``1`` when the condition already holds at the session's rate.
    """
    top = validation.integer("max_factor", max_factor, minimum=1)
    for k in range(1, top + 1):
        if convergence_margin(slow_denominator(a, k)) >= target_margin:
            return k
    return top


@dataclass(frozen=True)
class DecimationStats:
    """What a decimated run saw.

    Attributes
    ----------
    factor : int
        Fast samples per slow sample.
    groups : int
        Slow samples formed.
    used : int
        Slow samples handed to the estimator as measured.
    skipped : int
        Slow samples whose picked measurement was not usable.
    unheld : int
        Groups inside which the set point changed (their command was averaged).
    """

    factor: int
    groups: int
    used: int
    skipped: int
    unheld: int

    def to_dict(self) -> dict[str, Any]:
        """For JSON: the fields by name."""
        return {"factor": self.factor, "groups": self.groups, "used": self.used, "skipped": self.skipped,
                "unheld": self.unheld}  # fmt: skip


def decimate_record(
    u: Sequence[float] | np.ndarray,
    y: Sequence[float] | np.ndarray,
    factor: int,
    valid: Sequence[bool] | np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The slow record :class:`DecimatingEstimator` feeds its estimator, from whole arrays.

    Only complete groups are kept (a trailing part group is dropped, as the
    streaming estimator never completes it).

    Parameters
    ----------
    u, y : array_like
        The fast record (``y`` may be NaN where ``valid`` is False).
    factor : int
        Fast samples per slow sample.
    valid : array_like of bool, optional
        Usable fast samples; default all.

    Returns
    -------
    u_slow, y_slow, valid_slow, held : ndarray
        The slow command (the held set point, or the group's mean), the
        picked output, whether it is usable, and whether the group was held.
    """
    k = validation.integer("factor", factor, minimum=1)
    u_arr = np.asarray(u, dtype=np.float64)
    y_arr = np.asarray(y, dtype=np.float64)
    keep = np.ones(u_arr.shape, dtype=np.bool_) if valid is None else np.asarray(valid, dtype=np.bool_)
    if not (u_arr.shape == y_arr.shape == keep.shape) or u_arr.ndim != 1:
        raise ConfigError(f"u, y and valid must be 1-D of one length, not {u_arr.shape}, {y_arr.shape}, {keep.shape}")
    n = (u_arr.size // k) * k
    groups = u_arr[:n].reshape(-1, k)
    held = np.all(np.abs(groups - groups[:, :1]) <= _HELD_RTOL * (1.0 + np.abs(groups[:, :1])), axis=1)
    u_slow = np.where(held, groups[:, 0], groups.mean(axis=1))
    return u_slow, y_arr[:n:k].copy(), keep[:n:k].copy(), held


class DecimatingEstimator:
    """An :class:`~servoid.ident.online.estimator.Estimator` that hands another one every ``factor``-th sample.

    Parameters
    ----------
    inner : Estimator
        The estimator of the slow stream (an :class:`MRGIA`, or the wear estimator).
    factor : int
        Fast samples per slow sample (:func:`decimation_factor`); 1 passes every sample on.
    record_every : int
        For an inner :class:`MRGIA`: keep its theta and line coverage every
        ``record_every`` slow samples (:meth:`mrgia_result`).
    """

    def __init__(self, inner: Estimator, factor: int, *, record_every: int = 1) -> None:
        self.inner = inner
        self.factor = validation.integer("factor", factor, minimum=1)
        self.record_every = validation.integer("record_every", record_every, minimum=1)
        self._i = 0  # position inside the current group
        self._u_first = 0.0
        self._u_sum = 0.0
        self._held = True
        self._y: float | None = None  # the group's picked output, None when not usable
        self._groups = self._used = self._skipped = self._unheld = 0
        self._theta: list[np.ndarray] = []
        self._coverage: list[tuple[float, float]] = []

    def update(self, u: float, y: float) -> None:
        """Take a usable fast sample."""
        self._take(float(u), float(y))

    def skip(self, u: float) -> None:
        """Take a fast sample whose measurement is not to be used."""
        self._take(float(u), None)

    def _take(self, u: float, y: float | None) -> None:
        if self._i == 0:
            self._u_first, self._u_sum, self._held, self._y = u, 0.0, True, y
        elif abs(u - self._u_first) > _HELD_RTOL * (1.0 + abs(self._u_first)):
            self._held = False
        self._u_sum += u
        self._i += 1
        if self._i < self.factor:
            return
        self._i = 0
        u_slow = self._u_first if self._held else self._u_sum / self.factor
        self._groups += 1
        self._unheld += not self._held
        if self._y is None:
            self._skipped += 1
            self.inner.skip(u_slow)
        else:
            self._used += 1
            self.inner.update(u_slow, self._y)  # EstimatorDiverged propagates to the feed
        if isinstance(self.inner, MRGIA) and self._groups % self.record_every == 0:
            self._theta.append(self.inner.theta)
            self._coverage.append(self.inner.coverage)

    def warm_up(self) -> None:
        """Compile the inner estimator's kernels now."""
        self.inner.warm_up()

    def current(self) -> Mapping[str, float]:
        """The inner estimator's estimate by name."""
        return self.inner.current()

    @property
    def stats(self) -> DecimationStats:
        """Counts of the slow stream so far."""
        return DecimationStats(self.factor, self._groups, self._used, self._skipped, self._unheld)

    def mrgia_result(self) -> MRGIAResult | None:
        """The inner MRGIA's result over the slow stream, with the kept history (None for another estimator)."""
        if not isinstance(self.inner, MRGIA):
            return None
        n = self.inner.config.n_params
        theta = np.array(self._theta).reshape(-1, n)
        coverage = np.array(self._coverage, dtype=np.float64).reshape(-1, 2)
        return self.inner.result(theta, coverage, self.record_every)
