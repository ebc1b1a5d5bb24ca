"""The live answer's horn stage on the whole record (``refine_online``'s step 5): its gate, without fits."""

from __future__ import annotations

import dataclasses
import math
import threading
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

from servoid.ident.models.structure_names import OUTPUT_BACKLASH, PLAY_IN_LOOP
from servoid.ident.online import refinement

RATE = 200.0


def test_the_slow_parts_turn_acceleration_is_the_sines_peak_acceleration() -> None:
    t = np.arange(int(3 * RATE)) / RATE
    for amplitude, hz in ((0.1, 0.9), (0.05, 2.3)):
        u = amplitude * np.sin(2 * math.pi * hz * t + 0.3)
        assert refinement._turn_accel(u, 1 / RATE) == pytest.approx(amplitude * (2 * math.pi * hz) ** 2, rel=0.01)
    # sent in counts (4096 a turn), the top count held for several samples: the parabola through the turn reads it
    t = np.arange(int(6 * RATE)) / RATE
    for amplitude, hz in ((0.1, 0.3), (0.1, 0.9)):
        u = np.round(amplitude * np.sin(2 * math.pi * hz * t + 0.3) / (2 * math.pi / 4096)) * (2 * math.pi / 4096)
        assert refinement._turn_accel(u, 1 / RATE) == pytest.approx(amplitude * (2 * math.pi * hz) ** 2, rel=0.25)
    # a ramp has no reversal
    assert refinement._turn_accel(np.linspace(0.0, 1.0, 50), 1 / RATE) == 0.0


def _gate(monkeypatch: Any, *, named: bool = True, place: str = PLAY_IN_LOOP, kept: bool = True, al: float = 20.0,
          gaps: bool = False) -> tuple[str, Any, list[tuple[str, int]]]:  # fmt: skip
    """``_horn_on_whole`` on a slow part of 3 rad/s^2 turns, the search, the stage and the rebound replaced.

    The calls are returned as (which, readings it was told were lost): the rebound's, the search's, the stage's.
    """
    t = np.arange(int(6 * RATE)) / RATE
    hz = math.sqrt(3.0 / 0.1) / (2 * math.pi)  # 0.1 rad turning at 3 rad/s^2
    head = t.size // 2
    u = 0.1 * np.sin(2 * math.pi * hz * t)
    u[head:] = 0.1 * np.sin(4 * 2 * math.pi * hz * t[head:])  # a fast part 16x harder: not read by the rule
    keep = np.ones(u.size, dtype=bool)
    if gaps:
        keep[head + 5] = False
    calls: list[tuple[str, int]] = []
    whole = SimpleNamespace(structure=place, play=0.009)
    horn = SimpleNamespace(play=0.0105, model=SimpleNamespace(compliant=True, al=al))

    def search(u_arr: np.ndarray, *args: Any, keep: np.ndarray, load: Any) -> Any:
        assert load is False  # the massless search: its load stage could only move the place outside
        calls.append(("search", u_arr.size - int(np.sum(keep))))
        return whole

    def stage(*args: Any) -> Any:
        calls.append(("stage", args[0].size - int(np.sum(args[4]))))
        return horn if kept else whole

    def named_on(*args: Any, valid: np.ndarray) -> Any:
        calls.append(("rebound", valid.size - int(np.sum(valid))))
        return SimpleNamespace(named=named)

    monkeypatch.setattr(refinement, "fit_loop", search)
    monkeypatch.setattr(refinement, "with_horn", stage)
    monkeypatch.setattr(refinement, "rebound", named_on)
    fast = SimpleNamespace(model=SimpleNamespace(sample_period_s=1 / RATE), simulated=u[head:], play=0.008)
    note, found = refinement._horn_on_whole(u, u, keep, head, fast)  # type: ignore[arg-type]
    return note, found, calls


def test_the_horn_answers_where_its_friction_stops_the_load_faster_than_the_slow_part_turns(monkeypatch) -> None:
    note, found, calls = _gate(monkeypatch, al=20.0)
    assert found is not None and found.play == 0.0105 and note.startswith("answered")
    assert calls == [("rebound", 0), ("search", 0), ("stage", 0)]
    # the load's friction no stronger than the slow part's turns (3 rad/s^2): the slow part may hide the play too
    note, found, _ = _gate(monkeypatch, al=2.5)
    assert found is None and note.startswith("not taken") and "2.5" in note


def test_a_record_with_gaps_is_fitted_through_them(monkeypatch) -> None:
    # a lost reading (a real clock's records have 1.7-7 %): the rebound, the search and the stage are each told of it
    note, found, calls = _gate(monkeypatch, gaps=True)
    assert found is not None and note.startswith("answered")
    assert calls == [("rebound", 1), ("search", 1), ("stage", 1)]


@pytest.mark.parametrize(
    ("given", "searched", "says"),
    [
        ({"named": False}, False, "no rebound"),
        ({"place": OUTPUT_BACKLASH}, True, "output_backlash"),
        ({"kept": False}, True, "not kept"),
    ],
)
def test_the_fast_answer_stands_where_the_stage_does_not_apply(monkeypatch, given, searched, says) -> None:
    note, found, calls = _gate(monkeypatch, **given)
    assert found is None and says in note and any(c[0] == "search" for c in calls) == searched


