"""Tracking control of a backlash servo, with and without the backlash inverse.

The plant is the pseudo-Wiener model: the command ``u`` drives the linear
block ``x = q^-d B/A u`` and ``x`` drives the backlash, whose output ``y`` is
measured. The backlash inverse (:mod:`servoid.ident.control.compensate`) says which
``x`` gives a wanted ``y``; the command must then move ``x`` there through
the linear block. :class:`TrackingController` is a two-degree-of-freedom
controller a control engineer will recognise::

    v(k)    = v(k-1) + k_i (r(k-1) - y_m(k-1))          integral feedback on the latest measurement
    y_d     = r(k+P) + v(k)                              wanted output P samples ahead
    x_d     = inverse(y_d)          (compensated)        backlash inverse, smoothed
            = y_d                   (uncompensated)      the backlash ignored
    u(k)    = ZPETC(x_d)                                 feedforward through the linear block

The feedforward (:class:`~servoid.ident.control.feedforward.LinearInverse`, preview
``P = d`` for a minimum-phase block) takes a known reference ``P`` samples
ahead, as a trajectory planner provides it; on a real servo the motor's own
position loop usually plays this part and the inverse alone turns the load
setpoint into the motor setpoint. The integral term removes what the model
gets wrong; it acts on the wanted output *before* the inverse, so with the
inverse the loop sees a plain delay and without it the loop sees the
backlash. Both arms of a comparison use the same gains, the same
feedforward and the same model; only the inverse differs.

Units: ``r``, ``y``, ``x`` in the output unit, ``u`` in the command unit,
time in samples.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from servoid import validation
from servoid.errors import ConfigError
from servoid.ident.control.compensate import BacklashInverse, InverseParams
from servoid.ident.control.feedforward import LinearInverse
from servoid.ident.models.plant import Plant
from servoid.ident.models.pseudo_wiener import BacklashModel

__all__ = [
    "LoopDiverged",
    "TrackingController",
    "default_integral_gain",
    "Sensor",
    "TrackingMetrics",
    "tracking_metrics",
    "TrackingRun",
    "simulate_tracking",
]


class LoopDiverged(ConfigError, ArithmeticError):
    """The closed loop of :func:`simulate_tracking` diverged (a gain too high, or a model far off)."""


#: An output this many times beyond the path's amplitude plus the play counts as divergence.
_RUNAWAY = 100.0


def default_integral_gain(preview: int) -> float:
    """``k_i = 1 / (2 (P + 1))`` per sample for a loop delay of ``P + 1`` samples.

    With a perfect inverse the integral loop is ``v(k+1) = v(k) - k_i v(k-P)``;
    for ``P = 1`` this gain puts both poles at 0.5 (critically damped), and for
    longer delays it keeps a similar margin.
    """
    return 1.0 / (2.0 * (validation.integer("preview", preview, minimum=0) + 1))


class TrackingController:
    """Feedforward through the model, integral feedback, optional backlash inverse.

    Parameters
    ----------
    model : BacklashModel
        The controller's model of the servo (identified, possibly wrong).
    inverse : InverseParams or None
        The backlash inverse to insert; ``None`` for the uncompensated arm.
    integral_gain : float, optional
        ``k_i`` per sample, ``>= 0`` (default :func:`default_integral_gain`).
    upcoming : sequence of float, optional
        The reference for the first :attr:`preview` samples, ``r(0) ..
        r(P-1)``, which :meth:`step` is never given (default: all ``y0``).
    y0, x0 : float
        The servo's output and backlash input at rest at the start.

    Notes
    -----
    Public state: :attr:`preview` ``P``, :attr:`integral` ``v``. See the
    module docstring for the control law.
    """

    def __init__(
        self,
        model: BacklashModel,
        *,
        inverse: InverseParams | None,
        integral_gain: float | None = None,
        upcoming: Sequence[float] | None = None,
        y0: float = 0.0,
        x0: float = 0.0,
    ) -> None:
        self.model = model
        self._linear = LinearInverse(model, x0=x0)
        self.preview = self._linear.preview
        ki = default_integral_gain(self.preview) if integral_gain is None else integral_gain
        self.integral_gain = validation.non_negative("integral_gain", ki)
        self._inverse_params = inverse
        self.reset(upcoming, y0=y0, x0=x0)

    def reset(self, upcoming: Sequence[float] | np.ndarray | None = None, *, y0: float = 0.0, x0: float = 0.0) -> None:
        """Start again at rest (output ``y0``, backlash input ``x0``), with ``r(0) .. r(P-1)``."""
        y0 = validation.real("y0", y0)
        ahead = [y0] * self.preview if upcoming is None else validation.signal("upcoming", upcoming).tolist()
        if len(ahead) != self.preview:
            raise ConfigError(f"upcoming has {len(ahead)} values, the preview needs r(0) .. r({self.preview - 1})")
        # r(k-1), r(k), ..., r(k+P-1): the error uses the reference of the latest measurement
        self._reference: deque[float] = deque([ahead[0], *ahead], maxlen=self.preview + 1)
        self.integral = 0.0
        self._linear.reset(x0)
        self._inverse = None
        if self._inverse_params is not None:
            self._inverse = BacklashInverse(self._inverse_params, y0=ahead[-1], x0=x0)

    @property
    def compensated(self) -> bool:
        """Whether the backlash inverse is in."""
        return self._inverse is not None

    def step(self, reference_ahead: float, measured: float) -> float:
        """The command ``u(k)``.

        Parameters
        ----------
        reference_ahead : float
            ``r(k + P)``, the reference :attr:`preview` samples ahead (output unit).
        measured : float
            The latest measurement ``y_m(k-1)`` (output unit).
        """
        self.integral += self.integral_gain * (self._reference[0] - measured)
        self._reference.append(reference_ahead)
        wanted = reference_ahead + self.integral
        x_d = wanted if self._inverse is None else self._inverse.step(wanted)
        return self._linear.step(x_d)


@dataclass(frozen=True)
class Sensor:
    """The measurement of the simulated servo: quantisation and noise.

    Parameters
    ----------
    resolution : float
        Encoder step in the output unit (``0``: continuous).
    noise_std : float
        Standard deviation of Gaussian noise added before quantisation.
    seed : int
        Seed of the noise.
    """

    resolution: float = 0.0
    noise_std: float = 0.0
    seed: int = 0

    def __post_init__(self) -> None:
        object.__setattr__(self, "resolution", validation.non_negative("resolution", self.resolution))
        object.__setattr__(self, "noise_std", validation.non_negative("noise_std", self.noise_std))

    def noise(self, n: int) -> np.ndarray:
        """The noise of ``n`` readings, drawn from the seeded generator."""
        if self.noise_std == 0.0:
            return np.zeros(n)
        return np.random.default_rng(self.seed).normal(0.0, self.noise_std, size=n)

    def read(self, y: float, noise: float) -> float:
        """The reading of the true output ``y`` with the given noise sample."""
        value = y + noise
        if self.resolution > 0.0:
            value = self.resolution * round(value / self.resolution)
        return value


@dataclass(frozen=True)
class TrackingMetrics:
    """How well an output followed a reference.

    Attributes
    ----------
    rms_error, peak_error : float
        RMS and largest ``|r - y|`` (output unit).
    dead_time : float
        Mean samples, over the reversals of the reference, from the reference
        having moved ``threshold`` in the new direction to the output having
        done so (0: the output turns with the reference).
    dead_time_max : float
        The longest of those (samples).
    reversals : int
        Reversals of the reference that were measured.
    censored : int
        Reversals after which the output had not turned by the next one
        (counted with the time to the next reversal: a lower bound).
    threshold : float
        The travel that counts as having turned (output unit).
    """

    rms_error: float
    peak_error: float
    dead_time: float
    dead_time_max: float
    reversals: int
    censored: int
    threshold: float


def _turning_points(r: np.ndarray) -> list[tuple[int, int]]:
    """``(index, new direction)`` where the reference's direction of motion changes."""
    steps = np.sign(np.diff(r))
    moving = np.flatnonzero(steps)
    out = []
    for prev, cur in zip(moving[:-1], moving[1:]):
        if steps[cur] != steps[prev]:
            out.append((int(cur), int(steps[cur])))  # r[cur] is the turning value
    return out


