"""The play-inside-the-loop monitor's pieces: the play-only fit (exact recovery), the CUSUM's threshold and its false-alarm rate."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from servoid.errors import ConfigError
from servoid.excitation.generate import sample
from servoid.excitation.specs import GentleSpec
from servoid.ident.models.servo_loop import ServoLoopModel, simulate_kernel
from servoid.ident.models.structure_names import OUTPUT_BACKLASH, PLAY_IN_LOOP
from servoid.ident.monitoring.alarms import Bound
from servoid.ident.monitoring.cusum import Cusum, correlation_time, false_alarm_checks, threshold
from servoid.ident.monitoring.loop_wear import file_doubt
from servoid.ident.monitoring.play_fit import STEP, SUBSTEP_S, fit_play, fit_substeps

RATE = 200.0
LOOP = ServoLoopModel(PLAY_IN_LOOP, 1 / RATE, kp=12.0, kv=60.0, fc=0.3, fs=0.45, vs=0.05, veps=0.005, c1=0.01, c2=0.01)


@pytest.mark.parametrize("structure", [PLAY_IN_LOOP, OUTPUT_BACKLASH])
@pytest.mark.parametrize("worn", [0.8, 1.27])
def test_the_play_alone_is_recovered_on_a_short_window_of_the_models_own_output(structure: str, worn: float) -> None:
    # the estimator's exact-recovery case: the held loop is the truth, only its play changed
    held = dataclasses.replace(LOOP, structure=structure, c1=0.012, c2=0.008)
    truth = dataclasses.replace(held, c1=held.c1 * worn, c2=held.c2 * worn)
    u = sample(GentleSpec(amplitude=0.1, accel=8.0 / RATE**2, spread=8.0), int(1.6 * RATE), seed=4)
    # the truth simulated as the play fit simulates (its sub-steps: finer than the model's own for a massless load)
    y = np.empty(u.size)
    simulate_kernel(truth.vector(), truth.feedback_load, u - u[0], 0.0, 1 / RATE, fit_substeps(truth), y)
    y += u[0] + 1e-5 * np.random.default_rng(5).standard_normal(u.size)
    score = np.ones(u.size, dtype=bool)
    score[:80] = False  # the burn-in: simulated from rest, not scored
    model, q = fit_play(u, y, score, held)
    assert model.play == pytest.approx(truth.play, rel=STEP)
    assert model.c1 / model.c2 == pytest.approx(1.5) and model.kp == held.kp  # only the play moved
    assert 0.0 <= q < 0.05


def test_the_play_fit_simulates_a_massless_load_on_fine_sub_steps_and_a_massive_one_on_its_own() -> None:
    assert LOOP.substeps == 2 and not LOOP.massive
    assert fit_substeps(LOOP) == math.ceil(LOOP.sample_period_s / SUBSTEP_S)  # 25 at 200 Hz
    fast = dataclasses.replace(LOOP, sample_period_s=SUBSTEP_S / 3)
    assert fit_substeps(fast) == fast.substeps  # already finer: the model's own
    heavy = dataclasses.replace(LOOP, mu=0.5)
    assert heavy.massive and fit_substeps(heavy) == heavy.substeps


def test_the_cusum_threshold_gives_the_false_alarm_rate_it_was_set_for_on_independent_checks() -> None:
    kappa, arl = 1.0, 2000.0
    h = threshold(kappa, arl)
    assert false_alarm_checks(kappa, h) == pytest.approx(arl, rel=1e-6)
    assert threshold(kappa, arl, tau=3.0) > 2.0 * h  # correlated checks: a higher threshold
    assert threshold(5.0, 2.0) == 0.0  # far bound, short run: the plain comparison already does
    # seeded normal checks, the bound kappa sigmas above their mean: restarted at each alarm
    x = np.random.default_rng(7).standard_normal(200_000)
    alarms, s = 0, 0.0
    for xi in x:
        s = max(0.0, s + xi - kappa)
        if s > h:
            alarms, s = alarms + 1, 0.0
    assert 0.5 * x.size / arl < alarms < 1.5 * x.size / arl  # Siegmund's approximation, within its accuracy
    with pytest.raises(ConfigError, match="kappa"):
        threshold(0.0, arl)


def test_the_cusum_raises_after_a_step_past_its_bound_and_clears_when_the_mean_comes_back() -> None:
    sigma = 0.05
    bound = Bound(quantity="dead_zone", low=0.9, high=1.1)
    cusum = Cusum([bound], threshold(0.1 / sigma, 4e4))
    rng = np.random.default_rng(8)
    mean = np.r_[np.ones(400), np.full(100, 1.2), np.ones(200)]
    events = []
    for k, m in enumerate(mean):
        events += [(k, e) for e in cusum.check(k, {"dead_zone": (float(m + sigma * rng.standard_normal()), sigma)})]
    assert [(e.raised, e.side) for _, e in events] == [(True, "above"), (False, "above")]
    (k_up, up), (k_down, _) = events
    assert 400 <= k_up < 410 and up.since >= 395  # after the step and not before, within a few checks
    assert 500 <= k_down < 515 and not cusum.active
    with pytest.raises(ConfigError, match="one bound per quantity"):
        Cusum([bound, bound], 1.0)


def test_the_correlation_time_of_overlapping_estimates_is_above_one_and_of_independent_ones_about_one() -> None:
    rng = np.random.default_rng(9)
    white = rng.standard_normal(4000)
    assert correlation_time(white, 4) == pytest.approx(1.0, abs=0.2)
    smooth = np.convolve(white, np.ones(4) / 4, mode="valid")  # a moving mean over 4: tau = 4
    assert correlation_time(smooth, 4) == pytest.approx(4.0, rel=0.2)
    assert correlation_time([1.0, 1.0, 1.0], 2) == 1.0


def test_the_doubt_about_a_model_file_names_an_unidentifiable_play_and_a_refit_outside_its_interval() -> None:
    assert file_doubt(0.004, 0.0041, (0.0035, 0.0045), True) is None
    assert file_doubt(0.004, 0.0041, (math.nan, math.nan), None) is None  # no interval: nothing to judge by
    moved = file_doubt(0.004, 0.002, (0.0035, 0.0045), True)
    assert moved is not None and "-50%" in moved and "outside" in moved
    both = file_doubt(0.004, 0.006, (0.0035, 0.0045), False)
    assert both is not None and both.startswith("the model file says its play is not identifiable") and "+50%" in both


def test_one_wild_window_play_does_not_raise_the_alarm_and_a_step_past_the_bound_does() -> None:
    from servoid.ident.monitoring.loop_wear import PLAY, LoopWearTracker
    from servoid.ident.online.window import WindowRow

    tracker = LoopWearTracker(LOOP, [Bound(quantity=PLAY, low=0.9 * LOOP.play, high=1.1 * LOOP.play)],
                              background=False, rebase=True)  # fmt: skip
    noise = np.random.default_rng(11).standard_normal(400)
    t = 10.0
    tracker._take(WindowRow(t, LOOP.play, 0.01, 0.01, 0.0, PLAY_IN_LOOP))  # the first fit
    plays = LOOP.play * (1.0 + 0.02 * noise)
    plays[150] = 6.0 * LOOP.play  # one window gone wild after the baseline (80 estimates)
    plays[300:] *= 1.2  # then the play steps up by 20 %
    for i, p in enumerate(plays):
        tracker._take(WindowRow(t + 0.25 * (i + 1), float(p), 0.01, 0.01, 0.0, PLAY_IN_LOOP))
    base = tracker.baseline()
    assert base["scatter"] == pytest.approx(0.02 * LOOP.play, rel=0.3) and base["h"] > 0.0
    raised = [round((e.sample / RATE - t) / 0.25) - 1 for e in tracker.events if e.raised]
    assert raised and 300 <= raised[0] < 310  # not at the wild window: it adds at most CLIP robust scales


def test_windows_with_too_few_reversals_do_not_count_and_a_step_in_windows_that_hold_them_still_raises() -> None:
    from servoid.ident.monitoring.loop_wear import MIN_REVERSALS, PLAY, LoopWearTracker
    from servoid.ident.online.window import WindowRow

    def run(turns_in_wild: int) -> tuple[list[int], list[bool]]:
        tracker = LoopWearTracker(LOOP, [Bound(quantity=PLAY, low=0.9 * LOOP.play, high=1.1 * LOOP.play)],
                                  background=False, rebase=True)  # fmt: skip
        noise = np.random.default_rng(12).standard_normal(400)
        t = 10.0
        tracker._take(WindowRow(t, LOOP.play, 0.01, 0.01, 0.0, PLAY_IN_LOOP, reversals=0))  # the first fit
        plays = LOOP.play * (1.0 + 0.02 * noise)
        turns = np.full(plays.size, MIN_REVERSALS + 2)
        plays[150:200] *= 1.3  # a slow stretch of the input (one reversal a window) reading high for 12.5 s
        turns[150:200] = turns_in_wild
        plays[300:] *= 1.2  # then the play steps up by 20 %, in windows that cross it often
        for i, (p, n) in enumerate(zip(plays, turns, strict=True)):
            tracker._take(WindowRow(t + 0.25 * (i + 1), float(p), 0.01, 0.01, 0.0, PLAY_IN_LOOP, reversals=int(n)))
        rows = tracker.rows_since(0)[1:]
        return [round((e.sample / RATE - t) / 0.25) - 1 for e in tracker.events if e.raised], [r.counted for r in rows]

    raised, counted = run(MIN_REVERSALS - 1)
    assert raised and 300 <= raised[0] < 310  # the stretch without reversals raised nothing, the step did
    assert not any(counted[150:200]) and all(counted[:150]) and all(counted[200:])
    raised, _ = run(MIN_REVERSALS)  # the same stretch, counted: it raises (what the rule removes)
    assert raised and 150 <= raised[0] < 200


def test_a_window_row_counts_the_reversals_of_its_scored_readings_by_more_than_twice_the_play() -> None:
    from servoid.ident.online.window import WindowConfig, WindowRefit

    period = 1 / RATE
    n = int(4.0 * RATE)
    k = np.arange(n)
    u = 0.1 * np.sin(2 * np.pi * 2.0 * k * period)  # 2 Hz: 4 reversals a second
    y = LOOP.simulate(u)
    refit = WindowRefit(WindowConfig(period, window_s=1.6, every_s=1.0, first_s=2.0, burn_in_s=0.4), start=LOOP,
                        background=False, later=fit_play)  # fmt: skip
    for ui, yi in zip(u, y, strict=True):
        refit.update(float(ui), float(yi))
    rows = refit.result(final=False).history
    assert len(rows) >= 2 and all(4 <= r.reversals <= 5 for r in rows[1:])  # 1.2 s scored at 4 a second
    still = WindowRefit(WindowConfig(period, window_s=1.6, every_s=1.0, first_s=2.0, burn_in_s=0.4), start=LOOP,
                        background=False, later=fit_play)  # fmt: skip
    wiggle = 0.5 * LOOP.play * np.sin(2 * np.pi * 2.0 * k * period)  # reversals smaller than the play: none count
    for ui in wiggle:
        still.update(float(ui), float(ui))
    assert all(r.reversals == 0 for r in still.result(final=False).history)


def test_windows_that_begin_before_the_input_settles_do_not_count_in_the_baseline() -> None:
    # the monitor's first seconds after the first fit: windows that still hold the identification's sines read
    # another bias (on the XM430 twin 1.14 -> 0.92x across the switch); the baseline is the steady input's alone
    from servoid.ident.monitoring.loop_wear import PLAY, PLAY_WINDOW_S, LoopWearTracker
    from servoid.ident.online.window import WindowRow

    def run(steady_s: float) -> tuple[dict[str, float], list[bool]]:
        tracker = LoopWearTracker(LOOP, [Bound(quantity=PLAY, low=0.9 * LOOP.play, high=1.1 * LOOP.play)],
                                  background=False, rebase=True, steady_s=steady_s)  # fmt: skip
        noise = np.random.default_rng(13).standard_normal(120)
        t = 10.0
        tracker._take(WindowRow(t, LOOP.play, 0.01, 0.01, 0.0, PLAY_IN_LOOP))  # the first fit
        plays = LOOP.play * (1.0 + 0.01 * noise)
        plays[:10] *= np.linspace(1.25, 1.0, 10)  # the windows across the switch at 10.6 s read high
        for i, p in enumerate(plays):
            tracker._take(WindowRow(t + 0.25 * (i + 1), float(p), 0.01, 0.01, 0.0, PLAY_IN_LOOP))
        return tracker.baseline(), [r.counted for r in tracker.rows_since(0)[1:]]

    base, counted = run(10.6)
    first = math.ceil((10.6 + PLAY_WINDOW_S - 10.0) / 0.25 - 1e-9) - 1  # the first window that begins at 10.6 s
    assert not any(counted[:first]) and all(counted[first:])
    assert base["scatter"] == pytest.approx(0.01 * LOOP.play, rel=0.3)
    polluted, counted = run(0.0)  # every window counts: the switch's windows widen the scatter
    assert all(counted) and polluted["scatter"] > 2.0 * base["scatter"]
    with pytest.raises(ConfigError, match="steady_s"):
        LoopWearTracker(LOOP, [], background=False, steady_s=-1.0)


def test_the_first_refit_keeps_the_refit_that_fits_better_and_moves_a_worn_play() -> None:
    # the monitor's first fit: the whole loop refitted free and with the play held at the file's, the better kept
    from servoid.ident.monitoring.loop_wear import LoopWearTracker, first_refit
    from servoid.ident.offline.loop_fit import refit_loop
    from servoid.ident.online.window import WindowConfig

    u = sample(GentleSpec(amplitude=0.1, accel=8.0 / RATE**2, spread=8.0), int(6.0 * RATE), seed=8)
    score = np.ones(u.size, dtype=bool)
    score[:80] = False
    noise = 1e-4 * np.random.default_rng(9).standard_normal(u.size)
    start = dataclasses.replace(LOOP, kv=54.0, fs=0.5)  # the file: the loop a little off
    for worn in (1.0, 1.3):
        y = dataclasses.replace(LOOP, c1=LOOP.c1 * worn, c2=LOOP.c2 * worn).simulate(u) + noise
        model, q = first_refit(u, y, score, start, max_nfev=10)
        free = refit_loop(u, y, start, score=score, max_nfev=10)
        held = refit_loop(u, y, start, score=score, max_nfev=10, hold=("play",))
        assert q == pytest.approx(min(free.fit_nrmse, held.fit_nrmse))
        assert model.play == pytest.approx((held if held.fit_nrmse < free.fit_nrmse else free).model.play)
        if worn > 1.0:  # a worn play fits better moved: the free refit, near the truth
            assert free.fit_nrmse < held.fit_nrmse and model.play == pytest.approx(worn * LOOP.play, rel=0.05)
    # the tracker's first row is that fit
    config = WindowConfig(1 / RATE, window_s=1.6, every_s=0.25, first_s=u.size / RATE, burn_in_s=80 / RATE)
    tracker = LoopWearTracker(start, [], config, background=False)
    for ui, yi in zip([*u.tolist(), 0.0], [*y.tolist(), 0.0], strict=True):
        tracker.update(ui, yi)
    first = tracker.rows_since(0)[0].window
    assert first.play == pytest.approx(model.play, rel=1e-9)


@pytest.mark.parametrize("held_nrmse", [0.009, 0.011])
def test_the_first_refit_keeps_the_play_held_only_where_the_free_search_ended_higher(monkeypatch, held_nrmse) -> None:
    # the rule alone (the fits stubbed): the free refit unless the play-held one fits strictly better
    from servoid.ident.monitoring.loop_wear import first_refit
    from servoid.ident.offline import loop_fit

    def stub(u, y, start, *, score=None, max_nfev=10, hold=()):  # type: ignore[no-untyped-def]
        held = "play" in hold
        model = start if held else dataclasses.replace(start, c1=0.5 * start.c1, c2=0.5 * start.c2)
        return loop_fit.LoopRefit(model, held_nrmse if held else 0.010, 1, 0.0)

    monkeypatch.setattr(loop_fit, "refit_loop", stub)
    model, q = first_refit(np.zeros(10), np.zeros(10), np.ones(10, dtype=bool), LOOP)
    assert (model.play, q) == ((LOOP.play, 0.009) if held_nrmse < 0.010 else (0.5 * LOOP.play, 0.010))


def test_the_first_refit_with_the_loop_held_keeps_the_files_gains_and_moves_the_play_alone() -> None:
    # hold_loop: the file's gains held (the valley they form with the play is not refitted), the play refitted
    from servoid.ident.monitoring.loop_wear import LOOP_GAINS, first_refit

    u = sample(GentleSpec(amplitude=0.1, accel=8.0 / RATE**2, spread=8.0), int(6.0 * RATE), seed=8)
    score = np.ones(u.size, dtype=bool)
    score[:80] = False
    noise = 1e-4 * np.random.default_rng(9).standard_normal(u.size)
    worn = 1.3
    y = dataclasses.replace(LOOP, c1=LOOP.c1 * worn, c2=LOOP.c2 * worn).simulate(u) + noise
    model, q = first_refit(u, y, score, LOOP, max_nfev=10, hold_loop=True)
    assert all(getattr(model, name) == getattr(LOOP, name) for name in LOOP_GAINS)
    assert model.play == pytest.approx(worn * LOOP.play, rel=0.03)
    free, _ = first_refit(u, y, score, dataclasses.replace(LOOP, kv=54.0), max_nfev=10)
    assert free.kv != 54.0  # without it the gains move


def test_a_calibrated_tracker_reads_the_files_play_then_its_change_and_raises_as_the_uncalibrated_one() -> None:
    # the held loop reads the play 0.85x on the monitoring input: calibrated, the window plays read the file's play
    # on the first CALIBRATE_S of counted windows (which do not count otherwise), then that times their change
    from servoid.ident.monitoring.loop_wear import BASELINE_S, CALIBRATE_S, PLAY, LoopWearTracker
    from servoid.ident.online.window import WindowRow

    def run(calibrate: bool) -> LoopWearTracker:
        tracker = LoopWearTracker(LOOP, [Bound(quantity=PLAY, low=0.9 * LOOP.play, high=1.1 * LOOP.play)],
                                  background=False, rebase=True, calibrate=calibrate)  # fmt: skip
        noise = np.random.default_rng(14).standard_normal(300)
        t = 10.0
        tracker._take(WindowRow(t, LOOP.play, 0.01, 0.01, 0.0, PLAY_IN_LOOP))  # the first fit
        plays = 0.85 * LOOP.play * (1.0 + 0.01 * noise)
        plays[200:] *= 1.2  # the play steps up by 20 % after the baseline
        for i, p in enumerate(plays):
            tracker._take(WindowRow(t + 0.25 * (i + 1), float(p), 0.01, 0.01, 0.0, PLAY_IN_LOOP))
        return tracker

    plain, calibrated = run(False), run(True)
    n_cal = round(CALIBRATE_S / 0.25)
    rows = calibrated.rows_since(0)[1:]
    assert not any(r.counted for r in rows[:n_cal]) and all(r.counted for r in rows[n_cal:])
    scale = LOOP.play / float(np.median([r.window.play for r in rows[:n_cal]]))
    assert calibrated.scale == scale == pytest.approx(1 / 0.85, rel=0.01) and plain.scale == 1.0
    assert rows[n_cal].window.play == pytest.approx(scale * plain.rows_since(0)[n_cal + 1].window.play, rel=1e-12)
    assert np.median([r.window.play for r in rows[n_cal:200]]) == pytest.approx(LOOP.play, rel=0.01)
    assert rows[-1].mean == pytest.approx(1.2 * LOOP.play, rel=0.02)
    assert plain.rows_since(0)[-1].mean == pytest.approx(1.2 * 0.85 * LOOP.play, rel=0.02)  # as fitted
    # the baseline waits as long for as many counted windows, and the alarm comes as it does uncalibrated
    assert calibrated.baseline()["scatter"] / calibrated.baseline()["median"] == pytest.approx(
        plain.baseline()["scatter"] / plain.baseline()["median"], rel=0.3)  # fmt: skip
    assert len([r for r in rows if r.counted and r.window.t_s <= 10.0 + BASELINE_S + CALIBRATE_S]) == len(
        [r for r in plain.rows_since(0)[1:] if r.window.t_s <= 10.0 + BASELINE_S])  # fmt: skip
    raised = [[round((e.sample / RATE - 10.0) / 0.25) - 1 for e in t.events if e.raised] for t in (plain, calibrated)]
    assert raised[0] and raised[1] and 200 <= raised[0][0] < 206 and abs(raised[1][0] - raised[0][0]) <= 1
