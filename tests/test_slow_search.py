"""The slow phase searched once, on a thread from its end: handed to the windows and the answer."""

from __future__ import annotations

import dataclasses

import numpy as np
from test_window import RATE, TRUTH, _record, _two_phase

from servoid.ident.online.early_search import EarlySearch
from servoid.ident.online.window import SLOW, WindowConfig, WindowRefit, WindowResult

CONFIG = WindowConfig(1 / RATE, window_s=10.0, every_s=5.0, first_s=5.0)


def _counted(monkeypatch) -> list[int]:
    """Every ``fit_loop`` call's sample count (the windows, the early searches and the refinement import it late)."""
    from servoid.ident.offline import loop_fit
    from servoid.ident.online import refinement

    calls: list[int] = []
    fit = loop_fit.fit_loop

    def counted(u, *args, **kwargs):
        calls.append(np.asarray(u).size)
        return fit(u, *args, **kwargs)

    monkeypatch.setattr(loop_fit, "fit_loop", counted)
    monkeypatch.setattr(refinement, "fit_loop", counted)
    return calls


def test_the_windows_and_the_answer_take_the_slow_phase_search_run_from_its_end(monkeypatch) -> None:
    from servoid.ident.online import refinement
    from servoid.ident.online.refinement import refine_online

    u, y, slow, outside, _ = _two_phase(15.0, seed=7)  # short: the hand-over, not the play's accuracy
    calls = _counted(monkeypatch)
    search = EarlySearch(1 / RATE, slow, hold=True)  # fed first, as the session feeds it
    est = WindowRefit(CONFIG, start=dataclasses.replace(outside, kp=10.0), wait=True, slow=slow, slow_early=search)
    first = slow + CONFIG.samples(CONFIG.first_s)
    for ui, yi in zip(u[:first], y[:first], strict=True):
        search.update(ui, yi)
        est.update(ui, yi)
    assert search.ready and not search.started and calls == []  # held: no window has named the place yet
    for ui, yi in zip(u[first:], y[first:], strict=True):
        search.update(ui, yi)
        est.update(ui, yi)
    result = est.result()
    assert calls == [slow]  # the slow phase searched once, on its own thread, not again on the window's worker
    assert result.slow_search is search.result() and [r.part for r in result.history] == ["last", SLOW]
    calls.clear()
    # the answer asks for it only where the windows have not run it, and searches the fast part alone
    fast = []
    refine_fast = refinement._refine_fast
    monkeypatch.setattr(refinement, "_refine_fast", lambda *a: fast.append(refine_fast(*a)) or fast[-1])
    bare = WindowResult(outside, (), CONFIG, dropped=0, stall_s=0.0)
    asked: list[bool] = []
    choice, refined = refine_online(u, y, bare, slow=slow, slow_search=lambda: asked.append(True) or search.result())
    assert asked == [True] and calls == [u.size - slow]
    held = EarlySearch(1 / RATE, slow, hold=True)  # never asked for by a window: started by the refinement
    for ui, yi in zip(u[:slow], y[:slow], strict=True):
        held.update(ui, yi)
    assert not held.started and held.searched(wait=True) is not None and calls == [u.size - slow, slow]
    calls.clear()
    assert refined.fast_play is not None and choice.play == search.result().choice.play  # type: ignore[union-attr]
    # the fast part starting with unusable samples (the refinement's slow part runs to its first usable one): the
    # windows' search of the slow phase alone is the same search, not run again (the fast part's answer as above)
    keep = np.ones(u.size, dtype=bool)
    keep[slow : slow + 2] = False
    monkeypatch.setattr(refinement, "_refine_fast", lambda *a: fast[0])
    choice, refined = refine_online(u, y, result, keep=keep, slow=slow)
    assert calls == [] and refined.fast_play is not None
    assert choice.play == result.slow_search.choice.play  # type: ignore[union-attr]


def test_with_no_online_model_the_search_answers_alone_and_the_verdict_says_why(monkeypatch) -> None:
    # a loaded real clock: no window refit ended before the run did; the answer is still the servo-loop search (before:
    # no loop answer, and identification searched the record itself after the run)
    from types import SimpleNamespace

    from servoid.cli import _live
    from servoid.ident.online import refinement

    u, y = _record(8.0, seed=5)
    bare = WindowResult(None, (), CONFIG, dropped=3, stall_s=0.0, end_s=8.0)
    choice, refined = refinement.refine_online(u, y, bare)
    assert refined.online is None and not refined.online_won and choice.play == refined.search.play
    assert refined.to_dict()["online_candidate"] is None and abs(choice.play / TRUTH.play - 1) < 0.1
    monkeypatch.setattr(refinement, "refine_online", lambda *args, **kwargs: (choice, refined))
    session = SimpleNamespace(u=u, y=y, valid=np.ones(u.size, dtype=bool))
    out, loop = _live.loop_online(bare, session)  # type: ignore[arg-type]
    verdict = out["verdict"]
    assert loop is choice and not verdict["settled"] and "0 window refit(s)" in verdict["reasons"][0]
    assert verdict["refined_gap"] == choice.play and out["refined"]["online_won"] is False
