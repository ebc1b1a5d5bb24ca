"""Gear wear on a simulated servo: dead zones that grow over time, and a gear swap.

The paper's motivation is wear: the dead zones ``c1`` and ``c2`` grow over
months while the linear block stays as it was. :class:`Wear` describes that
as one factor on both dead zones, a function of the plant's sample index
``j`` (its age)::

    factor(j) = ramp(j) * (swap_factor if j >= swap_at else 1)
    ramp(j)   = 1                                   j <  drift_start
              = 1 + (drift - 1) (j - drift_start) / drift_samples     during the ramp
              = drift                               j >= drift_start + drift_samples

:class:`WearingPlant` is a :class:`~servoid.ident.Plant` that applies it on
its own sample grid, so a simulated servo wears the same way whatever the
host's timing (held samples included), and a restart of the device does not
undo it (a power cycle does not mend a gear).

The ramp moves the plant in steps of :data:`WEAR_RESOLUTION` of its factor
(0.01 % of the dead zone), far below any measurement noise: rebuilding the
validated model every sample would triple the cost of a simulated sample.

Units: ``c1``, ``c2`` in the plant's output unit; time in samples.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Any

from servoid import validation
from servoid.errors import ConfigError
from servoid.ident.models.plant import Plant
from servoid.ident.models.pseudo_wiener import BacklashModel
from servoid.ident.paper import PAPER_PLANT

__all__ = ["Wear", "WearingPlant", "GEAR_PLANT", "WEAR_RESOLUTION"]

#: The plant of the wear scenarios: the paper's linear block and down-line
#: slope with a new gear's dead zones c1 0.4, c2 0.6 (c1 + c2 = 1), so that the
#: issue's drift "from 1.0 to 1.5" is a factor of 1.5 (ending at the paper's
#: own dead zone, 1.5, with the split 0.6 / 0.9).
GEAR_PLANT = dataclasses.replace(PAPER_PLANT, c1=0.4, c2=0.6)

#: A ramping plant is rebuilt when its factor has moved by this much.
WEAR_RESOLUTION = 1e-4


@dataclass(frozen=True, kw_only=True)
class Wear:
    """How the dead zones of a simulated servo change with its age (samples).

    Parameters
    ----------
    drift : float
        Factor on ``c1`` and ``c2`` at the end of the ramp, ``> 0`` (1: no drift).
    drift_samples : int
        Length of the ramp in samples, ``>= 1`` when ``drift != 1``.
    drift_start : int
        Sample at which the ramp begins, ``>= 0``.
    swap_at : int, optional
        Sample of a gear swap: from there on the dead zones are multiplied by
        ``swap_factor`` (on top of the ramp).
    swap_factor : float
        Factor of the swap, ``> 0``.
    """

    drift: float = 1.0
    drift_samples: int | None = None
    drift_start: int = 0
    swap_at: int | None = None
    swap_factor: float = 1.0

    def __post_init__(self) -> None:
        drift = validation.positive("drift", self.drift)
        object.__setattr__(self, "drift", drift)
        object.__setattr__(self, "drift_start", validation.integer("drift_start", self.drift_start, minimum=0))
        if self.drift_samples is not None:
            object.__setattr__(
                self, "drift_samples", validation.integer("drift_samples", self.drift_samples, minimum=1)
            )
        elif drift != 1.0:
            raise ConfigError(f"drift (={drift:g}) needs drift_samples: the length of the ramp in samples")
        if self.swap_at is not None:
            object.__setattr__(self, "swap_at", validation.integer("swap_at", self.swap_at, minimum=0))
        object.__setattr__(self, "swap_factor", validation.positive("swap_factor", self.swap_factor))
        if self.swap_factor != 1.0 and self.swap_at is None:
            raise ConfigError(f"swap_factor (={self.swap_factor:g}) needs swap_at: the sample of the gear swap")

    @property
    def active(self) -> bool:
        """Whether the plant changes at all."""
        return self.drift != 1.0 or (self.swap_at is not None and self.swap_factor != 1.0)

    def factor(self, j: int) -> float:
        """The factor on ``c1`` and ``c2`` at sample ``j`` (see the module docstring)."""
        f = 1.0
        if self.drift != 1.0 and j > self.drift_start:
            share = min(1.0, (j - self.drift_start) / float(self.drift_samples or 1))
            f = 1.0 + (self.drift - 1.0) * share
        if self.swap_at is not None and j >= self.swap_at:
            f *= self.swap_factor
        return f

    def model(self, base: BacklashModel, j: int) -> BacklashModel:
        """``base`` with its dead zones as they are at sample ``j``."""
        f = self.factor(j)
        return base if f == 1.0 else dataclasses.replace(base, c1=base.c1 * f, c2=base.c2 * f)

    def describe(self) -> dict[str, Any]:
        """The non-default settings, for a driver's identity."""
        return {f.name: getattr(self, f.name) for f in dataclasses.fields(self) if getattr(self, f.name) != f.default}


class WearingPlant(Plant):
    """A :class:`Plant` whose dead zones follow a :class:`Wear` over its age.

    Parameters
    ----------
    model : BacklashModel
        The plant when new (age 0).
    wear : Wear
        How it changes.
    """

    def __init__(self, model: BacklashModel, wear: Wear) -> None:
        self.base = model
        self.wear = wear
        self.age = 0  # samples stepped since new; a reset (a power cycle) keeps it
        self._applied = 1.0
        super().__init__(model)

    @property
    def factor(self) -> float:
        """The factor the plant's dead zones have now (see :data:`WEAR_RESOLUTION`)."""
        return self._applied

    def step(self, u: float) -> float:
        f = self.wear.factor(self.age)
        moved = abs(f - self._applied)
        # inside a ramp the factor moves a little every sample: follow it in steps
        # of WEAR_RESOLUTION; anywhere else (a swap, the ramp's end) exactly
        if moved >= WEAR_RESOLUTION * self._applied or (moved > 0.0 and not self._ramping(self.age)):
            self.model = self.wear.model(self.base, self.age)
            self._applied = f
        self.age += 1
        return super().step(u)

    def _ramping(self, j: int) -> bool:
        w = self.wear
        return w.drift != 1.0 and w.drift_start < j < w.drift_start + (w.drift_samples or 0)
