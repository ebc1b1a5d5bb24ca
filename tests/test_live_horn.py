"""The live answer's horn stage on the whole record (``refine_online``'s step 5): its gate, without fits."""

from __future__ import annotations

import math
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
    # a ramp has no reversal
    assert refinement._turn_accel(np.linspace(0.0, 1.0, 50), 1 / RATE) == 0.0


def _gate(monkeypatch: Any, *, named: bool = True, place: str = PLAY_IN_LOOP, kept: bool = True, al: float = 20.0,
          gaps: bool = False) -> tuple[str, Any, list[int]]:  # fmt: skip
    """``_horn_on_whole`` on a slow part of 3 rad/s^2 turns, the search, the stage and the rebound replaced."""
    t = np.arange(int(6 * RATE)) / RATE
    hz = math.sqrt(3.0 / 0.1) / (2 * math.pi)  # 0.1 rad turning at 3 rad/s^2
    head = t.size // 2
    u = 0.1 * np.sin(2 * math.pi * hz * t)
    u[head:] = 0.1 * np.sin(4 * 2 * math.pi * hz * t[head:])  # a fast part 16x harder: not read by the rule
    keep = np.ones(u.size, dtype=bool)
    if gaps:
        keep[head + 5] = False
    calls: list[int] = []
    whole = SimpleNamespace(structure=place, play=0.009)
    horn = SimpleNamespace(play=0.0105, model=SimpleNamespace(compliant=True, al=al))

    def search(u_arr: np.ndarray, *args: Any, **kwargs: Any) -> Any:
        calls.append(u_arr.size)
        return whole

    monkeypatch.setattr(refinement, "fit_loop", search)
    monkeypatch.setattr(refinement, "with_horn", lambda *args: horn if kept else whole)
    monkeypatch.setattr(refinement, "rebound", lambda *args, **kwargs: SimpleNamespace(named=named))
    fast = SimpleNamespace(model=SimpleNamespace(sample_period_s=1 / RATE), simulated=u[head:], play=0.008)
    note, found = refinement._horn_on_whole(u, u, keep, head, fast)  # type: ignore[arg-type]
    return note, found, calls


def test_the_horn_answers_where_its_friction_stops_the_load_faster_than_the_slow_part_turns(monkeypatch) -> None:
    note, found, calls = _gate(monkeypatch, al=20.0)
    assert found is not None and found.play == 0.0105 and note.startswith("answered") and calls == [1200]
    # the load's friction no stronger than the slow part's turns (3 rad/s^2): the slow part may hide the play too
    note, found, _ = _gate(monkeypatch, al=2.5)
    assert found is None and note.startswith("not taken") and "2.5" in note


@pytest.mark.parametrize(
    ("given", "searched", "says"),
    [
        ({"gaps": True}, False, "gaps"),
        ({"named": False}, False, "no rebound"),
        ({"place": OUTPUT_BACKLASH}, True, "output_backlash"),
        ({"kept": False}, True, "not kept"),
    ],
)
def test_the_fast_answer_stands_where_the_stage_does_not_apply(monkeypatch, given, searched, says) -> None:
    note, found, calls = _gate(monkeypatch, **given)
    assert found is None and says in note and bool(calls) == searched


@pytest.mark.parametrize("late", [False, True])
def test_the_step_is_skipped_when_it_cannot_end_by_the_deadline(monkeypatch, late: bool) -> None:
    import time

    from servoid.ident.models.servo_loop import ServoLoopModel
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
    calls: list[int] = []
    monkeypatch.setattr(refinement, "_horn_on_whole", lambda *args: calls.append(1) or ("not kept", None))
    online = WindowResult(model, (), WindowConfig(1 / RATE), dropped=0, stall_s=0.0)
    # the search took 2 s: the step is predicted at HORN_PER_SEARCH times that
    deadline = time.perf_counter() + (1.0 if late else 10.0) * refinement.HORN_PER_SEARCH * fast.seconds
    choice, out = refinement.refine_online(u, y, online, slow=400, deadline_s=deadline)
    assert choice.play == fast.play and bool(calls) != late
    assert (out.horn or "").startswith("skipped") == late
