"""The mechanics behind both simulated CAN drives: a twin or the bench plant, sampled by the drive's cycles.

The plant is a :class:`~servoid.drivers.sampled.SampledPlant`: one sample per
cyclic command of the protocol, and held samples for the cycles the host
skipped, counted as the protocol allows:

* CiA 402 -- the drive runs one control cycle per SYNC; a SYNC that carries a
  counter (CiA 301 SYNC with counter, 0x1019) tells how many cycles passed
  since the previous one: a gap means SYNCs that never came, cycles the drive
  ran on the held target. The driver numbers its SYNCs by the sampling
  session's slots, so the drive's samples follow the host's exactly.
* ODrive -- CAN Simple carries no cycle number: a real axis runs on its own
  clock. With a period (``period_s``) the simulated axis does too, counting the
  samples between two inputs from the time between them; without one, each
  Set_Input_Pos / Set_Input_Torque is one sample. In-process tests may tell it
  the host's slot numbers out of band (``SimOdriveAxis.slot_source``).

Times are the frames' timestamps as the bus stamped them (python-can's
``Message.timestamp``: when the virtual bus took the frame, or the kernel's
receive time for ``udp_multicast``), as a CAN controller stamps frames in
hardware: how late the drive's own thread gets to a frame does not move it
to another sample.

The servo (:mod:`servoid.drivers.servos`) is a physical twin (the default
of each drive: ``cia402``, ``odrive``) or a pseudo-Wiener plant
(``model``: :data:`~servoid.drivers.model_plant.MODEL_PLANT`). A twin's sample
is one period of servo time: the period the drive is told (0x1006, its own
clock), else one at :data:`~servoid.drivers.servos.DEFAULT_RATE_HZ`; its
drive stage follows the power stage, and with the power off it coasts.

Position mode: the command is the target position, output rad. Torque
mode: a twin's drive runs its current loop on the torque (N m at the motor,
:meth:`~servoid.drivers.twin.Twin.set_mode`; the twins whose firmware has
no current loop, the Dynamixel's and Feetech's, run position mode only);
the pseudo-Wiener plant reads the command as a torque (Nm) times
:data:`TORQUE_GAIN` (rad per Nm) -- a joint held by a torsion spring of
``1 / TORQUE_GAIN`` Nm/rad, so that a torque moves it to a position
proportional to it, through the same dynamics and the same backlash.
"""

from __future__ import annotations

import math

from servoid import validation
from servoid.drivers.clock import NS_PER_S
from servoid.drivers.sampled import SampledPlant
from servoid.drivers.servos import DEFAULT_RATE_HZ, Servo
from servoid.drivers.twin import Twin, TwinPlant, TwinReading
from servoid.ident.models.plant import Plant

__all__ = ["SimAxis", "TORQUE_GAIN"]

#: Position (rad) per torque (Nm) of the simulated drives in torque mode.
TORQUE_GAIN = 1.0


class SimAxis:
    """The plant of a simulated drive, with its power stage.

    Parameters
    ----------
    servo : Servo
        The servo behind the drive (:func:`servoid.drivers.servos.servo`): rad in, rad out.
    torque_gain : float
        rad per Nm in torque mode (:data:`TORQUE_GAIN`).
    period_s : float, optional
        The drive's own sample period: commands further apart than one and a
        half periods run held samples in between (see
        :class:`~servoid.drivers.sampled.SampledPlant`); None: one sample per command.

    Attributes
    ----------
    sampled : SampledPlant
        The plant and its sample count.
    """

    def __init__(
        self,
        servo: Servo,
        *,
        torque_gain: float = TORQUE_GAIN,
        period_s: float | None = None,
    ) -> None:
        self.servo = servo
        # the kernels are compiled on first use (numba, ~0.1-1 s): do it now, not in a drive's first reply
        if servo.twin is None:
            assert servo.model is not None
            Plant(servo.model).step(0.0)
            self.sampled = SampledPlant(servo.model)
            self.twin: TwinPlant | None = None
        else:
            Twin(servo.twin).advance(1e-3)
            self.twin = TwinPlant(Twin(servo.twin), 1.0 / DEFAULT_RATE_HZ, torque=False)
            self.sampled = SampledPlant(self.twin)
        self.set_period(period_s)
        self.torque_gain = validation.positive("torque_gain", torque_gain)
        self._last_input = 0.0

    @property
    def position(self) -> float:
        """Output of the plant's latest sample, rad (a twin: its output encoder's reading)."""
        return self.sampled.plant.y

    @property
    def torque_capable(self) -> bool:
        """Whether the servo takes torque commands (a twin needs a current loop: a cascade drive)."""
        return self.twin is None or self.servo.twin.firmware == "cascade"  # type: ignore[union-attr]

    @property
    def reading(self) -> TwinReading | None:
        """A twin's registers as of the latest sample (None for the pseudo-Wiener plant)."""
        return self.twin.reading if self.twin is not None else None

    @property
    def velocity(self) -> float:
        """Change of :attr:`position` over the time between the last two samples, rad/s."""
        return self.sampled.velocity

    @property
    def steps(self) -> int:
        """Samples the plant has advanced (held ones included)."""
        return self.sampled.index + 1

    @property
    def powered(self) -> bool:
        return self.sampled.enabled

    def set_period(self, period_s: float | None) -> None:
        """The drive's own sample period, s (None: one sample per command)."""
        period = None if period_s is None else int(round(validation.positive("period_s", period_s) * NS_PER_S))
        self.sampled.set_period(period)

    def set_counter(self, modulus: int | None) -> None:
        """Slot numbers given to :meth:`step` count modulo ``modulus`` (a SYNC counter); None: plain numbers."""
        self.sampled.slot_modulus = modulus
        self.sampled.set_period(self.sampled.period_ns)  # the count starts afresh

    def power(self, on: bool) -> None:
        """Switch the power stage: on, the plant follows commands; off, it stays where it is."""
        if on:
            self.sampled.enable()
            return
        self.sampled.disable()

    def step(self, command: float, *, torque: bool, at: float, slot: int | None = None) -> float:
        """Apply ``command`` (rad, or Nm when ``torque``) as the next sample; return the position (rad).

        ``at`` is the command frame's timestamp, s; ``slot`` the host's number
        of the command's sample (or a counter of them), when the protocol
        carries one. A non-finite command (a corrupted frame) holds the last
        input rather than poisoning the plant's state.
        """
        if self.twin is not None:
            self.twin.set_mode("torque" if torque else "position")
            u = command
        else:
            u = command * self.torque_gain if torque else command
        if not math.isfinite(u):
            u = self._last_input
        self._last_input = u
        return self.sampled.command(u, _ns(at), slot=slot).position


def _ns(seconds: float) -> int:
    return int(round(seconds * NS_PER_S))
