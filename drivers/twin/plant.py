"""A twin seen by the app's ``SampledPlant``: one host period per ``step(u)``, with its drive stage, period and wear.

What a simulated device (``sim://``, the emulators) needs from a twin on
top of :class:`~servoid.drivers.twin.servo.Twin`: a step of one host period
in the convention of :class:`servoid.ident.Plant` (``y(k)`` before ``u(k)``
acts), the drive stage switched by the host's torque requests, the period
the host announces, and wear on the device's own age in samples.
"""

from __future__ import annotations

from servoid import validation
from servoid.drivers.twin.servo import Twin, TwinReading, TwinTruth
from servoid.ident.models.wear import Wear

__all__ = ["TwinPlant"]


class TwinPlant:
    """Steps a :class:`Twin` one host period per call, as :class:`servoid.ident.Plant` steps its model.

    ``step(u)`` takes the reading at the command's arrival (the drive's
    latest tick), sends ``u`` (latched at the drive's next tick), runs one
    period, and returns the reading: so ``y(k)`` depends on ``u(k-1)`` and
    earlier, the convention of :class:`servoid.ident.Plant`. With the torque
    off the command is not sent: the drive stage is open and the servo
    coasts through the period.

    Parameters
    ----------
    twin : Twin
        The servo.
    period_s : float
        The host's sample period, s (:meth:`set_period` changes it).
    torque : bool
        Switch the torque on at construction and at every :meth:`reset`
        (the stand-alone use); a simulated device passes False and follows
        the host's torque requests (:meth:`enable`, :meth:`disable`).
    wear : Wear, optional
        How the play changes with the plant's age in samples
        (:class:`~servoid.ident.models.wear.Wear`: its factor multiplies the
        play the twin was built with). A reset (a power cycle) keeps the age:
        it does not mend a gear.
    """

    def __init__(self, twin: Twin, period_s: float, *, torque: bool = True, wear: Wear | None = None) -> None:
        self.twin = twin
        self.period_s = validation.positive("period_s", period_s)
        self.wear = wear if wear is not None and wear.active else None
        self._torque_on_reset = bool(torque)
        self._base_play = twin.params.play_rad
        self._applied = 1.0
        #: Samples stepped since new (the clock of the wear).
        self.age = 0
        #: The latest output (output encoder, rad).
        self.y = 0.0
        #: The drive's registers as of the latest output.
        self.reading: TwinReading = twin.read()
        self.reset()

    @property
    def enabled(self) -> bool:
        """Whether the drive stage is on (it may have turned itself off: :attr:`TwinReading.fault`)."""
        return self.twin.read().enabled

    @property
    def truth(self) -> TwinTruth:
        """Ground truth now: the play as worn so far, the encoders, the loop structure."""
        return self.twin.truth

    def reset(self) -> None:
        """Power-cycle the twin (back at rest, torque off), then switch the torque on if built with ``torque``."""
        self.twin.reset()
        if self._torque_on_reset:
            self.twin.enable()
        self._wear_to(self.age)
        self.reading = self.twin.read()
        self.y = self.reading.position_rad

    def enable(self) -> None:
        """Torque on: the drive holds where it is (a drive that faulted is re-armed)."""
        self.twin.enable()

    def disable(self) -> None:
        """Torque off: the drive stage opens; the motor and load coast."""
        self.twin.disable()

    def set_mode(self, mode: str) -> None:
        """What the set points of :meth:`step` are: ``"position"`` (output rad) or ``"torque"`` (N m at the motor).

        Parameters
        ----------
        mode : {"position", "torque"}
            See :meth:`Twin.set_mode`.
        """
        self.twin.set_mode(mode)

    def set_period(self, period_s: float) -> None:
        """The host's sample period from now on, s.

        Parameters
        ----------
        period_s : float
            Period, > 0.
        """
        self.period_s = validation.positive("period_s", period_s)

    def step(self, u: float) -> float:
        """Read, command ``u`` if the torque is on, run one period; return the reading.

        Parameters
        ----------
        u : float
            Set point, output rad (torque mode: N m at the motor).
        """
        twin = self.twin
        reading = twin.read()
        if reading.enabled:
            twin.command(u)
        twin.advance(self.period_s)
        self.age += 1
        if self.wear is not None:
            self._wear_to(self.age)
        self.reading = reading
        self.y = reading.position_rad
        return self.y

    def _wear_to(self, age: int) -> None:
        """Set the play the wear gives at ``age`` (a write into the twin's constants: cheap every sample)."""
        if self.wear is None:
            return
        factor = self.wear.factor(age)
        if factor != self._applied:
            self.twin.set_play(self._base_play * factor)
            self._applied = factor
