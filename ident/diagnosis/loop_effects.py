"""The servo loop's effects in the diagnosis: ``friction_stall`` (:mod:`.friction_stall`) and ``flank_rebound`` (:mod:`.flank_rebound`).

The effect search of :func:`servoid.ident.diagnosis.diagnose` extends the
black box; a drive that stalls after each reversal until its velocity loop
overcomes break-away friction is an effect *inside* the loop, which the
black box books as play. So the diagnosis fits the servo-loop model on the
training record (:func:`servoid.ident.offline.loop_fit.fit_loop`: the place
of the play chosen by validation), refits the same structure without its
friction terms (:func:`~servoid.ident.offline.loop_fit.refit` with
``fc = fs = 0``), scores both on the validation record and names
``friction_stall`` when :func:`.friction_stall.matters` says the friction
terms pay: the gap shrinks by more than 2 % and the drive needs at least 5 %
of a typical speed error to break away. On the same validation run of the
chosen (massless) model it names ``flank_rebound`` when the residual around
the load's departures from a flank shows the load bouncing off it
(:func:`.flank_rebound.rebound`); no model here follows the bounce well enough
to give the play with it (README, "What we learned"), so only the massless
model's gap is reported for it.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from servoid.ident.diagnosis.flank_rebound import Rebound, rebound
from servoid.ident.diagnosis.friction_stall import describe, matters, stall_band
from servoid.ident.metrics import nrmse
from servoid.ident.models.effect_names import FLANK_REBOUND, FRICTION_STALL, NONE
from servoid.ident.models.servo_loop import ServoLoopModel

__all__ = ["LoopEffect", "loop_effects", "FRICTION_TERMS"]

#: The servo-loop model's friction parameters, held at zero in the fit without friction.
FRICTION_TERMS = ("fc", "fs", "vs", "veps")


@dataclass(frozen=True)
class LoopEffect:
    """What the servo-loop model says is missing: :func:`loop_effects`'s result.

    Attributes
    ----------
    effect : str
        ``friction_stall`` when it matters, else ``none``.
    structure : str
        The place of the play the servo-loop model chose on the training record.
    gap_without, gap_with : float
        Validation NRMSE of the servo-loop model without and with its friction terms.
    stall_ratio : float
        ``max(fs, fc) / (kv v_typ)``, ``v_typ = std(diff y) / T``: the speed error the drive needs to
        break away, relative to a typical speed (the model's break-away level is ``fc`` when a fit
        leaves ``fs < fc``: the Stribeck hump is then absent).
    stall_band : float
        ``max(fs, fc) / (kv kp)``, unit of y: the position error a P loop leaves standing against break-away friction.
    play : float
        The servo-loop model's play (with friction), unit of y.
    model : ServoLoopModel
        The servo-loop model with friction.
    rebound : Rebound or None
        Its validation residual around the load's departures from a flank (:func:`.flank_rebound.rebound`).
    """

    effect: str
    structure: str
    gap_without: float
    gap_with: float
    stall_ratio: float
    stall_band: float
    play: float
    model: ServoLoopModel
    rebound: Rebound | None = None

    @property
    def named(self) -> bool:
        """Whether ``friction_stall`` is named."""
        return self.effect == FRICTION_STALL

    @property
    def rebounds(self) -> bool:
        """Whether ``flank_rebound`` is named."""
        return self.rebound is not None and self.rebound.named

    def rebound_line(self, unit: str = "") -> str:
        """One line for the report on ``flank_rebound``: named or not, the numbers and the massless model's gap.

        Parameters
        ----------
        unit : str
            The unit of y, or "".
        """
        if self.rebound is None:
            return f"{FLANK_REBOUND}: not looked for"
        gap = f"servo-loop validation gap {self.gap_with:.4g} with the massless load"
        if self.rebounds:
            return (f"{self.rebound.line()}; {gap} (no model here follows the bounce: the play "
                    f"{self.play:.4g}{unit and ' ' + unit} is biased)")  # fmt: skip
        return f"{self.rebound.line()}; {gap}"

    def line(self, unit: str = "") -> str:
        """One line for the report: the effect and the gap it closes, or why it is not named.

        Parameters
        ----------
        unit : str
            The unit of y, or "".
        """
        gaps = f"servo-loop validation gap {self.gap_without:.4g} without friction -> {self.gap_with:.4g} with it"
        if self.named:
            return f"{describe(self.stall_band, self.play, unit)} ({gaps}, stall ratio {self.stall_ratio:.2g})"
        return f"{FRICTION_STALL}: not missing ({gaps}, stall ratio {self.stall_ratio:.2g})"

    def to_dict(self) -> dict[str, Any]:
        """``{"effect", "structure", "gap_without", "gap_with", "stall_ratio", "stall_band", "play", "params",
        "rebound"}`` (``rebound``: :meth:`.flank_rebound.Rebound.to_dict`, or None)."""
        return {"effect": self.effect, "structure": self.structure, "gap_without": self.gap_without,
                "gap_with": self.gap_with, "stall_ratio": self.stall_ratio, "stall_band": self.stall_band,
                "play": self.play, "params": self.model.params(),
                "rebound": None if self.rebound is None else self.rebound.to_dict()}  # fmt: skip


def _free_run(model: ServoLoopModel, u: np.ndarray, y: np.ndarray) -> np.ndarray:
    """The loop model's free run on a record, in its coordinates (it sees differences only: any one constant off both)."""
    centre = float(np.mean(u))
    return model.simulate(u - centre, y0=float(y[0]) - centre) + centre


