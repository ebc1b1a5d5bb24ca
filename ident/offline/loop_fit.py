"""Fit the servo-loop model with the play in both places and choose the place by validation: :func:`fit_loop`.

The steps (the issue-12 study, Q3; :mod:`servoid.ident.models.servo_loop` is the model):

1. **Operating point.** The same constant ``mean(u)`` comes off ``u`` and ``y`` (the loop
   compares set point and reading, so they share a unit); the model depends on differences
   only, so raw counts and centred records give the same fit up to rounding.
2. **Linear start.** A least-squares ARX(2, 2) of ``y`` on ``u``; its two poles in continuous
   time matched to ``kp kv / (s^2 + kv s + kp kv)``: ``kv = -(s1 + s2)``, ``kp = s1 s2 / kv``.
   Friction, Stribeck and smoothing speeds start from the record's typical speed
   ``v_typ = std(diff y) / T``.
3. **Scan.** For each place of the play, simulate (no fitting) a grid of plays (half the
   record's quantum to a quarter of its range) times three friction levels; the best is the start.
4. **Four candidates**: the play outside the loop (``output_backlash``) or inside it
   (``play_in_loop``), each with and without the velocity integrator; least squares over
   ``kp, kv, fc, fs, vs, veps, a0, play, asymmetry [, ki]`` on the **estimation blocks**
   (8 interleaved blocks; the simulation runs through the validation blocks but they are
   not scored). Each candidate starts from the scan (not the integrator's from the P loop's fit:
   tried, it inherited the P loop's basin and named the CiA 402 twin with friction x4 a play in
   the loop at +200 %, identifiable). Only a candidate whose play collapsed below what the record
   resolves, where its sibling found one, is fitted again from the sibling's fit
   (:data:`COLLAPSE_RESTART`); the best candidate whose loop, refitted with its play held a step
   either side, costs less than it did is fitted again from there (:data:`PROFILE_RESTART`).
5. **Select** the candidate with the smallest free-run NRMSE on the validation blocks; the
   **margin** is the best candidate of the other place relative to it (``val_other / val_best - 1``).
6. **Final refit** of the winner on all samples (a winner that lost its Stribeck hump is
   refitted from one too, on the window where the search ran on one; after a window's search each
   refit first takes its steps on a bridge of twice the window: :func:`_final_fit`), and the play's 95 %
   interval from the Newey-West (HAC) sandwich on that fit's Jacobian (noise), widened to the
   plays of the candidates that validate as well as the winner (within the structure margin):
   the model error the record cannot resolve.

7. **The load stage** (``load=``; :mod:`~servoid.ident.offline.load_stage`): the massless winner
   extended by a heavy load of its own inertia that meets the flanks in rigid impacts, found on a
   grid of inertia x restitution with the loop refitted at each point, kept only when it
   validates :data:`LOAD_MARGIN` better. ``identify`` runs it where the motor-side winner is off
   its floor (a load coasting across the play: the ODrive twin's -45 ... -80 % came to -14 ... +6 %).
   It starts from that structure's candidate that validates best, with an integrator
   (:func:`_stage_start`): the massless fits cannot tell whether a loop behind a heavy load
   integrates, and the stage frees only its start's parameters (from the candidate with an
   integrator, the ODrive twin's -14 ... +2 % came to -10 ... +2 %); where the best has none, its
   values start one, since the candidate with an integrator can be the worse start (the ODrive
   twin's sines at 10/20/50x, seeds 1-5: 10 -> 12 of 15 within 5 %, 20x s4 -79 -> +0.5 %).
   Where that candidate is at its floor instead, a few light loads are fitted as the stage's grid
   points (:func:`~servoid.ident.offline.load_stage.floor_rivals`): never the answer, only rivals
   whose plays widen the interval (a light load that bounces off the flanks hides play from a
   massless fit at the floor; :data:`LOAD_FLOOR_RIVALS`).

What makes the cost usable (the study's Q3 finding 4): the friction is smooth and the
contact is the play operator, so the free-run output is continuous in the parameters;
rates and the play are fitted as ``ln(p / p_start)`` with a 3 % finite-difference step,
which sees the slope rather than the sub-step roughness of events; the simulation stops at
the last scored sample; BLAS runs single-threaded (small matrices, many of them). Each search
ends at a step that lowers the cost by less than 1e-5 of it (:data:`FTOL`), and each candidate's
at an accepted step that lowers it by less than 1e-4 (:data:`STALL`): the searches' tails moved
the play by well under its interval and cost half the simulations (``benchmarks/loop_speed.py``).
The final refit ends by the same rule (:data:`FINAL_STALL`) and then takes one Jacobian at its
answer for the interval.
The Jacobian's columns and the two places' searches run at once on the shared thread pool
(:mod:`._threads`), the columns and the scan's starts two by two in one kernel
(:func:`~servoid.ident.models.servo_loop.simulate_pair_kernel`), with the same answer to the bit. A record of at least twice :data:`SEARCH_SAMPLES`
is searched (steps 3-5 and 7) on its first :data:`SEARCH_SAMPLES` samples (fewer where they hold more than
:data:`WINDOW_REVERSALS` reversals of the set point), with their own interleaved blocks; only the final refit (step 6) and what is read from it run on every sample
(the starts of step 2 read all): the search's cost no longer grows with the record, and on the
twins the play moved by well inside its interval (CiA 402, 20 000 samples: identify 3.3x faster); a
window whose winner is off the window's floor, or predicts the rest of the record worse than it validated,
is searched again on all.
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.optimize import least_squares

from servoid import validation
from servoid.errors import ConfigError, ModelError
from servoid.ident.diagnosis.friction_stall import stall_band
from servoid.ident.metrics import free_run_nrmse, nrmse
from servoid.ident.models.servo_loop import (
    KERNEL_NAMES,
    LOAD_NAMES,
    ServoLoopModel,
    simulate_kernel,
    simulate_pair_kernel,
    substeps,
)
from servoid.ident.models.structure_names import OUTPUT_BACKLASH, PLAY_IN_LOOP
from servoid.ident.offline import _threads
from servoid.ident.offline._oefit import single_threaded_blas
from servoid.ident.offline.intervals import (
    MAX_FIT_TO_FLOOR,
    MIN_STRUCTURE_MARGIN,
    Z95,
    floor_nrmse,
    hac_stderr,
    quantum,
    reversal_indices,
)
from servoid.ident.offline.load_stage import MU_LIMITS, Fit, Simulate, floor_rivals, load_stage
from servoid.ident.offline.place_test import catch_up_groups, reversal_z

__all__ = [
    "LoopChoice",
    "LoopCandidate",
    "fit_loop",
    "refit",
    "refit_loop",
    "LoopRefit",
    "block_mask",
    "place_margin",
    "MIN_SAMPLES",
]

#: Fewest samples :func:`fit_loop` accepts (8 blocks of at least 25 samples).
MIN_SAMPLES = 200
#: Interleaved blocks: even ones estimate, odd ones validate.
BLOCKS = 8
#: Relative finite-difference step of the fit (see the module docstring).
DIFF_STEP = 0.03
#: Evaluations of each candidate's fit and of the final refit (scipy's ``max_nfev``; a Jacobian
#: costs one simulation per free parameter on top).
CANDIDATE_NFEV = 40
FINAL_NFEV = 25
#: Parameters fitted as ``ln(p / p_start)`` (the restitution ``e`` and the asymmetry are fitted as they are;
#: the compliant contact's ``wc``, ``zeta``: only :mod:`.horn_contact` frees them).
_LOG = frozenset({"kp", "kv", "ki", "fc", "fs", "vs", "veps", "play", "mu", "al", "wc", "zeta"})
#: Absolute limits of log-fitted parameters: the load stage's inertia ratio stays a heavy load's
#: (:data:`~servoid.ident.offline.load_stage.MU_LIMITS`; towards 0 the load turns into a weightless
#: one that coasts, which fits a heavy load's record about as well with another play).
_LOG_LIMITS = {"mu": MU_LIMITS}
#: Parameters fitted as they are, bounded, and started where the start puts them (not at 0).
_BOUNDED = {"asym": (-0.5, 0.5), "e": (0.0, 1.0)}
#: The load stage (:mod:`.load_stage`, opt-in): how much better it must validate than the massless
#: winner to replace it (three parameters more), and the massless winner's validation NRMSE over the
#: record's floor above which it runs (at its floor no load validates that much better).
LOAD_MARGIN = 0.02
LOAD_FIT_TO_FLOOR = 1.1
#: Below :data:`LOAD_FIT_TO_FLOOR`, ``identify``'s fit (``load=None``) fits the light loads of
#: :func:`~servoid.ident.offline.load_stage.floor_rivals` as the play's rivals (False: nothing there). A fit at
#: its floor can hold a wrong play: the ODrive twin with a tenth of its load (inertia ratio 0.28) at 0.98 times
#: the floor with the play 25-32 % small and intervals ending at 0.87-0.97 of the truth (README, issue 12).
LOAD_FLOOR_RIVALS = True
#: A kept load's inertia ratio within this factor of :data:`MU_LIMITS` is on its limit (:func:`_load_noticed`).
LOAD_LIMIT_NEAR = 1.1
#: Search the two places of the play at once on the thread pool (:mod:`._threads`; the same answer to the bit).
PLACES_AT_ONCE = True
#: The first stage of each candidate's fit: the loop's rates, the friction level and the play.
_STAGE = ("kp", "kv", "fc", "play")
STAGE_NFEV = 15
#: scipy's ``ftol`` of :func:`fit_loop`'s massless fits (its stages, candidates and final refit): a step
#: that lowers the cost by less than this share (and that the linear model predicted) ends the fit.
#: scipy's 1e-8 ran most fits to their budget for the last 1e-5 of the cost, which moved the play by
#: under 0.5 %, far inside its interval (``benchmarks/loop_speed.py``). 1e-4 saved more but ended a
#: candidate of the live XM430 twin's first window early, in a minimum that fit 0.197 instead of 0.155.
FTOL = 1e-5
#: The candidates' searches (not the final refit, whose Jacobian the interval reads) also end at the
#: first accepted step that lowers the cost by less than this share: scipy's ``ftol`` waits for a step
#: whose reduction the linear model also predicted, and on this rough cost the play-in-loop
#: candidates crept on for ten more Jacobians at 1e-5 of the cost each.
STALL = 1e-4
#: Samples of the record's start that :func:`fit_loop` searches on (its scan, candidates and load stage;
#: 0: all): a longer record only adds its tail to the final refit, whose search starts at the winner.
SEARCH_SAMPLES = 6000
#: A window whose start holds this many reversals of the set point (by more than the play grid's low end) is cut
#: there, not below :data:`MIN_WINDOW` samples (0: always :data:`SEARCH_SAMPLES`): what the search reads of the play
#: is its reversals, not its samples. The CiA 402 twin's 6000-sample windows held 34-39 reversals at 50x, whose
#: answers the window kept, and 88-92 at 20x, which now search on about 3800 samples. 40 (3000 samples at 20x)
#: sent the 20 000-sample record's window winner to a search on all (:data:`TAIL_TO_VALIDATION`): 1911 simulations.
WINDOW_REVERSALS = 60
MIN_WINDOW = 3000
#: The window's winner may predict the samples after the window up to this factor worse (RMSE) than it
#: validated inside it; beyond, the search runs again on every sample (:func:`_holds_on_tail`). On the
#: twins the winners that held were within 1.03; the STS3215 at 50x, seed 2, whose window led to a
#: play +48 % instead of -16 %, predicted its tail 1.18 times worse.
TAIL_TO_VALIDATION = 1.1
#: The Stribeck hump a winner without one is refitted from (:func:`_final_fit`), as a ratio to its Coulomb
#: level: a start, not a value (drives break away at 1.2-1.5 times their running friction; the fit moves it).
HUMP_RESTART = 1.3
#: ... and its Stribeck speed at least this share of the record's typical speed (a hump narrower than
#: the speeds the record passes through has no slope to grow from).
HUMP_VS = 0.3
#: The final refit also ends at an accepted step that lowers the cost by less than this share (as the searches
#: do, :data:`STALL`; 0: at scipy's ``ftol`` only, the path before), then takes one Jacobian at its answer
#: for the interval.
FINAL_STALL = STALL
#: Two starts of the final refit whose costs on a search window differ by less than this many of the window's
#: residual variances tie there (the 95 % likelihood-ratio bound of one parameter, chi-square 3.84): both are
#: refitted on all samples and the lower cost kept. On the CiA 402 twin at 50x (seed 2) the window's costs
#: differed by 0.6 variances, and the start it kept ended on all samples at +14.5 % of play against +10.6 %
#: from the other, whose cost on all was lower.
WINDOW_TIE = 3.84
#: Where the search ran on a window, each final refit first runs on the scored samples up to this many times the
#: window's reach (0: none; not when that reaches the record's end): the steps from the window's winner towards the
#: record's minimum are taken there, at a fraction of a simulation on all, and the refit on all ends its path. On the
#: CiA 402 twin at 20x (12 000 and 20 000 samples, seeds 1-3) the window's winner took 40-64 simulations on all;
#: with the bridge the loop fit's simulated samples fell by 13 % (with the reversals' window, 34 % against 6000;
#: its CPU time by about 10 %, the shorter window's fits landing on faster loops with more sub-steps).
BRIDGE = 2
#: Where the search ran on the record's first window, the winner's place is searched on the last window of the same
#: length too, and that window's winner (when it has the first's integrator, and no load stage answers) starts the
#: final refit instead where it costs less on every sample (one simulation each): two looks at the record whose
#: minima differ (the CiA 402 twin's sines at 20x and 50x, seeds 1-5: see README, "LAST_WINDOW").
LAST_WINDOW = True
#: A candidate whose play ends below the scan grid's lowest play (about half the record's quantum: a play the record
#: does not resolve) while the other candidate of its place found one is fitted again from that one's fit, and the
#: lower estimation cost kept (:func:`_search`; False: never). On the XM430 twin at 10x (seed 2) the play-in-loop
#: candidate with an integrator collapsed to no play (estimation 1.37 times the floor), where the profile over the
#: play with every other parameter refitted had its minimum at 0.85 times the truth (1.04 times the floor).
COLLAPSE_RESTART = True
#: The best-validating candidate of the place behind, without a Stribeck hump (``fs <= fc``), is fitted again from
#: humps of these Stribeck speeds (shares of the record's typical speed; ``fs`` at :data:`HUMP_RESTART` times ``fc``),
#: the lowest estimation cost kept; when that puts its place ahead, the other place's best gets the same look
#: (:func:`_search`; empty: never). The searches lose the hump (:func:`_final_fit`), which the final refit gives back
#: to the winner only, so a place without one lost to a place with one by what the hump explains, not by the place.
#: The XM430 twin (play in the loop, break-away 1.5 times its Coulomb level), the fast part of a live record through
#: the ODrive emulator: the play in the loop without a hump validated 0.01228 (-4.0 %) against the play outside the
#: loop with one, 0.01205 (+202 %); from a hump of 0.03 the typical speed 0.01145 (-3.3 %), from 0.3 (``HUMP_VS``)
#: 0.01267 (the hump died again): a narrow start and a wide one. The monitor's 20 s reference records of the same
#: twin (seeds 1, 3): outside +118 / +210 % -> in the loop +17 / -32 %.
HUMP_CANDIDATES = (0.03, HUMP_VS)
#: The best-validating candidate's loop (the first stage's ``kp, kv, fc``) is refitted with its play held at these
#: multiples of its own; where the cheaper of these fits, with fewer parameters free, costs less on the estimation
#: blocks than the candidate did, the candidate stopped short of its minimum (the cost is rough at this scale), and a
#: full fit from that fit replaces it when it lowers the estimation cost (:func:`_search`; empty: never). A profile's
#: two neighbours, not a value: the STS3215 twin with its gear damped x10 at 50x (seed 3) stopped at +25 % of play
#: (estimation 1.11 times the floor) where the play held at the truth refits to 1.06 times; identify +23.3 % with an
#: interval excluding the truth, identifiable -> +2.0 %. Every parameter free in the held fits did the same there and
#: cost 310-410 simulations more on the CiA 402 twin, where it never fires (this: 60-110).
PROFILE_RESTART: tuple[float, ...] = (0.8, 1.25)
#: ... again while that replaces the best candidate, this many times at most (the best may change place between rounds;
#: one round left the x10 damped STS3215 at 50x, seed 5, at +32 % and 1.19 times the floor, three at +8 %).
PROFILE_ROUNDS = 3
#: Free parameters of every candidate; see :func:`_free` for what each structure adds.
_FREE = ("kp", "kv", "fc", "fs", "vs", "veps", "play")


def _free(structure: str, integrator: bool) -> tuple[str, ...]:
    """The free parameters of a candidate: only what the record can determine.

    The play's asymmetry ``c1 - c2`` only shifts the motor side when the loop reads the load
    (play in the loop), so it is fitted for the output backlash only; an integrator holds any
    constant force, so ``a0`` is fitted without one and ``ki`` with one.
    """
    extra = ("asym",) if structure == OUTPUT_BACKLASH else ()
    return _FREE + extra + (("ki",) if integrator else ("a0",))


@dataclass(frozen=True)
class LoopCandidate:
    """One fitted candidate of :func:`fit_loop`.

    Attributes
    ----------
    structure : str
        Where the play sits (a name of ``STRUCTURES``).
    integrator : bool
        Whether the velocity loop has an integrator (``ki`` fitted).
    model : ServoLoopModel
        The fitted model (estimation blocks only).
    estimation_nrmse, validation_nrmse : float
        Free-run NRMSE on the estimation and on the validation blocks.
    evaluations : int
        Simulations the fit used (its Jacobians included).
    """

    structure: str
    integrator: bool
    model: ServoLoopModel
    estimation_nrmse: float
    validation_nrmse: float
    evaluations: int


@dataclass(frozen=True)
class LoopChoice:
    """Result of :func:`fit_loop`: the place of the play chosen by validation, the play and the fitted loop.

    Attributes
    ----------
    structure : str
        The chosen place of the play: ``output_backlash`` or ``play_in_loop``.
    play : float
        ``c1 + c2`` of the final fit, in the unit of ``y``.
    play_interval : tuple of float
        Its 95 % interval ``(lo, hi)``: the HAC (Newey-West) sandwich's (noise), widened to the
        plays of the candidates that validate within :data:`MIN_STRUCTURE_MARGIN` of the best
        (model error the record cannot resolve, :func:`_with_rivals`); ``(nan, nan)`` when the
        Jacobian does not determine the play.
    fit_nrmse : float
        Free-run NRMSE of the final fit on the whole record.
    validation_nrmse : dict
        Structure name -> the best validation-block NRMSE of that place of the play.
    margin : float
        ``validation_nrmse[other] / validation_nrmse[structure] - 1``: how much worse the other
        place of the play validates (under 0.05 the two are not told apart).
    params : dict
        The final model's parameters by name (:data:`~servoid.ident.models.servo_loop.PARAM_NAMES`),
        in the record's units.
    simulated : ndarray
        The final model's free-run output, in the record's coordinates.
    reasons : tuple of str
        What the fit noticed that weakens the answer beyond the numbers here that the
        "not identifiable" rules read (:func:`servoid.ident.offline.intervals.verdict`: the
        margin, the fit, the dead time, the stall band); empty when nothing did.
    dead_time_samples : float
        The play's dead time at a reversal, in samples, of the best play-in-loop candidate
        (the final model when it won): ``play / (kp median|u - y|) / T``. Under about one the
        record cannot show a play inside the loop, so neither place can be told (the study's Q3:
        at 5x-10x the XM430's bandwidth the output backlash won with a play 2-3 times too large).
    stall_band : float
        The friction stall band ``max(fs, fc) / (kv kp)``, unit of ``y``: the position error a P loop
        leaves standing against break-away friction (not smaller than the play: the two are confused).
    model : ServoLoopModel
        The final model (simulate it with ``y0 = y[0]`` to get ``simulated``).
    candidates : tuple of LoopCandidate
        Every candidate, best validation first.
    seconds : float
        Wall-clock time of the whole fit.
    evaluations : int
        Simulations used in all.
    load_validation : float
        The validation NRMSE of the load stage (:func:`~servoid.ident.offline.load_stage.load_stage`) when it ran, else NaN; the
        massless winner's is ``validation_nrmse[structure]`` unless the stage replaced it
        (``model.massive``).
    load_candidate : LoopCandidate or None
        The load stage's fit (estimation blocks), kept or not; None when it did not run.
    place_z : float
        The winner's validation errors against the best candidate's of the other place on the catch-ups
        after the reversals, one loop time constant ``1 / kp`` each (:func:`~servoid.ident.offline.place_test.reversal_z`;
        positive: the winner's place predicts them better, not by chance); NaN when it was not computed.
    """

    structure: str
    play: float
    play_interval: tuple[float, float]
    fit_nrmse: float
    validation_nrmse: dict[str, float]
    margin: float
    params: dict[str, float]
    simulated: np.ndarray = field(repr=False)
    reasons: tuple[str, ...]
    dead_time_samples: float
    stall_band: float
    model: ServoLoopModel
    candidates: tuple[LoopCandidate, ...] = field(repr=False)
    seconds: float
    evaluations: int
    load_validation: float = math.nan
    load_candidate: LoopCandidate | None = field(default=None, repr=False)
    place_z: float = math.nan

    @property
    def determined(self) -> bool:
        """Whether the two places of the play differ by at least :data:`MIN_STRUCTURE_MARGIN` in validation (the study's rule)."""
        return bool(self.margin >= MIN_STRUCTURE_MARGIN)

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready summary (no arrays; non-finite numbers are left to ``servoid.ident.serialise``)."""
        return {
            "structure": self.structure,
            "play": self.play,
            "play_interval": list(self.play_interval),
            "fit_nrmse": self.fit_nrmse,
            "validation_nrmse": dict(self.validation_nrmse),
            "margin": self.margin,
            "params": dict(self.params),
            "reasons": list(self.reasons),
            "dead_time_samples": self.dead_time_samples,
            "stall_band": self.stall_band,
            "seconds": self.seconds,
            "evaluations": self.evaluations,
            "place_z": self.place_z,
        }


def block_mask(n: int, blocks: int = BLOCKS) -> np.ndarray:
    """Interleaved estimation (True) and validation (False) samples: ``blocks`` equal blocks, the odd ones validate.

    Parameters
    ----------
    n : int
        Samples.
    blocks : int
        Blocks (even, so that the record ends on a validation block).

    Returns
    -------
    ndarray of bool
    """
    edges = np.linspace(0, n, blocks + 1).astype(int)
    keep = np.ones(n, dtype=bool)
    for i in range(1, blocks, 2):
        keep[edges[i] : edges[i + 1]] = False
    return keep


class _Stalled(Exception):
    """The search's last accepted iterate ``z`` lowered the cost by less than the problem's ``stall`` share."""

    def __init__(self, z: np.ndarray) -> None:
        super().__init__("stalled")
        self.z = z


class _Problem:
    """The residual ``y_hat - y`` on the scored samples over the scaled free parameters."""

    def __init__(
        self,
        u: np.ndarray,
        y: np.ndarray,
        period: float,
        structure: str,
        free: tuple[str, ...],
        start: dict[str, float],
        score: np.ndarray,
        a_scale: float,
    ) -> None:
        self.u = u
        self.y = y
        self.period = period
        self.structure = structure
        self.feedback_load = structure == PLAY_IN_LOOP
        self.free = free
        self.start = dict(start)
        self.score = score
        self.stop = int(np.flatnonzero(score)[-1]) + 1
        self.y_scored = y[: self.stop][score[: self.stop]]
        self.scored_at = np.flatnonzero(score[: self.stop])
        #: The residual of a simulation that ran away (:meth:`scored`).
        self.runaway = 10.0 * (float(np.ptp(y)) + 1.0)
        self.a_scale = a_scale
        self.m = substeps(period, start["kv"], start.get("tq", 0.0))
        self.buffer = np.empty(self.stop)
        self.evaluations = 0
        self._last: tuple[np.ndarray, np.ndarray] | None = None
        self._buffers: list[np.ndarray] = []  # one per Jacobian column: the columns run at once
        #: A share of the cost (:data:`STALL`): an iterate that lowers the cost by less ends the search
        #: (:class:`_Stalled`) before its Jacobian; 0: never (scipy's own tests only).
        self.stall = 0.0
        self._cost: float | None = None
        # the first Jacobian column simulated with the last trial point (its steps and vectors; :meth:`__call__`)
        self._ahead: tuple[np.ndarray, list[float], list[np.ndarray]] | None = None
        self._column: np.ndarray | None = None

    def values(self, z: np.ndarray) -> dict[str, float]:
        d = dict(self.start)
        for zi, name in zip(z, self.free, strict=True):
            if name in _LOG:
                d[name] = self.start[name] * math.exp(float(zi))
            elif name == "a0":
                d[name] = self.start[name] + self.a_scale * float(zi)
            else:
                d[name] = float(zi)
        return d

    def vector(self, z: np.ndarray) -> np.ndarray:
        d = self.values(z)
        d["c1"] = d["play"] * (0.5 + d["asym"])
        d["c2"] = d["play"] * (0.5 - d["asym"])
        return np.array([d.get(name, 0.0) for name in KERNEL_NAMES])

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        lo = [math.log(1e-6) if n in _LOG else _BOUNDED.get(n, (-np.inf, np.inf))[0] for n in self.free]
        hi = [math.log(1e6) if n in _LOG else _BOUNDED.get(n, (-np.inf, np.inf))[1] for n in self.free]
        for i, n in enumerate(self.free):
            if n in _LOG_LIMITS:
                lo[i], hi[i] = (math.log(limit / self.start[n]) for limit in _LOG_LIMITS[n])
        return np.array(lo), np.array(hi)

    def simulate(self, p: np.ndarray, buffer: np.ndarray | None = None) -> np.ndarray:
        out = self.buffer if buffer is None else buffer
        simulate_kernel(p, self.feedback_load, self.u, float(self.y[0]), self.period, self.m, out)
        return out

    def residual(self, z: np.ndarray, buffer: np.ndarray | None = None) -> np.ndarray:
        """The residual at ``z``, simulated into ``buffer`` (default: the problem's own)."""
        return self.scored(self.simulate(self.vector(z), buffer))

    def simulate_pair(self, p: np.ndarray, q: np.ndarray, buffers: tuple[np.ndarray, np.ndarray]) -> None:
        """:meth:`simulate` of two parameter vectors at once (:func:`simulate_pair_kernel`), into ``buffers``."""
        simulate_pair_kernel(p, q, self.feedback_load, self.u, float(self.y[0]), self.period, self.m, *buffers)

    def scored(self, y_hat: np.ndarray) -> np.ndarray:
        """The residual of the simulated output ``y_hat`` (:meth:`simulate`'s) on the scored samples.

        Raises :class:`._threads.Stopped` inside :func:`._threads.stopping` once its stop has come: every
        search, refit and interval evaluates its cost here, on whichever thread, and unwinds from here.
        """
        _threads.check()
        r: np.ndarray = y_hat[self.scored_at] - self.y_scored
        # a simulation that ran away (absurd parameters on the way) costs a constant, large penalty
        if not (np.all(np.isfinite(r)) and float(np.max(np.abs(r))) < 100.0 * self.runaway):
            r = np.full(r.size, self.runaway)
        return r

    def __call__(self, z: np.ndarray) -> np.ndarray:
        self.evaluations += 1
        z = np.asarray(z, dtype=np.float64)
        self._ahead = None
        if z.size % 2:
            # an odd count of columns leaves one alone in the Jacobian: it runs now, with the trial point in one
            # kernel (a pair costs 1.1 simulations' time), and the Jacobian there, if the trial is kept, reads it
            steps, moved = self._steps(z)
            if self._column is None:
                self._column = np.empty(self.stop)
            self.simulate_pair(self.vector(z), moved[0], (self.buffer, self._column))
            self._ahead = (z.copy(), steps, moved)
            r = self.scored(self.buffer)
        else:
            r = self.residual(z)
        self._last = (z.copy(), r.copy())
        return r

    def _steps(self, z: np.ndarray) -> tuple[list[float], list[np.ndarray]]:
        """The Jacobian's steps at ``z`` (forward; backward at an upper bound) and the parameter vectors they reach."""
        hi = self.bounds()[1]
        steps = [DIFF_STEP if z[i] + DIFF_STEP <= hi[i] else -DIFF_STEP for i in range(z.size)]
        moved = []
        for i in range(z.size):
            zi = z.copy()
            zi[i] += steps[i]
            moved.append(self.vector(zi))
        return steps, moved

    def jacobian(self, z: np.ndarray) -> np.ndarray:
        """Forward differences with the absolute step :data:`DIFF_STEP` in the scaled coordinates.

        scipy's relative ``diff_step`` shrinks with ``|z|``, and ``z`` starts at 0: its steps would
        be far below the sub-step roughness of the simulation, whose slope a 3 % step sees.
        The columns are independent simulations, each into its own buffer: they run at once, two
        by two in one kernel (:func:`simulate_pair_kernel`, which hides each one's latency behind
        the other's) and the pairs on the threads (:func:`._threads.each`; the kernel releases the
        GIL), and give the same numbers as one after the other. Of an odd count, the first column
        ran with the trial point at ``z`` (:meth:`__call__`), which scipy keeps three times in four.
        """
        z = np.asarray(z, dtype=np.float64)
        last = self._last
        r0 = last[1] if last is not None and np.array_equal(last[0], z) else self(z)
        cost = float(r0 @ r0)
        if self.stall > 0.0 and self._cost is not None and self._cost - cost < self.stall * self._cost:
            raise _Stalled(z.copy())
        self._cost = cost
        jac = np.empty((r0.size, z.size))
        if len(self._buffers) < z.size:
            self._buffers = [np.empty(self.stop) for _ in range(z.size)]
        ahead = self._ahead
        first = 0  # the columns from here on run now
        if ahead is not None and np.array_equal(ahead[0], z):
            _, steps, moved = ahead
            assert self._column is not None
            jac[:, 0] = (self.scored(self._column) - r0) / steps[0]
            first = 1
        else:
            steps, moved = self._steps(z)

        def columns(t: int) -> None:
            """Columns ``first + 2 t`` and the next (the last alone when the count left is odd)."""
            pair = range(first + 2 * t, min(first + 2 * t + 2, z.size))
            if len(pair) == 2:
                self.simulate_pair(moved[pair[0]], moved[pair[1]], (self._buffers[pair[0]], self._buffers[pair[1]]))
            else:
                self.simulate(moved[pair[0]], self._buffers[pair[0]])
            for i in pair:
                jac[:, i] = (self.scored(self._buffers[i]) - r0) / steps[i]

        self.evaluations += z.size  # here, not in the columns: ``+=`` from several threads could lose counts
        _threads.each(columns, (z.size - first + 1) // 2)
        return jac


def _linear_start(u: np.ndarray, y: np.ndarray, period: float) -> tuple[float, float]:
    """``(kp, kv)`` from the two poles of an ARX(2, 2) of ``y`` on ``u`` (step 2 of the module docstring)."""
    phi = np.column_stack([-y[1:-1], -y[:-2], u[1:-1], u[:-2], np.ones(y.size - 2)])
    theta, *_ = np.linalg.lstsq(phi, y[2:], rcond=None)
    poles = np.roots(np.r_[1.0, theta[:2]]).astype(complex)
    # an integrating or unstable fit: pull the pole inside; a pole at 0 has no continuous image
    poles = np.where(np.abs(poles) >= 0.999, 0.999 * poles / np.maximum(np.abs(poles), 1e-12), poles)
    poles = np.where(np.abs(poles) < 1e-3, 1e-3, poles)
    s = np.log(poles) / period
    kv = float(max(-np.sum(s).real, 0.05 / period))
    kp = float(max((s[0] * s[1]).real / kv, 0.02 * kv))
    if not (math.isfinite(kp) and math.isfinite(kv)):
        return 0.1 / period, 1.0 / period
    # a position loop is not faster than the velocity loop inside it
    return min(kp, kv), kv


def _ki_start(kp: float, kv: float) -> float:
    """Where a velocity integrator starts, from the loop's rates: a fifth of ``kp kv`` (its zero well below the loop's)."""
    return 0.2 * kp * kv


def _start(kp: float, kv: float, v_typ: float, play: float, *, integrator: bool, friction: float) -> dict[str, float]:
    return {
        "kp": kp,
        "kv": kv,
        "ki": _ki_start(kp, kv) if integrator else 0.0,
        "vmax": 0.0,
        "fc": 0.1 * kv * v_typ * friction,
        "fs": 0.15 * kv * v_typ * friction,
        "vs": 0.1 * v_typ,
        "veps": 0.01 * v_typ,
        "a0": 0.0,
        "play": play,
        "asym": 0.0,
        "s0": 0.5,
    }


def _scan(
    u: np.ndarray,
    y: np.ndarray,
    period: float,
    structure: str,
    kp: float,
    kv: float,
    v_typ: float,
    score: np.ndarray,
    plays: np.ndarray,
) -> tuple[dict[str, float], int]:
    """The best start of a grid of plays x friction levels, simulated (not fitted) on the estimation blocks.

    The starts share the loop's rates, so their simulations run two by two (:meth:`_Problem.simulate_pair`).
    """
    best: tuple[float, dict[str, float]] | None = None
    starts = [
        _start(kp, kv, v_typ, float(play), integrator=False, friction=friction)
        for play in plays
        for friction in (0.3, 1.0, 3.0)
    ]
    none = np.zeros(0)
    for at in range(0, len(starts), 2):
        probs = [_Problem(u, y, period, structure, (), start, score, 1.0) for start in starts[at : at + 2]]
        if len(probs) == 2 and probs[0].m == probs[1].m:
            buffers = (probs[0].buffer, probs[1].buffer)
            probs[0].simulate_pair(probs[0].vector(none), probs[1].vector(none), buffers)
            residuals = [prob.scored(buffer) for prob, buffer in zip(probs, buffers, strict=True)]
        else:
            residuals = [prob(none) for prob in probs]
        for start, r in zip(starts[at : at + 2], residuals, strict=True):
            cost = float(r @ r)
            if best is None or cost < best[0]:
                best = (cost, start)
    assert best is not None
    return best[1], len(starts)


def _fit(
    u: np.ndarray,
    y: np.ndarray,
    period: float,
    structure: str,
    start: dict[str, float],
    score: np.ndarray,
    a_scale: float,
    *,
    integrator: bool,
    max_nfev: int,
    free: tuple[str, ...] | None = None,
    ftol: float = 1e-8,
    stall: float = 0.0,
    closing: bool = False,
) -> tuple[dict[str, float], _Problem, Any]:
    """Least squares of one candidate from ``start``; returns the values, the problem and the solution (None: none).

    A search that stalls (``stall``) has no solution object; with ``closing`` (the final refit, whose
    Jacobian the interval reads) it gets one, with the Jacobian at the kept iterate: one more
    Jacobian, where scipy's own stop would have taken several.
    """
    if free is None:
        free = _free(structure, integrator)
    prob = _Problem(u, y, period, structure, free, start, score, a_scale)
    prob.stall = stall
    lo, hi = prob.bounds()
    z0 = np.array([start[n] if n in _BOUNDED else 0.0 for n in free])
    with single_threaded_blas():
        try:
            sol = least_squares(
                prob, z0, prob.jacobian, bounds=(lo, hi), method="trf", x_scale=1.0, max_nfev=max_nfev, ftol=ftol
            )
        except ValueError:  # the search met a non-finite Jacobian: keep the start, no interval
            return prob.values(z0), prob, None
        except _Stalled as stalled:  # the last step gained under ``stall``: keep it
            if not closing:  # a search: no solution object
                return prob.values(stalled.z), prob, None
            # the final refit: the Jacobian at the kept iterate (its residual is cached), which the interval reads
            prob.stall = 0.0
            jac = prob.jacobian(stalled.z)
            assert prob._last is not None
            fun = prob._last[1]
            return prob.values(stalled.z), prob, _Closed(stalled.z, jac, fun, 0.5 * float(fun @ fun))
    return prob.values(sol.x), prob, sol


@dataclass(frozen=True)
class _Closed:
    """What :func:`_fit` reads of scipy's solution, for a final refit that stalled (:data:`FINAL_STALL`)."""

    x: np.ndarray
    jac: np.ndarray
    fun: np.ndarray
    cost: float


def _search_lengths(u: np.ndarray, y: np.ndarray, kept: np.ndarray, h: float) -> tuple[int, ...]:
    """The lengths of the record's start that :func:`fit_loop` searches on, in turn: the window, then all.

    The window is :data:`SEARCH_SAMPLES`, cut to the start that holds :data:`WINDOW_REVERSALS` reversals of the set
    point by more than ``h`` (:func:`_reversals_end`), not below :data:`MIN_WINDOW`. All only, when the record is
    shorter than twice :data:`SEARCH_SAMPLES` or when the window's estimation or validation blocks do not move (a
    record that starts at rest); raises when the whole record's do not.
    """
    n = int(y.size)
    # a window of more than half the record saves little, and a second search on all would cost more than it saved
    w = SEARCH_SAMPLES
    if WINDOW_REVERSALS and 0 < 2 * SEARCH_SAMPLES <= n:
        w = min(w, max(MIN_WINDOW, _reversals_end(u[:w], h, WINDOW_REVERSALS)))
    window = (w,) if 0 < 2 * SEARCH_SAMPLES <= n and int(np.sum(kept[:w])) >= MIN_SAMPLES else ()
    lengths = tuple(w for w in (*window, n) if _moves(y[:w], kept[:w]) is None)
    if lengths and lengths[-1] == n:
        return lengths
    raise ModelError(
        f"the output never moves in the {_moves(y, kept)} blocks ({int(np.unique(y[kept]).size)} distinct readings "
        "in all): the servo-loop model cannot be fitted and validated on this record"
    )


def _reversals_end(u: np.ndarray, h: float, count: int) -> int:
    """The samples of ``u``'s start that hold ``count`` reversals by more than ``h`` (``u.size`` when it holds fewer).

    The reversals are :func:`~servoid.ident.offline.intervals.reversal_indices`' (a hysteresis, as a play would see it).
    """
    turns = reversal_indices(u, h)
    return int(turns[count - 1]) + 1 if turns.size >= count else int(u.size)


def _moves(y: np.ndarray, kept: np.ndarray) -> str | None:
    """The name of the first of the record's estimation and validation blocks whose output never moves, or None."""
    mask = block_mask(y.size)
    for part, name in ((mask & kept, "estimation"), (~mask & kept, "validation")):
        if not np.any(part) or float(np.ptp(y[part])) <= 0.0:
            return name
    return None


def _holds_on_tail(
    model: ServoLoopModel, u: np.ndarray, y: np.ndarray, kept: np.ndarray, w: int, val: np.ndarray
) -> bool:
    """Whether the window's winner holds the window at its floor and predicts the rest about as well.

    The samples after the first ``w`` are data the search never saw: the winner's free-run RMSE there
    over its RMSE on the window's validation blocks (RMSE, not NRMSE: the floor of quantisation and
    noise is absolute) at most :data:`TAIL_TO_VALIDATION`. More says that the window led the search to
    a minimum the rest of the record does not hold; the search then runs again on all samples.
    A winner off the window's floor (more than :data:`MAX_FIT_TO_FLOOR` times it, the rule by which a
    model holds) misses an effect, and a search on all samples can land elsewhere however evenly it
    misses: a live CiA 402 twin record (12 000 samples at 200 Hz) gave the play in the loop at -51 %,
    3.6 times the window's floor, where the search on all gave the play outside it at -16 % with a
    validation NRMSE 0.0074 against 0.0125 (the load stage, the ratio's test passed).
    """
    y_hat = model.simulate(u, y0=float(y[0]))
    tail = np.zeros(y.size, dtype=bool)
    tail[w:] = kept[w:]
    inside = np.zeros(y.size, dtype=bool)
    inside[:w] = val
    rmse_val = float(np.sqrt(np.mean((y_hat[inside] - y[inside]) ** 2)))
    rmse_tail = float(np.sqrt(np.mean((y_hat[tail] - y[tail]) ** 2)))
    # a winner at the record's floor holds wherever it stays there (ratios of rounding errors say nothing)
    floor = floor_nrmse(y, kept) * float(np.std(y[kept]))
    window_floor = floor_nrmse(y[:w], kept[:w]) * float(np.std(y[:w][kept[:w]]))
    at_floor = not math.isfinite(window_floor) or rmse_val <= MAX_FIT_TO_FLOOR * window_floor
    return (
        at_floor
        and bool(np.any(tail))
        and rmse_tail <= TAIL_TO_VALIDATION * max(rmse_val, floor if math.isfinite(floor) else 0.0)
    )


def _search(
    us: np.ndarray,
    ys: np.ndarray,
    ks: np.ndarray,
    period: float,
    starts: tuple[float, float, float, float],
    grid: np.ndarray,
    places: tuple[str, ...] = (OUTPUT_BACKLASH, PLAY_IN_LOOP),
) -> tuple[list[tuple[LoopCandidate, dict[str, float]]], int, np.ndarray, np.ndarray]:
    """Steps 3-4 of the module docstring on ``us, ys`` (kept ``ks``): the candidates, best validation first.

    ``starts`` is ``(kp, kv, v_typ, a_scale)`` of the linear start; ``places``: the places of the play searched. Returns the candidates with their
    parameters, the simulations spent, and the estimation and validation masks of these samples.
    """
    kp, kv, v_typ, a_scale = starts
    collapsed = float(np.min(grid))
    est = block_mask(us.size) & ks
    val = ~block_mask(us.size) & ks
    found: list[list[tuple[LoopCandidate, dict[str, float]]]] = [[] for _ in places]
    spent = [0 for _ in places]

    def candidate(
        structure: str, integrator: bool, start: dict[str, float], *, stage: bool = True
    ) -> tuple[LoopCandidate, dict[str, float], int]:
        """One candidate fitted from ``start`` and the simulations of its two fits: the loop's rates and the play first
        (the linear start's rates are biased by the play; ``stage=False``: a fitted start's ``ki`` kept, no stage),
        then everything."""
        s = dict(start)
        staged = 0
        if stage:
            s["ki"] = _ki_start(s["kp"], s["kv"]) if integrator else 0.0
            s, first, _ = _fit(
                us, ys, period, structure, s, est, a_scale, integrator=integrator, max_nfev=STAGE_NFEV, free=_STAGE,
                ftol=FTOL, stall=STALL,
            )  # fmt: skip
            staged = first.evaluations
        d, prob, _ = _fit(
            us, ys, period, structure, s, est, a_scale, integrator=integrator, max_nfev=CANDIDATE_NFEV,
            ftol=FTOL, stall=STALL,
        )  # fmt: skip
        model = _model(structure, period, d)
        y_hat = model.simulate(us, y0=float(ys[0]))
        cand = LoopCandidate(
            structure=structure,
            integrator=integrator,
            model=model,
            estimation_nrmse=free_run_nrmse(ys[est], y_hat[est]),
            validation_nrmse=free_run_nrmse(ys[val], y_hat[val]),
            evaluations=prob.evaluations,
        )
        return cand, d, staged + prob.evaluations

    def place(i: int) -> None:
        """Scan and fit the two candidates of one place of the play into ``found[i]``, ``spent[i]``."""
        structure = places[i]
        start, spent[i] = _scan(us, ys, period, structure, kp, kv, v_typ, est, grid)
        for integrator in (False, True):
            cand, d, used = candidate(structure, integrator, start)
            found[i].append((cand, d))
            spent[i] += used
        if COLLAPSE_RESTART:
            resolved = [d["play"] >= collapsed for _, d in found[i]]
            for k in range(len(found[i])):
                if resolved[k] or not resolved[1 - k]:
                    continue
                # a play below what the record resolves where the sibling found one: a second look from the sibling's
                # fit (its loop and play), the lower estimation cost kept
                cand, d, used = candidate(structure, found[i][k][0].integrator, found[i][1 - k][1])
                spent[i] += used
                if cand.estimation_nrmse < found[i][k][0].estimation_nrmse:
                    found[i][k] = (cand, d)

    def humped(i: int) -> None:
        """The best candidate of place ``i``, without a hump, fitted again from humps (:data:`HUMP_CANDIDATES`)."""
        k = min(range(len(found[i])), key=lambda j: found[i][j][0].validation_nrmse)
        d = found[i][k][1]
        if not (d["fc"] > 0.0 and d["fs"] <= d["fc"]):
            return
        # a full fit from each width (the stage's rates and play are the candidate's already), the lowest
        # estimation cost kept
        for share in HUMP_CANDIDATES:
            start = dict(d, fs=HUMP_RESTART * d["fc"], vs=max(d["vs"], share * v_typ))
            cand, fitted, used = candidate(places[i], found[i][k][0].integrator, start, stage=False)
            spent[i] += used
            if cand.estimation_nrmse < found[i][k][0].estimation_nrmse:
                found[i][k] = (cand, fitted)

    def profiled(i: int) -> bool:
        """The best candidate of place ``i`` fitted again from its play held at :data:`PROFILE_RESTART` times its own;
        whether that replaced it."""
        k = min(range(len(found[i])), key=lambda j: found[i][j][0].validation_nrmse)
        cand, d = found[i][k]
        held = tuple(n for n in _STAGE if n != "play")
        best: tuple[float, dict[str, float]] | None = None
        for factor in PROFILE_RESTART:
            fitted, prob, _ = _fit(
                us, ys, period, places[i], dict(d, play=factor * d["play"]), est, a_scale,
                integrator=cand.integrator, max_nfev=STAGE_NFEV, free=held, ftol=FTOL, stall=STALL,
            )  # fmt: skip
            spent[i] += prob.evaluations
            cost = _cost(us, ys, period, places[i], fitted, est)
            spent[i] += 1
            if best is None or cost < best[0]:
                best = (cost, fitted)
        assert best is not None
        if best[0] >= _cost(us, ys, period, places[i], d, est):
            return False  # the candidate is at least as good as its profile's neighbours: at its minimum
        again, fitted, used = candidate(places[i], cand.integrator, best[1], stage=False)
        spent[i] += used + 1
        if again.estimation_nrmse >= cand.estimation_nrmse:
            return False
        found[i][k] = (again, fitted)
        return True

    # the two places are independent searches: on the pool at once (each one's Jacobians share it), which
    # also runs their scans and single evaluations side by side; BLAS is limited here, once, because the
    # two searches' own limits would otherwise restore each other's on their way out
    with single_threaded_blas():
        if PLACES_AT_ONCE:
            _threads.each(place, len(places))
        else:
            for i in range(len(places)):
                place(i)
        # the place behind gets the hump the final refit gives the winner; when that puts it ahead, the other too
        looked: set[int] = set()
        while HUMP_CANDIDATES and len(places) > 1:
            behind = max(range(len(places)), key=lambda i: min(c.validation_nrmse for c, _ in found[i]))
            if behind in looked:
                break
            looked.add(behind)
            humped(behind)
        for _ in range(PROFILE_ROUNDS if PROFILE_RESTART else 0):
            ahead = min(range(len(places)), key=lambda i: min(c.validation_nrmse for c, _ in found[i]))
            if not profiled(ahead):
                break
    candidates = [c for f in found for c in f]
    candidates.sort(key=lambda c: c[0].validation_nrmse)
    return candidates, sum(spent), est, val


def _model(structure: str, period: float, d: dict[str, float]) -> ServoLoopModel:
    p = dict(d)
    p["c1"] = p["play"] * (0.5 + p["asym"])
    p["c2"] = p["play"] * (0.5 - p["asym"])
    return ServoLoopModel(
        structure=structure, sample_period_s=period, **{n: float(p.get(n, 0.0)) for n in KERNEL_NAMES}
    )


def fit_loop(
    u: Any,
    y: Any,
    sample_period_s: float,
    *,
    seed: int = 0,
    keep: Any = None,
    load: bool | None = False,
    light_rivals: bool = True,
) -> LoopChoice:
    """Fit the servo-loop model with the play outside and inside the loop; choose by validation.

    Parameters
    ----------
    u : array_like
        Set points sent at the host instants, in the unit of ``y`` (the loop compares them).
    y : array_like
        The readings at the host instants (before each command is applied).
    sample_period_s : float
        The host period, s.
    seed : int
        Seeds the jitter of the play grid scanned for starts (each grid value moves within its
        own geometric cell), so that a second seed is a second look from other starts.
    keep : array_like of bool, optional
        ``False`` marks readings that were lost or late (a live session's validity mask); their
        ``y`` may be NaN. The simulation runs through every sample (the set point is known
        there); the fit, the validation, the NRMSE and the interval score kept samples only.
        The starts read ``y`` linearly interpolated across the gaps. Default: all kept.
    load : bool or None
        The load stage (:func:`~servoid.ident.offline.load_stage.load_stage`: a heavy load meeting
        the flanks in impacts): False (default) never; None on the best candidate with the play
        outside the loop (the motor-side structure) when it validates above :data:`LOAD_FIT_TO_FLOOR`
        times the record's floor (``identify``'s choice; below it, light loads fitted as the play's rivals
        only, :data:`LOAD_FLOOR_RIVALS`); True always, on the massless winner's structure.
        Either starts from that structure's candidate with an integrator. It replaces the massless winner only when it validates :data:`LOAD_MARGIN` better; a kept load whose inertia ratio
        ends on its limit is named in the reasons (not identifiable).
    light_rivals : bool
        Where ``load`` is None and the stage does not run, fit the light loads of
        :data:`LOAD_FLOOR_RIVALS` (they only widen the interval; False: the online windows, which
        report no interval, save their simulations).

    Returns
    -------
    LoopChoice
        The chosen place of the play, the play with its interval, the validation NRMSE of both
        places and the margin between them, the final model and what the fit noticed.

    Raises
    ------
    ConfigError
        Non-finite or mismatched signals, fewer than :data:`MIN_SAMPLES` samples (kept ones), a
        constant output, or a non-positive period.
    ModelError
        The output moves, but not in the estimation or the validation blocks (a heavy load the
        set point barely stirs): there is nothing to fit or to validate on.
    """
    t0 = time.perf_counter()
    u_arr, y_arr, kept, period = _checked(u, y, sample_period_s, keep)
    seed = validation.integer("seed", seed, minimum=0)
    if float(np.ptp(y_arr[kept])) <= 0.0:
        raise ConfigError("y is constant: the servo never moved, there is no loop to fit")
    # the operating point: one constant off both (they share a unit); the model sees differences only
    centre = float(np.mean(u_arr))
    uc = np.ascontiguousarray(u_arr - centre)
    yc = np.ascontiguousarray(y_arr - centre)

    kp, kv = _linear_start(uc, yc, period)
    v_typ = max(float(np.std(np.diff(yc))) / period, 1e-12 * float(np.ptp(yc)) / period)
    a_scale = 0.1 * kv * v_typ
    q = quantum(yc[kept])
    low = q / 2 if q > 0.0 else 1e-3 * float(np.std(yc))
    high = max(float(np.ptp(yc)) / 4, 2 * low)
    grid = np.geomspace(low, high, 10)
    rng = np.random.default_rng(seed)
    if seed:
        cell = (high / low) ** (1 / 9)
        grid = grid * cell ** rng.uniform(-0.5, 0.5, grid.size)

    # the search (scan, candidates, load stage) runs on the record's first ``w`` samples, and on all of them when
    # its winner predicts the rest of the record worse than it validated; the final refit runs on all
    evaluations = 0
    for w in _search_lengths(uc, yc, kept, low):
        candidates, spent, est, val = _search(uc[:w], yc[:w], kept[:w], period, (kp, kv, v_typ, a_scale), grid)
        evaluations += spent
        if w == yc.size or _holds_on_tail(candidates[0][0].model, uc, yc, kept, w, val):
            break
    us, ys, ks = uc[:w], yc[:w], kept[:w]
    best, best_d = candidates[0]
    per_structure = {
        s: min(c.validation_nrmse for c, _ in candidates if c.structure == s) for s in (OUTPUT_BACKLASH, PLAY_IN_LOOP)
    }
    margin = place_margin(per_structure, best.structure)

    load_val = math.nan
    heavy = None
    rivals: list[tuple[float, float]] = []
    # by default the stage extends the best motor-side candidate (a heavy load behind a play outside the
    # loop: where it coasts, the massless play in the loop can win by a hair), when that is off its floor
    base, base_d = (best, best_d) if load else next((c, d) for c, d in candidates if c.structure == OUTPUT_BACKLASH)
    off_floor = load or (load is None and base.validation_nrmse > LOAD_FIT_TO_FLOOR * floor_nrmse(ys, ks))
    if off_floor or (load is None and light_rivals and LOAD_FLOOR_RIVALS):
        base, base_d = _stage_start(candidates, base.structure)
        problem = _stage_problem(us, ys, period, base, base_d, est, a_scale)
    if off_floor:
        keep = (1.0 - LOAD_MARGIN) * best.validation_nrmse
        heavy, heavy_d, used, tried = _run_load_stage(ys, period, base, problem, est, val, keep)
        evaluations += used
        load_val = heavy.validation_nrmse
        if load_val < keep:
            rivals = tried
            best, best_d = heavy, heavy_d
            candidates.insert(0, (heavy, heavy_d))
            per_structure[best.structure] = load_val
            margin = place_margin(per_structure, best.structure)
    elif load is None and light_rivals and LOAD_FLOOR_RIVALS:
        # at its floor the massless fit may hide a bouncing load behind less play: such loads are the play's rivals
        fit, simulate, start = problem
        rivals, used = floor_rivals(ys, start, fit, simulate, est, val)
        evaluations += used

    # how surely the record prefers the winner's place: its validation errors against the other place's best
    rival = min((c for c, _ in candidates if c.structure != best.structure), key=lambda c: c.validation_nrmse)
    y_best, y_rival = (m.simulate(us, y0=float(ys[0])) for m in (best.model, rival.model))
    # on the catch-ups after the reversals, one loop time constant (1 / kp) each: where the places differ
    span = math.ceil(1.0 / (best.model.kp * period)) if best.model.kp > 0.0 else 0
    z = reversal_z(y_best - ys, y_rival - ys, catch_up_groups(y_best, best.model.play, span, val))
    evaluations += 2

    # the final refit of the winner on every sample
    free = _free(best.structure, best.integrator) + (LOAD_NAMES if best.model.massive else ())
    search = None
    start = best_d
    if w < yc.size:
        search = np.zeros(yc.size, dtype=bool)
        search[:w] = est
        if LAST_WINDOW and not best.model.massive:
            other, used = _last_window(uc, yc, kept, period, w, (kp, kv, v_typ, a_scale), grid, best)
            evaluations += used
            if other is not None:
                evaluations += 1  # the winner's cost on every sample, against the last window's
                if other[2] < _cost(uc, yc, period, best.structure, best_d, kept):
                    start, search = other[0], other[1]
    d, prob, sol, used = _final_fit(
        uc, yc, period, best.structure, best.integrator, start, kept, a_scale, free, v_typ, search
    )  # fmt: skip
    evaluations += used
    final = _model(best.structure, period, d)
    # the dead time is the play-in-loop candidate's: it says whether that place could be seen at all
    inside = (
        final if best.structure == PLAY_IN_LOOP else next(c.model for c, _ in candidates if c.structure == PLAY_IN_LOOP)
    )
    simulated = final.simulate(uc, y0=float(yc[0]))
    fit_nrmse = nrmse(yc[kept], simulated[kept])
    interval = (
        (math.nan, math.nan) if sol is None else _play_interval(*_spaced(sol.jac, sol.fun, kept), prob.free, d["play"])
    )
    interval = _with_rivals(interval, [c for c, _ in candidates], best.validation_nrmse)
    # a kept load stage: the grid's points too (a light coasting load and a heavy one can fit alike)
    interval = widened_to_rivals(interval, rivals, best.validation_nrmse)
    reasons = _noticed(final, q) + _load_noticed(final)
    return LoopChoice(
        structure=best.structure,
        play=final.play,
        play_interval=interval,
        fit_nrmse=fit_nrmse,
        validation_nrmse=per_structure,
        margin=float(margin),
        params=final.params(),
        simulated=simulated + centre,
        reasons=reasons,
        dead_time_samples=_dead_time_samples(inside, uc[kept], yc[kept]),
        # the model's break-away is the larger of the two: with fs < fc it has no Stribeck hump (servo_loop._friction)
        stall_band=stall_band(max(final.fs, final.fc), final.kv, final.kp),
        model=final,
        candidates=tuple(c for c, _ in candidates),
        seconds=time.perf_counter() - t0,
        evaluations=evaluations,
        load_validation=load_val,
        load_candidate=heavy,
        place_z=z,
    )


def place_margin(per_structure: dict[str, float], structure: str) -> float:
    """How much worse the other place of the play validates than ``structure``'s (the structure rule's number).

    Parameters
    ----------
    per_structure : dict of str to float
        The best validation NRMSE of each place of the play.
    structure : str
        The answer's place of the play.

    Returns
    -------
    float
        The other place's validation NRMSE over the answer's, minus 1 (infinite where the answer's is zero).
    """
    other = PLAY_IN_LOOP if structure == OUTPUT_BACKLASH else OUTPUT_BACKLASH
    v = per_structure[structure]
    return per_structure[other] / v - 1.0 if v > 0.0 else math.inf


def _final_fit(
    u: np.ndarray,
    y: np.ndarray,
    period: float,
    structure: str,
    integrator: bool,
    start: dict[str, float],
    score: np.ndarray,
    a_scale: float,
    free: tuple[str, ...],
    v_typ: float,
    search: np.ndarray | None = None,
) -> tuple[dict[str, float], _Problem, Any, int]:
    """The winner's final refit on ``score``; a winner without a Stribeck hump is refitted from one too.

    The searches lose the hump: where ``fc`` passes ``fs`` the model has none
    (:func:`~servoid.ident.models.servo_loop._friction`), the cost's slope in ``fs`` is zero and
    ``fs`` never comes back. A drive that breaks away above its Coulomb level then stalls after each
    reversal in a way the model can only book as play: the CiA 402 twin (break-away 1.3 times its
    Coulomb level, Stribeck speed 0.1 rad/s at the output) fitted ``fs`` = 0.03 ``fc`` and +13.6 %
    of play at 20x (2**16-count encoder); refitted from ``fs`` = 1.3 ``fc`` it fits 22 % better with
    +3.5 %, ``fs`` 1.32 ``fc`` and ``vs`` 0.11 rad/s. The hump's start is :data:`HUMP_RESTART`.

    A search on a window (``search``: the window's estimation blocks, on which the winner was fitted) restarts
    there: the humped fit replaces the winner as the final refit's start when it costs less on the window, and
    the final refit runs once on ``score``; when the two costs tie on the window (:data:`WINDOW_TIE`), both
    are refitted on ``score``. Without one, both starts are refitted on ``score`` and the lower cost
    kept. Each final refit ends as the searches do (:data:`FINAL_STALL`), with the Jacobian at its answer for
    the interval. Returns the values, the problem and the solution of the kept refit, and the simulations of all.
    """

    between = None
    if search is not None and BRIDGE:
        # the bridge: the scored samples up to BRIDGE times the window's reach, when that is short of the record's
        reach = BRIDGE * (int(np.flatnonzero(search)[-1]) + 1)
        if reach < int(np.flatnonzero(score)[-1]) + 1:
            between = score & (np.arange(score.size) < reach)

    def final(s: dict[str, float]) -> tuple[dict[str, float], _Problem, Any, int]:
        used = 0
        if between is not None:
            s, bridge, _ = _fit(
                u, y, period, structure, s, between, a_scale, integrator=integrator, max_nfev=FINAL_NFEV, free=free,
                ftol=FTOL, stall=FINAL_STALL,
            )  # fmt: skip
            used = bridge.evaluations
        d, prob, sol = _fit(
            u, y, period, structure, s, score, a_scale, integrator=integrator, max_nfev=FINAL_NFEV, free=free,
            ftol=FTOL, stall=FINAL_STALL, closing=True,
        )  # fmt: skip
        return d, prob, sol, used + prob.evaluations

    if not ("fs" in free and start["fc"] > 0.0 and start["fs"] <= start["fc"]):
        return final(start)
    humped = dict(start, fs=HUMP_RESTART * start["fc"], vs=max(start["vs"], HUMP_VS * v_typ))

    def lower(*starts: dict[str, float]) -> tuple[dict[str, float], _Problem, Any, int]:
        # each start refitted on all, the lower cost kept
        kept: list[Any] | None = None
        used = 0
        for s in starts:
            *one, spent = final(s)
            used += spent
            if kept is None or (one[2] is not None and (kept[2] is None or one[2].cost < kept[2].cost)):
                kept = one
        assert kept is not None
        return (*kept, used)

    if search is None:
        return lower(start, humped)
    # a window's search: restart the search there (cheap), then one refit on all unless the window ties
    fitted, prob, _ = _fit(
        u, y, period, structure, humped, search, a_scale, integrator=integrator, max_nfev=CANDIDATE_NFEV, free=free,
        ftol=FTOL, stall=STALL,
    )  # fmt: skip
    used = prob.evaluations + 2
    humped_cost, start_cost = (
        _cost(u, y, period, structure, fitted, search),
        _cost(u, y, period, structure, start, search),
    )
    tie = WINDOW_TIE * min(humped_cost, start_cost) / np.count_nonzero(search)  # in the window's residual variances
    starts = (
        (start, fitted) if abs(humped_cost - start_cost) <= tie else (fitted if humped_cost < start_cost else start,)
    )
    d, prob, sol, more = lower(*starts)
    return d, prob, sol, used + more


def _last_window(
    u: np.ndarray,
    y: np.ndarray,
    kept: np.ndarray,
    period: float,
    w: int,
    starts: tuple[float, float, float, float],
    grid: np.ndarray,
    best: LoopCandidate,
) -> tuple[tuple[dict[str, float], np.ndarray, float] | None, int]:
    """The search of ``best``'s place on the record's last ``w`` samples (:data:`LAST_WINDOW`).

    Returns its winner's values, the window's estimation samples (a mask of the record) and the winner's cost
    on every kept sample (None where the last window keeps under :data:`MIN_SAMPLES` samples or does not move, or
    where its winner's integrator is not ``best``'s), and the simulations spent.
    """
    a = y.size - w
    if int(np.sum(kept[a:])) < MIN_SAMPLES or _moves(y[a:], kept[a:]) is not None:
        return None, 0
    found, spent, est, _ = _search(u[a:], y[a:], kept[a:], period, starts, grid, (best.structure,))
    winner, winner_d = found[0]
    if winner.integrator != best.integrator:
        return None, spent
    search = np.zeros(y.size, dtype=bool)
    search[a:] = est
    return (winner_d, search, _cost(u, y, period, winner.structure, winner_d, kept)), spent + 1


def _cost(u: np.ndarray, y: np.ndarray, period: float, structure: str, d: dict[str, float], score: np.ndarray) -> float:
    """The sum of squared residuals of the model ``d`` on the samples ``score`` (one simulation)."""
    r = _Problem(u, y, period, structure, (), d, score, 1.0)(np.zeros(0))
    return float(r @ r)


def _stage_start(
    candidates: list[tuple[LoopCandidate, dict[str, float]]], structure: str
) -> tuple[LoopCandidate, dict[str, float]]:
    """Where the load stage starts: ``structure``'s candidate that validates best, with an integrator.

    The massless fits cannot tell whether a loop behind a heavy load integrates (the ODrive twin at 20x
    validates 0.0538 without, 0.0541 with), and the stage frees only its start's parameters: from the one
    without, the ODrive twin's fine record came to ki 0, mu 0.10 on its limit, -9.6 %; from the one with,
    ki 473 and mu 2.72 (truth 482, 2.84), +0.3 % at 0.4 times the error. Where the best has none, its values
    start one (:func:`_ki_start`; its constant torque ``a0`` to 0, as every candidate with an integrator
    has): the candidate with an integrator can be the worse start (the ODrive twin at 20x, seed 4: 0.0569
    against 0.0505, +165 % of play; the stage from it was not kept and the answer was -79 %).

    Parameters
    ----------
    candidates : list of (LoopCandidate, dict)
        The massless candidates and their values, best validation first.
    structure : str
        The place of the play the stage extends.

    Returns
    -------
    base : LoopCandidate
        The candidate whose structure and integrator the stage fits (one with an integrator when there is one).
    values : dict
        The stage's start.
    """
    base, values = next((c, d) for c, d in candidates if c.structure == structure)
    with_ki = next((c for c, _ in candidates if c.structure == structure and c.integrator), None)
    if base.integrator or with_ki is None:
        return base, values
    return with_ki, dict(values, ki=_ki_start(values["kp"], values["kv"]), a0=0.0)


def _run_load_stage(
    y: np.ndarray,
    period: float,
    base: LoopCandidate,
    problem: tuple[Fit, Simulate, dict[str, float]],
    est: np.ndarray,
    val: np.ndarray,
    kept_below: float,
) -> tuple[LoopCandidate, dict[str, float], int, list[tuple[float, float]]]:
    """:func:`~servoid.ident.offline.load_stage.load_stage` on ``base``'s structure (:func:`_stage_problem`), as a candidate."""
    fit, simulate, start = problem
    d, used, rivals = load_stage(y, start, _free(base.structure, base.integrator), fit, simulate, est, val, kept_below)
    model = _model(base.structure, period, d)
    y_hat = simulate(d)
    cand = LoopCandidate(
        structure=base.structure,
        integrator=base.integrator,
        model=model,
        estimation_nrmse=free_run_nrmse(y[est], y_hat[est]),
        validation_nrmse=free_run_nrmse(y[val], y_hat[val]),
        evaluations=used,
    )
    return cand, d, used, rivals


def _stage_problem(
    u: np.ndarray,
    y: np.ndarray,
    period: float,
    base: LoopCandidate,
    base_d: dict[str, float],
    est: np.ndarray,
    a_scale: float,
) -> tuple[Fit, Simulate, dict[str, float]]:
    """The load stage's fit and simulation on ``base``'s structure, and its start (``base_d`` with the load's friction)."""

    def fit(start: dict[str, float], free: tuple[str, ...], nfev: int) -> tuple[dict[str, float], float, int]:
        d, prob, sol = _fit(
            u, y, period, base.structure, start, est, a_scale, integrator=base.integrator, max_nfev=nfev, free=free
        )
        return d, float(sol.cost) if sol is not None else math.inf, prob.evaluations

    def simulate(d: dict[str, float]) -> np.ndarray:
        _threads.check()  # the grid's free runs (a load's sub-steps: 24-40 times a massless one's) stop as fits do
        return _model(base.structure, period, d).simulate(u, y0=float(y[0]))

    # the load's friction starts at the massless fit's Coulomb level (a deceleration of the same order)
    return fit, simulate, dict(base_d, al=max(base_d["fc"], 1e-6 * a_scale))


def refit(
    u: Any, y: Any, sample_period_s: float, start: ServoLoopModel, *, hold: tuple[str, ...] = (), keep: Any = None
) -> ServoLoopModel:
    """Refit a servo-loop model on a record with some of its parameters held at the start's values.

    A nested model for a comparison: ``diagnose`` fits the chosen structure without its friction
    terms (``start`` with ``fc = fs = 0``, ``hold=("fc", "fs", "vs", "veps")``) to see what they
    buy. It is :func:`refit_loop` with :func:`fit_loop`'s candidate budget on every kept sample.

    Parameters
    ----------
    u, y : array_like
        The record, as for :func:`fit_loop`.
    sample_period_s : float
        The host period, s.
    start : ServoLoopModel
        Where the fit starts; its structure and whether it has an integrator (``ki > 0``) stay.
    hold : tuple of str
        Names of :data:`~servoid.ident.models.servo_loop.PARAM_NAMES` (or ``play``, ``asym``)
        held at ``start``'s values.
    keep : array_like of bool, optional
        Readings to score, as for :func:`fit_loop`.

    Returns
    -------
    ServoLoopModel
    """
    u_arr, y_arr, kept, period = _checked(u, y, sample_period_s, keep)
    if period != start.sample_period_s:
        start = dataclasses.replace(start, sample_period_s=period)
    return refit_loop(u_arr, y_arr, start, score=kept, max_nfev=CANDIDATE_NFEV, hold=hold).model


def _checked(u: Any, y: Any, sample_period_s: float, keep: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """The record checked (``y`` bridged across the readings not kept), the mask of kept readings and the period."""
    u_arr = validation.signal("u", u, min_length=MIN_SAMPLES)
    kept = _kept(keep, u_arr.size)
    y_arr = validation.signal("y", _bridged(y, kept), min_length=MIN_SAMPLES)
    if u_arr.size != y_arr.size:
        raise ConfigError(f"u and y differ in length: {u_arr.size} against {y_arr.size}")
    return u_arr, y_arr, kept, validation.positive("sample_period_s", sample_period_s)


def _kept(keep: Any, n: int) -> np.ndarray:
    """The mask of kept readings (all when None), checked: its length, and enough kept samples to fit."""
    if keep is None:
        return np.ones(n, dtype=bool)
    kept = np.asarray(keep, dtype=np.bool_)
    if kept.shape != (n,):
        raise ConfigError(f"keep has shape {kept.shape}; expected ({n},), one flag per sample of u")
    if int(kept.sum()) < MIN_SAMPLES:
        raise ConfigError(f"keep leaves {int(kept.sum())} samples; the servo-loop fit needs at least {MIN_SAMPLES}")
    return kept


def _bridged(y: Any, kept: np.ndarray) -> np.ndarray:
    """``y`` with the readings not kept interpolated from their kept neighbours (for the starts; never scored)."""
    y_arr = np.asarray(y, dtype=np.float64)
    if kept.all() or y_arr.shape != kept.shape:
        return y_arr  # the length is checked by the caller
    at = np.flatnonzero(kept)
    return np.interp(np.arange(y_arr.size), at, y_arr[at])


def _spaced(jac: np.ndarray, residual: np.ndarray, kept: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The final fit's Jacobian rows and residuals at their own samples, zeros where a reading was not kept.

    The HAC sandwich then sees each lag at its true distance in time: the amplitude-modulated
    series of Parzen (1963), the estimator Datta & Du (2012, "Nonparametric HAC estimation
    for time series data with missing observations") show consistent with gaps. Closing the
    gaps up instead would count a lag across a lost sample as one sample shorter.
    """
    if kept.all():
        return jac, residual
    stop = int(np.flatnonzero(kept)[-1]) + 1
    rows = np.zeros((stop, jac.shape[1]))
    rows[kept[:stop]] = jac
    r = np.zeros(stop)
    r[kept[:stop]] = residual
    return rows, r


def _play_interval(jac: np.ndarray, residual: np.ndarray, free: tuple[str, ...], play: float) -> tuple[float, float]:
    """95 % interval of the play from the HAC standard error of ``ln(play)`` (so both ends are positive).

    Columns of the Jacobian the record does not move at all (a nuisance parameter at a bound)
    are left out: the interval is then conditional on them.
    """
    jac = np.asarray(jac, dtype=np.float64)
    norms = np.linalg.norm(jac, axis=0)
    used = norms > 1e-9 * float(np.max(norms)) if norms.size and float(np.max(norms)) > 0.0 else norms > 0.0
    i = free.index("play")
    if not used[i]:
        return (math.nan, math.nan)
    gradient = np.zeros(int(np.sum(used)))
    gradient[int(np.sum(used[:i]))] = 1.0
    se = hac_stderr(jac[:, used], np.asarray(residual, dtype=np.float64), gradient)
    if not math.isfinite(se) or Z95 * se > _MAX_LOG_SPREAD:
        return (math.nan, math.nan)  # an error of ln(play) this large bounds nothing (and exp would overflow)
    return (play * math.exp(-Z95 * se), play * math.exp(Z95 * se))


#: Largest ``Z95 * se(ln play)`` given as an interval: e^50 is no bound on a play, and e^710 overflows.
_MAX_LOG_SPREAD = 50.0


def _with_rivals(interval: tuple[float, float], candidates: list[LoopCandidate], best: float) -> tuple[float, float]:
    """The statistical interval widened to the plays of every candidate the validation cannot tell from the best.

    The HAC interval measures noise; on a physical servo the play's error is model error (an
    unmodelled load inertia, a feedback quantised to counts: the study's Q5, 0 of 14 twin intervals
    covered the truth). The data's own measure of that error is how far models that fit equally
    well put the play: every candidate, of either place and with or without the integrator,
    whose validation NRMSE is within :data:`MIN_STRUCTURE_MARGIN` of the best -- the margin the
    verdict uses to call two structures equal. Their plays join the interval (its hull), so the
    interval and the structure rule say the same thing: models the record cannot separate bound
    what it knows about the play. A statistical interval that is not finite stays so.
    """
    return widened_to_rivals(interval, [(c.model.play, c.validation_nrmse) for c in candidates], best)


def widened_to_rivals(
    interval: tuple[float, float], rivals: list[tuple[float, float]], best: float
) -> tuple[float, float]:
    """The hull of ``interval`` and the plays of the ``(play, nrmse)`` rivals within the structure margin of ``best``.

    The one rule of :func:`_with_rivals` (validation fits) and of the online refinement's reach
    (:mod:`servoid.ident.online.refinement`, fits on the whole record). A statistical interval
    that is not finite stays so.

    Parameters
    ----------
    interval : tuple of float
        The statistical interval.
    rivals : list of (float, float)
        Each rival's play and its NRMSE, on the same data as ``best``.
    best : float
        The answer's NRMSE.
    """
    low, high = interval
    if not (math.isfinite(low) and math.isfinite(high)):
        return interval
    plays = [play for play, nrmse in rivals if nrmse <= (1.0 + MIN_STRUCTURE_MARGIN) * best]
    return (min([low, *plays]), max([high, *plays]))


def _dead_time_samples(model: ServoLoopModel, u: np.ndarray, y: np.ndarray) -> float:
    """The play's dead time at a reversal in samples, ``play / (kp median|u - y|) / T``, of a play-in-loop model.

    While the horn waits in the play the loop drives the motor at about ``kp`` times the error;
    the median error of the record stands for the error at a reversal (the study's Q3 rule).
    Under about one sample the place of the play cannot be seen, whichever place won.
    """
    speed = model.kp * float(np.median(np.abs(u - y)))
    return model.play / speed / model.sample_period_s if speed > 0.0 else math.inf


def _noticed(model: ServoLoopModel, q: float) -> tuple[str, ...]:
    """What the fit noticed beyond the numbers the verdict rules read (margin, stall band, dead time, fit)."""
    reasons = []
    if q > 0.0 and model.play < q:
        reasons.append(f"the fitted play {model.play:.4g} is smaller than the record's resolution {q:.4g}")
    return tuple(reasons)


def _load_noticed(model: ServoLoopModel) -> tuple[str, ...]:
    """Why a kept load stage's play is not identifiable: the rigid-impact load is not yet proven on servos.

    Every kept load gives a reason. On the ODrive twin the stage's plays scatter -14 ... +17 % around
    the truth (its gear contact rings for 8 ms, one to two host periods, so the impacts are not
    instantaneous), while its interval can stay narrow: the live record of seed 1 gave +11.9 % with
    a 95 % interval [1.06, 1.17] times the truth, which the fit and margin rules alone called
    identifiable. A second reason names an inertia ratio on its limit: at 50x the fit runs to the
    light end and puts the play 8-14 % small, so the load does not describe the record at all.
    Started from the integrator candidate (fit_loop), the stage put the ODrive twin's sines at
    -9.8 ... +1.8 % with fits 1.00-1.02 times the floor, yet the fit's own interval missed the
    truth on 2 of 6 ([0.89, 0.98] at -4.2 %, [1.01, 1.19] at +1.6 %): the reason stays.
    """
    if not model.massive:
        return ()
    reasons = [
        f"the play comes from the load model (inertia ratio {model.mu:.3g}, restitution {model.e:.2g}), whose "
        "rigid impacts only approximate a gear contact that takes a host period or more; its plays on the "
        "servo twins scatter -14 ... +17 % around the truth, more than its own spread says"
    ]
    lo, hi = MU_LIMITS
    if not (lo * LOAD_LIMIT_NEAR < model.mu < hi / LOAD_LIMIT_NEAR):
        reasons.append(
            f"the load's inertia ratio {model.mu:.3g} is at the fit's limit ({lo:g}..{hi:g}): the load meeting the "
            "flanks in rigid impacts does not describe this record"
        )
    return tuple(reasons)


@dataclass(frozen=True)
class LoopRefit:
    """Result of :func:`refit_loop`: one place of the play, refitted from a known model.

    Attributes
    ----------
    model : ServoLoopModel
        The refitted model (the start's structure and integrator).
    fit_nrmse : float
        Free-run NRMSE on the scored samples.
    evaluations : int
        Simulations used (Jacobians included).
    seconds : float
        Wall-clock time of the refit.
    play_interval : tuple of float
        The play's 95 % HAC interval from the refit's Jacobian (noise only, as :func:`fit_loop`'s
        before its rivals widen it); ``(nan, nan)`` when the Jacobian does not determine it.
    """

    model: ServoLoopModel
    fit_nrmse: float
    evaluations: int
    seconds: float
    play_interval: tuple[float, float] = (math.nan, math.nan)


def refit_loop(
    u: Any,
    y: Any,
    start: ServoLoopModel,
    *,
    score: Any = None,
    max_nfev: int = FINAL_NFEV,
    hold: tuple[str, ...] = (),
) -> LoopRefit:
    """Refit a servo-loop model on a record, starting from ``start`` (a warm start: no scan, one place of the play).

    The place of the play and whether the velocity loop has an integrator are
    the start's; the free parameters, their scaling and the fit are those of
    :func:`fit_loop`'s candidates. What a moving-window estimator runs every
    few seconds on its last window (:mod:`servoid.ident.online.window`).

    Parameters
    ----------
    u : array_like
        Set points at the host instants, in the unit of ``y``; ``start.sample_period_s`` apart.
    y : array_like
        Readings at the host instants; ``y[0]`` must be measured (the simulation starts there),
        others may be anything where ``score`` is False.
    start : ServoLoopModel
        The model to start from (the previous window's answer, or :func:`fit_loop`'s).
    score : array_like of bool, optional
        Samples the fit scores (default all): leave out lost samples and a burn-in at the
        start, where the loop's state is not known.
    max_nfev : int
        scipy's ``max_nfev`` (a Jacobian costs one simulation per free parameter on top).
    hold : tuple of str
        Names of :data:`~servoid.ident.models.servo_loop.PARAM_NAMES` (or ``play``, ``asym``)
        held at ``start``'s values (a nested model, as :func:`refit` fits).

    Returns
    -------
    LoopRefit
    """
    t0 = time.perf_counter()
    u_arr = validation.signal("u", u, min_length=2)
    y_arr = np.asarray(y, dtype=np.float64)
    if y_arr.shape != u_arr.shape:
        raise ConfigError(f"u and y differ in shape: {u_arr.shape} against {y_arr.shape}")
    keep = np.ones(u_arr.size, dtype=bool) if score is None else np.asarray(score, dtype=bool)
    if keep.shape != u_arr.shape or int(np.sum(keep)) < 2:
        raise ConfigError(f"score must be a bool array of u's shape {u_arr.shape} with at least 2 samples scored")
    if not (math.isfinite(float(y_arr[0])) and np.all(np.isfinite(y_arr[keep]))):
        raise ConfigError("y must be finite at its first sample and wherever it is scored")
    if not isinstance(start, ServoLoopModel):
        raise ConfigError(f"start must be a ServoLoopModel, not {type(start).__name__}")
    max_nfev = validation.integer("max_nfev", max_nfev, minimum=1)
    period = start.sample_period_s
    centre = float(np.mean(u_arr))
    uc = np.ascontiguousarray(u_arr - centre)
    yc = np.ascontiguousarray(np.where(keep, y_arr, y_arr[0]) - centre)
    v_typ = max(float(np.std(np.diff(yc[keep]))) / period, 1e-12 * float(np.ptp(yc[keep])) / period, 1e-300)
    d = start.params()
    play = max(start.play, 1e-12 * max(float(np.ptp(yc[keep])), 1e-300))
    d["play"] = play
    d["asym"] = float(np.clip(start.c1 / play - 0.5, -0.5, 0.5)) if start.play > 0.0 else 0.0
    integrator = start.ki > 0.0
    free = tuple(n for n in _free(start.structure, integrator) if n not in hold)
    d, prob, sol = _fit(
        uc, yc, period, start.structure, d, keep, 0.1 * start.kv * v_typ, integrator=integrator, max_nfev=max_nfev,
        free=free,
    )  # fmt: skip
    d["s0"] = start.s0
    model = _model(start.structure, period, d)
    y_hat = model.simulate(uc, y0=float(yc[0]))
    interval = (
        (math.nan, math.nan)
        if sol is None or "play" not in free
        else _play_interval(*_spaced(sol.jac, sol.fun, keep), free, d["play"])
    )
    return LoopRefit(model, nrmse(yc[keep], y_hat[keep]), prob.evaluations, time.perf_counter() - t0, interval)
