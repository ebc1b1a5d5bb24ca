"""Whether an online estimate has converged: judged on its trajectory and against the refined fit, not on line coverage alone.

The MRGIA's own ``settled`` flag only says that both backlash lines kept
receiving updates; on physically modelled servos it said "settled" for runs
whose online fit was 7-100x worse than the refined one (issue 15). An online
estimate is called settled here only when all of these hold:

coverage
    both lines are still being updated at the end (:attr:`MRGIAResult.settled`);
trajectory
    the dead zone ``c1 + c2`` moved by at most ``drift_tol`` (relative) over
    the last ``tail`` of the run, and no recovery happened in it;
fit
    when a refined fit of the same record is given: the online model's
    free-run NRMSE, on the samples the refined one's was computed on (like
    with like: after a live design's slow phase the refined fit scores one part
    of the record, :meth:`~servoid.ident.online.refinement.Refined.score`),
    is at most ``fit_ratio`` times the refined one (plus ``fit_slack``), and its
    dead zone lies within ``gap_tol`` of the refined one.

Every rule that fails is named in :attr:`OnlineVerdict.reasons`.

The servo-loop model's online estimate (a moving-window refit,
:mod:`servoid.ident.online.window`) has no line coverage; it is judged by
:func:`judge_window` on its trajectory over the last :data:`LAST_WINDOWS`
refits (the play moved by at most ``drift_tol``), on the last window's fit
against the floor its resolution and noise leave (at most
:data:`~servoid.ident.offline.intervals.MAX_FIT_TO_FLOOR` times, the
offline rule: a model off its floor misses something, and a settled estimate
of a wrong model is the worst outcome), and, as above, against the refined fit.
When its last window ended more than a refit period before the stream did (a
live identify that did not wait for the last refit,
:attr:`~servoid.ident.online.window.WindowResult.age_s`), the trajectory and
floor rules saw none of the samples after it: the verdict says so
(:attr:`OnlineVerdict.judged`), and without a refined fit to judge the model on
those samples it is not settled.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from servoid.errors import ModelError
from servoid.ident.models.pseudo_wiener import BacklashModel
from servoid.ident.online.mrgia import MRGIAResult

if TYPE_CHECKING:  # pragma: no cover
    from servoid.ident.online.window import WindowResult

__all__ = ["OnlineVerdict", "judge_online", "judge_window", "LAST_WINDOWS", "DRIFT_TOL", "GAP_TOL", "FIT_RATIO", "TAIL"]

#: Share of the run (its end) over which the trajectory must be still.
TAIL = 0.25
#: Largest relative movement of ``c1 + c2`` over the tail.
DRIFT_TOL = 0.05
#: Largest relative difference between the online and the refined dead zone.
GAP_TOL = 0.10
#: Largest ratio of the online fit's NRMSE to the refined one's.
FIT_RATIO = 1.25
#: Added to the allowed NRMSE, so that near-perfect fits are not judged on rounding.
FIT_SLACK = 0.01
#: Refits of a moving-window estimate whose plays must agree (:func:`judge_window`): with
#: the default refit period, the last 10 s of servo time.
LAST_WINDOWS = 3


@dataclass(frozen=True)
class OnlineVerdict:
    """The verdict on an online estimate, with the numbers it rests on.

    Attributes
    ----------
    settled : bool
        True only when every rule held (see the module's text).
    reasons : tuple of str
        One line per rule that failed; empty when settled.
    online_gap, refined_gap : float
        Dead zone ``c1 + c2`` of the online estimate and of the refined model (NaN when there is none).
    online_nrmse, refined_nrmse : float
        Free-run NRMSE of each on the same samples of the record, the refined fit's (NaN when unknown).
    drift : float
        Relative movement of the online dead zone over the last part of the run.
    judged : str
        What the trajectory and fit rules saw when it was not the whole run (a moving-window
        estimate whose last window ended before the stream); empty otherwise.
    """

    settled: bool
    reasons: tuple[str, ...]
    online_gap: float
    refined_gap: float
    online_nrmse: float
    refined_nrmse: float
    drift: float
    judged: str = ""

    def to_dict(self) -> dict[str, Any]:
        """For JSON (NaN as null through :func:`servoid.ident.serialise.dumps`)."""
        return {"settled": self.settled, "reasons": list(self.reasons), "online_gap": self.online_gap,
                "refined_gap": self.refined_gap, "online_nrmse": self.online_nrmse,
                "refined_nrmse": self.refined_nrmse, "drift": self.drift, "judged": self.judged}  # fmt: skip

    def line(self, unit: str = "") -> str:
        """One line for the terminal: both numbers and the verdict."""
        u = f" {unit}" if unit else ""
        text = (f"online estimate: play {self.online_gap:.4g}{u} (fit {self.online_nrmse:.3g}); refined: "
                f"{self.refined_gap:.4g}{u} (fit {self.refined_nrmse:.3g}); ")  # fmt: skip
        said = "settled" if self.settled else "NOT settled: " + "; ".join(self.reasons)
        return text + said + (f" ({self.judged})" if self.judged else "")


def judge_online(
    online: MRGIAResult,
    online_nrmse: float | None = None,
    refined: BacklashModel | None = None,
    refined_nrmse: float | None = None,
    *,
    tail: float = TAIL,
    drift_tol: float = DRIFT_TOL,
    gap_tol: float = GAP_TOL,
    fit_ratio: float = FIT_RATIO,
    fit_slack: float = FIT_SLACK,
) -> OnlineVerdict:
    """Judge an online estimate (the module's rules).

    Parameters
    ----------
    online : MRGIAResult
        The online run, with its parameter history.
    online_nrmse : float, optional
        Free-run NRMSE of the online model on the record the refined fit is on (None: not a valid model).
    refined : BacklashModel, optional
        The refined model of the same record; without it only coverage and trajectory are judged.
    refined_nrmse : float, optional
        Its free-run NRMSE.
    tail : float
        Share of the run, at its end, over which the trajectory must be still.
    drift_tol : float
        Largest relative movement of ``c1 + c2`` over the tail.
    gap_tol : float
        Largest relative difference of the dead zones.
    fit_ratio : float
        Largest ratio of the online NRMSE to the refined one.
    fit_slack : float
        Added to the allowed NRMSE.
    """
    reasons: list[str] = []
    lay = online.config.theta_layout
    try:
        gap = online.model.dead_zone
    except ModelError as exc:
        gap = float(online.theta[lay.c1] + online.theta[lay.c2])
        reasons.append(f"not a valid model ({exc})")
    if not online.settled:
        up, down = online.coverage
        reasons.append(f"a backlash line stopped receiving updates (coverage up {up:.2f} / down {down:.2f})")
    hist = online.theta_history
    drift = math.nan
    if hist.shape[0] >= 4:
        gaps = hist[:, lay.c1] + hist[:, lay.c2]
        last = gaps[int(math.floor((1.0 - tail) * gaps.size)) :]
        # relative to the play, or to the largest play of the tail when the estimate sits near 0 (a bounded ratio)
        scale = max(abs(gap), float(np.max(np.abs(last))), 1e-300)
        drift = float(np.ptp(last) / scale)
        if not drift <= drift_tol:
            reasons.append(f"the play still moved {100 * drift:.0f} % over the last {100 * tail:.0f} % of the run")
    else:
        reasons.append("too short a history to judge the trajectory")
    start = online.samples * (1.0 - tail)
    if any(r.sample >= start for r in online.recoveries):
        reasons.append(f"it recovered from a stuck zone classification in the last {100 * tail:.0f} % of the run")
    o_fit = math.nan if online_nrmse is None else float(online_nrmse)
    r_gap = math.nan if refined is None else refined.dead_zone
    r_fit = math.nan if refined_nrmse is None else float(refined_nrmse)
    if refined is not None:
        _against_refined(reasons, gap, o_fit, r_gap, r_fit, gap_tol, fit_ratio, fit_slack)
    return OnlineVerdict(not reasons, tuple(reasons), float(gap), float(r_gap), o_fit, r_fit, drift)


def _against_refined(
    reasons: list[str],
    gap: float,
    o_fit: float,
    r_gap: float,
    r_fit: float,
    gap_tol: float,
    fit_ratio: float,
    fit_slack: float,
) -> None:
    """The rules against the refined fit of the same record (both judges)."""
    if not o_fit <= fit_ratio * r_fit + fit_slack:
        reasons.append(f"its fit ({o_fit:.3g}) is worse than {fit_ratio:g}x the refined one ({r_fit:.3g})")
    if not abs(gap - r_gap) <= gap_tol * abs(r_gap):
        reasons.append(f"its play differs from the refined one by {100 * (gap / r_gap - 1):+.0f} %")


def judge_window(
    online: WindowResult,
    online_nrmse: float | None = None,
    refined_play: float | None = None,
    refined_nrmse: float | None = None,
    *,
    last: int = LAST_WINDOWS,
    drift_tol: float = DRIFT_TOL,
    gap_tol: float = GAP_TOL,
    fit_ratio: float = FIT_RATIO,
    fit_slack: float = FIT_SLACK,
) -> OnlineVerdict:
    """Judge a moving-window estimate (:mod:`servoid.ident.online.window`; the module's rules).

    Parameters
    ----------
    online : WindowResult
        The run, with every refit.
    online_nrmse : float, optional
        Free-run NRMSE of the online model on the samples the refined fit was scored on
        (:meth:`~servoid.ident.online.refinement.Refined.score`).
    refined_play : float, optional
        The play of the refined fit of the same record; without it only trajectory and floor are judged.
    refined_nrmse : float, optional
        Its free-run NRMSE.
    last : int
        Refits whose plays must agree.
    drift_tol : float
        Largest spread of those plays, relative to the last.
    gap_tol, fit_ratio, fit_slack : float
        As in :func:`judge_online`.
    """
    from servoid.ident.offline.intervals import MAX_FIT_TO_FLOOR

    reasons: list[str] = list(online.errors[-1:])
    plays = online.plays
    gap = float(plays[-1]) if plays.size else math.nan
    drift = math.nan
    if plays.size < last:
        reasons.append(f"{plays.size} window refit(s): too few to judge the trajectory (at least {last})")
    else:
        tail = plays[-last:]
        drift = float(np.ptp(tail) / max(abs(gap), float(np.max(np.abs(tail))), 1e-300))
        if not drift <= drift_tol:
            reasons.append(f"the play still moved {100 * drift:.0f} % over the last {last} windows")
    if online.history:
        row = online.history[-1]
        if not row.nrmse <= MAX_FIT_TO_FLOOR * row.floor:
            reasons.append(f"the last window's fit ({row.nrmse:.3g}) is {row.nrmse / row.floor:.2g}x the floor "
                           f"its resolution and noise leave (at most {MAX_FIT_TO_FLOOR:g})")  # fmt: skip
    o_fit = math.nan if online_nrmse is None else float(online_nrmse)
    r_gap = math.nan if refined_play is None else float(refined_play)
    r_fit = math.nan if refined_nrmse is None else float(refined_nrmse)
    if refined_play is not None:
        _against_refined(reasons, gap, o_fit, r_gap, r_fit, gap_tol, fit_ratio, fit_slack)
    judged, age = "", online.age_s
    if age > online.config.every_s:  # a stale last window: the rules above saw none of the stream's last samples
        seen = (
            f"windows ending by {online.history[-1].t_s:.1f} s of the stream's {online.end_s:.1f} s ({age:.1f} s old)"
        )
        if refined_play is None:
            reasons.append(f"the last window ended {age:.1f} s before the stream: its last samples are not judged")
            judged = f"trajectory and fit on {seen}"
        else:
            judged = f"trajectory and fit on {seen}; the later samples only against the whole record's fit"
    return OnlineVerdict(not reasons, tuple(reasons), gap, r_gap, o_fit, r_fit, drift, judged)
