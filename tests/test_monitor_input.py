"""The monitor's steady sine with its amplitude dithered or cycled over the loop encoder's count grid."""

from __future__ import annotations

import math

import numpy as np
import pytest

from servoid.excitation.generate import sample
from servoid.excitation.gentle import segment_end, segments
from servoid.excitation.monitor_input import (
    CYCLED,
    IDENT,
    MAX_COUNT_SHARE,
    SINE,
    STEADY,
    cycled_sine,
    default_input,
    grid_count,
    monitor_spec,
    monitor_stream,
)
from servoid.ident.models.structure_names import OUTPUT_BACKLASH, PLAY_IN_LOOP


def test_no_dither_is_the_steady_sine_as_before() -> None:
    spec = monitor_spec(SINE, 0.1, 1e-4)
    assert (spec.smallest, spec.spread, spec.cycles) == (1.0, 1.0, 3)
    assert monitor_spec(SINE, 0.1, 1e-4, dither=0.0) == spec


def test_dither_draws_each_period_its_own_amplitude_at_the_same_acceleration() -> None:
    accel = 4.0 / 200.0**2
    spec = monitor_spec(SINE, 0.1, 2.0 * accel, dither=0.05)  # the sine's peak: half the identification's
    amp, freq, length = segments(spec, 7, 0, 40)
    assert spec.cycles == 1
    assert np.all(amp <= 0.1 + 1e-12) and np.all(amp >= 0.095 - 1e-12)
    assert np.ptp(amp) > 0.02 * 0.1  # spread over most of the span: many places on a count grid
    np.testing.assert_allclose(amp * (2.0 * math.pi * freq) ** 2, accel, rtol=1e-9)
    u = sample(spec, int(length.sum()), seed=7)
    assert np.max(np.abs(u)) <= 0.1 + 1e-12


@pytest.mark.parametrize("dither", [-0.1, 0.6, math.nan])
def test_dither_out_of_range_is_refused(dither: float) -> None:
    with pytest.raises(ValueError, match="dither"):
        monitor_spec(SINE, 0.1, 1e-4, dither=dither)


def _reversals(u: np.ndarray) -> np.ndarray:
    """Indices of the local extremes of ``u`` (a reversal of the set point each; of a peak between two samples, two
    equal ones, the first)."""
    d = np.diff(u)
    moves = np.flatnonzero(np.abs(d) > 1e-12)
    return moves[:-1][np.sign(d[moves[1:]]) != np.sign(d[moves[:-1]])] + 1


