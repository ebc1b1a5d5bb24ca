"""The smoothed backlash inverse: the position the backlash's input must take for a wanted output.

For the backlash of :mod:`servoid.ident.models.pseudo_wiener` (up line ``y = x - c1``, down
line ``y = m2 (x + c2)``, memory zone between), the inverse of Tao &
Kokotović maps a wanted output ``y_d`` to the input that produces it::

    y_d rising    x_d = y_d + c1           (on the up line)
    y_d falling   x_d = y_d / m2 - c2      (on the down line)
    y_d standing  x_d held

At every reversal of ``y_d`` this *naive* inverse jumps across the whole gap
``(y_d + c1) - (y_d / m2 - c2)``. Where ``y_d`` reverses for a sample or two
(a feedback correction overshooting, measurement noise, a quantised
encoder) the command jumps across the gap and back, and a servo whose
dead zones are even slightly overestimated then stutters.

The smoothing band
------------------
:class:`BacklashInverse` blends the two lines with a weight ``s`` in
``[0, 1]`` (0: up line, 1: down line) that is itself a play of width
``band`` on ``y_d``::

    s(k) = clip(s(k-1) + (y_d(k-1) - y_d(k)) / band, 0, 1)
    x_d  = (1 - s) (y_d + c1) + s (y_d / m2 - c2)

so the command crosses the gap while ``y_d`` travels ``band`` in the new
direction. A reversal of ``e < band`` moves the command by the fraction
``e / band`` of the gap, not the whole gap; a reversal of at least ``band``
(or a step larger than ``band``) puts it on the new line exactly, and from
there on ``backlash(x_d) == y_d``. The price is a lag: after a reversal the
output waits until ``y_d`` has travelled about ``band``, so the tracking
error there is at most about ``band``. ``band = 0`` is the naive inverse.
The weight is rate-independent (it depends on how far ``y_d`` went back, not
how fast), so it behaves the same at every sampling rate and speed.

Units: ``y_d``, ``x_d``, ``c1``, ``c2`` and ``band`` are in the output unit.

The C header of ``servoid export --format c`` implements the same arithmetic
in the same order; a test compiles it and compares sample by sample.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from servoid import validation
from servoid.errors import ConfigError, ModelError
from servoid.ident.models.pseudo_wiener import BacklashModel

__all__ = ["InverseParams", "BacklashInverse", "backlash_inverse", "default_band"]

#: Default smoothing band relative to the dead zone ``c1 + c2``.
BAND_DEAD_ZONE_SHARE = 0.02

#: Default smoothing band relative to the output noise (the residual of the fit).
#: Feedback brings the measurement noise into the wanted output, which then
#: reverses every few samples by about a noise standard deviation; with a band
#: of two of them such a reversal moves the command across a part of the gap
#: only. On the paper's plant at SNR 43 this cuts the motor's travel from 8x to
#: 3x the reference's; wider bands gain little more and cost accuracy, since the
#: error after each reversal grows with the band (docs/compensation.md).
BAND_NOISE_MULTIPLE = 2.0


def default_band(model: BacklashModel, *, noise_std: float | None = None) -> float:
    """The smoothing band servoid proposes for ``model``, in the output unit.

    ``max(0.02 (c1 + c2), 2 noise_std)``: a small share of the dead zone,
    widened where the output noise would otherwise make the weight flip.

    Parameters
    ----------
    model : BacklashModel
        The identified model.
    noise_std : float, optional
        Standard deviation of the output noise (for instance the residual of
        the identification fit), in the output unit.
    """
    band = BAND_DEAD_ZONE_SHARE * model.dead_zone
    if noise_std is not None:
        band = max(band, BAND_NOISE_MULTIPLE * validation.non_negative("noise_std", noise_std))
    return band


@dataclass(frozen=True)
class InverseParams:
    """What the backlash inverse needs: the two lines and the smoothing band.

    Parameters
    ----------
    m2 : float
        Slope of the down line, ``> 0``.
    c1, c2 : float
        Dead zones of the up and down lines, ``> 0``, output unit.
    band : float
        Smoothing band, ``>= 0``, output unit (0: the naive inverse).
    """

    m2: float
    c1: float
    c2: float
    band: float

    def __post_init__(self) -> None:
        try:
            for name in ("m2", "c1", "c2"):
                object.__setattr__(self, name, validation.positive(name, getattr(self, name)))
            object.__setattr__(self, "band", validation.non_negative("band", self.band))
        except ConfigError as exc:
            raise ModelError(str(exc)) from None

    @classmethod
    def from_model(cls, model: BacklashModel, *, band: float) -> InverseParams:
        """The backlash part of ``model`` with the given band."""
        return cls(m2=model.m2, c1=model.c1, c2=model.c2, band=band)

    def weight_for(self, y: float, x: float) -> float:
        """The weight ``s`` that puts the command at ``x`` for output ``y``, clipped to ``[0, 1]``.

        ``s = 0`` at ``x = y + c1`` (resting on the up line), ``s = 1`` at
        ``x = y / m2 - c2`` (resting on the down line); in between, the
        share of the gap the input has crossed.
        """
        up = y + self.c1
        gap = up - (y / self.m2 - self.c2)
        if gap == 0.0:  # exactly where the lines cross: both lines agree
            return 0.0
        return min(1.0, max(0.0, (up - x) / gap))


class BacklashInverse:
    """The smoothed backlash inverse, one sample at a time.

    Parameters
    ----------
    params : InverseParams
        Lines and smoothing band.
    y0 : float
        The output at the start (output unit).
    x0 : float, optional
        The backlash input at the start (for a servo, the motor-side
        position), if known: the weight starts where it puts the command at
        ``x0`` (see :meth:`InverseParams.weight_for`). Unknown: the up line.

    Notes
    -----
    Public state: :attr:`weight` (``s``, 0 up line, 1 down line) and
    :attr:`y_prev` (the previous wanted output). See the module docstring
    for the equations.
    """

    def __init__(self, params: InverseParams, *, y0: float = 0.0, x0: float | None = None) -> None:
        self.params = params
        self.reset(y0, x0=x0)

    def reset(self, y0: float, *, x0: float | None = None) -> None:
        """Start again from output ``y0`` (and backlash input ``x0`` when known)."""
        self.y_prev = validation.real("y0", y0)
        self.weight = 0.0 if x0 is None else self.params.weight_for(self.y_prev, validation.real("x0", x0))

    def step(self, y_d: float) -> float:
        """The backlash input ``x_d`` that gives the output ``y_d`` (output unit)."""
        if not math.isfinite(y_d):
            raise ConfigError(f"y_d (={y_d!r}) must be finite")
        p = self.params
        s = self.weight
        if p.band > 0.0:
            s = s + (self.y_prev - y_d) / p.band
            s = 1.0 if s > 1.0 else (0.0 if s < 0.0 else s)
        elif y_d < self.y_prev:
            s = 1.0
        elif y_d > self.y_prev:
            s = 0.0
        self.weight = s
        self.y_prev = y_d
        # The same expression, in the same order, as the exported C function.
        return (1.0 - s) * (y_d + p.c1) + s * (y_d / p.m2 - p.c2)


def backlash_inverse(
    params: InverseParams,
    y_d: Sequence[float] | np.ndarray,
    *,
    y0: float | None = None,
    x0: float | None = None,
) -> np.ndarray:
    """The batch twin of :class:`BacklashInverse`: ``x_d`` for a whole wanted output.

    Parameters
    ----------
    params : InverseParams
        Lines and smoothing band.
    y_d : array_like
        Wanted output, 1-D, finite (output unit).
    y0 : float, optional
        Output before the first sample (default ``y_d[0]``: the first sample
        is then not a move).
    x0 : float, optional
        Backlash input before the first sample, if known.

    Returns
    -------
    ndarray
        The command ``x_d``, one per sample.
    """
    y = validation.signal("y_d", y_d)
    inverse = BacklashInverse(params, y0=float(y[0]) if y0 is None else y0, x0=x0)
    return np.array([inverse.step(v) for v in y.tolist()])