@pytest.mark.parametrize("late", [False, True])
def test_the_step_is_stopped_at_the_deadline_and_the_fast_answer_stands(monkeypatch, late: bool) -> None:
    import time

    from servoid.ident.models.servo_loop import ServoLoopModel
    from servoid.ident.offline import _threads
    from servoid.ident.offline.loop_fit import LoopCandidate, LoopChoice
    from servoid.ident.online.window import WindowConfig, WindowResult

    model = ServoLoopModel(PLAY_IN_LOOP, 1 / RATE, kp=12.0, kv=60.0, c1=0.005, c2=0.005)
    u = 0.1 * np.sin(2 * math.pi * 0.8 * np.arange(800) / RATE)
    y = model.simulate(u, y0=0.0)
    fast = LoopChoice(structure=PLAY_IN_LOOP, play=model.play, play_interval=(0.009, 0.011), fit_nrmse=0.01,
                      validation_nrmse={PLAY_IN_LOOP: 0.01}, margin=0.1, params=model.params(), simulated=y[400:],
                      reasons=(), dead_time_samples=2.0, stall_band=0.0, model=model, candidates=(), seconds=2.0,
                      evaluations=1)  # fmt: skip
    refined = refinement.Refined(LoopCandidate(PLAY_IN_LOOP, False, model, 0.01, 0.01, 1), fast, False)
    monkeypatch.setattr(refinement, "_refine_fast", lambda *args: (fast, refined))
    horn = dataclasses.replace(fast, play=0.0105)
    threads: list[str] = []

    def step(*args: Any) -> Any:
        # a search that evaluates its cost every 10 ms for 0.2 s, on this thread and on the pool's helper
        threads.append(threading.current_thread().name)
        for _ in range(20 if not late else 10**6):
            _threads.each(lambda i: (time.sleep(0.005), _threads.check()), 2)
        return "answered", horn

    monkeypatch.setattr(refinement, "_horn_on_whole", step)
    monkeypatch.setenv(_threads.ENV, "2")
    online = WindowResult(model, (), WindowConfig(1 / RATE), dropped=0, stall_s=0.0)
    before = {t.ident for t in threading.enumerate()}
    began = time.perf_counter()
    choice, out = refinement.refine_online(u, y, online, slow=400, deadline_s=began + (5.0 if not late else 0.3))
    took = time.perf_counter() - began
    assert threads == [threading.main_thread().name]  # run here: nothing left behind to run on
    assert choice.play == (fast.play if late else 0.0105)
    assert (out.horn or "").startswith("skipped: stopped at the wall budget's deadline") == late
    assert bool(out.cut) == late and not choice.reasons  # the fast answer stands, as when the step does not apply
    if late:
        assert took < 1.0  # stopped at its next evaluation, not at its end
    assert not _threads._open  # no batch left open
    assert {t.ident for t in threading.enumerate() if t.name.startswith("servoid-ahead")} <= before
    # no time left: stopped at once; no deadline (a virtual clock): run here to its end
    threads.clear()
    _, out = refinement.refine_online(u, y, online, slow=400, deadline_s=time.perf_counter() - 1.0)
    assert threads == [] and (out.horn or "").startswith("skipped")
    if not late:
        choice, out = refinement.refine_online(u, y, online, slow=400)
        assert threads == [threading.main_thread().name] and choice.play == 0.0105 and out.cut == ()


def test_a_cut_search_leaves_the_online_estimate_as_the_answer_and_says_so(monkeypatch) -> None:
    import time

    from servoid.ident.models.servo_loop import ServoLoopModel
    from servoid.ident.offline import _threads
    from servoid.ident.online.window import WindowConfig, WindowResult

    model = ServoLoopModel(OUTPUT_BACKLASH, 1 / RATE, kp=12.0, kv=60.0, c1=0.005, c2=0.005)
    u = 0.1 * np.sin(2 * math.pi * 0.8 * np.arange(600) / RATE)
    y = model.simulate(u, y0=0.0)

    def search(*args: Any, **kwargs: Any) -> Any:
        while True:  # a search that ends only when stopped
            time.sleep(0.005)
            _threads.check()

    monkeypatch.setattr(refinement, "fit_loop", search)
    online = WindowResult(model, (), WindowConfig(1 / RATE), dropped=0, stall_s=0.0)
    choice, out = refinement.refine_online(u, y, online, deadline_s=time.perf_counter() + 0.2)
    assert choice.model is model and choice.play == model.play
    assert not all(math.isfinite(v) for v in choice.play_interval)  # no interval: not validated against any search
    assert choice.reasons[0].startswith(refinement.CUT) and "online estimate" in choice.reasons[0]
    assert out.cut and out.cut[0].startswith("the search on the fast part")
    # no online model to answer with: the stop reaches the caller
    empty = WindowResult(None, (), WindowConfig(1 / RATE), dropped=0, stall_s=0.0)
    with pytest.raises(_threads.Stopped):
        refinement.refine_online(u, y, empty, deadline_s=time.perf_counter() + 0.1)


def test_an_answer_whose_search_was_cut_is_said_to_be_the_online_estimate_not_validated() -> None:
    from servoid.cli._live import answer

    loop = object()
    refined = {"online_won": True, "cut": ["the search on the fast part (stopped ...): the online estimate answers"]}
    record = SimpleNamespace(output_unit="rad", loop=loop, live={"online_loop": {"refined": refined}})
    result = SimpleNamespace(loop=loop, play=0.004, structure=PLAY_IN_LOOP, form="servo_loop")
    said = answer(record, result, {"online_gap": 0.004, "estimator": "window", "settled": False})
    assert said["source"] == "loop_online_cut" and "cut by the wall budget" in said["line"]
    assert "not validated" in said["line"] and "won" not in said["line"]
    refined["cut"] = []
    assert answer(record, result, {"online_gap": 0.004, "estimator": "window"})["source"] == "loop_online"
