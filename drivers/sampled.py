"""The bench servo's physics on a time grid: what every simulated device puts behind its protocol.

A real servo moves continuously; the model servoid identifies is its
discrete-time behaviour at the session's sample period ``T``
(:data:`servoid.drivers.model_plant.MODEL_PLANT` is "the servo at the session's
rate"). :class:`SampledPlant` makes a :class:`~servoid.ident.Plant` behave
like a bench controller whose position loop is triggered by the host's set
points and keeps running on its own when the host falls silent:

* each command is one sample of the plant: the sample is taken, then the
  command applied (``y(j)`` depends on ``u(j - d)`` and earlier), and the reply
  is the position of that sample;
* when a command comes ``n`` periods after the previous one (``n >= 2``: the
  host skipped ``n - 1`` slots or stalled), the plant first runs ``n - 1``
  samples on the held command, as a position loop holds its set point;
  between requests nothing needs to run;
* ``n`` is what the host says when it does -- a count of periods
  (``periods=``), or the number of the command's slot (``slot=``; also a
  counter modulo ``slot_modulus``, such as the CiA 301 SYNC counter, whose
  wraps the time since the previous command resolves): then the plant's
  samples follow the host's slots exactly, and the jitter of the link shows
  in the timestamps only; otherwise ``n`` is the time since the previous
  command in periods, rounded (commands closer than one and a half periods
  are one sample each): a device that runs on its own clock;
* a read without a command runs the held samples due up to its time and
  returns the latest (the first request after the torque went on, command or
  read, starts the count of sample times);
* with the torque off the plant does not move and commands are refused.

Without a period (``period_ns=None``) every command is one sample, whatever
the time between them.

The plant is either a pseudo-Wiener model (stepped by :class:`~servoid.ident.Plant`)
or a physical twin (:class:`~servoid.drivers.twin.TwinPlant`: one sample is one
period of servo time, the period the host announces). A twin has a drive
stage: the torque requests switch it, and with the torque off it coasts --
reads then run the samples due with the stage open, where the model plant
stands still.

The serial firmware's simulated motor (``drivers/serial/firmware/host/sim_motor.c``)
implements the same rules in C; the simulated CAN drives and the emulated
Dynamixel servos use this class.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from servoid import validation
from servoid.drivers.clock import NS_PER_S
from servoid.drivers.twin.plant import TwinPlant
from servoid.errors import ConfigError, DriverError
from servoid.ident.models.plant import Plant
from servoid.ident.models.pseudo_wiener import BacklashModel
from servoid.ident.models.wear import Wear, WearingPlant

__all__ = ["SampledPlant", "PlantSample"]


@dataclass(frozen=True, slots=True)
class PlantSample:
    """One reading of the plant.

    Attributes
    ----------
    position : float
        Measured position (with noise, when configured), plant unit.
    index : int
        Sample ``j`` the reading belongs to (-1 before the first).
    time_ns : int
        Time of that sample (the command's arrival; for held samples, the
        previous sample's time plus whole periods).
    fault : str or None
        A twin whose drive turned its stage off by itself says why (``"overspeed"``).
    """

    position: float
    index: int
    time_ns: int
    fault: str | None = None


class SampledPlant:
    """A backlash plant sampled by the host's commands, running on by itself when they stop.

    Parameters
    ----------
    model : BacklashModel or TwinPlant
        The plant (unit of its input and output: the device's): a
        pseudo-Wiener model, or a physical twin (built with ``torque=False``:
        its drive stage follows :meth:`enable` and :meth:`disable`; its
        sample length follows ``period_ns`` when one is set).
    period_ns : int, optional
        Sample period; None: one sample per command.
    noise_std : float
        Standard deviation of Gaussian measurement noise added to each
        reading (not to the plant's state), plant unit.
    rng : numpy.random.Generator, optional
        Source of the noise; required when ``noise_std > 0``.
    wear : Wear, optional
        Dead zones that change with the plant's age in samples
        (:class:`~servoid.ident.models.wear.WearingPlant`); :attr:`model` is then
        the plant as it is now. A twin's wear is its own (``TwinPlant(wear=)``).
    slot_modulus : int, optional
        The slot numbers given to :meth:`command` count modulo this (a
        CiA 301 SYNC counter: 2..240); None: they are plain sample numbers.
    """

    def __init__(
        self,
        model: BacklashModel | TwinPlant,
        *,
        period_ns: int | None = None,
        noise_std: float = 0.0,
        rng: np.random.Generator | None = None,
        wear: Wear | None = None,
        slot_modulus: int | None = None,
    ) -> None:
        self.twin: TwinPlant | None = model if isinstance(model, TwinPlant) else None
        self.plant: Plant | TwinPlant
        if isinstance(model, TwinPlant):
            if wear is not None and wear.active:
                raise ConfigError("a twin wears by its own clock: give wear to TwinPlant(wear=), not to SampledPlant")
            self.plant = model
        else:
            self.plant = Plant(model) if wear is None or not wear.active else WearingPlant(model, wear)
        self.slot_modulus = (
            None if slot_modulus is None else validation.integer("slot_modulus", slot_modulus, minimum=2)
        )
        self._last_slot: int | None = None
        self.noise_std = validation.non_negative("noise_std", noise_std)
        if self.noise_std > 0 and rng is None:
            raise DriverError("noise_std > 0 needs rng=np.random.default_rng(seed)")
        self._rng = rng
        self.period_ns: int | None = None
        self.enabled = False
        self.held = 0.0
        self.index = -1
        #: Change of the output over the time between the latest two timed samples, plant unit per second.
        self.velocity = 0.0
        self._last_ns: int | None = None  # time of the latest sample (None: the next command starts afresh)
        self.set_period(period_ns)

    @property
    def model(self) -> BacklashModel:
        """The pseudo-Wiener plant as it is now (a twin has none)."""
        if isinstance(self.plant, TwinPlant):
            raise ConfigError("a physical twin is not a pseudo-Wiener model: see its truth (TwinPlant.truth)")
        return self.plant.model

    def set_period(self, period_ns: int | None) -> None:
        """Change the sample period; the next command starts the count afresh (a twin's samples get this length)."""
        if period_ns is not None:
            period_ns = validation.integer("period_ns", period_ns, minimum=1)
            if self.twin is not None:
                self.twin.set_period(period_ns / NS_PER_S)
        self.period_ns = period_ns
        self._last_ns = None
        self._last_slot = None

    def enable(self) -> None:
        """Torque on: the plant follows commands from the next one on."""
        if self.twin is not None:
            self.twin.enable()  # also re-arms a twin that turned its stage off by itself
        if not self.enabled:
            self.enabled = True
            self._last_ns = None
            self._last_slot = None

    def disable(self) -> None:
        """Torque off: the model plant stays where it is; a twin's stage opens and it coasts."""
        self.enabled = False
        if self.twin is not None:
            self.twin.disable()
            self._last_ns = None  # the coasting samples count from the next read

    def reset(self) -> None:
        """Back to rest, torque off (a power cycle)."""
        self.plant.reset()
        self.enabled = False
        self.held = 0.0
        self.index = -1
        self.velocity = 0.0
        self._last_ns = None
        self._last_slot = None

    def command(self, u: float, t_ns: int, *, periods: int | None = None, slot: int | None = None) -> PlantSample:
        """Apply the set point ``u`` arriving at ``t_ns``; return the reading of its sample.

        Parameters
        ----------
        u : float
            The set point.
        t_ns : int
            Its arrival time.
        periods : int, optional
            Periods since the previous set point as the host counts them
            (>= 1); default: from ``slot``, else from the time since the previous one.
        slot : int, optional
            The host's number of this set point's sample (modulo
            ``slot_modulus`` when set): the periods since the previous set
            point are the difference of the two (at least one).

        Raises
        ------
        DriverError
            With the torque off.
        """
        if not self.enabled:
            raise DriverError("the torque is off: commands are refused")
        if slot is not None:
            if periods is None:
                periods = self._slot_periods(int(slot), t_ns)
            self._last_slot = int(slot)
        before, last_ns = self.plant.y, self._last_ns
        if last_ns is not None:
            if periods is None and self.period_ns is not None:
                periods = _nearest(t_ns - last_ns, self.period_ns)
            for _ in range((periods or 1) - 1):
                self._step(self.held)
        self._step(float(u))
        self.held = float(u)
        self._last_ns = t_ns
        if last_ns is not None and t_ns > last_ns:
            self.velocity = (self.plant.y - before) * NS_PER_S / (t_ns - last_ns)
        return self._reading(t_ns)

    def read(self, t_ns: int) -> PlantSample:
        """The reading of the latest sample at or before ``t_ns`` (running the held samples due; a twin coasts)."""
        if (self.enabled or self.twin is not None) and self.period_ns is not None:
            if self._last_ns is None:
                self._last_ns = t_ns  # sample times count from the first request, command or read
            due = max((t_ns - self._last_ns) // self.period_ns, 0)
            before = self.plant.y
            for _ in range(due):
                self._step(self.held)
            if due:
                self.velocity = (self.plant.y - before) * NS_PER_S / (due * self.period_ns)
            self._last_ns += due * self.period_ns
            return self._reading(self._last_ns)
        return self._reading(t_ns)

    def _slot_periods(self, slot: int, t_ns: int) -> int | None:
        """Periods from the previous set point's slot to ``slot`` (None for the first after the torque went on)."""
        last = self._last_slot
        if last is None or self._last_ns is None:
            return None
        modulus = self.slot_modulus
        if modulus is None:
            # a device cannot refuse a sample: a slot number that does not follow (told late, out of
            # band) counts as the next sample
            return max(slot - last, 1)
        gap = (slot - last) % modulus or modulus
        if self.period_ns is not None:
            # a counter cannot tell n from n + modulus periods: the time since the last set point can
            elapsed = (t_ns - self._last_ns) / self.period_ns
            gap += modulus * max(0, round((elapsed - gap) / modulus))
        return gap

    def _step(self, u: float) -> None:
        self.plant.step(u)
        self.index += 1

    def _reading(self, time_ns: int) -> PlantSample:
        y = self.plant.y
        if self.noise_std > 0 and self._rng is not None:
            y += float(self._rng.normal(0.0, self.noise_std))
        fault = self.twin.twin.read().fault if self.twin is not None else None
        return PlantSample(position=y, index=self.index, time_ns=int(time_ns), fault=fault)


def _nearest(offset_ns: int, period_ns: int) -> int:
    """Whole periods nearest to ``offset_ns`` (a half rounds up)."""
    return (offset_ns + period_ns // 2) // period_ns
