"""The probe: a short, safe experiment before live identification, and what its record says about the servo.

:func:`probe_input` builds the experiment around the servo's centre: held
steps of half and full probe amplitude both ways, each followed by a return
to the centre (so the centre is approached from above and from below), then
a short chirp of half the amplitude. Every value lies within ``centre +/-
amplitude``, which the caller keeps inside the user's limits.

:func:`analyse_probe` reads from the record (only its usable samples):

* the delay (samples until the output leaves its noise after a step) and the
  10-90 % rise time, whence the loop's bandwidth ``0.35 / t_rise`` (exact for
  a first-order loop, within 10 % for a damped second-order one);
* the noise (standard deviation at the end of each hold) and the quantisation
  (the smallest step between two outputs);
* saturation: a linear loop moves twice as fast after a step twice as large
  (``2A`` against ``A``, and ``A`` against ``A/2``);
  a ratio of the peak speeds under :data:`SATURATION_RATIO` says the drive hit
  a speed, current or voltage limit, and the speed it reached is kept;
* the rough size of the play: the hysteresis at rest, the difference between
  the positions at which the output settles at the same set point approached
  from above and from below. It is the play plus what friction holds off a
  proportional loop, less what a loop closed on the output encoder takes
  back: a size to design the excitation by, not an identified play (on the
  twins it read 0.4-4x the true play);
* the range of motion the probe saw.

The probe's model for the MRGIA's convergence condition is the slower of two:
a damped second-order loop (damping 0.7) of the measured bandwidth, and the
ARX(2, 1) equation-error fit of the whole probe record
(:func:`servoid.ident.offline.refine.arx_start`), which backlash and noise
bias towards too fast poles.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from servoid import readings_side, validation
from servoid.errors import ConfigError, DataError, ModelError

__all__ = ["ProbePlan", "ProbeResult", "probe_input", "analyse_probe", "loop_denominator", "SATURATION_RATIO"]

#: Peak speed after a full step over that after a half step below which the drive is called saturated (linear: 2).
SATURATION_RATIO = 1.6

#: Seconds each level of the probe is held: long enough for loops of 1 Hz and faster to settle.
HOLD_S = 0.4
#: Seconds of the chirp.
CHIRP_S = 2.0
#: Levels of the steps, in probe amplitudes around the centre.
_LEVELS = (0.0, 0.5, 0.0, -0.5, 0.0, 1.0, -1.0, 0.0, 1.0, 0.0)


@dataclass(frozen=True)
class ProbePlan:
    """Where the probe's steps are: what :func:`analyse_probe` needs besides the record.

    Attributes
    ----------
    centre, amplitude : float
        The probe's set points lie in ``centre +/- amplitude``.
    rate_hz : float
        Sample rate of the probe.
    hold : int
        Samples per held level.
    levels : tuple of float
        The held levels in amplitudes (relative to the centre), in order.
    """

    centre: float
    amplitude: float
    rate_hz: float
    hold: int
    levels: tuple[float, ...]


def probe_input(centre: float, amplitude: float, rate_hz: float) -> tuple[np.ndarray, ProbePlan]:
    """The probe's set points and its plan.

    Parameters
    ----------
    centre : float
        The servo's centre (the driver's ``limits.centre``).
    amplitude : float
        Largest excursion from the centre, inside the user's limits.
    rate_hz : float
        Sample rate of the session.
    """
    validation.real("centre", centre)
    validation.positive("amplitude", amplitude)
    validation.positive("rate_hz", rate_hz)
    hold = max(8, int(round(HOLD_S * rate_hz)))
    steps = np.repeat(np.asarray(_LEVELS), hold)
    n = max(16, int(round(CHIRP_S * rate_hz)))
    t = np.arange(n) / rate_hz
    f0, f1 = 0.5, min(20.0, rate_hz / 10.0)
    chirp = 0.5 * np.sin(2 * np.pi * (f0 * t + (f1 - f0) * t**2 / (2 * CHIRP_S)))
    u = centre + amplitude * np.concatenate((steps, chirp, np.zeros(hold // 2)))
    return u, ProbePlan(float(centre), float(amplitude), float(rate_hz), hold, _LEVELS)


@dataclass(frozen=True)
class ProbeResult:
    """What the probe found (NaN where the record could not tell).

    Attributes
    ----------
    bandwidth_hz : float
        The loop's bandwidth, ``0.35 / rise_s``.
    rise_s : float
        Median 10-90 % rise time of the steps.
    delay_samples : int
        Samples from a step until the output leaves its noise (median over the steps).
    noise_std : float
        Output noise, output unit.
    quantum : float
        Smallest change between two outputs (the encoder's resolution where it dominates).
    speed_ratio : float
        Peak speed after steps of ``2 amplitude`` over that after steps of one (2 when linear).
    saturated : bool
        Whether the speed ratio says the drive saturated on the largest steps (``2 amplitude``).
    saturated_half : bool
        Whether it saturated on steps of one amplitude already.
    peak_speed : float
        The largest speed the probe saw, output unit per second.
    play : float
        Rough play: the hysteresis at rest (see the module's text).
    y_min, y_max : float
        The range of motion the probe saw.
    amplitude : float
        The probe's largest excursion from the centre.
    a : tuple of float
        The probe's model of the loop (denominator at the probe's rate), for the convergence condition.
    model_source : str
        ``"arx"`` or ``"bandwidth"``: which of the two models :attr:`a` is.
    rate_hz : float
        The probe's sample rate.
    samples, lost : int
        Samples of the probe and how many were not usable.
    readings : {"output", "motor"}
        Which shaft the probe read (:mod:`servoid.readings_side`, the driver's): on the motor, the play
        lies beyond the readings and :attr:`play` is not its size.
    """

    bandwidth_hz: float
    rise_s: float
    delay_samples: int
    noise_std: float
    quantum: float
    speed_ratio: float
    saturated: bool
    saturated_half: bool
    peak_speed: float
    play: float
    y_min: float
    y_max: float
    amplitude: float
    a: tuple[float, ...]
    model_source: str
    rate_hz: float
    samples: int
    lost: int
    readings: str = readings_side.OUTPUT

    def to_dict(self) -> dict[str, Any]:
        """For ``model.json`` and ``--json``: the fields by name."""
        return {"bandwidth_hz": self.bandwidth_hz, "rise_s": self.rise_s, "delay_samples": self.delay_samples,
                "noise_std": self.noise_std, "quantum": self.quantum, "speed_ratio": self.speed_ratio,
                "saturated": self.saturated, "saturated_half": self.saturated_half, "peak_speed": self.peak_speed, "hysteresis_at_rest": self.play,
                "range_seen": [self.y_min, self.y_max], "amplitude": self.amplitude, "a": list(self.a),
                "model_source": self.model_source, "rate_hz": self.rate_hz, "samples": self.samples,
                "lost": self.lost, readings_side.METADATA_KEY: self.readings}  # fmt: skip

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> ProbeResult:
        """Read back :meth:`to_dict` (the ``probe`` section of a ``model.json``; null numbers as NaN).

        Parameters
        ----------
        data : dict
            The section.

        Raises
        ------
        DataError
            A missing or malformed field, named.
        """
        try:
            lo, hi = data["range_seen"]

            def num(key: str) -> float:
                v = data[key]
                return math.nan if v is None else float(v)

            return cls(
                bandwidth_hz=num("bandwidth_hz"), rise_s=num("rise_s"), delay_samples=int(data["delay_samples"]),
                noise_std=num("noise_std"), quantum=num("quantum"), speed_ratio=num("speed_ratio"),
                saturated=bool(data["saturated"]), saturated_half=bool(data["saturated_half"]),
                peak_speed=num("peak_speed"), play=num("hysteresis_at_rest"),
                y_min=math.nan if lo is None else float(lo), y_max=math.nan if hi is None else float(hi),
                amplitude=num("amplitude"), a=tuple(float(v) for v in data["a"]), model_source=str(data["model_source"]),
                rate_hz=num("rate_hz"), samples=int(data["samples"]), lost=int(data["lost"]),
                readings=readings_side.of(data),
            )  # fmt: skip
        except (KeyError, TypeError, ValueError) as exc:
            raise DataError(f"the probe section is malformed ({type(exc).__name__}: {exc}): expected what "
                            "servoid identify --driver writes") from None  # fmt: skip

    def rows(self, unit: str = "") -> list[list[str]]:
        """The probe's short table: quantity, value."""
        u = f" {unit}" if unit else ""
        return [
            ["loop bandwidth", f"{self.bandwidth_hz:.3g} Hz (rise {1e3 * self.rise_s:.3g} ms; "
                               f"{self.rate_hz / self.bandwidth_hz:.0f}x at {self.rate_hz:g} Hz)"],
            ["delay", f"{self.delay_samples} samples"],
            ["noise / quantisation", f"{self.noise_std:.3g}{u} / {self.quantum:.3g}{u}"],
            ["saturation", f"{'yes' if self.saturated else 'no'} (speed ratio {self.speed_ratio:.2f}, 2 is linear; "
                           f"peak {self.peak_speed:.3g}{u}/s)"],
            ["play (rough: hysteresis at rest)", f"{self.play:.3g}{u}" if self.readings != readings_side.MOTOR else
             f"cannot be seen: the readings are the motor's, the play lies beyond them ({self.play:.3g}{u} at rest)"],
            ["range seen", f"[{self.y_min:.4g}, {self.y_max:.4g}]{u} (probe +/-{self.amplitude:.3g}{u})"],
            ["samples lost", f"{self.lost} of {self.samples}"],
        ]  # fmt: skip


def loop_denominator(bandwidth_hz: float, rate_hz: float, zeta: float = 0.7) -> np.ndarray:
    """Denominator ``a_1, a_2`` of a damped second-order loop of this bandwidth, sampled at ``rate_hz``.

    Parameters
    ----------
    bandwidth_hz : float
        Natural frequency of the loop, Hz.
    rate_hz : float
        Sample rate, Hz.
    zeta : float
        Damping ratio.
    """
    w = 2 * math.pi * validation.positive("bandwidth_hz", bandwidth_hz)
    s = w * (-zeta + 1j * math.sqrt(max(1.0 - zeta * zeta, 0.0)))
    p = np.exp(np.array([s, np.conj(s)]) / validation.positive("rate_hz", rate_hz))
    out: np.ndarray = np.real(np.poly(p))[1:]
    return out


def analyse_probe(u: np.ndarray, y: np.ndarray, valid: np.ndarray | None, plan: ProbePlan) -> ProbeResult:
    """Read the probe's record (see the module's text).

    Parameters
    ----------
    u, y : ndarray
        The probe's commands and measured outputs (``y`` may be NaN where not usable).
    valid : ndarray of bool, optional
        Usable samples; default all.
    plan : ProbePlan
        The plan :func:`probe_input` returned.

    Raises
    ------
    DataError
        When too few samples were usable, or the output never left its noise.
    """
    u = np.asarray(u, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    keep = np.isfinite(y) if valid is None else np.asarray(valid, dtype=np.bool_) & np.isfinite(y)
    if keep.sum() < 0.5 * keep.size:
        raise DataError(
            f"the probe lost {int(keep.size - keep.sum())} of {keep.size} samples: it cannot judge the servo "
            "(a slower --rate may keep up; --no-probe with --decimate and --amplitude runs without it)"
        )
    h, T = plan.hold, 1.0 / plan.rate_hz
    ends = []  # settled level at the end of each hold, and its noise
    noise = []
    for i in range(len(plan.levels)):
        tail = slice(i * h + int(0.7 * h), (i + 1) * h)
        seg = y[tail][keep[tail]]
        ends.append(float(np.median(seg)) if seg.size else math.nan)
        if seg.size >= 3:
            noise.append(float(np.std(seg)))
    noise_std = float(np.median(noise)) if noise else math.nan
    dy = np.abs(np.diff(y))
    ok = keep[1:] & keep[:-1]
    moves = dy[ok & (dy > 0)]
    quantum = float(np.min(moves)) if moves.size else math.nan
    threshold = max(3.0 * noise_std, 1.5 * quantum if math.isfinite(quantum) else 0.0, 1e-12)
    rises: list[float] = []
    delays: list[int] = []
    speeds: dict[float, list[float]] = {}
    segments: list[tuple[float, np.ndarray, np.ndarray]] = []
    for i in range(1, len(plan.levels)):
        size = plan.levels[i] - plan.levels[i - 1]
        seg_y, seg_k = y[i * h : (i + 1) * h], keep[i * h : (i + 1) * h]
        start, final = ends[i - 1], ends[i]
        change = final - start
        if not (math.isfinite(change) and abs(change) > threshold):
            continue
        frac = np.where(seg_k, (seg_y - start) / change, np.nan)
        moved = np.flatnonzero(np.abs(seg_y - start) > threshold)
        if moved.size:
            delays.append(int(moved[0]))
        t10, t90 = np.flatnonzero(frac >= 0.1), np.flatnonzero(frac >= 0.9)
        if t10.size and t90.size and t90[0] > t10[0]:
            rises.append((t90[0] - t10[0]) * T)
        segments.append((abs(size), seg_y, seg_k))
    if not rises:
        raise DataError("the servo's output did not follow the probe's steps beyond its noise: check the driver, "
                        "the limits and that the torque is on")  # fmt: skip
    rise = float(np.median(rises))
    rise = max(rise, T)  # a step done within one sample: the bandwidth is at least the rate's
    # speed over a fifth of the rise time: a one-sample difference would measure the noise
    m = max(1, int(round(0.2 * rise / T)))
    for size, seg_y, seg_k in segments:
        both = seg_k[m:] & seg_k[:-m]
        if both.any():
            speeds.setdefault(size, []).append(float(np.max(np.abs(seg_y[m:] - seg_y[:-m])[both])) / (m * T))
    bandwidth = 0.35 / rise
    v_of = {size: float(np.median(v)) for size, v in speeds.items()}
    ratio = v_of.get(2.0, math.nan) / v_of.get(1.0, math.nan)
    ratio_small = v_of.get(1.0, math.nan) / v_of.get(0.5, math.nan)
    peak = max((max(v) for v in speeds.values()), default=math.nan)
    # the centre approached from below (after -A, level 7) and from above (after +A, level 9)
    play = abs(ends[7] - ends[9]) if math.isfinite(ends[7]) and math.isfinite(ends[9]) else math.nan
    a, source = _model(u, y, keep, plan, bandwidth, int(np.median(delays)) if delays else 1)
    seen = y[keep]
    return ProbeResult(
        bandwidth_hz=bandwidth, rise_s=rise, delay_samples=int(np.median(delays)) if delays else 0,
        noise_std=noise_std, quantum=quantum, speed_ratio=ratio, saturated=bool(ratio < SATURATION_RATIO),
        saturated_half=bool(ratio_small < SATURATION_RATIO),
        peak_speed=peak, play=play, y_min=float(seen.min()), y_max=float(seen.max()), amplitude=plan.amplitude,
        a=tuple(float(v) for v in a), model_source=source, rate_hz=plan.rate_hz, samples=int(keep.size),
        lost=int(keep.size - keep.sum()),
    )  # fmt: skip


def _model(
    u: np.ndarray, y: np.ndarray, keep: np.ndarray, plan: ProbePlan, bandwidth: float, delay: int
) -> tuple[np.ndarray, str]:
    """The probe's loop model: ARX(2, 1) when it is a position loop near the measured bandwidth, else second order."""
    from servoid.ident.offline.refine import arx_start

    fallback = loop_denominator(bandwidth, plan.rate_hz)
    try:
        model = arx_start(u, np.where(keep, y, 0.0), na=2, nb=1, delay=max(1, delay), valid=keep)
    except (ConfigError, ModelError):
        return fallback, "bandwidth"
    arx = np.asarray(model.a, dtype=np.float64)
    # an equation-error fit on a fast record with play lands on too fast poles (measured on the twins:
    # margin -0.4 where the refined fit had -1.3): keep the slower of the two, the one that asks more decimation
    slowest = float(np.max(np.abs(np.roots(np.r_[1.0, arx]))))
    if slowest > float(np.max(np.abs(np.roots(np.r_[1.0, fallback])))) and slowest < 1.0:
        return arx, "arx"
    return fallback, "bandwidth"
