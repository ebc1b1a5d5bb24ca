"""Design a live identification from the probe: the estimator's rate, the shape of the set point, the amplitude.

Each choice is stated with its reason (:attr:`LiveDesign.reasons`) and each
can be overridden:

decimation ``k``
    the smallest at which the MRGIA's convergence condition holds on the
    probe's model (:func:`~servoid.ident.online.decimate.decimation_factor`).
shape
    gentle sines (:mod:`~servoid.excitation.gentle`) whose fastest segment
    runs at :data:`GENTLE_SHARE` of the probe's bandwidth (peak acceleration
    ``A (2 pi GENTLE_SHARE f_bw)^2``): at each reversal the load waits on the
    trailing flank while the motor crosses the whole play. Held random levels
    (the design before) decelerate harder than the load's friction, the load
    coasts across the play and the record hides it: on the XM430 and STS3215
    twins at 200 Hz the offline fit of the live record of held levels gave
    -43 % and -26 %, of gentle sines designed by this rule -0.1 % and -9 %
    (issue 15). Whether the rule stays below the load's friction's
    deceleration depends on the load, which the probe does not measure: it
    does on the horn twins, not on the motor-side CiA 402 (-19 %), where a
    quarter of it (:data:`SLOW_SHARE`) serves and breaks the horn twins
    (XM430 +244 %, the place named wrong). So the run begins with a slow
    phase (:data:`SLOW_PART` of it) and the refinement
    (:func:`~servoid.ident.online.refinement.refine_online`) names the place
    on the fast phase and takes a play outside the loop from the slow one.
    The online MRGIA sees the anti-aliased means of groups of
    ``k`` samples, which a sine far below the slow rate's Nyquist survives.
    ``--hold`` asks for held levels instead.
hold
    (held levels, and ``servoid excite --probe``'s settling time) uniform
    random levels held for whole groups of ``k`` samples (the slow
    record is then a ZOH record of the plant) and for at least half a period
    of the loop's bandwidth and :data:`MIN_GROUPS` groups: a reversal then
    happens at a group's boundary with the loop nearly at rest, so the slow
    picks see the backlash turn where it turns (held for one group, the
    exact loop at 50x lost 30-40 % of its play; three gave 0.2 %).
amplitude
    several (:data:`PLAY_MULTIPLE`) times the probe's rough play and well
    above the noise and the quantisation, never above what the probe
    showed the drive follows linearly: uniform levels in ``+/-A`` step by up
    to ``2 A``; the probe stepped by ``2 A_probe`` and by ``A_probe``, so
    ``A <= A_probe`` when neither saturated, ``A_probe / 2`` when only the
    largest did, ``A_probe / 4`` when both did (and it says so). Gentle
    sines take that cap whole: their segments' amplitudes run down to a
    quarter of it, and their steps per sample are far smaller than a level's.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from servoid import validation
from servoid.ident.online.decimate import decimation_factor, slow_denominator
from servoid.ident.online.mrgia import convergence_margin
from servoid.ident.online.probe import ProbeResult

__all__ = [
    "LiveDesign",
    "design_live",
    "amplitude_cap",
    "PLAY_MULTIPLE",
    "MIN_GROUPS",
    "GENTLE_SHARE",
    "SLOW_SHARE",
    "SLOW_PART",
]

#: The amplitude aims at this many times the probe's rough play.
PLAY_MULTIPLE = 5.0
#: ... and at this many times the noise or the quantisation, whichever is larger.
NOISE_MULTIPLE = 30.0
#: Fewest slow samples a level is held for.
MIN_GROUPS = 3
#: The fastest gentle-sine segment at full amplitude, as a share of the probe's loop bandwidth. Tuned between two
#: limits, not derived: the play shows when the deceleration stays below the load's friction's (Coulomb torque over
#: inertia), which the probe does not measure (the rule exceeds it on the CiA 402 and ODrive twins; at 0.4 the
#: STS3215 twin's load coasted, -24/-27 %); and a horn encoder read without noise places the play only on faster
#: sines (the XM430 twin at 200 Hz, 4096 counts, no noise: peak 8 rad/s^2 put it outside the loop at +152/+200 %,
#: 12 inside at -8/-8/-8 %; at 0.3 live -25/+265 %, at 0.35 +18/+10/+3 %; docs/online.md, issue 15 fifth pass).
GENTLE_SHARE = 0.35
#: The slow phase's fastest segment, as a share of the probe's loop bandwidth (about a fifth of the fast phase's peak
#: acceleration): below the load's friction's deceleration on the motor-side twins, where the fast phase is above it.
#: Alone it broke the horn twins (XM430 +244 %, the place named wrong; docs/online.md): the refinement names the
#: place and fits the loop on the fast phase, and refits a play outside the loop on this one.
SLOW_SHARE = 0.15
#: The share of a gentle design's run spent in the slow phase (the run's first part; the fast phase follows).
SLOW_PART = 1.0 / 3.0
#: The designed shapes of the set point.
GENTLE, STEPS = "gentle", "steps"


@dataclass(frozen=True)
class LiveDesign:
    """The designed live run.

    Attributes
    ----------
    factor : int
        Decimation of the online estimator.
    hold : int
        Fast samples each level is held (a multiple of :attr:`factor`) when :attr:`shape` is ``"steps"``;
        else the settling time the rule gives (``servoid excite --probe``).
    amplitude : float
        Half-width of the set point around the centre.
    margin : float
        The convergence margin on the probe's model at the decimated rate.
    estimator_rate_hz : float
        The estimator's rate.
    reasons : dict of str
        Why each of ``factor``, ``shape``, ``hold``, ``amplitude`` is what it is.
    shape : str
        ``"gentle"`` (gentle sines) or ``"steps"`` (held uniform levels).
    accel : float
        The gentle sines' highest peak acceleration, unit per sample squared (0 for steps).
    slow_accel : float
        The slow phase's highest peak acceleration, unit per sample squared (0: no slow phase).
    slow_part : float
        The share of the run spent in the slow phase, which comes first (0: none).
    """

    factor: int
    hold: int
    amplitude: float
    margin: float
    estimator_rate_hz: float
    reasons: dict[str, str]
    shape: str = GENTLE
    accel: float = 0.0
    slow_accel: float = 0.0
    slow_part: float = 0.0

    def to_dict(self) -> dict[str, Any]:
        """For ``model.json`` and ``--json``."""
        return {"factor": self.factor, "shape": self.shape, "hold": self.hold, "amplitude": self.amplitude,
                "accel": self.accel, "slow_accel": self.slow_accel, "slow_part": self.slow_part, "margin": self.margin, "estimator_rate_hz": self.estimator_rate_hz,
                "reasons": dict(self.reasons)}  # fmt: skip

    def spec(self) -> str:
        """The designed excitation as a spec (:func:`servoid.excitation.parse_spec`), without its centre."""
        if self.shape == GENTLE:
            return f"gentle:amplitude={self.amplitude!r},accel={self.accel!r}"
        return f"steps:amplitude={self.amplitude!r},hold={self.hold}"

    def slow_spec(self) -> str | None:
        """The slow phase as a spec (:func:`servoid.excitation.parse_spec`), without its centre; None without one."""
        if self.shape != GENTLE or self.slow_part <= 0.0:
            return None
        return f"gentle:amplitude={self.amplitude!r},accel={self.slow_accel!r}"

    def rows(self, unit: str = "") -> list[list[str]]:
        """The design's short table: choice, value and why."""
        u = f" {unit}" if unit else ""
        slow = (f" ({100 * self.slow_part:.0f} % of the run first at up to {self.slow_accel:.3g})"
                if self.slow_part > 0.0 else "")  # fmt: skip
        shape = (f"gentle sines, peak acceleration up to {self.accel:.3g}{u} per sample^2{slow}"
                 if self.shape == GENTLE else f"levels held {self.hold} samples: {self.reasons['hold']}")  # fmt: skip
        return [
            ["estimator rate", f"1 in {self.factor} ({self.estimator_rate_hz:.4g} Hz): {self.reasons['factor']}"],
            ["shape", f"{shape}: {self.reasons['shape']}"],
            ["amplitude", f"+/-{self.amplitude:.4g}{u}: {self.reasons['amplitude']}"],
        ]


