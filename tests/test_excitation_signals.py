"""Excitation generators: the bound and the rate limit always hold, chunks equal one shot, and each kind is what it claims."""

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from servoid.errors import ConfigError
from servoid.excitation import (
    ChirpSpec,
    GentleSpec,
    LevelsSpec,
    MultisineSpec,
    PRBSSpec,
    SignalState,
    StepsSpec,
    UniformSpec,
    generate,
    sample,
    stream,
)
from servoid.excitation.periodic import crest_factor, multisine_period
from servoid.excitation.prbs import mls

# -- strategies ------------------------------------------------------------------------
amplitudes = st.floats(1e-3, 1e3)
offsets = st.floats(-1e3, 1e3)
rates = st.one_of(st.just(math.inf), st.floats(1e-4, 1e3))


@st.composite
def specs(draw):
    common = dict(amplitude=draw(amplitudes), offset=draw(offsets), rate=draw(rates))
    kind = draw(st.sampled_from(["uniform", "prbs", "steps", "multisine", "chirp", "levels", "gentle"]))
    if kind == "uniform":
        return UniformSpec(**common)
    if kind == "prbs":
        return PRBSSpec(**common, hold=draw(st.integers(1, 7)), order=draw(st.integers(2, 12)))
    if kind == "steps":
        return StepsSpec(**common, hold=draw(st.integers(1, 9)), levels=draw(st.sampled_from([0, 2, 3, 7])))
    if kind == "multisine":
        lo = draw(st.floats(0.001, 0.3))
        hi = draw(st.floats(lo + 0.05, 0.5))
        return MultisineSpec(**common, bands=((lo, hi),), period=draw(st.integers(64, 2000)))
    if kind == "chirp":
        return ChirpSpec(
            **common,
            f0=draw(st.floats(0.001, 0.5)),
            f1=draw(st.floats(0.001, 0.5)),
            period=draw(st.integers(2, 3000)),
            sweep=draw(st.sampled_from(["linear", "log"])),
        )
    if kind == "gentle":
        return GentleSpec(
            **common,
            accel=common["amplitude"] * draw(st.floats(1e-5, 0.5)),
            spread=draw(st.floats(1.0, 20.0)),
            cycles=draw(st.integers(1, 4)),
            smallest=draw(st.floats(0.01, 1.0)),
        )
    count = draw(st.integers(1, 5))
    share = draw(st.floats(0.0, 0.99))
    return LevelsSpec(
        **common,
        count=count,
        dwell=draw(st.integers(1, 50)),
        dither=share * common["amplitude"],
        hold=draw(st.integers(1, 5)),
    )


PROPERTY = settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])


# -- properties --------------------------------------------------------------------------
@PROPERTY
@given(spec=specs(), n=st.integers(0, 1500), seed=st.integers(0, 2**32))
def test_bound_and_rate_limit_always_hold(spec, n, seed):
    u = sample(spec, n, seed=seed)
    assert u.shape == (n,)
    assert np.all(u >= spec.low) and np.all(u <= spec.high)
    steps = np.abs(np.diff(np.concatenate([[spec.offset], u])))  # the first step is from the offset
    assert np.all(steps <= spec.rate)


@PROPERTY
@given(spec=specs(), cuts=st.lists(st.integers(0, 400), min_size=1, max_size=6), seed=st.integers(0, 2**32))
def test_chunked_output_equals_one_shot(spec, cuts, seed):
    state = None
    parts = []
    for size in cuts:
        values, state = generate(spec, size, state, seed=None if state else seed)
        parts.append(values)
    assert state.sample == sum(cuts)
    np.testing.assert_array_equal(np.concatenate(parts), sample(spec, sum(cuts), seed=seed))


def test_stream_yields_the_same_samples_as_sample():
    spec = StepsSpec(amplitude=2.0, hold=3, rate=0.7)
    streamed = np.fromiter(stream(spec, seed=5, n=1000, chunk=37), dtype=float)
    np.testing.assert_array_equal(streamed, sample(spec, 1000, seed=5))


def test_the_uniform_kind_is_the_papers_input_bit_for_bit():
    np.testing.assert_array_equal(
        sample(UniformSpec(amplitude=2.4), 500, seed=11), np.random.default_rng(11).uniform(-2.4, 2.4, 500)
    )


