"""The live answer's search started before the run ends: what it covers, when it starts, how the answer takes it."""

from __future__ import annotations

import dataclasses
import os
import threading
import time
from types import SimpleNamespace

import numpy as np
import pytest
from test_window import RATE, TRUTH, _record

from servoid.errors import ConfigError
from servoid.excitation.generate import sample
from servoid.excitation.specs import GentleSpec
from servoid.ident.models.servo_loop import ServoLoopModel
from servoid.ident.models.structure_names import OUTPUT_BACKLASH, PLAY_IN_LOOP
from servoid.ident.offline.intervals import MIN_STRUCTURE_MARGIN
from servoid.ident.online import early_search
from servoid.ident.online.early_search import (
    HEAD_LATE_S,
    HEAD_SHARE,
    TAKE_FIRST,
    EarlySearch,
    full_in_time,
    head_samples,
)
from servoid.ident.online.window import SlowSearch, WindowConfig, WindowRefit, WindowResult


def _feed(est: EarlySearch, u: np.ndarray, y: np.ndarray, keep: np.ndarray) -> None:
    for ui, yi, k in zip(u, y, keep, strict=True):
        if k:
            est.update(ui, yi)
        else:
            est.skip(ui)


def test_the_head_is_a_share_of_the_run_after_the_slow_phase() -> None:
    assert head_samples(9000, 3000) == int(HEAD_SHARE * 6000)
    assert head_samples(9000, 0, share=0.5) == 4500
    assert head_samples(10, 10) == 1  # nothing after the slow phase: never reached by a run of 10
    with pytest.raises(ConfigError, match="share"):
        head_samples(9000, 3000, share=0.0)


def test_the_search_starts_at_its_sample_on_the_fast_part_so_far_and_is_the_offline_search_of_it(monkeypatch) -> None:
    from servoid.ident.offline import loop_fit

    u, y = _record(16.0, seed=3)
    keep = np.random.default_rng(4).random(u.size) > 0.05
    slow, at = 400, 800
    keep[slow : slow + 3] = False  # the fast part starts with lost readings: the search starts at a measured one
    y[~keep] = np.nan
    searched: list[tuple[int, float]] = []
    gate = threading.Event()
    fit = loop_fit.fit_loop

    def gated(u_: np.ndarray, y_: np.ndarray, *args, **kwargs):
        searched.append((u_.size, float(u_[0])))
        gate.wait(10.0)  # held until the test lets it go: the run goes on meanwhile
        return fit(u_, y_, *args, **kwargs)

    monkeypatch.setattr(loop_fit, "fit_loop", gated)
    est = EarlySearch(1 / RATE, at, skip=slow)
    _feed(est, u[: slow + at - 1], y[: slow + at - 1], keep[: slow + at - 1])
    assert not est.started  # one sample short
    _feed(est, u[slow + at - 1 :], y[slow + at - 1 :], keep[slow + at - 1 :])  # the rest of the run
    assert est.started and est.result(wait=False) is None  # still searching: an interrupted run would not wait
    assert est.searched(wait=False) is None  # nor does a window's look on a real clock
    gate.set()
    found = est.searched(wait=True)  # a look on a virtual clock waits for it
    assert found is not None and est.error is None and est.result() is found
    assert (found.start, found.samples) == (3, at - 3) and searched == [(at - 3, u[slow + 3])]
    again = fit(u[slow + 3 : slow + at], y[slow + 3 : slow + at], 1 / RATE, keep=keep[slow + 3 : slow + at], load=None)
    assert found.choice.play == again.play and found.choice.structure == again.structure


def test_a_run_that_ends_before_its_start_or_with_too_few_readings_has_no_search(monkeypatch) -> None:
    from servoid.ident.online import early_search

    monkeypatch.setattr(early_search, "BEGIN_WAIT_S", 0.01)
    u, y = _record(4.0, seed=5)
    short = EarlySearch(1 / RATE, u.size + 1)
    _feed(short, u, y, np.ones(u.size, dtype=bool))
    assert not short.started and short.result() is None and short.searched(wait=True) is None
    lost = EarlySearch(1 / RATE, 300)
    _feed(lost, u, y, np.arange(u.size) % 4 == 0)  # 75 usable of 300
    assert not lost.started and lost.result() is None and "usable samples" in (lost.error or "")


