"""Fitting the servo-loop model with the play in both places, and choosing the place by validation."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import numpy as np
import pytest

from servoid.drivers.twin import Twin, preset
from servoid.errors import ConfigError, ModelError
from servoid.excitation.generate import sample
from servoid.excitation.specs import GentleSpec
from servoid.ident import MRGIAConfig, identify
from servoid.ident.identify import SELECTABLE
from servoid.ident.models.servo_loop import ServoLoopModel
from servoid.ident.models.structure_names import OUTPUT_BACKLASH, PLAY_IN_LOOP, SERVO_LOOP
from servoid.ident.offline import loop_fit
from servoid.ident.offline.loop_fit import LOAD_MARGIN, MIN_SAMPLES, LoopChoice, block_mask, fit_loop

#: The presets' loop bandwidths, Hz (measured in the issue-12 study): only to set the host rate.
BANDWIDTH_HZ = {"xm430": 3.5, "cia402": 20.0}


def _gentle(amplitude: float, period: float, n: int, seed: int) -> np.ndarray:
    # peak accelerations 1-8 unit/s^2: gentler than the load's friction decelerates it
    return sample(GentleSpec(amplitude=amplitude, accel=8.0 * period**2, spread=8.0), n, seed=seed)


def _twin_record(name: str, amplitude: float, seconds: float, seed: int) -> tuple[np.ndarray, np.ndarray, float, float]:
    """A gentle-sine record of a twin at 20x its loop bandwidth, 4096-count output encoder, 0.3 count noise."""
    twin = Twin(preset(name, load_encoder_cpr=4096, encoder_noise_counts=0.3), seed=seed)
    twin.enable()
    period = 1.0 / (20.0 * BANDWIDTH_HZ[name])
    u = _gentle(amplitude, period, int(seconds / period), seed)
    rec = twin.sample(u, period)
    return rec.u, rec.y, period, twin.truth.play_rad


def _loop(structure: str, period: float) -> ServoLoopModel:
    """A servo loop with friction and a play of 7 thousandths of the unit, no integrator."""
    return ServoLoopModel(
        structure=structure, sample_period_s=period, kp=25.0, kv=120.0, fc=3.0, fs=4.0, vs=0.02, veps=0.002,
        c1=0.004, c2=0.003,
    )  # fmt: skip


@pytest.mark.parametrize("structure", [PLAY_IN_LOOP, OUTPUT_BACKLASH])
def test_recovers_its_own_simulation(structure: str) -> None:
    # the one place a test may use the estimator's own equations: exact recovery
    period = 0.01
    truth = _loop(structure, period)
    u = _gentle(0.1, period, 2000, seed=3)
    y = truth.simulate(u, y0=0.0)
    choice = fit_loop(u, y, period)
    assert choice.structure == structure
    assert choice.play == pytest.approx(truth.play, rel=0.02)
    assert choice.fit_nrmse < 0.01
    assert choice.margin > 0.05
    lo, hi = choice.play_interval
    assert lo < choice.play < hi
    np.testing.assert_allclose(choice.simulated, choice.model.simulate(u - u.mean(), y0=y[0] - u.mean()) + u.mean())


def test_a_winner_that_lost_its_stribeck_hump_is_refitted_from_one() -> None:
    # exact recovery: a drive that breaks away at 1.5 x its Coulomb level; the final refit starts from a
    # winner whose hump died (fs below fc: no hump, and no slope in fs to bring it back; refitted from there
    # alone fs stays below fc)
    period = 0.01
    truth = dataclasses.replace(_loop(OUTPUT_BACKLASH, period), ki=2000.0, fc=3.0, fs=4.5, vs=0.2)
    u = _gentle(0.1, period, 2000, seed=3)
    y = truth.simulate(u, y0=0.0)
    start = dict(truth.params(), kv=100.0, fc=3.5, fs=1.0, vs=0.01, play=0.008, asym=0.0)
    free = loop_fit._free(OUTPUT_BACKLASH, True)
    v_typ = float(np.std(np.diff(y))) / period
    every = np.ones(y.size, dtype=bool)
    d, _, _, _ = loop_fit._final_fit(
        u, y, period, OUTPUT_BACKLASH, True, start, every, 0.1 * 100.0 * v_typ, free, v_typ
    )
    assert d["fs"] == pytest.approx(truth.fs, rel=0.01)
    assert d["play"] == pytest.approx(truth.play, rel=1e-3)


def test_identify_names_the_play_in_the_loop_of_a_horn_encoder_twin() -> None:
    # the seam: identify() fits the black box, then the servo-loop model, which names the structure
    u, y, period, play = _twin_record("xm430", 0.1, 40.0, seed=1)
    result = identify(u + 1.5, y + 1.5, MRGIAConfig(), sample_period_s=period)  # raw coordinates: an offset
    assert result.structure == PLAY_IN_LOOP and result.form == SERVO_LOOP
    assert abs(result.play / play - 1.0) <= 0.15
    loop = result.loop
    assert isinstance(loop, LoopChoice)
    assert set(loop.validation_nrmse) == {PLAY_IN_LOOP, OUTPUT_BACKLASH}
    assert loop.dead_time_samples is not None and loop.dead_time_samples > 0.0


def test_motor_side_loop_twin_is_never_named_play_in_loop(monkeypatch: pytest.MonkeyPatch) -> None:
    # a play of 1.5 counts: the two places differ by 1-2 % in validation (the study's cia402), so the
    # honest answers are the output backlash or "undetermined" -- never a confident play in the loop
    u, y, period, play = _twin_record("cia402", 0.02, 6.0, seed=1)
    choice = fit_loop(u, y, period)
    assert choice.structure == OUTPUT_BACKLASH or not choice.determined
    assert abs(choice.play / play - 1.0) <= 0.3
    # FTOL and STALL end each search at a step that gains under 1e-5 / 1e-4 of the cost; scipy's own 1e-8 (the
    # path before) runs on: the early stop lands inside the full search's interval, on fewer simulations
    monkeypatch.setattr(loop_fit, "FTOL", 1e-8)
    monkeypatch.setattr(loop_fit, "STALL", 0.0)
    monkeypatch.setattr(loop_fit, "FINAL_STALL", 0.0)
    full = fit_loop(u, y, period)
    assert choice.structure == full.structure
    lo, hi = full.play_interval
    assert lo <= choice.play <= hi
    assert abs(choice.play / full.play - 1.0) < 0.25 * (hi - lo) / full.play
    assert choice.evaluations < full.evaluations


def test_raw_counts_and_centred_records_give_the_same_loop() -> None:
    period = 0.01
    truth = _loop(PLAY_IN_LOOP, period)
    u = _gentle(0.1, period, 800, seed=5)
    y = np.round(truth.simulate(u, y0=0.0) / 1e-3) * 1e-3
    centred = fit_loop(u, y, period)
    raw = fit_loop(u + 2.047, y + 2.047, period)
    assert raw.structure == centred.structure
    assert raw.play == pytest.approx(centred.play, rel=0.05)


@pytest.mark.parametrize(
    ("u", "y", "period", "match"),
    [
        (np.zeros(100), np.zeros(100), 0.01, "at least 200"),
        (np.zeros(300), np.zeros(301), 0.01, "differ in length"),
        (np.arange(300.0), np.zeros(300), 0.01, "constant"),
        (np.arange(300.0), np.arange(300.0), 0.0, "sample_period_s"),
    ],
)
def test_bad_records_are_refused(u: np.ndarray, y: np.ndarray, period: float, match: str) -> None:
    with pytest.raises(ConfigError, match=match):
        fit_loop(u, y, period)


def test_lost_readings_are_simulated_through_and_never_read() -> None:
    # a live record's mask: the set point is known everywhere, 3 % of the readings are lost (NaN)
    period = 0.01
    truth = _loop(PLAY_IN_LOOP, period)
    u = _gentle(0.1, period, 500, seed=5)
    y = truth.simulate(u, y0=0.0)
    keep = np.random.default_rng(2).random(u.size) > 0.03
    keep[0] = True
    choice = fit_loop(u, np.where(keep, y, np.nan), period, keep=keep)
    assert choice.structure == PLAY_IN_LOOP
    assert choice.play == pytest.approx(truth.play, rel=0.02)
    lo, hi = choice.play_interval
    assert lo < choice.play < hi
    assert np.all(np.isfinite(choice.simulated))  # simulated through the gaps
    with pytest.raises(ConfigError, match="keep"):
        fit_loop(u, y, period, keep=keep[:-1])


def test_a_long_record_is_searched_on_its_start_and_refitted_on_all(monkeypatch: pytest.MonkeyPatch) -> None:
    # every search (the candidates' and their first stages) reads the first SEARCH_SAMPLES samples only; the
    # final refit scores the whole record, and the play of the model's own simulation is still recovered;
    # unless the window's winner predicts the rest worse than it validated: then the search runs on all
    monkeypatch.setattr(loop_fit, "SEARCH_SAMPLES", 600)  # half the record
    # the fits counted here are the window's (the hump and profile restarts: their own tests)
    monkeypatch.setattr(loop_fit, "HUMP_CANDIDATES", ())
    monkeypatch.setattr(loop_fit, "PROFILE_RESTART", ())
    read: list[int] = []
    fit = loop_fit._fit

    def recorded(u: np.ndarray, y: np.ndarray, *args: object, **kwargs: object) -> object:
        read.append(min(u.size, int(np.flatnonzero(args[3])[-1]) + 1))  # type: ignore[call-overload]
        return fit(u, y, *args, **kwargs)  # type: ignore[arg-type]

    monkeypatch.setattr(loop_fit, "_fit", recorded)
    period = 0.01
    truth = _loop(OUTPUT_BACKLASH, period)
    u = _gentle(0.1, period, 1200, seed=4)
    y = truth.simulate(u, y0=0.0)
    choice = fit_loop(u, y, period)
    # eight searches on the window, four of the winner's place on the last window (LAST_WINDOW; the hump restart
    # where the winner lost its hump), then the final refit: its bridge on twice the window's reach (BRIDGE), then on all
    assert len(read) in (14, 15) and max(read[:-2]) <= 600 and 600 < read[-2] < u.size and read[-1] == u.size
    assert choice.structure == OUTPUT_BACKLASH
    assert choice.play == pytest.approx(truth.play, rel=0.02)
    assert choice.fit_nrmse < 0.01
    # a tail the window's winner does not predict (a drift the model has no term for): searched again on all
    read.clear()
    fit_loop(u, y + np.where(np.arange(u.size) >= 600, 0.002 * np.sin(np.arange(u.size) / 40.0), 0.0), period)
    assert len(read) in (17, 18) and max(read[:8]) <= 600 and min(read[8:]) > 600
    # the same drift all along: the winner predicts the tail as well as it validated, but off the window's floor
    read.clear()
    fit_loop(u, y + 0.002 * np.sin(np.arange(u.size) / 40.0), period)
    assert len(read) in (17, 18) and max(read[:8]) <= 600 and min(read[8:]) > 600
    # the winner and its humped restart tie on the window (WINDOW_TIE): both refitted on all, the lower kept
    read.clear()
    monkeypatch.setattr(loop_fit, "_cost", lambda *args: 1.0)
    tied = fit_loop(u, y, period)
    assert read[-4] == read[-2] < u.size and read[-3] == read[-1] == u.size and max(read[:-4]) <= 600
    assert tied.play == pytest.approx(truth.play, rel=0.02)
    # the window is cut where its start holds WINDOW_REVERSALS reversals of the set point, not below MIN_WINDOW
    tri = np.abs((np.arange(1000) % 100) - 50.0)  # reverses at every 50th sample
    assert loop_fit._reversals_end(tri, 0.5, 3) == 152 and loop_fit._reversals_end(tri, 60.0, 1) == tri.size
    monkeypatch.setattr(loop_fit, "MIN_WINDOW", 200)
    monkeypatch.setattr(loop_fit, "WINDOW_REVERSALS", 6)
    kept = np.ones(u.size, dtype=bool)
    cut = loop_fit._reversals_end(u, 1e-6, 6)
    assert 200 < cut < 600 and loop_fit._search_lengths(u, y, kept, 1e-6) == (cut, u.size)
    monkeypatch.setattr(loop_fit, "MIN_WINDOW", 590)
    assert loop_fit._search_lengths(u, y, kept, 1e-6) == (590, u.size)


def test_the_interval_takes_in_the_plays_of_candidates_that_validate_as_well() -> None:
    # model error the record cannot resolve: a rival within the structure margin widens the interval,
    # one clearly worse does not, and an interval the Jacobian could not give stays absent
    from servoid.ident.offline.loop_fit import LoopCandidate, _with_rivals

    def cand(structure: str, play: float, val: float) -> LoopCandidate:
        model = ServoLoopModel(structure=structure, sample_period_s=0.01, kp=10.0, kv=100.0, c1=play / 2, c2=play / 2)
        return LoopCandidate(structure, False, model, val, val, 1)

    cands = [cand(OUTPUT_BACKLASH, 1.0, 0.010), cand(PLAY_IN_LOOP, 0.8, 0.0104), cand(PLAY_IN_LOOP, 3.0, 0.0106)]
    assert _with_rivals((0.95, 1.05), cands, 0.010) == (0.8, 1.05)
    lo, hi = _with_rivals((np.nan, np.nan), cands, 0.010)
    assert np.isnan(lo) and np.isnan(hi)


def test_an_output_that_never_moves_where_it_is_validated_is_named_not_a_crash() -> None:
    # a heavy load the set point barely stirs: a few counts of motion, all of it in estimation blocks
    n = 4 * MIN_SAMPLES
    u = np.random.default_rng(1).uniform(-0.1, 0.1, n)
    y = np.where(block_mask(n), np.round(30.0 * np.cumsum(u)) * 1e-3, 0.0)
    with pytest.raises(ModelError, match="never moves in the validation blocks"):
        fit_loop(u, y, 0.01)


def test_the_load_stage_stands_only_when_it_validates_better() -> None:
    # a massless loop: the opt-in load stage runs, but the massless answer stands unless the stage
    # validates LOAD_MARGIN better; off by default (not run)
    period = 0.01
    truth = _loop(PLAY_IN_LOOP, period)
    u = _gentle(0.1, period, 2000, seed=3)
    y = truth.simulate(u, y0=0.0)
    plain = fit_loop(u, y, period)
    assert np.isnan(plain.load_validation) and plain.load_candidate is None
    tried = fit_loop(u, y, period, load=True)
    assert tried.load_candidate is not None and np.isfinite(tried.load_validation)
    if tried.model.massive:
        assert tried.load_validation < (1.0 - LOAD_MARGIN) * plain.validation_nrmse[plain.structure]
    else:
        assert tried.play == plain.play


def test_the_load_stage_recovers_a_heavy_load_and_its_integrator_from_the_massless_start() -> None:
    # exact recovery of the impact model's own simulation: a load twice the motor side's inertia
    # coasts across the play after each reversal; the massless fit books most of the play away,
    # the load stage's grid (the loop refitted at each point) finds the load from the massless start.
    # The loop integrates, which the massless candidates cannot tell (with and without an integrator they
    # validate alike, the one without first): identify's stage (load=None) starts from the one with it
    period = 0.01
    mu = 2.0
    truth = dataclasses.replace(
        _loop(OUTPUT_BACKLASH, period), kv=120.0 * (1 + mu), ki=600.0 * (1 + mu), fc=3.0 * (1 + mu),
        fs=4.0 * (1 + mu), mu=mu, e=0.0, al=3.0,
    )  # fmt: skip
    u = _gentle(0.1, period, 2000, seed=3)
    y = truth.simulate(u, y0=0.0)
    choice = fit_loop(u, y, period, load=None)
    assert choice.model.massive
    assert choice.play == pytest.approx(truth.play, rel=0.03)
    assert 0.5 * mu < choice.model.mu < 2.0 * mu
    assert 0.5 * truth.ki < choice.model.ki < 2.0 * truth.ki
    assert choice.fit_nrmse < 0.002
    # the massless answer the stage replaced was far off: the test can fail
    plain = next(c for c in choice.candidates if not c.model.massive)
    assert abs(plain.model.play / truth.play - 1.0) > 0.3


def test_the_load_stage_starts_from_the_best_candidate_with_an_integrator_started_where_it_has_none() -> None:
    # the candidate with an integrator can fit worse (the ODrive twin at 20x, seed 4: +165 % of play); the stage
    # then starts from the better one's values with an integrator started, and fits the integrator's structure
    from servoid.ident.offline.loop_fit import LoopCandidate, _ki_start, _stage_start

    def cand(structure: str, integrator: bool, play: float, val: float) -> tuple[LoopCandidate, dict[str, float]]:
        model = ServoLoopModel(structure=structure, sample_period_s=0.01, kp=10.0, kv=100.0, c1=play / 2, c2=play / 2)
        values = {"kp": 10.0 + play, "kv": 100.0, "ki": 50.0 if integrator else 0.0, "a0": 0.0 if integrator else 0.3}
        return LoopCandidate(structure, integrator, model, val, val, 1), dict(values, play=play)

    cands = [
        cand(PLAY_IN_LOOP, False, 0.2, 0.049),
        cand(OUTPUT_BACKLASH, False, 0.4, 0.050),
        cand(OUTPUT_BACKLASH, True, 2.6, 0.057),
        cand(PLAY_IN_LOOP, True, 0.9, 0.091),
    ]
    base, values = _stage_start(cands, OUTPUT_BACKLASH)
    assert base is cands[2][0]
    assert values["play"] == 0.4 and values["ki"] == _ki_start(10.4, 100.0) > 0.0 and values["a0"] == 0.0
    # the better one has an integrator: its own values, unchanged
    cands[1], cands[2] = cands[2], cands[1]
    base, values = _stage_start(cands, OUTPUT_BACKLASH)
    assert base is cands[1][0] and values == cands[1][1]
    # no candidate with an integrator: the best one as it is
    base, values = _stage_start(cands[:1], PLAY_IN_LOOP)
    assert base is cands[0][0] and values == cands[0][1]


def test_a_kept_load_is_never_identifiable_and_its_limit_is_named() -> None:
    # the rigid-impact load is an approximation whose plays scatter more than its interval: a reason whenever
    # it is kept, and a second one at the light or heavy end of its range (it does not describe the record)
    from servoid.ident.offline.load_stage import MU_LIMITS
    from servoid.ident.offline.loop_fit import _load_noticed

    base = _loop(OUTPUT_BACKLASH, 0.01)
    assert _load_noticed(base) == ()
    (inside,) = _load_noticed(dataclasses.replace(base, mu=1.0, e=0.2, al=3.0))
    assert "load model" in inside and "limit" not in inside
    for mu in MU_LIMITS:
        first, limit = _load_noticed(dataclasses.replace(base, mu=mu, e=0.2, al=3.0))
        assert "load model" in first and "inertia ratio" in limit and "limit" in limit


def test_the_jacobians_columns_on_threads_equal_them_one_after_the_other(monkeypatch: pytest.MonkeyPatch) -> None:
    # each column is its own simulation into its own buffer: on the pool it must give the same bits
    from servoid.ident.offline import _threads
    from servoid.ident.offline.loop_fit import _free, _Problem, _start

    period = 0.01
    u = _gentle(0.1, period, 800, seed=5)
    y = _loop(OUTPUT_BACKLASH, period).simulate(u, y0=0.0) + np.random.default_rng(5).normal(0.0, 1e-4, u.size)
    start = _start(30.0, 100.0, float(np.std(np.diff(u))) / period, 0.005, integrator=False, friction=1.0)
    free = _free(OUTPUT_BACKLASH, False)
    z = np.random.default_rng(6).uniform(-0.2, 0.2, len(free))
    jacobians = []
    for n in ("1", "3"):
        monkeypatch.setenv(_threads.ENV, n)
        prob = _Problem(u, y, period, OUTPUT_BACKLASH, free, start, block_mask(u.size), 0.01)
        jacobians.append(prob.jacobian(z))
        assert prob.evaluations == 1 + len(free)
    assert _threads.pool() is not None  # three threads were asked for: two helpers
    assert np.array_equal(jacobians[0], jacobians[1])
    assert np.all(np.isfinite(jacobians[0])) and np.any(jacobians[0] != 0.0)
    # the two places of the play are searched at once on the pool: the same candidates to the bit
    fits = []
    for n in ("1", "2"):
        monkeypatch.setenv(_threads.ENV, n)
        fits.append(fit_loop(u, y, period))
    assert fits[0].evaluations == fits[1].evaluations
    assert [c.model for c in fits[0].candidates] == [c.model for c in fits[1].candidates]
    assert np.array_equal(fits[0].simulated, fits[1].simulated)
    with _threads.one_thread():
        assert _threads.threads() == 1 and _threads.pool() is None
    monkeypatch.setenv(_threads.ENV, "two")
    with pytest.raises(ConfigError, match="SERVOID_THREADS='two' is not a positive integer"):
        _threads.threads()


def test_each_task_runs_once_and_a_tasks_error_reaches_the_caller(monkeypatch: pytest.MonkeyPatch) -> None:
    from servoid.ident.offline import _threads

    monkeypatch.setenv(_threads.ENV, "3")
    seen: list[int] = []
    _threads.each(seen.append, 40)
    assert sorted(seen) == list(range(40))

    def fail(i: int) -> None:
        if i == 7:
            raise ModelError("task 7")

    with pytest.raises(ModelError, match="task 7"):
        _threads.each(fail, 12)


def test_a_thread_waiting_for_its_tasks_runs_another_threads_tasks(monkeypatch: pytest.MonkeyPatch) -> None:
    # two outer tasks, one short and one that opens tasks of its own which need two threads at once (a barrier):
    # they only pass when the thread whose outer task ended runs them while it waits for the other
    import threading

    from servoid.ident.offline import _threads

    monkeypatch.setenv(_threads.ENV, "2")
    barrier = threading.Barrier(2, timeout=20.0)
    ran: list[tuple[int, int]] = []

    def inner(i: int) -> None:
        barrier.wait()
        ran.append((i, threading.get_ident()))

    def outer(i: int) -> None:
        if i == 1:
            _threads.each(inner, 2)

    _threads.each(outer, 2)
    assert sorted(i for i, _ in ran) == [0, 1]
    assert len({thread for _, thread in ran}) == 2


def test_a_job_ahead_gives_its_value_or_its_error_and_is_joined(monkeypatch: pytest.MonkeyPatch) -> None:
    import threading
    import time

    from servoid.ident.offline import _threads

    monkeypatch.setenv(_threads.ENV, "2")
    where: list[str] = []

    def job() -> int:
        where.append(threading.current_thread().name)
        return 42

    assert _threads.Ahead(job).result() == 42
    assert where == ["servoid-ahead"]

    def fails() -> int:
        raise ModelError("the job failed")

    with pytest.raises(ModelError, match="the job failed"):
        _threads.Ahead(fails).result()
    # one thread: the job runs where its result is asked for
    with _threads.one_thread():
        assert _threads.Ahead(job).result() == 42
    assert where[-1] == threading.current_thread().name
    # a call that starts a job and ends without asking for it still waits for it
    release = threading.Event()
    done: list[bool] = []

    def slow() -> int:
        release.wait(20.0)
        time.sleep(0.2)  # still running when the caller raises
        done.append(True)
        return 1

    @_threads.joins_ahead
    def caller() -> None:
        _threads.Ahead(slow)
        release.set()
        raise ConfigError("the caller failed")

    with pytest.raises(ConfigError, match="the caller failed"):
        caller()
    assert done == [True]


def test_the_last_window_searches_the_winners_place_on_the_records_end() -> None:
    # LAST_WINDOW: the winner's place searched again on the record's last window; its winner, that window's
    # estimation blocks and the winner's cost on every sample come back, or nothing where the window never moves
    period = 0.01
    truth = _loop(OUTPUT_BACKLASH, period)
    u = _gentle(0.1, period, 2400, seed=3)
    y = truth.simulate(u, y0=0.0)
    every = np.ones(y.size, dtype=bool)
    v_typ = float(np.std(np.diff(y))) / period
    starts = (25.0, 120.0, v_typ, 0.1 * 120.0 * v_typ)
    grid = np.geomspace(1e-3, 0.03, 4)
    best = loop_fit.LoopCandidate(
        structure=OUTPUT_BACKLASH, integrator=False, model=truth, estimation_nrmse=0.0, validation_nrmse=0.0,
        evaluations=0,
    )  # fmt: skip
    other, spent = loop_fit._last_window(u, y, every, period, 1000, starts, grid, best)
    assert other is not None and spent > 0
    d, search, cost = other
    assert not search[:1400].any()
    np.testing.assert_array_equal(search[1400:], block_mask(1000))
    assert cost == loop_fit._cost(u, y, period, OUTPUT_BACKLASH, d, every)
    assert d["play"] > 0.0  # (a window that starts in motion: the model starts at rest, its play need not be the truth)
    # a record that ends at rest: no window to search there
    held = np.concatenate([u[:1400], np.full(1000, u[1399])])
    y_held = np.concatenate([y[:1400], np.full(1000, y[1399])])
    assert loop_fit._last_window(held, y_held, every, period, 1000, starts, grid, best) == (None, 0)


def test_a_load_stage_grid_point_that_runs_away_fits_infinitely_badly() -> None:
    # a heavy load the loop cannot hold runs away (its output past what a square holds): the grid ranks it
    # last, with no overflow (an error under the tests' warnings rule; a live Feetech record met one)
    from servoid.ident.metrics import free_run_nrmse
    from servoid.ident.offline import load_stage as stage

    n = 400
    y = np.sin(np.arange(n) * 0.05)
    est = np.arange(n) % 2 == 0
    best = {"kp": 10.0, "kv": 50.0, "ki": 0.0, "fc": 0.1, "fs": 0.1, "vs": 0.1, "a0": 0.0, "play": 0.01, "al": 5.0}

    def simulate(d: dict[str, float]) -> np.ndarray:
        if d["play"] > 4.0 * best["play"]:  # the largest play factor of the grid: runs away
            return np.full(n, 1e200)
        return y + 0.1 * abs(d["play"] / best["play"] - 1.0) + 0.01 * d.get("mu", 0.0)

    def fit(start: dict[str, float], free: tuple[str, ...], nfev: int) -> tuple[dict[str, float], float, int]:
        return dict(start), free_run_nrmse(y[est], simulate(start)[est]), 1

    d, evaluations, rivals = stage.load_stage(y, best, ("kp", "kv", "fc", "play", "al"), fit, simulate, est, ~est)
    assert d["play"] == best["play"] and evaluations > 0
    assert all(np.isfinite(nrmse) for _, nrmse in rivals)  # the runaway point never left the grid


def test_a_light_load_at_the_floor_joins_the_interval_as_the_plays_rival(monkeypatch: pytest.MonkeyPatch) -> None:
    # the ODrive twin with a tenth of its load (inertia ratio 0.28): the load bounces off the flanks, and a
    # massless play about a fifth small holds the record at its floor, so the load stage does not run; the
    # light loads fitted as rivals widen the interval to the truth, and leave the answer as it was
    p = preset("odrive", load_encoder_cpr=4096, encoder_noise_counts=0.3)
    twin = Twin(dataclasses.replace(p, load_inertia_kgm2=0.1 * p.load_inertia_kgm2), seed=2)
    twin.enable()
    period = 1.0 / (20.0 * 5.5)  # 20x the loop's bandwidth
    rec = twin.sample(_gentle(0.05, period, int(20.0 / period), 1002), period)
    truth = twin.truth.play_rad
    choice = fit_loop(rec.u, rec.y, period, load=None)
    assert not choice.model.massive and np.isnan(choice.load_validation)  # at its floor: no stage
    assert abs(choice.play / truth - 1.0) > 0.1  # the massless play is off: the test can fail
    lo, hi = choice.play_interval
    assert lo <= truth <= hi
    monkeypatch.setattr(loop_fit, "LOAD_FLOOR_RIVALS", False)
    plain = fit_loop(rec.u, rec.y, period, load=None)
    assert plain.play == choice.play
    assert plain.play_interval[1] < truth  # without the rivals the interval missed the truth


def _in_loop_search_record() -> tuple[float, ServoLoopModel, np.ndarray, np.ndarray, tuple, np.ndarray, np.ndarray]:
    """The model's own simulation of a play in the loop, centred, with what :func:`loop_fit._search` takes besides:
    the period, the truth, ``uc, yc``, the linear start, the play grid and the mask of every sample."""
    period = 0.01
    truth = _loop(PLAY_IN_LOOP, period)
    u = _gentle(0.1, period, 2000, seed=3)
    y = truth.simulate(u, y0=0.0)
    uc, yc = u - u.mean(), y - u.mean()
    v_typ = float(np.std(np.diff(yc))) / period
    starts = (*loop_fit._linear_start(uc, yc, period), v_typ, 0.1 * 120.0 * v_typ)
    return period, truth, uc, yc, starts, np.geomspace(1e-4, 0.03, 10), np.ones(y.size, dtype=bool)


def _spoiled_searches(
    monkeypatch: pytest.MonkeyPatch, spoil: Callable[[dict], dict], count: int, *, integrator_only: bool = False
) -> list[bool]:
    """Make the first ``count`` candidate searches of the play in the loop (with an integrator, ``integrator_only``)
    end at ``spoil`` of their values; the list grows by one for each spoiled search."""
    fit = loop_fit._fit
    spoiled: list[bool] = []

    def spoiling(*args: object, **kwargs: object) -> object:
        d, prob, sol = fit(*args, **kwargs)  # type: ignore[arg-type]
        search = kwargs.get("free") is None and kwargs.get("max_nfev") == loop_fit.CANDIDATE_NFEV
        if (
            search
            and args[3] == PLAY_IN_LOOP
            and (kwargs["integrator"] or not integrator_only)
            and len(spoiled) < count
        ):
            spoiled.append(True)
            return spoil(d), prob, sol
        return d, prob, sol

    monkeypatch.setattr(loop_fit, "_fit", spoiling)
    return spoiled


def test_a_candidate_whose_play_collapsed_is_fitted_again_from_the_other_candidates_fit(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # COLLAPSE_RESTART: exact recovery of a play in the loop, where the search with an integrator is made to end
    # at no play (the XM430 twin at 10x did so by itself); its sibling found the play, and the candidate fitted
    # again from the sibling's fit comes back with it (the lower estimation cost kept); without the rule it stays
    period, truth, uc, yc, starts, grid, every = _in_loop_search_record()
    collapsed = _spoiled_searches(monkeypatch, lambda d: dict(d, play=1e-9), 1, integrator_only=True)
    plays = {}
    for rule in (True, False):
        monkeypatch.setattr(loop_fit, "COLLAPSE_RESTART", rule)
        collapsed.clear()
        found, spent, _, _ = loop_fit._search(uc, yc, every, period, starts, grid, (PLAY_IN_LOOP,))
        assert collapsed and spent > 0
        plays[rule] = {c.integrator: d["play"] for c, d in found}
        assert len(found) == 2
    assert plays[False][True] == 1e-9
    assert plays[True][True] == pytest.approx(truth.play, rel=0.05)
    assert plays[True][False] == plays[False][False] == pytest.approx(truth.play, rel=0.05)


def test_the_place_behind_without_a_hump_is_fitted_again_from_one(monkeypatch: pytest.MonkeyPatch) -> None:
    # HUMP_CANDIDATES: exact recovery of a play in the loop whose drive breaks away above its Coulomb level, where
    # both play-in-loop candidates are made to end without the hump (fs below fc, where the cost has no slope in fs)
    # and in a worse basin (kv three times the truth's), behind the play outside the loop (the XM430 twin's records:
    # the place in the loop without its hump lost to the other with one); fitted again from humps, the place comes
    # back with a hump, the truth's play and the lead; without the rule it stays behind
    period, truth, uc, yc, starts, grid, every = _in_loop_search_record()  # the truth: fs 4 over fc 3
    stripped = _spoiled_searches(monkeypatch, lambda d: dict(d, fs=0.5 * d["fc"], kv=3.0 * d["kv"]), 2)
    monkeypatch.setattr(loop_fit, "PLACES_AT_ONCE", False)  # the stripped fits are the place's first two
    ahead = {}
    for rule in (loop_fit.HUMP_CANDIDATES, ()):
        monkeypatch.setattr(loop_fit, "HUMP_CANDIDATES", rule)
        stripped.clear()
        found, _, _, _ = loop_fit._search(uc, yc, every, period, starts, grid, (OUTPUT_BACKLASH, PLAY_IN_LOOP))
        assert len(stripped) == 2
        ahead[bool(rule)] = found[0]  # the best validation
    (won, d_won), (lost, _) = ahead[True], ahead[False]
    assert lost.structure == OUTPUT_BACKLASH  # the stripped place behind, without the rule
    assert won.structure == PLAY_IN_LOOP and d_won["fs"] > d_won["fc"]
    assert d_won["play"] == pytest.approx(truth.play, rel=0.05)


def test_a_candidate_that_stopped_short_of_its_minimum_is_fitted_again_from_its_held_play(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # PROFILE_RESTART: exact recovery of a play in the loop, where both candidates' searches are made to stop with
    # the play 30 % long (the STS3215 twin with its gear damped x10 stopped at +25 % by itself, at 50x, seed 3); the
    # loop refitted with the play held at 0.8 of that costs less than the candidate, so the candidate is fitted again
    # from there and comes back with the truth's play; without the rule it stays long
    period, truth, uc, yc, starts, grid, every = _in_loop_search_record()
    stopped = _spoiled_searches(monkeypatch, lambda d: dict(d, play=1.3 * d["play"]), 2)
    monkeypatch.setattr(loop_fit, "COLLAPSE_RESTART", False)
    best = {}
    for rule in (loop_fit.PROFILE_RESTART, ()):
        monkeypatch.setattr(loop_fit, "PROFILE_RESTART", rule)
        stopped.clear()
        found, _, _, _ = loop_fit._search(uc, yc, every, period, starts, grid, (PLAY_IN_LOOP,))
        assert len(stopped) == 2
        best[bool(rule)] = found[0]
    assert best[False][1]["play"] == pytest.approx(1.3 * truth.play, rel=0.05)
    assert best[True][1]["play"] == pytest.approx(truth.play, rel=0.05)
    assert best[True][0].estimation_nrmse < best[False][0].estimation_nrmse


@pytest.mark.slow
def test_a_well_damped_horn_twin_is_not_answered_confidently_wrong() -> None:
    # the STS3215 twin with its gear damping x10 (a contact that does not rebound), gentle sines at 50x its loop
    # bandwidth (issue 12): the search stopped at +23 % with an interval [1.11, 1.36] times the truth, identifiable;
    # whatever the answer, an identifiable one must hold the truth in its interval and be within the 15 %
    rate = 50.0 * 7.0  # the STS3215 twin's loop bandwidth is 7 Hz
    twin = Twin(
        preset("sts3215", load_encoder_cpr=4096, encoder_noise_counts=0.3,
               gear_damping_nms=10 * preset("sts3215").gear_damping_nms),
        seed=3,
    )  # fmt: skip
    twin.enable()
    u = sample(GentleSpec(amplitude=0.1, accel=8.0 / rate**2, spread=8.0), 12000, seed=1003)
    rec = twin.sample(u, 1.0 / rate)
    play = twin.truth.play_rad
    result = identify(rec.u, rec.y, MRGIAConfig(), select=SELECTABLE, sample_period_s=1.0 / rate)
    assert result.structure == PLAY_IN_LOOP
    if result.identifiable:
        lo, hi = result.play_interval
        assert lo <= play <= hi
        assert result.play == pytest.approx(play, rel=0.15)


def test_a_stop_reaches_every_thread_of_an_each_call_and_only_inside_stopping(monkeypatch: pytest.MonkeyPatch) -> None:
    import threading

    from servoid.ident.offline import _threads

    monkeypatch.setenv(_threads.ENV, "2")
    barrier = threading.Barrier(2, timeout=20.0)
    raised: list[str] = []

    def task(i: int) -> None:
        barrier.wait()  # the two tasks at once: on the caller and on the pool's helper
        try:
            _threads.check()
        except _threads.Stopped:
            raised.append(threading.current_thread().name)
            raise

    stop = _threads.Stop(why="the test")
    stop.now()
    with _threads.stopping(stop), pytest.raises(_threads.Stopped, match="stopped by the test"):
        _threads.each(task, 2)
    assert len(set(raised)) == 2 and stop.fired
    assert not _threads._open  # the batch closed
    _threads.each(task, 2)  # outside stopping(): nothing is checked, on either thread
    with pytest.raises(ConfigError, match="NaN"):
        _threads.Stop(float("nan"))


def test_a_fit_stopped_by_its_deadline_returns_in_time_and_one_never_stopped_is_unchanged(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    import threading
    import time

    from servoid.ident.offline import _threads

    monkeypatch.setenv(_threads.ENV, "2")
    period = 0.01
    truth = _loop(PLAY_IN_LOOP, period)
    u = _gentle(0.1, period, 1000, seed=4)
    y = truth.simulate(u, y0=0.0)
    t0 = time.perf_counter()
    whole = fit_loop(u, y, period, load=False)
    whole_s = time.perf_counter() - t0
    # a stop that never comes: the same answer, to the bit (an offline fit runs outside any stop)
    with _threads.stopping(_threads.Stop()):
        again = fit_loop(u, y, period, load=False)
    assert again.play == whole.play and np.array_equal(again.simulated, whole.simulated)
    # a deadline a tenth into the fit: it unwinds at its next evaluation, long before its end, on every thread
    before = {t.ident for t in threading.enumerate()}
    stop = _threads.Stop(time.perf_counter() + 0.1 * whole_s, "the test's budget")
    t0 = time.perf_counter()
    with _threads.stopping(stop), pytest.raises(_threads.Stopped, match="the test's budget's deadline"):
        fit_loop(u, y, period, load=False)
    assert time.perf_counter() - t0 < 0.6 * whole_s and stop.fired
    assert not _threads._open
    assert {t.ident for t in threading.enumerate() if t.name.startswith("servoid-ahead")} <= before