@pytest.mark.parametrize("steps", [3, 4])
def test_cycled_sine_puts_each_side_on_distinct_places_of_the_grid(steps: int) -> None:
    count = 2.0 * math.pi / 4096.0
    accel = 4.0 / 200.0**2
    spec = monitor_spec(SINE, 0.1, 2.0 * accel, offset=0.3)
    u = cycled_sine(spec, count, steps, 4000)
    assert np.max(np.abs(np.diff(u))) <= math.sqrt(0.1 * accel) * (1.0 + 1e-9)  # no step: the sine's own slope at most
    idx = _reversals(u)
    amp = np.abs(u[idx] - 0.3)
    expected = 0.1 - np.arange(steps) * count / steps
    # every peak sits within the sampling's rounding of one of the cycle's amplitudes, in the cycle's order
    nearest = np.argmin(np.abs(amp[:, None] - expected[None, :]), axis=1)
    np.testing.assert_allclose(amp, expected[nearest], atol=accel)  # a peak sample's rounding: under a w^2 / 8
    np.testing.assert_array_equal(nearest[: 2 * steps], np.arange(2 * steps) % steps)
    tops = {int(k) for k, v in zip(nearest, u[idx] > 0.3, strict=True) if v}
    # odd steps: both sides pass every place; even: each side half of them
    assert len(tops) == (steps if steps % 2 else steps // 2)


def test_cycled_sine_of_one_step_is_the_steady_sine_at_its_peak_acceleration() -> None:
    accel = 4.0 / 200.0**2
    spec = monitor_spec(SINE, 0.1, 2.0 * accel)
    u = cycled_sine(spec, 0.0015, 1, 2000, whole=False)
    t = np.arange(2000)
    np.testing.assert_allclose(u, 0.1 * np.sin(np.sqrt(accel / 0.1) * t), atol=1e-9)


@pytest.mark.parametrize("steps", [1, 2, 4])
def test_cycled_sine_of_whole_halves_repeats_its_sampled_cycle_exactly(steps: int) -> None:
    # the XM430 twin's live design: +/-0.1 rad at 6.045 rad/s^2 and 200 Hz, half-periods of 80.8 samples
    accel = 6.045 / 200.0**2
    spec = monitor_spec(SINE, 0.1, 2.0 * accel, offset=0.05)
    count = 2.0 * math.pi / 4096.0
    amps = 0.1 - np.arange(steps) * count / steps
    lengths = np.ceil(np.pi * np.sqrt(amps / accel))
    assert np.all(lengths > np.pi * np.sqrt(amps / accel))  # (none is whole already: the case that slid)
    period = int(np.sum(lengths)) * (2 if steps % 2 else 1)  # (odd steps: both sides before the sampled cycle repeats)
    u = cycled_sine(spec, count, steps, 3 * period, whole=True)
    np.testing.assert_array_equal(u[period : 2 * period], u[:period])
    np.testing.assert_array_equal(u[2 * period :], u[:period])
    # each half-period at most at the peak acceleration (lowered by under 3 %), its places as before
    assert np.max(np.abs(np.diff(u, 2))) <= accel * (1.0 + 1e-9)
    assert np.max(np.abs(np.diff(u, 2))) >= 0.97 * accel * np.cos(np.pi / np.min(lengths))
    idx = _reversals(u)
    np.testing.assert_allclose(np.sort(np.unique(np.round(np.abs(u[idx] - 0.05), 6)))[::-1], amps, atol=accel)
    # the fractional lengths (the cycle before): the sampled cycle does not repeat, each peak slides between samples
    frac = cycled_sine(spec, count, steps, 3 * period, whole=False)
    assert np.max(np.abs(frac[period : 2 * period] - frac[:period])) > 1e-4
    np.testing.assert_array_equal(cycled_sine(spec, count, steps, 3 * period), frac)  # off by default (WHOLE_HALVES)


@pytest.mark.parametrize("phases", [3, 4, 5])
def test_cycled_sine_of_even_phases_repeats_and_its_peaks_pass_evenly_spaced_sample_phases(phases: int) -> None:
    # the XM430 twin's live design as above (half-periods of 80.8 samples), four steps
    accel, steps = 6.045 / 200.0**2, 4
    spec = monitor_spec(SINE, 0.1, 2.0 * accel, offset=0.05)
    count = 2.0 * math.pi / 4096.0
    halves = math.lcm(steps, 2, phases)  # the sampled pattern's half-periods
    free = np.pi * np.sqrt((0.1 - np.arange(steps) * count / steps) / accel)
    period = round(float(np.sum(np.resize(free, halves))))  # about; the repeat is searched near it
    n = 2 * period + 4 * halves + 400
    u = cycled_sine(spec, count, steps, n, phases=phases)
    shifts = [p for p in range(period - 2 * halves, period + 2 * halves + 1)
              if np.allclose(u[p : p + period], u[:period], rtol=0.0, atol=1e-12)]  # fmt: skip
    assert len(shifts) == 1
    assert np.max(np.abs(np.diff(u, 2))) <= accel * (1.0 + 1e-9)  # at most the peak acceleration
    # each peak from its three top samples (the vertex of their parabola): any ``phases`` peaks in a row lie at
    # ``phases`` fractional positions 1 / phases apart; coprime to the steps, so do every amplitude's
    idx = _reversals(u)[: 2 * halves]
    y0, y1, y2 = (np.abs(u[idx + j] - 0.05) for j in (-1, 0, 1))
    peaks = idx + 0.5 * (y0 - y2) / (y0 - 2.0 * y1 + y2)
    for first in range(halves):
        got = np.sort(np.mod(peaks[first : first + phases] - peaks[first], 1.0))
        np.testing.assert_allclose(got, np.arange(phases) / phases, atol=0.01)
    if math.gcd(steps, phases) == 1:
        for k in range(steps):
            got = np.sort(np.mod(peaks[k:halves:steps] - peaks[k], 1.0))
            np.testing.assert_allclose(got, np.arange(phases) / phases, atol=0.01)
    frac = cycled_sine(spec, count, steps, n)  # off by default (EVEN_PHASES): the sliding cycle
    assert np.max(np.abs(frac[shifts[0] : shifts[0] + period] - frac[:period])) > 1e-4


@pytest.mark.parametrize(("phases", "whole"), [(1, False), (-3, False), (3, True)])
def test_cycled_sine_refuses_one_phase_or_phases_with_whole_halves(phases: int, whole: bool) -> None:
    with pytest.raises(ValueError, match="phases"):
        cycled_sine(monitor_spec(SINE, 0.1, 1e-4), 0.0015, 4, 10, phases=phases, whole=whole)


@pytest.mark.parametrize(("count", "steps"), [(0.0, 3), (0.2, 3), (math.nan, 3), (0.0015, 0)])
def test_cycled_sine_refuses_a_bad_count_or_steps(count: float, steps: int) -> None:
    with pytest.raises(ValueError, match="count|steps"):
        cycled_sine(monitor_spec(SINE, 0.1, 1e-4), count, steps, 10)


COUNT = 2.0 * math.pi / 4096.0  # a 4096-count encoder's, rad


def test_the_cycled_sine_is_off_by_default_and_never_the_default_outside_the_loop() -> None:
    assert default_input(PLAY_IN_LOOP) == STEADY and default_input(OUTPUT_BACKLASH) == STEADY
    assert default_input(PLAY_IN_LOOP, cycled=True) == CYCLED and default_input(OUTPUT_BACKLASH, cycled=True) == STEADY


def test_cycled_sine_in_chunks_equals_one_call() -> None:
    spec = monitor_spec(SINE, 0.1, 2e-4, offset=-0.2)
    whole = cycled_sine(spec, COUNT, 4, 3000)
    parts = np.concatenate([cycled_sine(spec, COUNT, 4, 1000, start=k) for k in (0, 1000, 2000)])
    np.testing.assert_array_equal(parts, whole)


def test_grid_count_reads_the_encoders_count_and_says_why_when_it_cannot() -> None:
    rng = np.random.default_rng(3)
    angle = 0.08 * np.sin(np.arange(2000) / 30.0) + rng.normal(0.0, 0.3 * COUNT, 2000)  # 0.3 count of noise
    counts = np.round(angle / COUNT) * COUNT
    found = grid_count(counts, 0.08)
    assert found.found and found.count == pytest.approx(COUNT, rel=1e-9) and found.readings == 2000 and not found.why
    few = grid_count(counts[:8], 0.08)  # a too short reading set
    assert not few.found and math.isnan(few.count) and "too few readings" in few.why
    still = grid_count(np.full(500, 3 * COUNT), 0.08)  # a servo that did not move
    assert not still.found and "too few readings" in still.why
    smooth = grid_count(angle, 0.08)  # a continuous encoder
    assert not smooth.found and "not whole multiples" in smooth.why
    coarse = grid_count(counts, COUNT / MAX_COUNT_SHARE * 0.9)  # a count above a tenth of the amplitude
    assert not coarse.found and "more than" in coarse.why


def _stream(n: int, **kw: object) -> np.ndarray:
    it = monitor_stream(0.08, 8e-4, 1000, seed=5, offset=0.1, **kw)  # type: ignore[arg-type]
    return np.fromiter(it, dtype=np.float64, count=n)


def test_the_cycled_stream_takes_its_count_when_the_steady_part_starts_and_only_lowers_the_amplitude() -> None:
    ident = monitor_spec(IDENT, 0.08, 8e-4, offset=0.1)
    cut = segment_end(ident, 5, 1000)
    steady = monitor_spec(SINE, 0.08, 8e-4, offset=0.1)
    calls: list[int] = []
    n = cut + 3000

    def count() -> float:
        calls.append(1)
        return COUNT

    it = monitor_stream(0.08, 8e-4, 1000, seed=5, offset=0.1, count=count)
    head = [next(it) for _ in range(cut)]
    assert calls == []  # not before the steady part: the readings until then are the count's
    u = np.concatenate([head, np.fromiter(it, dtype=np.float64, count=n - cut)])
    assert calls == [1]
    old = _stream(n)  # the steady sine, the input before
    np.testing.assert_array_equal(u[:cut], old[:cut])  # the first fit's sines unchanged
    np.testing.assert_array_equal(u[cut:], cycled_sine(steady, COUNT, 4, n - cut))
    # inside the steady sine's band and no steeper than it: the cycle only lowers the amplitude
    assert np.max(np.abs(u[cut:] - 0.1)) <= 0.08 + 1e-15 and np.max(np.abs(old[cut:] - 0.1)) > 0.08 - 1e-5
    assert np.max(np.abs(np.diff(u[cut - 1 :]))) <= math.sqrt(0.08 * 4e-4) * (1.0 + 1e-9)
    assert np.max(np.abs(np.diff(old[cut - 1 :]))) > math.sqrt(0.08 * 4e-4) * 0.99
    assert np.min(np.abs(u[cut:][_reversals(u[cut:])] - 0.1)) >= 0.08 - 0.75 * COUNT - 1e-4
    # without a count (NaN: the readings showed none) the steady sine, bit for bit
    np.testing.assert_array_equal(_stream(n, count=lambda: math.nan), old)


def test_the_cycled_stream_keeps_the_rate_limit() -> None:
    cut = segment_end(monitor_spec(IDENT, 0.08, 8e-4, offset=0.1, rate=5e-4), 5, 1000)
    old = _stream(4000, rate=5e-4)[cut:]  # the steady part (each part limited from the offset, as before)
    u = _stream(4000, rate=5e-4, count=lambda: COUNT)[cut:]
    assert np.max(np.abs(np.diff(u))) <= 5e-4 + 1e-15 and np.max(np.abs(u - 0.1)) <= 0.08 + 1e-15
    assert np.max(np.abs(np.diff(old))) == pytest.approx(5e-4) and not np.array_equal(u, old)