def amplitude_cap(probe: ProbeResult) -> tuple[float, str]:
    """The largest amplitude of uniform levels the probe showed the drive follows linearly, and why.

    Levels in ``+/-A`` step by up to ``2 A``; the probe stepped by ``2 A_probe``,
    ``A_probe`` and ``A_probe / 2``. ``servoid excite --design --probe`` caps its
    proposal with the same number.

    Parameters
    ----------
    probe : ProbeResult
        What the probe found.
    """
    if probe.saturated_half:
        return probe.amplitude / 4, "the drive saturated on the probe's steps of one amplitude"
    if probe.saturated:
        return probe.amplitude / 2, "the drive saturated on the probe's largest steps"
    return probe.amplitude, "the probe's amplitude, which the drive followed linearly"


def design_live(
    probe: ProbeResult,
    rate_hz: float,
    *,
    factor: int | None = None,
    hold: int | None = None,
    amplitude: float | None = None,
) -> LiveDesign:
    """Design the live run from the probe (the module's rules); a given value overrides the rule.

    Parameters
    ----------
    probe : ProbeResult
        What the probe found (at ``rate_hz``).
    rate_hz : float
        The session's rate.
    factor : int, optional
        Decimation to use instead of the designed one.
    hold : int, optional
        Held levels of this many samples (rounded up to a multiple of the factor) instead of gentle sines.
    amplitude : float, optional
        Amplitude instead of the designed one (the caller has checked it against the limits).
    """
    rate = validation.positive("rate_hz", rate_hz)
    reasons: dict[str, str] = {}
    a = np.asarray(probe.a, dtype=np.float64)
    if factor is None:
        k = decimation_factor(a)
        reasons["factor"] = (f"the smallest at which |A(e^jw) - 1| < 1 holds on the probe's model "
                             f"(margin {convergence_margin(a):.2f} at the full rate)")  # fmt: skip
    else:
        k = validation.integer("factor", factor, minimum=1)
        reasons["factor"] = "given"
    margin = convergence_margin(slow_denominator(a, k))
    if margin < 0:
        reasons["factor"] += (
            f"; the condition still fails at this rate (margin {margin:.2f}): the online estimate may not converge"
        )
    if hold is None:
        groups = max(MIN_GROUPS, math.ceil(0.5 / probe.bandwidth_hz * rate / k))
        h = groups * k
        reasons["hold"] = f"{groups} groups of {k}, at least half a period of the {probe.bandwidth_hz:.3g} Hz loop"
        shape = GENTLE
        reasons["shape"] = (f"the fastest segment at {GENTLE_SHARE:g}x the {probe.bandwidth_hz:.3g} Hz loop, after "
                            f"{100 * SLOW_PART:.0f} % of the run at {SLOW_SHARE:g}x: at each reversal the load stays on "
                            "the trailing flank when the set point decelerates more gently than the load's friction, "
                            "which the probe does not measure (the slow phase for a play outside the loop, the fast one "
                            "for a play inside it; held levels let the load coast across the play)")  # fmt: skip
    else:
        h = math.ceil(validation.integer("hold", hold, minimum=1) / k) * k
        reasons["hold"] = "given" + ("" if h == hold else f", rounded up to whole groups of {k}")
        shape, reasons["shape"] = STEPS, "--hold given"
    if amplitude is None and shape == GENTLE:
        amp, why = amplitude_cap(probe)
        reasons["amplitude"] = f"the largest the probe allows ({why}); the sines' segments run down to a quarter of it"
    elif amplitude is None:
        floor = max(probe.noise_std, probe.quantum)
        wanted = max(PLAY_MULTIPLE * probe.play, NOISE_MULTIPLE * floor if math.isfinite(floor) else 0.0)
        top, why = amplitude_cap(probe)
        amp = min(max(wanted, 0.5 * top), top) if math.isfinite(wanted) else top
        reasons["amplitude"] = (f"{PLAY_MULTIPLE:g}x the rough play and {NOISE_MULTIPLE:g}x the noise, at least half of and "
                                f"at most {top:.3g} ({why})")  # fmt: skip
        if wanted > top:
            reasons["amplitude"] += f"; {wanted:.3g} was wanted: the play may be poorly excited"
    else:
        amp = validation.positive("amplitude", amplitude)
        reasons["amplitude"] = "given"
    gentle = shape == GENTLE
    accel = float(amp) * (2.0 * math.pi * GENTLE_SHARE * probe.bandwidth_hz / rate) ** 2 if gentle else 0.0
    slow = accel * (SLOW_SHARE / GENTLE_SHARE) ** 2
    return LiveDesign(
        k, h, float(amp), float(margin), rate / k, reasons, shape, accel, slow, SLOW_PART if gentle else 0.0
    )
