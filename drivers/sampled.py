"""The bench servo's physics on a time grid: what every simulated device puts behind its protocol.

A real servo moves continuously; the model servoid identifies is its
discrete-time behaviour at the session's sample period ``T``
(:data:`servoid.drivers.bench.BENCH_PLANT` is "the servo at the session's
rate"). :class:`SampledPlant` makes a :class:`~servoid.ident.Plant` behave
like a device that keeps running between requests:

* its sample instants lie on a grid ``t0 + j T``, anchored at the first
  command after the torque was switched on (so the host's slots and the
  plant's samples coincide);
* a command belongs to the sample instant nearest to its arrival
  (``j = round((t - t0) / T)``): the plant is stepped once per instant, with
  the sample taken before the command is applied (``y(j)`` depends on
  ``u(j - d)`` and earlier), so the reply to a command is the position at its
  own instant;
* instants that received no command (a missed slot, a stalled host) hold the
  last command, as a position loop holds its set point; they are stepped
  when the next request arrives, so between requests nothing needs to run;
* a second command in the same instant does not re-step the plant: it
  becomes the held command from the next instant on;
* a read without a command returns the latest instant at or before its time;
* with the torque off the plant does not move and commands are refused.

Without a period (``period_ns=None``) every command is one sample (the plant
follows the requests, whatever their timing).

The serial firmware's simulated motor (``drivers/serial/firmware/host/sim_motor.c``)
implements the same rules in C; the CAN and Dynamixel emulators use this class.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from servoid import validation
from servoid.errors import DriverError
from servoid.ident.model import BacklashModel
from servoid.ident.plant import Plant

__all__ = ["SampledPlant", "PlantSample"]


@dataclass(frozen=True)
class PlantSample:
    """One reading of the plant.

    Attributes
    ----------
    position : float
        Measured position (with noise, when configured), plant unit.
    index : int
        Sample instant ``j`` the reading belongs to (-1 before the first).
    time_ns : int
        Time of that instant, ``t0 + j T`` (the request's time without a period).
    """

    position: float
    index: int
    time_ns: int


class SampledPlant:
    """A backlash plant that lives on the time grid of its sample period.

    Parameters
    ----------
    model : BacklashModel
        The plant (unit of its input and output: the device's).
    period_ns : int, optional
        Sample period; None: one sample per command.
    noise_std : float
        Standard deviation of Gaussian measurement noise added to each
        reading (not to the plant's state), plant unit.
    rng : numpy.random.Generator, optional
        Source of the noise; required when ``noise_std > 0``.
    """

    def __init__(
        self,
        model: BacklashModel,
        *,
        period_ns: int | None = None,
        noise_std: float = 0.0,
        rng: np.random.Generator | None = None,
    ) -> None:
        self.plant = Plant(model)
        self.noise_std = validation.non_negative("noise_std", noise_std)
        if self.noise_std > 0 and rng is None:
            raise DriverError("noise_std > 0 needs rng=np.random.default_rng(seed)")
        self._rng = rng
        self.period_ns: int | None = None
        self.set_period(period_ns)
        self.enabled = False
        self.held = 0.0
        self.index = -1
        self._anchor_ns: int | None = None

    @property
    def model(self) -> BacklashModel:
        return self.plant.model

    def set_period(self, period_ns: int | None) -> None:
        """Change the sample period; the grid is anchored again at the next command."""
        if period_ns is not None:
            period_ns = validation.integer("period_ns", period_ns, minimum=1)
        self.period_ns = period_ns
        self._anchor_ns = None

    def enable(self) -> None:
        """Torque on: the plant follows commands; the grid is anchored at the next command."""
        if not self.enabled:
            self.enabled = True
            self._anchor_ns = None

    def disable(self) -> None:
        """Torque off: the plant stays where it is."""
        self.enabled = False

    def reset(self) -> None:
        """Back to rest, torque off (a power cycle)."""
        self.plant.reset()
        self.enabled = False
        self.held = 0.0
        self.index = -1
        self._anchor_ns = None

    def command(self, u: float, t_ns: int) -> PlantSample:
        """Apply the set point ``u`` arriving at ``t_ns``; return the reading of its instant.

        Raises
        ------
        DriverError
            With the torque off.
        """
        if not self.enabled:
            raise DriverError("the torque is off: commands are refused")
        u = float(u)
        if self.period_ns is None:
            self._step(u)
            self.held = u
            return self._reading(t_ns)
        if self._anchor_ns is None:
            self._anchor_ns = t_ns - (self.index + 1) * self.period_ns
        target = _nearest(t_ns - self._anchor_ns, self.period_ns)
        self._hold_until(target - 1)
        if self.index < target:
            self._step(u)
        self.held = u
        return self._reading(self._anchor_ns + self.index * self.period_ns)

    def read(self, t_ns: int) -> PlantSample:
        """The reading of the latest instant at or before ``t_ns``."""
        if self.enabled and self.period_ns is not None and self._anchor_ns is not None:
            self._hold_until((t_ns - self._anchor_ns) // self.period_ns)
            return self._reading(self._anchor_ns + self.index * self.period_ns)
        return self._reading(t_ns)

    def _hold_until(self, index: int) -> None:
        while self.index < index:
            self._step(self.held)

    def _step(self, u: float) -> None:
        self.plant.step(u)
        self.index += 1

    def _reading(self, time_ns: int) -> PlantSample:
        y = self.plant.y
        if self.noise_std > 0 and self._rng is not None:
            y += float(self._rng.normal(0.0, self.noise_std))
        return PlantSample(position=y, index=self.index, time_ns=int(time_ns))


def _nearest(offset_ns: int, period_ns: int) -> int:
    """Index of the grid point nearest to ``offset_ns`` (halves round up: a half-period-late command is the next)."""
    return (offset_ns + period_ns // 2) // period_ns
