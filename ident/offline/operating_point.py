"""The record's operating point: the constant taken off ``u`` and ``y`` before the fit, and the model moved between coordinates.

A position servo's input and output share a unit, so the fit subtracts the
**same** data-derived constant ``r = mean(u)`` from both (``u~ = u - r``,
``y~ = y - r``). Any constant added to a record (raw encoder counts around
2047 instead of a centred position) moves ``r`` by the same amount, so the
raw and the centred record are the same numbers to the fit and give the same
model (issue 12, item 2).

The model fitted on ``(u~, y~)`` and the model of the record's own
coordinates describe the same servo when the latter exists. With ``G`` the
linear block's static gain, a constant ``r`` on the input moves ``x`` by
``G r`` and the output by ``r``, which the dead zones absorb exactly (up
line ``y = x - c1``, down line ``y = m2 (x + c2)``)::

    c1_record = c1 + (G - 1) r                  c2_record = c2 - G r + r / m2

``c1 + c2`` changes only by ``r (1/m2 - 1)``: not at all for ``m2 = 1``.
The record's form exists only while both dead zones stay positive; otherwise
the model is kept about its operating point and the operating point travels
with it (the model file stores it).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from servoid.errors import ModelError
from servoid.ident.models.pseudo_wiener import BacklashModel

__all__ = ["OperatingPoint", "operating_point", "to_record", "to_centred"]


@dataclass(frozen=True)
class OperatingPoint:
    """The constants subtracted from ``u`` and ``y`` before the model applies.

    Attributes
    ----------
    u, y : float
        Taken off the input and off the output (equal for a position servo).
    """

    u: float = 0.0
    y: float = 0.0

    @property
    def is_zero(self) -> bool:
        """Whether the model applies to the record's own coordinates."""
        return self.u == 0.0 and self.y == 0.0

    def centre(self, u: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(u - self.u, y - self.y)`` as float arrays."""
        return np.asarray(u, dtype=np.float64) - self.u, np.asarray(y, dtype=np.float64) - self.y

    def to_dict(self) -> dict[str, Any]:
        """For JSON: ``{"u": ..., "y": ...}``."""
        return {"u": self.u, "y": self.y}

    @classmethod
    def from_dict(cls, data: Any) -> OperatingPoint:
        """Inverse of :meth:`to_dict`; a missing entry (older model files) is 0."""
        if data is None:
            return cls()
        return cls(u=float(data.get("u", 0.0)), y=float(data.get("y", 0.0)))


def operating_point(u: np.ndarray, y: np.ndarray, *, same_unit: bool = True) -> OperatingPoint:
    """The record's operating point: ``mean(u)`` off both signals, or each its own mean.

    Parameters
    ----------
    u, y : ndarray
        The record (``y`` only for ``same_unit=False``; its lost samples
        must already be left out).
    same_unit : bool
        Whether ``u`` and ``y`` share a unit (a position servo's set point and
        position): then one constant, so that the backlash's dead zones keep
        their meaning.

    Returns
    -------
    OperatingPoint
    """
    ru = float(np.mean(u))
    return OperatingPoint(u=ru, y=ru if same_unit else float(np.mean(y)))


def _moved(model: BacklashModel, du: float, dy: float) -> BacklashModel | None:
    """The model for ``u + du``, ``y + dy`` (None when a dead zone would not stay positive)."""
    g = model.dc_gain
    dx = g * du  # the linear block's output moves by G du at rest
    c1 = model.c1 + dx - dy
    c2 = model.c2 - dx + dy / model.m2
    try:
        return BacklashModel(a=model.a, b=model.b, delay=model.delay, m2=model.m2, c1=c1, c2=c2)
    except ModelError:
        return None


def to_record(model: BacklashModel, point: OperatingPoint) -> BacklashModel | None:
    """The model fitted about ``point`` in the record's own coordinates; None when it does not exist there."""
    return model if point.is_zero else _moved(model, point.u, point.y)


def to_centred(model: BacklashModel, point: OperatingPoint) -> BacklashModel | None:
    """Inverse of :func:`to_record`: a model of the record's coordinates about ``point``; None when it does not exist."""
    return model if point.is_zero else _moved(model, -point.u, -point.y)