def _first_travel(values: np.ndarray, direction: int, threshold: float) -> int | None:
    """First index where ``values`` has travelled ``threshold`` in ``direction`` from its extreme so far."""
    if direction > 0:
        travelled = values - np.minimum.accumulate(values)
    else:
        travelled = np.maximum.accumulate(values) - values
    hits = np.flatnonzero(travelled >= threshold)
    return int(hits[0]) if hits.size else None


def tracking_metrics(
    r: Sequence[float] | np.ndarray, y: Sequence[float] | np.ndarray, *, threshold: float
) -> TrackingMetrics:
    """RMS and peak error, and the dead time after each reversal of ``r``.

    Parameters
    ----------
    r, y : array_like
        Reference and (true) output, same length, output unit.
    threshold : float
        Travel in the new direction that counts as having turned, ``> 0``
        (output unit); take it above the measurement noise and the encoder step.
    """
    r_arr = validation.signal("r", r)
    y_arr = validation.signal("y", y)
    if r_arr.shape != y_arr.shape:
        raise ConfigError(f"r and y differ in length: {r_arr.size} against {y_arr.size}")
    threshold = validation.positive("threshold", threshold)
    err = r_arr - y_arr
    turns = _turning_points(r_arr)
    dead: list[int] = []
    censored = 0
    for i, (start, direction) in enumerate(turns):
        end = turns[i + 1][0] if i + 1 < len(turns) else r_arr.size
        k_r = _first_travel(r_arr[start:end], direction, threshold)
        if k_r is None:
            continue  # the reference itself turned back before travelling the threshold
        k_y = _first_travel(y_arr[start:end], direction, threshold)
        if k_y is None:
            censored += 1
            k_y = end - start
        dead.append(max(k_y - k_r, 0))
    return TrackingMetrics(
        rms_error=float(np.sqrt(np.mean(err**2))),
        peak_error=float(np.max(np.abs(err))),
        dead_time=float(np.mean(dead)) if dead else 0.0,
        dead_time_max=float(np.max(dead)) if dead else 0.0,
        reversals=len(dead),
        censored=censored,
        threshold=threshold,
    )