def _gap(model: ServoLoopModel, u: np.ndarray, y: np.ndarray) -> float:
    """Free-run NRMSE of the loop model on a record."""
    return nrmse(y, _free_run(model, u, y))


def loop_effects(
    train: tuple[np.ndarray, np.ndarray], validate: tuple[np.ndarray, np.ndarray], sample_period_s: float
) -> LoopEffect:
    """Fit the servo-loop model with and without friction on ``train``, score both on ``validate``.

    Parameters
    ----------
    train, validate : tuple of ndarray
        ``(u, y)`` of the training and the validation record (set point and position, one unit).
    sample_period_s : float
        The host period of both records, s.

    Returns
    -------
    LoopEffect

    Raises
    ------
    ConfigError
        A record the servo-loop model cannot be fitted on (:func:`~servoid.ident.offline.loop_fit.fit_loop`).
    """
    from servoid.ident.offline.loop_fit import fit_loop, refit

    u_t, y_t = train
    choice = fit_loop(u_t, y_t, sample_period_s)
    with_friction = choice.model
    start = dataclasses.replace(with_friction, fc=0.0, fs=0.0)
    without = refit(u_t, y_t, sample_period_s, start, hold=FRICTION_TERMS)
    u_v, y_v = validate
    run = _free_run(with_friction, u_v, y_v)
    gap_with, gap_without = nrmse(y_v, run), _gap(without, *validate)
    v_typ = float(np.std(np.diff(y_t))) / sample_period_s
    m = with_friction
    # the model's break-away level: a fit with fs < fc has no Stribeck hump, and fc is where it breaks away
    breakaway = max(m.fs, m.fc)
    ratio = breakaway / (m.kv * v_typ) if m.kv > 0.0 and v_typ > 0.0 else math.inf
    named = matters(gap_with, gap_without, ratio)
    return LoopEffect(
        effect=FRICTION_STALL if named else NONE, structure=choice.structure, gap_without=gap_without,
        gap_with=gap_with, stall_ratio=ratio, stall_band=stall_band(breakaway, m.kv, m.kp), play=m.play, model=m,
        rebound=rebound(y_v, run, m.play, sample_period_s),
    )  # fmt: skip
