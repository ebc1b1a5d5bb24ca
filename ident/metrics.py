"""Fit metrics, defined once."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from servoid import validation
from servoid.errors import ConfigError

__all__ = ["nrmse", "free_run_nrmse", "residual_nrmse"]


def nrmse(y: Sequence[float] | np.ndarray, y_hat: Sequence[float] | np.ndarray) -> float:
    """Normalised root-mean-square error ``rms(y - y_hat) / std(y)``.

    0 is a perfect fit; 1 is no better than the mean of ``y``.

    Raises
    ------
    ConfigError
        If the lengths differ, a value is not finite, or ``y`` is constant.
    """
    y_arr = validation.signal("y", y)
    yh = validation.signal("y_hat", y_hat)
    if y_arr.shape != yh.shape:
        raise ConfigError(f"y and y_hat differ in length: {y_arr.size} against {yh.size}")
    std = float(np.std(y_arr))
    if std == 0.0:
        raise ConfigError("y is constant: an NRMSE against it is undefined")
    return float(np.sqrt(np.mean((y_arr - yh) ** 2)) / std)


def free_run_nrmse(y: Sequence[float] | np.ndarray, y_hat: Sequence[float] | np.ndarray) -> float:
    """:func:`nrmse` of a simulated free run that may have run away: infinite then, not an error.

    A candidate model met on the way (a search's start, a fit that stalled at absurd gains) can
    diverge: its output grows past what a square holds (about 1e154) or leaves the floats. Such a
    model fits infinitely badly, which is what a comparison of candidates needs to read.

    Raises
    ------
    ConfigError
        As :func:`nrmse`, for ``y``.
    """
    yh = np.asarray(y_hat, dtype=np.float64)
    if not np.all(np.isfinite(yh)):
        return math.inf
    with np.errstate(over="ignore"):
        return nrmse(y, yh)


def residual_nrmse(residual: np.ndarray, y_std: float) -> float:
    """:func:`nrmse` from the residual ``y_hat - y`` and ``std(y)``: no copy of a long record.

    Parameters
    ----------
    residual : ndarray
        ``y_hat - y``.
    y_std : float
        The standard deviation of the measured ``y``.

    Raises
    ------
    ConfigError
        If ``y_std`` is 0 (a constant ``y``).
    """
    if y_std == 0.0:
        raise ConfigError("y is constant: an NRMSE against it is undefined")
    return float(np.sqrt(float(residual @ residual) / residual.size) / y_std)
