"""Reference paths for tracking tests: sines, steps and a triangle, scaled to the backlash.

Backlash hurts most where the motion is comparable with the play, so the
amplitudes are multiples of the dead zone ``c1 + c2`` (or of an amplitude
the caller gives). With ``m2 != 1`` the up and down lines cross, and there
the backlash (and so its inverse) is not the play it is elsewhere; the
paths stay within half the distance from 0 to that crossing.

Units: output unit; time in samples.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from servoid import validation
from servoid.ident.models.pseudo_wiener import BacklashModel

__all__ = ["Reference", "reference_suite", "amplitude_limit"]

#: Share of the distance from 0 to the crossing of the lines the paths may use.
_CROSSING_SHARE = 0.5


@dataclass(frozen=True)
class Reference:
    """A reference path.

    Attributes
    ----------
    name : str
        Short label: kind, amplitude, period in samples (``"sine 0.75 T200"``).
    values : ndarray
        The wanted output per sample (output unit).
    amplitude : float
        Largest ``|r|`` (output unit).
    period : int or None
        Period in samples (sines and triangle), ``None`` for the steps.
    """

    name: str
    values: np.ndarray
    amplitude: float
    period: int | None


def amplitude_limit(model: BacklashModel) -> float | None:
    """Largest amplitude the paths may have for ``model``, or ``None`` (no limit, ``m2 == 1``).

    Half the distance from 0 to the output where the up and down lines cross.
    """
    cross = model.lines_cross_at
    if cross is None:
        return None
    return _CROSSING_SHARE * abs(cross - model.c1)


def _sine(amplitude: float, period: int, n: int) -> np.ndarray:
    return amplitude * np.sin(2.0 * np.pi * np.arange(n) / period)


def _triangle(amplitude: float, period: int, n: int) -> np.ndarray:
    phase = (np.arange(n) / period + 0.75) % 1.0  # starts at 0, rising, like the sine
    return amplitude * (4.0 * np.abs(phase - 0.5) - 1.0)


def reference_suite(model: BacklashModel, *, samples: int = 600, scale: float | None = None) -> tuple[Reference, ...]:
    """Five paths that start at rest at 0 and reverse many times.

    ==========================  ===============================================
    ``sine s/2 T(N/3)``         slow sine, amplitude half the scale
    ``sine 3s/2 T(N/3)``        slow sine, large (capped by :func:`amplitude_limit`)
    ``sine s/2 T(N/12)``        fast sine
    ``steps s/2``               holds at ``s (0, .5, -.5, .25, -.25, .1, -.1, 0)``:
                                steps from ``s`` down to ``s/10``, most within the play
    ``triangle s/2 T(N/3)``     constant speed between reversals
    ==========================  ===============================================

    Parameters
    ----------
    model : BacklashModel
        The servo (for the dead zone and where its lines cross).
    samples : int
        Length ``N`` of each path, ``>= 96``.
    scale : float, optional
        ``s`` (output unit); default the dead zone ``c1 + c2``.
    """
    n = validation.integer("samples", samples, minimum=96)
    s = model.dead_zone if scale is None else validation.positive("scale", scale)
    limit = amplitude_limit(model)

    def capped(amplitude: float) -> float:
        return amplitude if limit is None else min(amplitude, limit)

    slow, fast = n // 3, n // 12
    small, large = capped(0.5 * s), capped(1.5 * s)
    levels = s * np.array([0.0, 0.5, -0.5, 0.25, -0.25, 0.1, -0.1, 0.0])
    levels = np.clip(levels, -capped(s), capped(s))
    steps = np.repeat(levels, -(-n // levels.size))[:n]
    return (
        Reference(f"sine {small:.3g} T{slow}", _sine(small, slow, n), small, slow),
        Reference(f"sine {large:.3g} T{slow}", _sine(large, slow, n), large, slow),
        Reference(f"sine {small:.3g} T{fast}", _sine(small, fast, n), small, fast),
        Reference(f"steps {float(np.max(np.abs(steps))):.3g}", steps, float(np.max(np.abs(steps))), None),
        Reference(f"triangle {small:.3g} T{slow}", _triangle(small, slow, n), small, slow),
    )