def test_the_answer_takes_the_head_search_and_refits_it_on_the_whole_fast_part(monkeypatch) -> None:
    from servoid.ident.offline.loop_fit import fit_loop
    from servoid.ident.online import refinement

    u, y = _record(24.0, seed=6)
    slow, m = 600, 1200  # a slow phase, then the head the early search covered, then the run's tail
    online = WindowResult(dataclasses.replace(TRUTH, kp=10.0), (), WindowConfig(1 / RATE), dropped=0, stall_s=0.0)
    head = fit_loop(u[slow : slow + m], y[slow : slow + m], 1 / RATE, load=None)
    calls: list[int] = []
    fit = refinement.fit_loop

    def counted(*args, **kwargs):
        calls.append(args[0].size)
        return fit(*args, **kwargs)

    monkeypatch.setattr(refinement, "fit_loop", counted)
    choice, refined = refinement.refine_online(u, y, online, slow=slow, early=SlowSearch(head, slow, m))
    assert calls == []  # neither part searched again: the head's search, and inside the loop no slow-part search
    assert refined.search is head and choice.structure == head.structure == PLAY_IN_LOOP
    assert choice.margin == pytest.approx(refinement.place_margin(choice.validation_nrmse, PLAY_IN_LOOP))
    # the answer is the head's refitted on every sample of the fast part: its fit and simulation are the whole part's
    assert refined.scored == (slow, u.size) and choice.simulated.size == u.size
    assert refined.score(choice.model, u, y) == pytest.approx(choice.fit_nrmse, rel=1e-9)
    assert abs(choice.play / TRUTH.play - 1) < 0.03
    low, high = choice.play_interval
    assert low <= min(choice.play, head.play_interval[0]) and high >= head.play_interval[1]  # never narrower
    # a search that does not start at the fast part's first sample is not of this record's head: searched afresh
    choice2, _ = refinement.refine_online(u, y, online, slow=slow, early=SlowSearch(head, slow + 1, m))
    assert calls == [u.size - slow] and choice2.structure == PLAY_IN_LOOP


def _args(**given):
    import argparse

    base = {"samples": None, "seconds": None, "rate": 200.0, "excitation": None, "amplitude": None, "seed": 0,
            "driver": "sim://xm430"}  # fmt: skip
    return argparse.Namespace(**{**base, **given})


def test_a_designed_live_run_lasts_the_default_servo_seconds_unless_told_and_says_why() -> None:
    from servoid.cli import _live
    from servoid.drivers.base import Limits

    spec, slow = "gentle:amplitude=0.1,accel=0.0001", ("gentle:amplitude=0.1,accel=0.00002", 1 / 3)
    u, first = _live.excitation(_args(), 0.1, Limits(), designed=spec, slow=slow)
    assert u.size == round(_live.DEFAULT_LIVE_S * 200.0) and 0 < first <= u.size // 3
    assert "the default" in _live.length_note(_args(), u.size, spec)
    told = _live.with_length(_args(seconds=12.5))
    assert told.samples == 2500 and told.seconds is None
    u, _ = _live.excitation(told, 0.1, Limits(), designed=spec, slow=slow)
    assert u.size == 2500 and "default" not in _live.length_note(told, u.size, spec)
    assert _live.with_length(_args(samples=300)).samples == 300
    for given, fragment in (({"seconds": 5.0, "samples": 10}, "not both"), ({"seconds": 5.0, "driver": None}, "live"),
                            ({"seconds": -1.0}, "> 0")):  # fmt: skip
        with pytest.raises(ConfigError, match=fragment):
            _live.with_length(_args(**given))


