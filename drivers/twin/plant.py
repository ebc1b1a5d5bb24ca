"""A twin seen by the app's ``SampledPlant``: ``step(u) -> y`` once per host period, and ``reset()``."""

from __future__ import annotations

from servoid import validation
from servoid.drivers.twin.servo import Twin

__all__ = ["TwinPlant"]


class TwinPlant:
    """Steps a :class:`Twin` one host period per call, as :class:`servoid.ident.Plant` steps its model.

    ``step(u)`` takes the reading at the command's arrival (the drive's
    latest tick), sends ``u`` (latched at the drive's next tick), runs one
    period, and returns the reading: so ``y(k)`` depends on ``u(k-1)`` and
    earlier, the convention of :class:`servoid.ident.Plant`.

    Parameters
    ----------
    twin : Twin
        The servo (its torque is switched on by :meth:`reset`).
    period_s : float
        The host's sample period, s.
    """

    def __init__(self, twin: Twin, period_s: float) -> None:
        self.twin = twin
        self.period_s = validation.positive("period_s", period_s)
        #: The latest output (output encoder, rad).
        self.y = 0.0
        self.reset()

    def reset(self) -> None:
        """Power-cycle the twin and switch its torque on."""
        self.twin.reset()
        self.twin.enable()
        self.y = self.twin.read().position_rad

    def step(self, u: float) -> float:
        """Read, command ``u`` (output rad), run one period; return the reading.

        Parameters
        ----------
        u : float
            Set point, output rad.
        """
        y = self.twin.read().position_rad
        self.twin.command(u)
        self.twin.advance(self.period_s)
        self.y = y
        return y
