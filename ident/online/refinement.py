"""The final servo-loop answer of a live session: the offline search on the live record, with the online estimate as one more candidate.

A live session's moving-window refit (:mod:`servoid.ident.online.window`) ends
with a model of the last window; it is the session's progress. The answer is
then the offline fit of the whole record -- :func:`~servoid.ident.offline.loop_fit.fit_loop`
as identification's second structure calls it (``load=None``: both places
searched fresh from their scans, the load stage on a motor-side candidate off
its floor) -- with the online estimate offered as **one more candidate**, judged
like the search's own on the same validation blocks (:func:`refine_online`):

1. the online model is refitted on the estimation blocks
   (:func:`~servoid.ident.offline.loop_fit.refit_loop`, :data:`~servoid.ident.offline.loop_fit.CANDIDATE_NFEV`
   evaluations, as a search candidate gets) and scored on the validation blocks;
2. when it validates better than the search's answer (its load stage included), it is
   refitted on every usable sample and answers; else the search's answer stands;
3. the margin between the places and the play's interval take the candidate in as
   ``fit_loop`` takes its own: the best validation of each place, and the hull of every
   candidate's play within :data:`~servoid.ident.offline.intervals.MIN_STRUCTURE_MARGIN` of
   the answer's validation;
4. after a live design's slow phase (``slow``), steps 1-3 run on the fast part; an answer
   with the play outside the loop is replaced by the search on the slow part when that
   search puts the play outside the loop too (issue 15: CiA 402 twin -19/-16 % -> +3/+3 %); when
   the online estimate searched the same slow phase already (:attr:`WindowResult.slow_search`,
   its windows having put the play outside the loop), or the session holds a search of it
   (``slow_search``: :class:`~servoid.ident.online.early_search.EarlySearch`, started when first
   asked for), that search is taken, not run again.
   Only where the fast part names the place: where its places tie (validation margin under
   :data:`~servoid.ident.offline.intervals.MIN_STRUCTURE_MARGIN`) the fast answer stands and its
   interval takes in the slow part's play (:attr:`Refined.slow_play`). The slow part cannot place
   the play: on a horn servo (play in the loop) its gentle reversals sit in the motor's stall band,
   which the play outside the loop takes for play (the XM430 twin's live records on ``sim://``, seeds
   0-2, the slow part alone: outside at +252 ... +284 %, margins 17-37 %, intervals 3.5-4.1 times the
   truth; the fast part: in the loop at +6 ... +10 %, margins 2-10 %), so its confirmation turned a
   fast-part tie into +270 % with the slow part's interval (the XM430 through the real-clock
   emulators: +272 ... +285 %).
5. after a slow phase, where the fast part puts the play in the loop: the horn stage
   (:func:`~servoid.ident.offline.horn_contact.with_horn`) on the whole record (slow and fast
   parts, fitted through its gaps as ``fit_loop`` fits), after ``fit_loop(load=False)`` on it (the massless search:
   its load stage was 22-69 % of the step's time, :func:`_horn_on_whole`) puts the play in the loop too, answers when
   it is kept and the load's friction it fits (``al``, the horn's deceleration by its own friction)
   stops the load faster than the slow phase's set point ever decelerates: then the slow part's
   reversals show the whole play (the load stays on the trailing flank) and the fast part's the
   horn's coasting, which the horn fits. The horn stage sized the play offline only on about 40 s
   holding turns gentler than the load's friction; the fast part alone (27 s at up to 0.35x the
   probe's bandwidth, 16.5 rad/s^2 on the STS3215 twin, whose load stops at 20) left it to chance
   (docs/online.md, "The horn stage on live records"). The live records of the twins
   (``sim://``, virtual clock, seeds 0-5): STS3215 -17 / -7 / -12 / -14 / -14 % -> -10 / -9 / -1 / -12 /
   +7 % (``al`` 16-20 rad/s^2 against the slow phase's turns at 1.2-2.9; the twin's load stops at 20),
   XM430 seeds 3 / 5 -17 / -30 -> -1 / -1 % (``al`` 8 / 18), its seeds 0-2 not kept and 4 not run
   (the fast answer stands); an STS3215 with its load friction doubled -12 / -8 -> -7 / -16 % (``al``
   40 / 17.5). A kept horn keeps its doubt
   (:data:`~servoid.ident.offline.horn_contact.REASON`). Cost: one ``fit_loop`` on the whole record
   and the stage (7.7-14.8 s at load 6-8 with the search massless; 17-38 s at load 8-9 with its load stage);
   stopped at ``deadline_s`` when it has not ended by then (the fast answer stands).

With a deadline (``deadline_s``: a live run on a real clock, its wall budget) every fit above runs under
one :class:`~servoid.ident.offline._threads.Stop` and unwinds where it evaluates its cost when the
deadline comes (:class:`~servoid.ident.offline._threads.Stopped`, on every thread it uses); the answer is
then the best one already made, and :attr:`Refined.cut` says which stage was cut and what answers instead:
the horn stage (step 5) cut, the fast answer stands; the slow part's search (step 4) cut, the fast answer
stands with the reason that the slow part did not size it; the warm refit of the early search's answer on
the whole fast part cut, the head's answer stands; the online candidate's refit cut, the search answers
alone; the search itself cut, the online estimate answers as it is (not validated against any search).
Every cut but the horn stage's joins the answer's ``reasons``, so identification calls it not identifiable:
a stage cut short never makes a confident answer out of less evidence.

Why a candidate and not a start (issue 15). The refinement this replaces started
from the first window's place of the play and refitted it massless: on the
CiA 402 and ODrive twins it kept a wrong place or the wrong loop (-51 ... -57 %)
where the offline search on the same records gave -10 ... +20 %. A start alone
also cannot protect an answer the search gets wrong: on the XM430 twin's seed-1
record the search puts the play outside the loop at +202 %, 1.3 % better in
validation than inside (a tie, which identification's verdict calls
undetermined); the online model refitted on the estimation blocks validated
0.0152 against the search's 0.0137, so judged on validation it does not win
either -- the record does not place the play, and the verdict says so. As a
candidate the online estimate answers exactly when the record prefers it.

Cost: ``fit_loop`` on the whole record (2-4 warm-started searches; 8-40 s on
12 000 samples, by the machine's load) and two warm refits.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from servoid import validation
from servoid.errors import ConfigError
from servoid.ident.diagnosis.flank_rebound import rebound
from servoid.ident.diagnosis.friction_stall import stall_band
from servoid.ident.metrics import free_run_nrmse, nrmse
from servoid.ident.models.servo_loop import ServoLoopModel
from servoid.ident.models.structure_names import PLAY_IN_LOOP
from servoid.ident.offline import _threads
from servoid.ident.offline.horn_contact import with_horn
from servoid.ident.offline.intervals import MIN_STRUCTURE_MARGIN, quantum
from servoid.ident.offline.loop_fit import (
    CANDIDATE_NFEV,
    FINAL_NFEV,
    MIN_SAMPLES,
    LoopCandidate,
    LoopChoice,
    _dead_time_samples,
    _load_noticed,
    _noticed,
    _with_rivals,
    block_mask,
    fit_loop,
    place_margin,
    refit_loop,
)
from servoid.ident.online.window import SlowSearch, WindowResult

__all__ = ["refine_online", "Refined", "CUT"]

#: How a reason of the answer that a stage was cut by the wall budget starts (:attr:`Refined.cut`).
CUT = "cut by the wall budget"
#: Samples each side of a set point's turn that :func:`_turn_accel` fits its parabola to, at least.
TURN_HALF = 3


@dataclasses.dataclass(frozen=True)
class Refined:
    """What :func:`refine_online` found besides the answer.

    Attributes
    ----------
    online : LoopCandidate or None
        The online model refitted on the estimation blocks and scored on the validation blocks
        (None: there was no online model, and the search answered alone).
    search : LoopChoice
        The offline search's own answer (:func:`~servoid.ident.offline.loop_fit.fit_loop`).
    online_won : bool
        Whether the online candidate validated better and answers.
    fast_play : float or None
        With a slow phase: the answer's play on the fast part before the slow part's refit (the
        play outside the loop, step 4) or the whole record's horn (step 5) replaced it (None: neither did).
    slow_play : float or None
        With a slow phase, the play outside the loop on the fast part and its places tied there
        (validation margin under :data:`~servoid.ident.offline.intervals.MIN_STRUCTURE_MARGIN`): the
        slow part's play outside the loop, taken into the interval only (None: no such tie).
    scored : tuple of int
        The samples ``[start, stop)`` of the record on whose usable ones the answer's
        ``fit_nrmse`` was computed: the whole record, or the fast or the slow part after a
        slow phase (:meth:`score` scores another model there).
    horn : str or None
        Step 5 (the horn stage on the whole record after a slow phase, the play in the loop): what
        became of it (answered, not kept, its load friction too weak for the slow phase, ...); None
        where it does not apply. When it answered, :attr:`online_won` is False (the answer is the
        whole record's search with the horn) and :attr:`fast_play` the fast part's play before it.
    cut : tuple of str
        The stages the deadline cut (``refine_online(deadline_s=)``), each with what answers instead
        (the module's text); empty when none was.
    """

    online: LoopCandidate | None
    search: LoopChoice
    online_won: bool
    fast_play: float | None = None
    slow_play: float | None = None
    scored: tuple[int, int] = (0, 0)
    horn: str | None = None
    cut: tuple[str, ...] = ()

    def score(self, model: ServoLoopModel, u: Any, y: Any, keep: Any = None) -> float:
        """Free-run NRMSE of ``model`` on the samples the answer's fit is on, computed as the answer's.

        The record's part :attr:`scored`, centred on its command's mean, simulated from its first
        sample, scored on its usable samples: the online estimate is then compared with the answer
        like with like (the verdict's fit rule, :func:`~servoid.ident.online.verdict.judge_window`).

        Parameters
        ----------
        model : ServoLoopModel
            The model to score (the online estimate).
        u, y, keep : array_like
            The record :func:`refine_online` was given (``keep`` default all).

        Returns
        -------
        float
            The NRMSE (infinite when the free run runs away).
        """
        lo, hi = self.scored
        u_arr = np.asarray(u, dtype=np.float64)[lo:hi]
        y_arr = np.asarray(y, dtype=np.float64)[lo:hi]
        kept = np.ones(u_arr.size, dtype=bool) if keep is None else np.asarray(keep, dtype=np.bool_)[lo:hi]
        if u_arr.size == 0 or not kept[0]:
            raise ConfigError(f"the answer's samples {lo}..{hi} do not start with a usable one in this record")
        centre = float(np.mean(u_arr))
        y_hat = model.simulate(u_arr - centre, y0=float(y_arr[0]) - centre)
        return free_run_nrmse(y_arr[kept] - centre, y_hat[kept])

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready: the candidate's place, play and fits, the search's, and which answered."""
        c, s = self.online, self.search
        return {"online_candidate": None if c is None else {
                    "structure": c.structure, "play": c.model.play, "estimation_nrmse": c.estimation_nrmse,
                    "validation_nrmse": c.validation_nrmse},
                "search": {"structure": s.structure, "play": s.play, "validation_nrmse": s.validation_nrmse[s.structure],
                           "load": s.model.massive, "seconds": s.seconds},
                "online_won": self.online_won, "fast_play": self.fast_play, "slow_play": self.slow_play,
                "scored": list(self.scored), "horn": self.horn, "cut": list(self.cut)}  # fmt: skip


def refine_online(
    u: Any,
    y: Any,
    online: WindowResult,
    *,
    keep: Any = None,
    slow: int = 0,
    early: SlowSearch | None = None,
    deadline_s: float = math.inf,
    slow_search: Callable[[], SlowSearch | None] | None = None,
) -> tuple[LoopChoice, Refined]:
    """The offline search on the whole record with the online estimate as one more candidate (the module's steps).

    With a live design's slow phase (its first ``slow`` samples, :data:`~servoid.ident.online.probe_design.SLOW_SHARE`)
    the search and the candidate run on the fast part after it, which names the place of the play;
    when that is outside the loop and the search on the slow part agrees, the slow part's answer
    stands (step 4): there the set point decelerates more gently than the load's friction and the
    load shows the whole play at each reversal, which the fast part's coasting load hides (the
    CiA 402 twin). A play inside the loop keeps the fast part's answer (the slow part hands a
    horn twin's record to its motor's stall band).

    Parameters
    ----------
    u, y : array_like
        The record at the online estimate's sample period (``y`` is not read where ``keep`` is False);
        ``y[0]`` must be measured.
    online : WindowResult
        The window refit's run; its :attr:`~WindowResult.model` is the candidate (None: no window
        refit ended before the run did, on a loaded real clock: the search answers alone, where
        identification would otherwise search the record itself after it, 24-30 s at load 8).
    keep : array_like of bool, optional
        The usable samples (a live session's validity mask); default all.
    slow : int
        How many of the first samples are a slow phase (0: none; ignored when fewer than
        :data:`~servoid.ident.offline.loop_fit.MIN_SAMPLES` usable samples are on either side).
    early : SlowSearch, optional
        The search of the fast part's head run while the session went on
        (:class:`~servoid.ident.online.early_search.EarlySearch`; ``start`` an index of this
        record): when it starts at the fast part's first usable sample and ends before the
        record does, steps 1-3 run on the samples it searched with its answer, and the answer
        is then refitted warm on the whole fast part (:func:`_extended`); else ignored.
    deadline_s : float
        The :func:`time.perf_counter` instant at which every fit here stops (a live run on a real clock:
        its wall budget; :class:`~servoid.ident.offline._threads.Stop`): the best answer made by then
        answers, the cut stages named (:attr:`Refined.cut`, the module's text). Default: no deadline.
    slow_search : callable, optional
        Asked (once, only when step 4 needs the slow part's search and the windows did not run it)
        for the slow phase's search run during the session
        (:class:`~servoid.ident.online.early_search.EarlySearch` of the slow phase; ``start`` an
        index of this record): taken when it starts at this record's first sample and covers the
        slow part, else the slow part is searched here.

    Returns
    -------
    choice : LoopChoice
        The answer, as :func:`~servoid.ident.offline.loop_fit.fit_loop` gives one (what
        :func:`servoid.ident.identify.identify` takes as ``loop=``).
    refined : Refined
        The online candidate, the search's own answer and which one answered.

    Raises
    ------
    ConfigError
        Mismatched signals or fewer than
        :data:`~servoid.ident.offline.loop_fit.MIN_SAMPLES` usable samples.
    ~servoid.ident.offline._threads.Stopped
        The deadline came before any answer was made (no online model, and the search was cut).
    """
    stop = None if math.isinf(deadline_s) else _threads.Stop(deadline_s, "the wall budget")
    with _threads.stopping(stop):
        return _refine_online(u, y, online, keep, slow, early, slow_search)


def _refine_online(
    u: Any,
    y: Any,
    online: WindowResult,
    keep: Any,
    slow: int,
    early: SlowSearch | None,
    slow_search: Callable[[], SlowSearch | None] | None,
) -> tuple[LoopChoice, Refined]:
    """:func:`refine_online` inside its stop (where a fit raises :class:`~servoid.ident.offline._threads.Stopped`)."""
    t0 = time.perf_counter()
    start = online.model  # None: no window refit ended (a loaded real clock); the search alone answers
    period = online.config.sample_period_s
    u_arr = validation.signal("u", u, min_length=MIN_SAMPLES)
    y_arr = np.asarray(y, dtype=np.float64)
    kept = np.ones(u_arr.size, dtype=bool) if keep is None else np.asarray(keep, dtype=np.bool_)
    if y_arr.shape != u_arr.shape or kept.shape != u_arr.shape:
        raise ConfigError(f"u, y and keep differ in shape: {u_arr.shape}, {y_arr.shape}, {kept.shape}")
    if int(kept.sum()) < MIN_SAMPLES:
        raise ConfigError(f"{int(kept.sum())} usable samples; the servo-loop refinement needs at least {MIN_SAMPLES}")
    y_arr = np.where(kept, y_arr, y_arr[0])
    slow = validation.integer("slow", slow, minimum=0)
    head = _fast_start(kept, slow)
    searched = None
    if early is not None and early.start == head and MIN_SAMPLES <= early.samples < u_arr.size - head:
        searched = early
    try:
        choice, refined = _refine_fast(u_arr[head:], y_arr[head:], kept[head:], start, period, t0, searched)
    except _threads.Stopped as exc:
        if start is None:
            raise  # nothing made yet to answer with
        choice = _online_answer(u_arr[head:], y_arr[head:], kept[head:], start, t0, f"the search ({exc})")
        refined = Refined(
            None, choice, True, cut=(f"the search on the fast part ({exc}): the online estimate answers",)
        )
    if head == 0:
        return choice, dataclasses.replace(refined, scored=(0, u_arr.size))
    scored = (head, u_arr.size)
    # back on the whole record: a play outside the loop from the search on the slow part
    centre = float(np.mean(u_arr))
    uc, yc = u_arr - centre, y_arr - centre
    fast_play = slow_play = None
    if choice.structure != PLAY_IN_LOOP:
        # the slow part as searched during the session: up to the fast part's first usable sample, or to the slow
        # phase's end when the fast part starts with unusable samples (not scored: the same search; on the ODrive
        # twin through the serial emulator one such sample cost a second search of the slow part, 11 s at load 8)
        same = {head, slow}
        done = online.slow_search
        if (done is None or done.samples not in same) and slow_search is not None:
            done = slow_search()  # the session's own search of the slow phase
            done = done if done is not None and done.start == 0 else None
        slow_choice: LoopChoice | None = None
        if done is not None and done.samples in same:  # the online estimate's search of the same samples
            slow_choice = done.choice
        else:
            try:
                slow_choice = fit_loop(u_arr[:head], y_arr[:head], period, keep=kept[:head], load=None)
            except _threads.Stopped as exc:
                why = f"the slow part's search ({exc}): the fast part's play outside the loop answers, not sized by the slow part"
                choice = dataclasses.replace(choice, reasons=(*choice.reasons, f"{CUT}: {why}"))
                refined = dataclasses.replace(refined, cut=(*refined.cut, why))
        if slow_choice is None:
            pass  # cut: the fast answer stands, with its reason
        elif slow_choice.structure == PLAY_IN_LOOP:
            pass  # the slow part does not confirm the place: the fast answer stands
        elif not choice.margin >= MIN_STRUCTURE_MARGIN:
            # the fast part's places tie: the place is not named, so the slow part does not size the answer; its
            # play (what a play outside the loop would be) joins the interval, which holds the fast part's rivals
            slow_play = slow_choice.play
            interval = _hull(choice.play_interval, (*slow_choice.play_interval, slow_play))
            choice = dataclasses.replace(choice, play_interval=interval)
        else:
            fast_play, scored = choice.play, (0, head)
            choice = dataclasses.replace(
                choice,
                play=slow_choice.play,
                play_interval=slow_choice.play_interval,
                fit_nrmse=slow_choice.fit_nrmse,
                params=slow_choice.params,
                reasons=slow_choice.reasons,
                dead_time_samples=slow_choice.dead_time_samples,
                stall_band=slow_choice.stall_band,
                model=slow_choice.model,
                evaluations=choice.evaluations + slow_choice.evaluations,
            )
    horn: str | None = None
    whole: LoopChoice | None = None
    if choice.structure == PLAY_IN_LOOP:
        # 5. the horn stage on the whole record: the slow part's gentle reversals, the fast part's coasting; stopped
        # at the deadline when it has not ended (its cost is not predicted: 3.4-23 s on the twins' records, below)
        began = time.perf_counter()
        try:
            _threads.check()
            horn, whole = _horn_on_whole(u_arr, y_arr, kept, head, choice)
            horn = f"{horn} [{time.perf_counter() - began:.1f} s]"
        except _threads.Stopped as exc:
            horn = f"skipped: {exc} after {time.perf_counter() - began:.1f} s (the fast answer stands)"
            refined = dataclasses.replace(
                refined, cut=(*refined.cut, f"the horn stage ({exc}): the fast answer stands")
            )
    if whole is not None:
        fast_play, scored, refined = choice.play, (0, u_arr.size), dataclasses.replace(refined, online_won=False)
        choice = dataclasses.replace(whole, evaluations=choice.evaluations + whole.evaluations)
    simulated = choice.model.simulate(uc, y0=float(yc[0]))
    choice = dataclasses.replace(choice, simulated=simulated + centre, seconds=time.perf_counter() - t0)
    return choice, dataclasses.replace(refined, fast_play=fast_play, slow_play=slow_play, scored=scored, horn=horn)


def _horn_on_whole(
    u_arr: np.ndarray, y_arr: np.ndarray, kept: np.ndarray, head: int, fast: LoopChoice
) -> tuple[str, LoopChoice | None]:
    """Step 5: what became of the horn stage on the whole record, and its answer when it answers (else None).

    Run where the fast part's answer ``fast`` (the play in the loop, on ``[head:]``) shows the
    horn's rebound on its usable readings ``kept`` (the stage's own gate, checked before the search);
    the search and the stage run through the gaps and score the usable readings only. It
    answers when the massless search on the whole record (``fit_loop(load=False)``) puts the play in
    the loop, the stage keeps the horn, and the horn's own friction (``al``) stops the load faster than
    the slow part's set point decelerates into any of its reversals (:func:`_turn_accel`).

    The search runs without its load stage (a heavy load behind a play outside the loop): the stage
    can only move the search's answer outside the loop, where the horn is not run, never change the
    horn's start (the best play-in-loop candidate) or its answer, and the fast part's search, which
    put the play in the loop for this step to run, had run it already. On the horn twins' live records
    it was 22-69 % of the step's wall time (``benchmarks/horn_cost.py``: STS3215 7.5 of 17.5 s, XM430
    13.2 of 31.9 s, ``sim://``, load 8-9; through serial (C) 5.2 of 23.5 s and 20.4 of 29.5 s, load 6)
    and moved the place on none of them (``sim://`` seeds 0-3 of both, and two through serial (C)).
    """
    period = fast.model.sample_period_s
    if not rebound(y_arr[head:], np.asarray(fast.simulated), float(fast.play), period, valid=kept[head:]).named:
        return "not run: the fast part shows no rebound off the flank", None
    whole = fit_loop(u_arr, y_arr, period, keep=kept, load=False)
    if whole.structure != PLAY_IN_LOOP:
        return f"not run: the whole record's massless search puts the play {whole.structure}", None
    found = with_horn(u_arr, y_arr, period, whole, kept)
    if found is whole or not found.model.compliant:
        return "not kept (no rebound named, or the horn did not validate better)", None
    slow_accel = _turn_accel(u_arr[:head], period)
    if not found.model.al > slow_accel:
        return (f"not taken: the horn's friction stops it at {found.model.al:.3g}/s^2, no faster than the slow "
                f"part's set point decelerates ({slow_accel:.3g}/s^2)"), None  # fmt: skip
    return (f"answered: play {found.play:.4g} (massless {whole.play:.4g}); the horn's friction stops it at "
            f"{found.model.al:.3g}/s^2, the slow part's set point at most {slow_accel:.3g}/s^2"), found  # fmt: skip


def _turn_accel(u: np.ndarray, period: float) -> float:
    """The set point's largest deceleration into a reversal, unit/s^2 (0 without a turn).

    At each reversal of the set point's moving steps, the curvature of a parabola fitted by least
    squares to the samples around the turn: :data:`TURN_HALF` samples each side of it, or twice the
    turn's plateau where the set point is sent in counts (a gentle sine held at its top count for
    several samples: the 200 Hz STS3215 records through serial (C) hold it 4-8). A gentle sine's peak
    acceleration is at its turns. (The turns' second difference alone reads 0 where the top count is
    held: the gate then never held the horn back on a real transport.)
    """
    moving = np.flatnonzero(np.diff(u) != 0.0)
    if moving.size < 2:
        return 0.0
    sign = np.sign(np.diff(u)[moving])
    largest = 0.0
    for f in np.flatnonzero(sign[1:] != sign[:-1]):
        first, last = moving[f] + 1, moving[f + 1]  # the turn's samples (one where the set point is not held)
        half = max(TURN_HALF, 2 * (last - first))
        lo, hi = first - half, last + half
        if lo < 0 or hi >= u.size:
            continue
        t = (np.arange(lo, hi + 1) - 0.5 * (first + last)) * period
        largest = max(largest, abs(2.0 * float(np.polyfit(t, u[lo : hi + 1], 2)[0])))
    return largest


def _hull(interval: tuple[float, float], values: tuple[float, ...]) -> tuple[float, float]:
    """The hull of ``interval`` and the finite ``values``; an interval that is not finite stays so."""
    low, high = interval
    if not (math.isfinite(low) and math.isfinite(high)):
        return interval
    ends = [v for v in values if math.isfinite(v)]
    return (min([low, *ends]), max([high, *ends]))


def _fast_start(kept: np.ndarray, slow: int) -> int:
    """The first usable sample after a slow phase of ``slow`` samples; 0 when either part is too short to fit."""
    after = np.flatnonzero(kept[slow:]) if slow < kept.size else np.empty(0, dtype=np.int64)
    if slow == 0 or after.size < MIN_SAMPLES or int(kept[:slow].sum()) < MIN_SAMPLES:
        return 0
    return slow + int(after[0])


def _refine_fast(
    u_arr: np.ndarray,
    y_arr: np.ndarray,
    kept: np.ndarray,
    start: ServoLoopModel | None,
    period: float,
    t0: float,
    early: SlowSearch | None,
) -> tuple[LoopChoice, Refined]:
    """Steps 1-3 on the fast part: on all of it, or on the head ``early`` searched and then extended to all."""
    if early is None:
        return _refine(u_arr, y_arr, kept, start, period, t0)
    m = early.samples
    choice, refined = _refine(u_arr[:m], y_arr[:m], kept[:m], start, period, t0, early.choice)
    try:
        return _extended(choice, u_arr, y_arr, kept, t0), refined
    except _threads.Stopped as exc:  # the head's answer, not refitted on the rest of the fast part
        why = (f"the answer's refit on the whole fast part ({exc}): the answer is the search's on its first "
               f"{m} samples")  # fmt: skip
        choice = dataclasses.replace(choice, reasons=(*choice.reasons, f"{CUT}: {why}"))
        return choice, dataclasses.replace(refined, cut=(*refined.cut, why))


def _online_answer(
    u_arr: np.ndarray, y_arr: np.ndarray, kept: np.ndarray, model: ServoLoopModel, t0: float, cut: str
) -> LoopChoice:
    """The online estimate as the answer when the search was ``cut``: its free run, no interval, the cut its reason.

    Not refitted and not validated against any search: the play's interval is not finite, the places'
    margin unknown (NaN), and the reason (:data:`CUT`) makes identification call it not identifiable.
    """
    centre = float(np.mean(u_arr))
    uc, yc = u_arr - centre, y_arr - centre
    simulated = model.simulate(uc, y0=float(yc[0]))
    return LoopChoice(
        structure=model.structure,
        play=model.play,
        play_interval=(math.nan, math.nan),
        fit_nrmse=nrmse(yc[kept], simulated[kept]),
        validation_nrmse={model.structure: math.nan},
        margin=math.nan,
        params=model.params(),
        simulated=simulated + centre,
        reasons=(f"{CUT}: {cut}; the answer is the online estimate (the last window's model), not validated",),
        dead_time_samples=math.nan,
        stall_band=stall_band(max(model.fs, model.fc), model.kv, model.kp),
        model=model,
        candidates=(),
        seconds=time.perf_counter() - t0,
        evaluations=0,
    )


def _extended(choice: LoopChoice, u_arr: np.ndarray, y_arr: np.ndarray, kept: np.ndarray, t0: float) -> LoopChoice:
    """The answer of a search on the record's head refitted warm on every usable sample (``fit_loop``'s final refit).

    The place, the margin, the candidates and the dead time stay the head's (what its validation
    said); the model, the play, the fit and what the fit noticed are the whole record's. The
    play's interval is the refit's own widened to the head's rivals (``fit_loop``'s rule; not
    finite when the refit's Jacobian does not determine it), then to the head's interval (its
    load grid included): never narrower for the samples added.
    """
    fit = refit_loop(u_arr, y_arr, choice.model, score=kept, max_nfev=FINAL_NFEV)
    model = fit.model
    centre = float(np.mean(u_arr))
    uc, yc = u_arr - centre, y_arr - centre
    simulated = model.simulate(uc, y0=float(yc[0]))
    return dataclasses.replace(
        choice,
        play=model.play,
        play_interval=_hull(
            _with_rivals(fit.play_interval, list(choice.candidates), choice.validation_nrmse[choice.structure]),
            choice.play_interval,
        ),
        fit_nrmse=nrmse(yc[kept], simulated[kept]),
        params=model.params(),
        simulated=simulated + centre,
        reasons=_noticed(model, quantum(yc[kept])) + _load_noticed(model),
        stall_band=stall_band(max(model.fs, model.fc), model.kv, model.kp),
        model=model,
        seconds=time.perf_counter() - t0,
        evaluations=choice.evaluations + fit.evaluations,
    )


def _refine(
    u_arr: np.ndarray,
    y_arr: np.ndarray,
    kept: np.ndarray,
    start: ServoLoopModel | None,
    period: float,
    t0: float,
    search: LoopChoice | None = None,
) -> tuple[LoopChoice, Refined]:
    """The module's steps 1-3 on one record (``y_arr[0]`` measured, unusable samples filled); ``search``: its
    ``fit_loop(load=None)`` when already run; ``start`` None (no online model): the search answers alone."""
    # the search identification's second structure runs (second_structure: load=None)
    if search is None:
        search = fit_loop(u_arr, y_arr, period, keep=kept, load=None)
    if start is None:
        return dataclasses.replace(search, seconds=time.perf_counter() - t0), Refined(None, search, False)
    try:
        return _judged(u_arr, y_arr, kept, start, t0, search)
    except _threads.Stopped as exc:  # the candidate's refits cut: the search answers alone
        why = f"the online candidate's refit ({exc}): the search answers, the online estimate not judged"
        choice = dataclasses.replace(
            search, reasons=(*search.reasons, f"{CUT}: {why}"), seconds=time.perf_counter() - t0
        )
        return choice, Refined(None, search, False, cut=(why,))


def _judged(
    u_arr: np.ndarray, y_arr: np.ndarray, kept: np.ndarray, start: ServoLoopModel, t0: float, search: LoopChoice
) -> tuple[LoopChoice, Refined]:
    """Steps 1-3 once the search has answered: the online model ``start`` judged as one more candidate."""
    # 1. the online model as a candidate: the estimation blocks fitted, the validation blocks scored (fit_loop's split)
    blocks = block_mask(u_arr.size)
    est, val = blocks & kept, ~blocks & kept
    centre = float(np.mean(u_arr))
    uc, yc = u_arr - centre, y_arr - centre
    fit = refit_loop(u_arr, y_arr, start, score=est, max_nfev=CANDIDATE_NFEV)
    y_hat = fit.model.simulate(uc, y0=float(yc[0]))
    cand = LoopCandidate(
        fit.model.structure, fit.model.ki > 0.0, fit.model, nrmse(yc[est], y_hat[est]), nrmse(yc[val], y_hat[val]),
        fit.evaluations,
    )  # fmt: skip
    best_val = search.validation_nrmse[search.structure]
    per_structure = dict(search.validation_nrmse)
    per_structure[cand.structure] = min(per_structure.get(cand.structure, math.inf), cand.validation_nrmse)
    candidates = sorted((*search.candidates, cand), key=lambda c: c.validation_nrmse)
    won = cand.validation_nrmse < best_val
    if not won:
        # 3. the search answers; the candidate joins its margin and its interval's rivals
        choice = dataclasses.replace(
            search,
            validation_nrmse=per_structure,
            margin=place_margin(per_structure, search.structure),
            play_interval=_with_rivals(search.play_interval, [cand], best_val),
            candidates=tuple(candidates),
            seconds=time.perf_counter() - t0,
            evaluations=search.evaluations + cand.evaluations,
        )
        return choice, Refined(cand, search, False)
    # 2. the online candidate answers: refitted on every usable sample, as fit_loop's winner is
    final = refit_loop(u_arr, y_arr, cand.model, score=kept, max_nfev=FINAL_NFEV)
    model = final.model
    simulated = model.simulate(uc, y0=float(yc[0]))
    inside = model if model.structure == PLAY_IN_LOOP else None
    choice = LoopChoice(
        structure=model.structure,
        play=model.play,
        play_interval=_with_rivals(final.play_interval, candidates, cand.validation_nrmse),
        fit_nrmse=nrmse(yc[kept], simulated[kept]),
        validation_nrmse=per_structure,
        margin=place_margin(per_structure, model.structure),
        params=model.params(),
        simulated=simulated + centre,
        reasons=_noticed(model, quantum(yc[kept])),
        dead_time_samples=(
            search.dead_time_samples if inside is None else _dead_time_samples(inside, uc[kept], yc[kept])
        ),
        stall_band=stall_band(max(model.fs, model.fc), model.kv, model.kp),
        model=model,
        candidates=tuple(candidates),
        seconds=time.perf_counter() - t0,
        evaluations=search.evaluations + cand.evaluations + final.evaluations,
    )
    return choice, Refined(cand, search, True)