def test_identify_help_names_the_default_length_and_why(capsys) -> None:
    from servoid.cli import _live
    from servoid.cli import main as servoid_main

    with pytest.raises(SystemExit):
        servoid_main(["identify", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert f"{_live.DEFAULT_LIVE_S:g} s, {_live.DEFAULT_LIVE_WHY}" in text and "--seconds S" in text


def test_the_slow_phase_holds_enough_reversals_and_a_default_run_keeps_its_fast_part() -> None:
    from servoid.cli import _live
    from servoid.drivers.base import Limits
    from servoid.excitation import parse_spec, sample
    from servoid.excitation.gentle import whole_segments
    from servoid.ident.offline.intervals import reversal_indices

    # a slow loop's design (the ODrive twin's, at 200 Hz): long segments, few reversals in a third of 40 s
    slow_text = "gentle:amplitude=0.05,accel=2.7758e-05"
    spec, slow_spec = "gentle:amplitude=0.05,accel=0.000151", parse_spec(slow_text)
    share = int(_live.DEFAULT_LIVE_S * 200.0 / 3)

    def turns(u: np.ndarray) -> int:
        return int(reversal_indices(u, 0.1 * 0.05).size)

    cut = whole_segments(slow_spec, 1, share)
    assert turns(sample(slow_spec, cut, seed=1)) < _live.SLOW_REVERSALS  # the share alone: too few
    u, first = _live.excitation(_args(seed=1), 0.05, Limits(), designed=spec, slow=(slow_text, 1 / 3))
    assert first > share and turns(u[:first]) >= _live.SLOW_REVERSALS
    assert first == whole_segments(slow_spec, 1, first)  # at a segment's end: no step into the fast phase
    assert u.size - first == round(_live.DEFAULT_LIVE_S * 200.0) - share  # the fast part as long as before
    told, first_told = _live.excitation(_args(seed=1, samples=8000), 0.05, Limits(), designed=spec,
                                        slow=(slow_text, 1 / 3))  # fmt: skip
    assert told.size == 8000 and first_told == first  # a length the user gave stays; the fast part gives way


#: A heavy load behind a play outside the loop (the CiA 402 and ODrive twins' kind): a massless fit ties the places.
HEAVY = ServoLoopModel(
    OUTPUT_BACKLASH, 1 / RATE, kp=12.0, kv=60.0, fc=0.3, fs=0.45, vs=0.05, veps=0.005, c1=0.01, c2=0.01, mu=1.0, al=2.0
)


def _heavy_record(n: int = 1200) -> tuple[np.ndarray, np.ndarray]:
    u = sample(GentleSpec(amplitude=0.1, accel=8.0 / RATE**2, spread=8.0), n, seed=7)
    return u, HEAVY.simulate(u, y0=0.0) + 1e-4 * np.random.default_rng(7).standard_normal(n)


def test_a_slow_machine_searches_the_head_warm_from_the_first_windows_load() -> None:
    u, y = _heavy_record()
    # the first window's search found a load elsewhere in its basin (a shorter window) and took 100 s: on a real clock
    # the head's full search would end long after the run
    first = dataclasses.replace(HEAVY, c1=0.008, c2=0.008, mu=0.6, al=3.0, kv=50.0)
    est = EarlySearch(1 / RATE, u.size, end=u.size + 400)
    est.offer(first, 100.0, 600)
    _feed(est, u, y, np.ones(u.size, dtype=bool))
    found = est.result(wait=True)
    assert found is not None and est.warm and est.error is None
    assert found.choice.structure == OUTPUT_BACKLASH and found.choice.model.massive
    assert found.choice.margin >= MIN_STRUCTURE_MARGIN  # the massless fit alone ties the places here
    assert abs(found.choice.play / HEAVY.play - 1) < 0.1


@pytest.mark.parametrize(
    ("end", "offered", "seconds", "loads"),
    [
        (0, "heavy", 100.0, [None]),  # a virtual clock: always the full search
        (1600, "heavy", 0.1, [None]),  # a fast machine: the full search ends in time
        (1600, "inside", 100.0, [None]),  # the first window found no load outside the loop: the grid runs here
        (1600, None, 0.0, [None]),  # no first window by the head's end, then none (released): in full, nothing before
    ],
)
def test_the_head_is_searched_in_full_unless_a_slow_machine_has_the_first_windows_load(
    monkeypatch, end: int, offered: str | None, seconds: float, loads: list[bool | None]
) -> None:
    from servoid.ident.offline import loop_fit

    calls: list[bool | None] = []

    def recorded(u_: np.ndarray, y_: np.ndarray, *args, load: bool | None = False, **kwargs):
        calls.append(load)
        return "massless" if load is False else "full"

    monkeypatch.setattr(loop_fit, "fit_loop", recorded)
    u, y = _heavy_record(300)
    est = EarlySearch(1 / RATE, u.size, end=end)
    if offered is not None:
        est.offer(HEAVY if offered == "heavy" else dataclasses.replace(HEAVY, structure=PLAY_IN_LOOP), seconds, 200)
    _feed(est, u, y, np.ones(u.size, dtype=bool))
    if offered is None:
        time.sleep(0.05)
        assert est.result(wait=False) is None  # waiting for the first window, which the stream's end releases
        est.release()
    found = est.result(wait=True)
    assert found is not None and found.choice == "full" and calls == loads and not est.warm


def test_the_head_is_predicted_in_time_from_the_first_windows_search() -> None:
    assert full_in_time(4.0, 2000, 4000, left_s=7.0)  # 8 s predicted, 7 + HEAD_LATE_S left
    assert not full_in_time(15.0, 2000, 4000, left_s=7.0)
    assert full_in_time(15.0, 2000, 4000, left_s=30.0 - HEAD_LATE_S)


def test_the_window_offers_its_first_search_to_the_head_or_releases_it_at_the_end() -> None:
    u, y = _record(16.0, seed=3)
    est = EarlySearch(1 / RATE, u.size + 1, end=u.size)  # never reached: only the offer is looked at
    refit = WindowRefit(WindowConfig(1 / RATE, first_s=10.0), background=False, early=est)
    for ui, yi in zip(u, y, strict=True):
        refit.update(ui, yi)
    rows = refit.rows()
    assert est._first is not None and rows[0].searched
    model, seconds, samples = est._first
    assert 0.0 < seconds <= rows[0].seconds and samples == 1000 and model.structure == rows[0].structure
    # no first window's search (a run shorter than it): released at the stream's end, the head's search runs in full
    none = EarlySearch(1 / RATE, u.size + 1, end=u.size)
    short = WindowRefit(WindowConfig(1 / RATE, first_s=10.0), background=False, early=none)
    for ui, yi in zip(u[:500], y[:500], strict=True):
        short.update(ui, yi)
    assert not none._offered.is_set()
    short.result()
    assert none._offered.is_set() and none._first is None


def test_the_first_windows_search_starts_the_slow_phases_search_where_it_names_the_play_outside() -> None:
    began: list[bool] = []

    class Held:  # the slow phase's held search: only whether it is started matters here
        def begin(self) -> None:
            began.append(True)

    refit = WindowRefit(WindowConfig(1 / RATE), background=False, slow=100, slow_early=Held())
    tied = SimpleNamespace(structure=OUTPUT_BACKLASH, margin=0.5 * MIN_STRUCTURE_MARGIN, model=HEAVY)
    refit._first_searched(tied, 1.0, 1000)
    refit._first_searched(SimpleNamespace(structure=PLAY_IN_LOOP, margin=1.0, model=HEAVY), 1.0, 1000)
    assert began == []  # the place not named outside the loop: the slow phase may never be needed
    refit._first_searched(
        SimpleNamespace(structure=OUTPUT_BACKLASH, margin=2 * MIN_STRUCTURE_MARGIN, model=HEAVY), 1.0, 1000
    )
    assert began == [True]


def test_a_search_past_its_wall_budget_is_stopped_and_leaves_no_result_and_no_thread() -> None:
    from servoid.ident.offline import _threads

    u, y = _record(6.0, seed=5)
    stop = _threads.Stop(time.perf_counter() - 1.0, "the wall budget")  # already past: stopped at its first evaluation
    est = EarlySearch(1 / RATE, 600, stop=stop)
    _feed(est, u, y, np.ones(u.size, dtype=bool))
    assert est.started
    t0 = time.perf_counter()
    assert est.result(wait=True) is None and time.perf_counter() - t0 < 5.0
    assert est.cut and "cut" in (est.error or "") and stop.fired
    assert est._thread is not None and not est._thread.is_alive()


def test_a_head_waiting_for_the_first_windows_offer_is_cut_at_its_wall_budget(monkeypatch) -> None:
    # the head's samples have all come before the first window's search ended (a slow machine): the head's massless
    # search runs, then it waits for that search's offer; if none ever comes (a way out of the window refit that
    # neither offers nor releases), the wall budget must cut the wait as it cuts a search, not leave it waiting
    from servoid.ident.offline import _threads, loop_fit

    stop = _threads.Stop(time.perf_counter() - 1.0, "the wall budget")  # past: only a wait that looks at it ends
    calls: list[bool | None] = []

    def unstoppable(u_: np.ndarray, y_: np.ndarray, *args, load: bool | None = False, **kwargs):
        calls.append(load)  # (a fit that never looks at the stop: only the wait can be cut)
        return "massless"

    monkeypatch.setattr(loop_fit, "fit_loop", unstoppable)
    u, y = _heavy_record(300)
    est = EarlySearch(1 / RATE, u.size, end=u.size, stop=stop)
    _feed(est, u, y, np.ones(u.size, dtype=bool))
    assert est._thread is not None
    est._thread.join(30.0)  # a guard against the hang, not a timing: the cut search ends at once
    assert not est._thread.is_alive() and est.cut and "cut" in (est.error or "")
    assert calls == ([] if TAKE_FIRST else [False]) and est.result(wait=True) is None and not est._offered.is_set()


@pytest.mark.parametrize("offered", [True, False])
def test_a_slow_machines_head_takes_the_first_windows_search_instead_of_searching(monkeypatch, offered: bool) -> None:
    # the head's samples have all come before the first window's search ended: the head waits for it and takes it
    # (its choice and its samples) without a search of its own; released with none, the head's own search runs
    from servoid.ident.offline import loop_fit

    calls: list[bool | None] = []

    def recorded(u_: np.ndarray, y_: np.ndarray, *args, load: bool | None = False, **kwargs):
        calls.append(load)
        return "full"

    monkeypatch.setattr(loop_fit, "fit_loop", recorded)
    monkeypatch.setattr(early_search, "TAKE_FIRST", True)
    u, y = _heavy_record(300)
    est = EarlySearch(1 / RATE, u.size, end=u.size)
    _feed(est, u, y, np.ones(u.size, dtype=bool))
    assert est.started and est.result(wait=False) is None  # waiting for the first window's search
    first = SimpleNamespace(structure=OUTPUT_BACKLASH, play=0.01)  # (only handed on: the refinement reads it)
    if offered:
        est.offer(HEAVY, 50.0, 200, first)  # type: ignore[arg-type]
    else:
        est.release()
    found = est.result(wait=True)
    assert found is not None, est.error
    if offered:
        assert found.choice is first and found.samples == 200 and found.start == 0 and est.taken and calls == []
    else:
        assert found.choice == "full" and not est.taken and calls == [None]


def test_warm_up_runs_the_search_once_so_its_kernels_are_loaded_before_the_sampler_starts(monkeypatch) -> None:  # type: ignore[no-untyped-def]
    from servoid.ident.offline import loop_fit

    calls: list[object] = []
    real = loop_fit.fit_loop

    def counted(*args, **kwargs):  # type: ignore[no-untyped-def]
        calls.append(kwargs.get("load", False))
        return real(*args, **kwargs)

    monkeypatch.setattr(loop_fit, "fit_loop", counted)
    EarlySearch(0.005, 4000).warm_up()
    assert calls == [None]  # with the load stage, as the search runs it


@pytest.mark.skipif(not hasattr(os, "getpriority") or os.geteuid() != 0, reason="raising a priority needs root")
def test_a_searchs_thread_yields_to_the_sampler_until_the_run_ends() -> None:
    from servoid.ident.online.window import WORKER_NICENESS

    gate, seen = threading.Event(), []
    est = EarlySearch(1 / RATE, 600)

    def held(*a: object) -> None:
        tid = threading.get_native_id()
        seen.append(os.getpriority(os.PRIO_PROCESS, tid))
        gate.wait(10.0)
        seen.append(os.getpriority(os.PRIO_PROCESS, tid))
        raise RuntimeError("done")  # no search: only the thread's priority matters here

    est._warm = held  # noqa: SLF001
    before = os.getpriority(os.PRIO_PROCESS, threading.get_native_id())
    u, y = _record(6.0, seed=5)
    _feed(est, u, y, np.ones(u.size, dtype=bool))
    while not seen:
        time.sleep(0.01)
    est.full_speed()  # the run has ended
    gate.set()
    assert est.result(wait=True) is None and "failed" in (est.error or "")
    assert seen == [min(19, before + WORKER_NICENESS), before]


@pytest.mark.parametrize("budget", [True, False])
def test_a_first_windows_search_running_at_the_streams_end_carries_on_for_the_head_only_under_a_budget(
    monkeypatch, budget: bool
) -> None:
    from servoid.ident.offline import _threads, loop_fit

    real, entered, gate = loop_fit.fit_loop, threading.Event(), threading.Event()

    def held(*args, **kwargs):  # the window's search is held until the stream has ended (a slow machine's)
        entered.set()
        gate.wait(30.0)
        return real(*args, **kwargs)

    monkeypatch.setattr(loop_fit, "fit_loop", held)
    u, y = _record(10.5, seed=3)
    est = EarlySearch(1 / RATE, u.size + 1, end=u.size)  # never reached: only the offer is looked at
    stop = _threads.Stop(why="the wall budget") if budget else None
    refit = WindowRefit(WindowConfig(1 / RATE, first_s=10.0), wait=False, end=u.size, early=est, budget=stop)
    for ui, yi in zip(u, y, strict=True):
        refit.update(ui, yi)
    assert entered.wait(30.0)  # the worker runs the first window's search
    out = refit.result(final=True, wait=False, wait_s=0.0)  # the search still held: not waited for
    gate.set()
    assert out.model is None and out.abandoned == 1 and out.carried is budget
    assert est._offered.wait(30.0)  # offered as it ended (carried), or released as it was stopped
    if budget:  # carried on: its model offered to the head, its window's warm refit told to stop
        assert est._first is not None and est._first[2] == 1000 and refit._carried is not None
        assert refit._carried.wait(5.0)
    else:  # stopped at the stream's end: nothing offered, the head searches in full
        assert est._first is None
