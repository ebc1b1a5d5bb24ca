"""The compensator for a play inside the position loop: a brief set-point lead at each reversal.

When the drive closes its loop on the load's encoder (``play_in_loop``), the
loop already drives the load to the set point whatever the play: adding the
play to the set point, as the output-backlash inverse does, would make it
overshoot by the play. What the play leaves is dynamic: at each reversal the
load waits while the motor crosses the play (a dead time of ``play / motor
speed``), then jumps when the motor reaches it. The lead shortens that wait:

* at a reversal of the set point ``r`` (its step changes sign), add
  ``+lead_up`` (going up) or ``-lead_down`` (going down) to the set point sent;
* remove it as soon as the load has moved ``threshold`` in the new direction
  from where it stood at the reversal (the encoder on the load sees that
  within a sample), or after ``max_samples`` samples, whichever comes first.

With the lead the loop's error is at least the play during the crossing, so
the motor crosses it at the speed the loop gives a play's error; once the load
moves the set point is the user's again. :func:`lead_step` is the rule, one
sample at a time (the C header's ``servoid_reversal_lead`` is the same code),
:func:`simulate_lead` runs it in closed loop on a servo-loop model.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from servoid import validation
from servoid.ident._jit import jit
from servoid.ident.models.servo_loop import STATE_SIZE, ServoLoopModel, advance, initial_state

__all__ = [
    "ReversalLead",
    "LeadPath",
    "lead_step",
    "simulate_lead",
    "lead_study",
    "LEAD_STATE_SIZE",
    "MAX_LEAD_TIME_CONSTANTS",
    "STUDY_PERIODS",
]

#: The lead lasts at most this many of the position loop's time constants ``1/kp`` (by then the
#: motor has crossed the play even at the loop's own speed).
MAX_LEAD_TIME_CONSTANTS = 3.0
#: Floats in the rule's state: last set point, direction, active, load at the reversal, samples active.
LEAD_STATE_SIZE = 5


@dataclass(frozen=True)
class ReversalLead:
    """The parameters of the reversal lead (units of the model's output ``y``; time in samples).

    Attributes
    ----------
    lead_up, lead_down : float
        Added to (going up) or taken from (going down) the set point after a reversal: the
        play's two sides ``c1`` and ``c2``, ``>= 0``.
    threshold : float
        How far the load must move in the new direction before the lead is removed, ``> 0``.
    max_samples : int
        The longest a lead lasts, samples, ``>= 1``.
    """

    lead_up: float
    lead_down: float
    threshold: float
    max_samples: int

    def __post_init__(self) -> None:
        validation.non_negative("lead_up", self.lead_up)
        validation.non_negative("lead_down", self.lead_down)
        validation.positive("threshold", self.threshold)
        validation.integer("max_samples", self.max_samples, minimum=1)

    @classmethod
    def for_model(cls, model: ServoLoopModel, threshold: float) -> ReversalLead:
        """The lead for a servo-loop model: its ``c1``, ``c2``, and at most ``MAX_LEAD_TIME_CONSTANTS / kp``.

        Parameters
        ----------
        model : ServoLoopModel
            The identified loop (``play_in_loop``).
        threshold : float
            The load's movement that ends a lead (e.g. the compensation band: a few counts).

        Returns
        -------
        ReversalLead
        """
        samples = max(1, math.ceil(MAX_LEAD_TIME_CONSTANTS / (model.kp * model.sample_period_s)))
        return cls(lead_up=model.c1, lead_down=model.c2, threshold=threshold, max_samples=samples)

    def vector(self) -> np.ndarray:
        """``[lead_up, lead_down, threshold, max_samples]`` for :func:`lead_step`."""
        return np.array([self.lead_up, self.lead_down, self.threshold, float(self.max_samples)])

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready fields (what the YAML and JSON exports carry)."""
        return {
            "lead_up": self.lead_up,
            "lead_down": self.lead_down,
            "threshold": self.threshold,
            "max_samples": self.max_samples,
        }


@jit
def lead_step(q: np.ndarray, state: np.ndarray, r: float, y: float) -> float:
    """One sample of the reversal lead: the set point to send for the wanted ``r`` and the reading ``y``.

    Parameters
    ----------
    q : ndarray
        :meth:`ReversalLead.vector`.
    state : ndarray
        :data:`LEAD_STATE_SIZE` floats: last set point, direction (-1, 0, 1), active (0/1), the load
        at the reversal, samples active. Start with ``[r0, 0, 0, 0, 0]``.
    r : float
        The wanted set point now.
    y : float
        The load's reading now (before the set point is sent).

    Returns
    -------
    float
        The set point to send.
    """
    step = r - state[0]
    state[0] = r
    d = 0.0
    if step > 0.0:
        d = 1.0
    elif step < 0.0:
        d = -1.0
    if d != 0.0 and d != state[1]:
        if state[1] != 0.0:
            state[2] = 1.0
            state[3] = y
            state[4] = 0.0
        state[1] = d
    if state[2] > 0.0:
        state[4] += 1.0
        if state[1] * (y - state[3]) >= q[2] or state[4] > q[3]:
            state[2] = 0.0
    if state[2] > 0.0:
        return float(r + q[0] if state[1] > 0.0 else r - q[1])
    return r


@jit
def _lead_kernel(
    p: np.ndarray,
    feedback_load: bool,
    q: np.ndarray,
    use_lead: bool,
    r: np.ndarray,
    y0: float,
    period: float,
    m: int,
    y_out: np.ndarray,
    u_out: np.ndarray,
) -> None:
    state = np.empty(STATE_SIZE)
    initial_state(p, y0, state)
    lead = np.zeros(LEAD_STATE_SIZE)
    lead[0] = r[0]
    for k in range(r.shape[0]):
        y = state[1]
        y_out[k] = y
        u = lead_step(q, lead, r[k], y) if use_lead else r[k]
        u_out[k] = u
        advance(p, feedback_load, state, u, period, m)


def simulate_lead(
    model: ServoLoopModel, lead: ReversalLead | None, r: Any, *, y0: float | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """Closed-loop simulation of the servo loop with the reversal lead (or without: ``lead=None``).

    Parameters
    ----------
    model : ServoLoopModel
        The servo.
    lead : ReversalLead or None
        The compensator; None sends ``r`` as it is.
    r : array_like
        The wanted set points, one per host period.
    y0 : float, optional
        The load at the start, at rest (default ``r[0]``).

    Returns
    -------
    y : ndarray
        The load's readings.
    u : ndarray
        The set points sent.
    """
    r_arr = np.ascontiguousarray(validation.signal("r", r), dtype=np.float64)
    start = validation.real("y0", float(r_arr[0]) if y0 is None else y0)
    y = np.empty_like(r_arr)
    u = np.empty_like(r_arr)
    q = lead.vector() if lead is not None else np.zeros(4)
    _lead_kernel(
        model.vector(), model.feedback_load, q, lead is not None, r_arr - start, 0.0, model.sample_period_s,
        model.substeps, y, u,
    )  # fmt: skip
    return y + start, u + start


#: The study's reference paths: sines of this many plays of amplitude, with these periods in samples.
STUDY_AMPLITUDE_PLAYS = 10.0
STUDY_PERIODS = (30, 120, 480)


@dataclass(frozen=True)
class LeadPath:
    """The play's error on one reference path, without and with the lead (units of ``y``).

    Attributes
    ----------
    period : int
        The sine's period, samples.
    rms_without, rms_with : float
        RMS of ``y - y_no_play`` (the same loop without its play) without and with the lead.
    peak_without, peak_with : float
        Largest ``|y - y_no_play|``.
    """

    period: int
    rms_without: float
    rms_with: float
    peak_without: float
    peak_with: float


def lead_study(model: ServoLoopModel, lead: ReversalLead, *, cycles: int = 4) -> tuple[LeadPath, ...]:
    """What the lead does on the model: the play's error on sines of :data:`STUDY_PERIODS` samples.

    The error is measured against the same loop without its play, so that the loop's own lag
    (which no play compensator removes) is left out.

    Parameters
    ----------
    model : ServoLoopModel
        The servo (``play_in_loop``).
    lead : ReversalLead
        The compensator.
    cycles : int
        Periods of each sine.

    Returns
    -------
    tuple of LeadPath
    """
    import dataclasses

    ideal = dataclasses.replace(model, c1=0.0, c2=0.0)
    amplitude = STUDY_AMPLITUDE_PLAYS * max(model.play, 1e-12)
    out = []
    for period in STUDY_PERIODS:
        r = amplitude * np.sin(2.0 * np.pi * np.arange(cycles * period) / period)
        y_ideal, _ = simulate_lead(ideal, None, r)
        y_without, _ = simulate_lead(model, None, r)
        y_with, _ = simulate_lead(model, lead, r)
        e0 = y_without - y_ideal
        e1 = y_with - y_ideal
        out.append(
            LeadPath(
                period=period,
                rms_without=float(np.sqrt(np.mean(e0 * e0))),
                rms_with=float(np.sqrt(np.mean(e1 * e1))),
                peak_without=float(np.max(np.abs(e0))),
                peak_with=float(np.max(np.abs(e1))),
            )
        )
    return tuple(out)