def test_same_seed_same_signal_other_seed_other_signal():
    spec = StepsSpec(amplitude=1.0, hold=2)
    np.testing.assert_array_equal(sample(spec, 200, seed=1), sample(spec, 200, seed=1))
    assert not np.array_equal(sample(spec, 200, seed=1), sample(spec, 200, seed=2))


def test_rate_limit_ramps_towards_the_target_and_arrives():
    u = sample(PRBSSpec(amplitude=1.0, hold=20, rate=0.25), 400, seed=0)
    flips = np.flatnonzero(np.abs(np.diff(u)) > 0)
    assert np.max(np.abs(np.diff(u))) == pytest.approx(0.25)
    assert set(np.round(u, 12)) >= {-1.0, 1.0}  # the full levels are reached between ramps
    assert flips.size > 0


def test_resuming_with_another_seed_is_refused():
    _, state = generate("uniform:amplitude=1", 10, seed=3)
    with pytest.raises(ConfigError, match="seed"):
        generate("uniform:amplitude=1", 10, state, seed=4)
    with pytest.raises(ConfigError, match="n \\(=-1\\)"):
        generate("uniform:amplitude=1", -1)
    assert isinstance(state, SignalState) and state.sample == 10


# -- what each kind claims ---------------------------------------------------------------
@pytest.mark.parametrize("order", [3, 5, 9])
def test_prbs_autocorrelation_is_an_impulse(order):
    period = 2**order - 1
    u = sample(PRBSSpec(amplitude=1.5, order=order), period, seed=order)
    assert set(u) == {-1.5, 1.5}
    corr = np.array([np.dot(u, np.roll(u, lag)) for lag in range(period)]) / 1.5**2
    assert corr[0] == period
    np.testing.assert_array_equal(corr[1:], -1.0)
    # and the sequence repeats with its period, held `hold` samples per bit
    held = sample(PRBSSpec(amplitude=1.0, order=order, hold=3), 6 * period, seed=1)
    np.testing.assert_array_equal(held[: 3 * period], held[3 * period :])
    np.testing.assert_array_equal(held[0::3], held[1::3])


def test_mls_is_a_maximum_length_sequence():
    seq = mls(7)
    assert seq.size == 127 and seq.sum() == 1  # 64 ones and 63 minus ones


def test_multisine_crest_factor_is_low_and_its_spectrum_is_the_band():
    spec = MultisineSpec(amplitude=2.0, bands=((0.01, 0.2),), period=1000)
    u = sample(spec, 3000, seed=0)
    assert np.max(np.abs(u)) == pytest.approx(2.0)
    schroeder = crest_factor(u)
    lines = spec.harmonics
    k = np.arange(1000)
    zero_phase = sum(np.cos(2 * np.pi * line * k / 1000) for line in lines)
    assert schroeder < 2.0  # near sqrt(2) for a flat multisine
    assert crest_factor(zero_phase) > 5 * schroeder  # sqrt(2 K) with K = 191 lines
    power = np.abs(np.fft.rfft(u[:1000])) ** 2
    excited = np.flatnonzero(power > 1e-9 * power.max())
    np.testing.assert_array_equal(excited, lines)


def test_multisine_joins_several_bands():
    spec = MultisineSpec(amplitude=1.0, bands=((0.01, 0.02), (0.3, 0.31)), period=1000)
    assert spec.harmonics == (*range(10, 21), *range(300, 311))
    assert np.abs(multisine_period(1000, spec.harmonics)).max() == 1.0


def test_chirp_sweeps_its_band_with_continuous_phase():
    spec = ChirpSpec(amplitude=1.0, f0=0.01, f1=0.1, period=500)
    u = sample(spec, 1500, seed=0)
    assert u[0] == 0.0 and u[1] > 0.0  # starts at the offset, rising
    # no jump at the restart of a sweep: steps there are as small as elsewhere at f1
    assert np.max(np.abs(np.diff(u))) <= 2 * np.pi * 0.1 * 1.0 + 1e-9
    # the zero crossings get denser as the frequency rises
    first, last = u[:250], u[250:500]
    assert np.count_nonzero(np.diff(np.sign(last))) > 2 * np.count_nonzero(np.diff(np.sign(first)))