@dataclass(frozen=True)
class TrackingRun:
    """A closed-loop run of the simulated servo.

    Attributes
    ----------
    reference : ndarray
        ``r``, output unit.
    y : ndarray
        The servo's true output (output unit).
    measured : ndarray
        What the sensor reported (quantised, noisy).
    u : ndarray
        The command.
    x : ndarray
        The linear block's output (the backlash input, e.g. the motor side).
    compensated : bool
        Whether the backlash inverse was in.
    metrics : TrackingMetrics
        Errors of ``y`` against ``r``.
    """

    reference: np.ndarray
    y: np.ndarray
    measured: np.ndarray
    u: np.ndarray
    x: np.ndarray
    compensated: bool
    metrics: TrackingMetrics

    @property
    def motor_travel(self) -> float:
        """Distance the backlash input travelled, per unit the reference travelled.

        About 1 for a servo that follows the path; a command that chatters
        across the play (the stutter of a naive inverse) drives it far up.
        """
        path = float(np.sum(np.abs(np.diff(self.reference))))
        return float(np.sum(np.abs(np.diff(self.x)))) / path if path > 0.0 else float("nan")


def simulate_tracking(
    plant: BacklashModel,
    controller: TrackingController,
    reference: Sequence[float] | np.ndarray,
    *,
    sensor: Sensor = Sensor(),
    threshold: float,
) -> TrackingRun:
    """Run ``controller`` on the simulated servo ``plant`` along ``reference``.

    The servo starts at rest at ``x = 0``, ``y = 0`` (the controller is reset
    to that state). Each sample: the controller gets ``r(k + P)`` (the
    reference's last value beyond its end) and the measurement of ``y(k-1)``,
    and its command drives the plant.

    Parameters
    ----------
    plant : BacklashModel
        The true servo.
    controller : TrackingController
        Reset here, then stepped.
    reference : array_like
        Wanted output, output unit.
    sensor : Sensor
        Quantisation and noise of the measurement.
    threshold : float
        See :func:`tracking_metrics`.

    Raises
    ------
    LoopDiverged
        If the closed loop diverges (the output runs 100 times beyond the
        path's amplitude plus the play).
    """
    r = validation.signal("reference", reference)
    n, preview = r.size, controller.preview
    ahead = np.concatenate((r, np.full(preview, r[-1])))
    controller.reset(ahead[:preview], y0=0.0, x0=0.0)
    servo = Plant(plant, y0=0.0)
    noise = sensor.noise(n + 1)
    y = np.empty(n)
    x = np.empty(n)
    u = np.empty(n)
    measured = np.empty(n)
    latest = sensor.read(0.0, float(noise[n]))
    # An output this far beyond the path means an unstable loop: stop before the numbers overflow.
    runaway = _RUNAWAY * (float(np.max(np.abs(r))) + plant.dead_zone)
    for k in range(n):
        u[k] = controller.step(float(ahead[k + preview]), latest)
        y[k] = servo.step(u[k])
        x[k] = servo.x
        latest = measured[k] = sensor.read(float(y[k]), float(noise[k]))
        if not abs(y[k]) < runaway:
            raise LoopDiverged(
                f"the closed loop diverged at sample {k} (|y| = {abs(y[k]):.3g}): integral_gain "
                f"(={controller.integral_gain:g}) is too high for this servo, or the model is far from it "
                f"(default gain {default_integral_gain(preview):g})"
            )
    return TrackingRun(
        reference=r, y=y, measured=measured, u=u, x=x, compensated=controller.compensated,
        metrics=tracking_metrics(r, y, threshold=threshold),
    )  # fmt: skip
