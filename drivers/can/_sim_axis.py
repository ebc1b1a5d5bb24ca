"""The mechanics behind both simulated CAN drives: the bench plant, stepped once per cycle.

Sample-synchronous by design: the plant advances one sample per cyclic
exchange of the protocol (per SYNC for CiA 402, per Set_Input_Pos /
Set_Input_Torque for ODrive), never on a clock. Whatever the bus's latency
and jitter, the k-th reply therefore carries ``y(k)`` of the plant driven by
the commands ``u(0..k)`` -- exactly what :func:`servoid.ident.simulate` gives
for the same inputs. Transports differ in timing (rate, late samples), not in
the data; that is what makes their identification results comparable.

Position mode: the command is the target position (rad) fed to
:data:`~servoid.drivers.bench.BENCH_PLANT`. Torque mode: the same plant, with
the command read as a torque (Nm) times :data:`TORQUE_GAIN` (rad per Nm) --
a joint held by a torsion spring of ``1 / TORQUE_GAIN`` Nm/rad, so that a
torque moves it to a position proportional to it, through the same dynamics
and the same backlash.
"""

from __future__ import annotations

import math
import time

from servoid import validation
from servoid.drivers.bench import BENCH_PLANT
from servoid.ident.model import BacklashModel
from servoid.ident.plant import Plant

__all__ = ["SimAxis", "TORQUE_GAIN"]

#: Position (rad) per torque (Nm) of the simulated drives in torque mode.
TORQUE_GAIN = 1.0


class SimAxis:
    """The plant of a simulated drive, with its power stage.

    Parameters
    ----------
    model : BacklashModel
        Plant behind the drive (rad in, rad out).
    torque_gain : float
        rad per Nm in torque mode (:data:`TORQUE_GAIN`).

    Attributes
    ----------
    position : float
        Last output of the plant, rad.
    velocity : float
        Change of :attr:`position` over the wall-clock time between the last
        two steps, rad/s (0 before the second step).
    steps : int
        Samples the plant has advanced.
    """

    def __init__(self, model: BacklashModel = BENCH_PLANT, *, torque_gain: float = TORQUE_GAIN) -> None:
        self.plant = Plant(model)
        # the backlash step is compiled on first use (numba, ~0.1-1 s): do it now, not in a drive's first reply
        Plant(model).step(0.0)
        self.torque_gain = validation.positive("torque_gain", torque_gain)
        self.position = self.plant.y
        self.velocity = 0.0
        self.steps = 0
        self._last_input = 0.0
        self._last_step_ns: int | None = None

    def step(self, command: float, *, torque: bool) -> float:
        """Advance one sample with ``command`` (rad, or Nm when ``torque``); return the position (rad).

        A non-finite command (a corrupted frame) holds the last input rather
        than poisoning the plant's state.
        """
        u = command * self.torque_gain if torque else command
        if not math.isfinite(u):
            u = self._last_input
        self._last_input = u
        previous = self.position
        self.position = self.plant.step(u)
        now = time.perf_counter_ns()
        if self._last_step_ns is not None and now > self._last_step_ns:
            self.velocity = (self.position - previous) / ((now - self._last_step_ns) * 1e-9)
        self._last_step_ns = now
        self.steps += 1
        return self.position

    def hold(self) -> None:
        """A sample with the power stage off: nothing moves."""
        self.velocity = 0.0
        self._last_step_ns = None