def test_steps_take_only_their_levels_and_hold_them():
    spec = StepsSpec(amplitude=2.0, offset=1.0, hold=4, levels=5)
    u = sample(spec, 4000, seed=3)
    np.testing.assert_allclose(sorted(set(u)), [-1.0, 0.0, 1.0, 2.0, 3.0])
    blocks = u.reshape(-1, 4)
    assert np.all(blocks == blocks[:, :1])


def test_levels_visit_every_level_each_cycle():
    spec = LevelsSpec(amplitude=3.0, count=3, dwell=10, dither=0.0)
    u = sample(spec, 300, seed=8)
    visits = u.reshape(-1, 10)[:, 0].reshape(-1, 3)
    for cycle in visits:
        np.testing.assert_allclose(sorted(cycle), [-3.0, 0.0, 3.0])
    dithered = sample(LevelsSpec(amplitude=3.0, count=3, dwell=100), 3000, seed=8)
    assert 0.9 < np.ptp(dithered.reshape(-1, 100), axis=1).min() <= 2.0  # dither amplitude 1 around each level


def test_the_compiled_rate_limit_equals_its_python_original():
    from servoid.excitation.shaping import rate_limit_kernel
    from servoid.ident._jit import python_version

    target = np.random.default_rng(2).uniform(-1.0, 1.0, 500)
    compiled, plain = np.empty(500), np.empty(500)
    last_c = rate_limit_kernel(target, 0.3, 0.07, -1.0, 1.0, compiled)
    last_p = python_version(rate_limit_kernel)(target, 0.3, 0.07, -1.0, 1.0, plain)
    np.testing.assert_array_equal(compiled, plain)
    assert last_c == last_p == compiled[-1]


def test_gentle_sines_keep_their_peak_acceleration_and_amplitude():
    spec = GentleSpec(amplitude=0.1, accel=2e-3, spread=8.0, smallest=0.25)
    u = sample(spec, 20000, seed=7)
    # the second difference of a sampled sine is at most its peak acceleration (plus the jump between segments)
    accel = np.abs(np.diff(u, 2))
    assert np.quantile(accel, 0.99) <= 2e-3 * 1.01
    assert np.max(np.abs(u)) <= 0.1
    # segments of random amplitude and acceleration: many reversals, some small, some near the bound
    reversals = np.sum(np.diff(np.sign(np.diff(u))) != 0)
    assert reversals >= 40
    assert np.max(np.abs(u)) > 0.07


def test_whole_segments_end_at_a_segment_boundary_back_at_the_offset():
    from servoid.excitation.gentle import segments, whole_segments

    spec = GentleSpec(amplitude=0.1, accel=1e-3, offset=0.02)
    ends = np.cumsum(segments(spec, 3, 0, 600)[2])  # past the walk's first batch of 256 segments
    for limit in (int(ends[0]) - 1, int(ends[4]), int(ends[4]) + 1, int(ends[300]) + 2):
        cut = whole_segments(spec, 3, limit)
        assert cut <= limit and (cut == 0 or cut in ends)
        assert not np.any((ends > cut) & (ends <= limit))  # the last whole segment, not an earlier one
    assert whole_segments(spec, 3, int(ends[0]) - 1) == 0
    # a whole segment is whole periods: the next sample is back at the offset
    cut = whole_segments(spec, 3, int(ends[10]) + 3)
    assert sample(spec, cut + 1, seed=3)[cut] == pytest.approx(0.02, abs=1e-12)


def test_segment_end_is_the_end_of_the_segment_that_holds_an_index_back_at_the_offset():
    from servoid.excitation.gentle import segment_end, segments

    spec = GentleSpec(amplitude=0.1, accel=1e-3, offset=0.02)
    ends = np.cumsum(segments(spec, 3, 0, 600)[2])  # past the walk's first batch of 256 segments
    assert segment_end(spec, 3, 0) == 0
    assert segment_end(spec, 3, 1) == ends[0] and segment_end(spec, 3, int(ends[0])) == ends[0]
    for i in (4, 255, 256, 300):
        assert segment_end(spec, 3, int(ends[i]) + 1) == ends[i + 1]
        assert segment_end(spec, 3, int(ends[i + 1]) - 1) == ends[i + 1]
    cut = segment_end(spec, 3, int(ends[10]) + 3)
    assert sample(spec, cut + 1, seed=3)[cut] == pytest.approx(0.02, abs=1e-12)
