"""The servo-loop model (second structure): its kernel, its physics, its parameters."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from servoid.errors import ConfigError
from servoid.ident._jit import python_version
from servoid.ident.models.servo_loop import (
    CONTACT_NAMES,
    PARAM_NAMES,
    STATE_SIZE,
    ServoLoopModel,
    advance,
    initial_state,
    simulate_kernel,
    simulate_pair_kernel,
)
from servoid.ident.models.structure_names import OUTPUT_BACKLASH, PLAY_IN_LOOP


def _model(structure: str, **kw: float) -> ServoLoopModel:
    values = {"kp": 20.0, "kv": 150.0, "ki": 300.0, "fc": 2.0, "fs": 3.0, "vs": 0.05, "veps": 0.005}
    values.update({"a0": 0.5, "c1": 0.01, "c2": 0.012, "s0": 0.3})
    values.update(kw)
    return ServoLoopModel(structure=structure, sample_period_s=0.01, **values)


@pytest.mark.parametrize("structure", [OUTPUT_BACKLASH, PLAY_IN_LOOP])
def test_compiled_kernel_equals_python(structure: str) -> None:
    model = _model(structure)
    u = 0.1 * np.sin(np.arange(300) * 0.05)
    fast = np.empty(u.size)
    slow = np.empty(u.size)
    args = (model.vector(), model.feedback_load, u, 0.0, 0.01, model.substeps)
    simulate_kernel(*args, fast)
    python_version(simulate_kernel)(*args, slow)
    np.testing.assert_allclose(fast, slow, rtol=0, atol=1e-12)


@pytest.mark.parametrize("structure", [OUTPUT_BACKLASH, PLAY_IN_LOOP])
def test_the_pair_kernel_gives_each_simulation_to_the_bit(structure: str) -> None:
    # two simulations in one loop must be two simulations: other gains, limits, friction, no integrator
    u = 0.1 * np.sin(np.arange(700) * 0.04) + np.random.default_rng(3).normal(0.0, 0.01, 700)
    first = _model(structure)
    others = [
        _model(structure, kp=35.0, ki=0.0, vmax=0.4, fs=1.0, c1=0.02, s0=0.9),
        _model(structure, fs=2.0, veps=0.02),
        _model(structure, mu=1.5, e=0.3, al=4.0),  # a massive load beside a massless one: one after the other
    ]
    pairs = [(first, other) for other in others]
    # two massive loads: their impacts and contacts side by side
    pairs.append((others[2], _model(structure, mu=0.4, e=0.0, al=8.0, ki=0.0, c2=0.005)))
    # a load on a compliant contact (its own sub-steps) beside a rigid one: one after the other
    compliant = _model(structure, mu=0.4, al=8.0, wc=900.0, zeta=0.1)
    pairs.append((others[2], compliant))
    # two compliant contacts side by side, each with its own sub-steps (more on either side), with and without
    # an integrator and a speed limit; one beside a massless load: one after the other
    pairs.append((compliant, _model(structure, mu=0.4, al=8.0, wc=1500.0, zeta=0.3, ki=0.0, vmax=0.4)))
    pairs.append((_model(structure, mu=0.03, al=3.0, wc=700.0, zeta=0.05, c2=0.005), compliant))
    pairs.append((first, compliant))
    for a, b in pairs:
        alone = [np.empty(650), np.empty(650)]
        for model, out in zip((a, b), alone, strict=True):
            simulate_kernel(model.vector(), a.feedback_load, u, 0.01, 0.01, a.substeps, out)
        both = [np.empty(650), np.empty(650)]
        simulate_pair_kernel(a.vector(), b.vector(), a.feedback_load, u, 0.01, 0.01, a.substeps, *both)
        assert np.array_equal(both[0], alone[0]) and np.array_equal(both[1], alone[1])
        assert not np.array_equal(both[0], both[1])
    slow = [np.empty(650), np.empty(650)]
    python_version(simulate_pair_kernel)(
        first.vector(), others[0].vector(), first.feedback_load, u, 0.01, 0.01, 7, *slow
    )
    simulate_pair_kernel(first.vector(), others[0].vector(), first.feedback_load, u, 0.01, 0.01, 7, *both)
    np.testing.assert_allclose(both[0], slow[0], rtol=0, atol=1e-12)
    np.testing.assert_allclose(both[1], slow[1], rtol=0, atol=1e-12)


@pytest.mark.parametrize("structure", [OUTPUT_BACKLASH, PLAY_IN_LOOP])
def test_simulation_does_not_depend_on_the_origin(structure: str) -> None:
    model = _model(structure)
    u = 0.1 * np.sin(np.arange(500) * 0.03)
    shifted = model.simulate(u + 2047.0, y0=2047.0)
    np.testing.assert_allclose(shifted - 2047.0, model.simulate(u, y0=0.0), atol=1e-9)


def test_where_the_loop_reads_decides_where_the_load_settles() -> None:
    # no friction, no force: after a step up the loop settles where its encoder reads the set point
    u = np.full(400, 0.2)
    outside = _model(OUTPUT_BACKLASH, fc=0.0, fs=0.0, a0=0.0, ki=0.0).simulate(u, y0=0.0)
    inside = _model(PLAY_IN_LOOP, fc=0.0, fs=0.0, a0=0.0, ki=0.0).simulate(u, y0=0.0)
    # motor side on the set point, the load one play side behind it
    assert outside[-1] == pytest.approx(0.2 - 0.01, abs=1e-6)
    # the loop closed on the load drives the load itself to the set point
    assert inside[-1] == pytest.approx(0.2, abs=1e-6)


def test_the_load_waits_in_the_play_at_a_reversal() -> None:
    model = _model(PLAY_IN_LOOP, fc=0.0, fs=0.0, a0=0.0)
    u = np.r_[np.linspace(0, 0.2, 200), np.linspace(0.2, 0.0, 200)]
    y = model.simulate(u, y0=0.0)
    # the horn stands still for a while after the set point reverses: the motor crosses the play
    after = np.diff(y[200:260])
    assert np.sum(np.abs(after) < 1e-12) >= 2


def test_parameters_round_trip_and_are_checked() -> None:
    model = _model(PLAY_IN_LOOP)
    assert ServoLoopModel.from_dict(model.to_dict()) == model
    assert ServoLoopModel.from_vector(PLAY_IN_LOOP, 0.01, model.vector()) == model
    assert model.play == pytest.approx(0.022)
    assert tuple(model.params()) == PARAM_NAMES
    with pytest.raises(ConfigError, match="structure"):
        _model("somewhere")
    with pytest.raises(ConfigError, match="c1"):
        _model(PLAY_IN_LOOP, c1=-0.1)
    with pytest.raises(ConfigError, match="kv"):
        _model(PLAY_IN_LOOP, kv=0.0)
    with pytest.raises(ConfigError, match="unknown"):
        ServoLoopModel.from_dict({**model.to_dict(), "mass": 1.0})


def _light(structure: str, **kw: float) -> ServoLoopModel:
    return _model(structure, **{"ki": 0.0, "a0": 0.0, **kw})


@pytest.mark.parametrize("structure", [OUTPUT_BACKLASH, PLAY_IN_LOOP])
def test_a_vanishing_plastic_load_is_the_massless_play(structure: str) -> None:
    # mu -> 0, e = 0 and a load its friction stops at once: the play operator of the massless load
    u = 0.1 * np.sin(np.arange(600) * 0.03)
    massless = _light(structure)
    heavy = _light(structure, mu=1e-9, e=0.0, al=1e6)  # the load's friction force mu al -> 0 too
    gap = np.max(np.abs(heavy.simulate(u, y0=0.0) - massless.simulate(u, y0=0.0)))
    assert gap < 1e-3 * massless.play
    # and with the option off the kernel is the massless one, whatever the load's other numbers say
    np.testing.assert_array_equal(_light(structure, e=0.7, al=5.0).simulate(u), massless.simulate(u))


@pytest.mark.parametrize("e", [0.0, 0.6])
def test_an_impact_keeps_momentum_and_applies_the_restitution(e: float) -> None:
    # no loop force (kp tiny, no friction anywhere): the motor side coasts at 1 into a load at rest
    model = _light(OUTPUT_BACKLASH, kp=1e-9, kv=1e-9, fc=0.0, fs=0.0, mu=0.5, e=e, al=0.0, c1=0.01, c2=0.01)
    p = model.vector()
    state = np.empty(STATE_SIZE)
    initial_state(p, 0.0, state)
    state[0], state[2] = 0.0, 1.0  # in the middle of the play, moving up
    advance(p, False, state, 0.0, 0.02, 20)  # 20 ms: to the flank at 10 ms, and not yet across the play again
    v, w = state[2], state[4]
    assert v + model.mu * w == pytest.approx(1.0, rel=1e-6)
    assert w - v == pytest.approx(e * 1.0, rel=1e-6, abs=1e-9)
    if e > 0.0:  # the load bounced off: it is ahead of the flank
        assert state[0] - state[1] < model.c1


def test_a_massless_model_writes_no_load_and_old_files_read_as_massless() -> None:
    model = _model(PLAY_IN_LOOP)
    assert tuple(model.params()) == PARAM_NAMES
    old = {k: v for k, v in model.to_dict().items() if k not in ("mu", "e", "al")}
    assert ServoLoopModel.from_dict(old) == model
    heavy = _model(PLAY_IN_LOOP, mu=0.1, e=0.5, al=3.0)
    assert tuple(heavy.params())[-3:] == ("mu", "e", "al")
    with pytest.raises(ConfigError, match="e"):
        _model(PLAY_IN_LOOP, mu=0.1, e=1.5)


def test_a_compliant_contact_kernel_equals_python_and_is_off_without_its_frequency() -> None:
    u = 0.1 * np.sin(np.arange(300) * 0.05)
    model = _model(PLAY_IN_LOOP, mu=0.05, al=3.0, wc=900.0, zeta=0.1)
    assert model.compliant and tuple(model.params())[-2:] == CONTACT_NAMES
    fast = np.empty(u.size)
    slow = np.empty(u.size)
    args = (model.vector(), True, u, 0.0, 0.01, model.substeps)
    simulate_kernel(*args, fast)
    python_version(simulate_kernel)(*args, slow)
    np.testing.assert_allclose(fast, slow, rtol=0, atol=1e-12)
    assert ServoLoopModel.from_vector(PLAY_IN_LOOP, 0.01, model.vector()) == model
    # wc = 0: the rigid impacts, bit for bit (and their files, without the contact's fields)
    rigid = _model(PLAY_IN_LOOP, mu=0.05, e=0.5, al=3.0)
    assert not rigid.compliant and tuple(rigid.params())[-3:] == ("mu", "e", "al")
    np.testing.assert_array_equal(dataclasses.replace(rigid, zeta=0.3).simulate(u), rigid.simulate(u))
    assert ServoLoopModel.from_vector(PLAY_IN_LOOP, 0.01, rigid.vector()[:15]) == rigid
    # mu = 0: the massless play, whatever the contact says
    np.testing.assert_array_equal(
        _model(PLAY_IN_LOOP, wc=900.0, zeta=0.1).simulate(u), _model(PLAY_IN_LOOP).simulate(u)
    )
    # the contact changes the free run: the horn rings on it
    assert np.max(np.abs(model.simulate(u) - rigid.simulate(u))) > 1e-2 * model.play


@pytest.mark.parametrize("zeta", [0.0, 0.1])
def test_a_compliant_contact_keeps_momentum_and_rebounds_as_its_damping_says(zeta: float) -> None:
    # the motor side coasts at 1 into a load at rest; the contact (8 ms of 20, resolved by its own sub-step)
    # keeps the pair's momentum and rebounds with about exp(-zeta pi / sqrt(1 - zeta^2)) (a clipped damper: not exactly)
    model = _light(
        OUTPUT_BACKLASH, kp=1e-9, kv=1e-9, fc=0.0, fs=0.0, mu=0.5, al=0.0, c1=0.01, c2=0.01, wc=2000.0, zeta=zeta
    )
    p = model.vector()
    state = np.empty(STATE_SIZE)
    initial_state(p, 0.0, state)
    state[0], state[2] = 0.0, 1.0
    advance(p, False, state, 0.0, 0.02, 20)
    v, w = state[2], state[4]
    assert v + model.mu * w == pytest.approx(1.0, rel=1e-6)
    assert w - v == pytest.approx(np.exp(-zeta * np.pi / np.sqrt(1.0 - zeta**2)), abs=0.03)
    assert -model.c2 < state[0] - state[1] < model.c1  # apart again, inside the play


def test_the_profile_over_the_play_of_a_horn_on_a_contact_has_its_minimum_at_its_play() -> None:
    # the model's own simulation (a light horn on a contact of 800 rad/s, 4096 counts, 0.3 count of noise), the rest
    # held at the truth: the profile over the play is lowest at the true play, at the record's floor; the massless
    # load with the same loop is far above it (the horn's ringing is in the record)
    truth = _light(PLAY_IN_LOOP, c1=0.011, c2=0.011, mu=0.03, al=20.0, wc=800.0, zeta=0.1)
    t = np.arange(2000) * 0.01
    u = 0.08 * np.sin(2 * np.pi * 0.4 * t) + 0.04 * np.sin(2 * np.pi * 1.1 * t + 1.0)
    q = 2 * np.pi / 4096
    y = np.round((truth.simulate(u) + np.random.default_rng(2).normal(0.0, 0.3 * q, u.size)) / q) * q
    floor = np.sqrt(1.0 / 12.0 + 0.3**2)
    factors = np.linspace(0.85, 1.15, 7)
    rms = [
        np.sqrt(np.mean((dataclasses.replace(truth, c1=f * 0.011, c2=f * 0.011).simulate(u) - y) ** 2)) / q
        for f in factors
    ]
    assert factors[int(np.argmin(rms))] == pytest.approx(1.0)
    assert min(rms) < 1.05 * floor and max(rms[0], rms[-1]) > 1.5 * floor
    massless = dataclasses.replace(truth, mu=0.0, wc=0.0)
    assert np.sqrt(np.mean((massless.simulate(u) - y) ** 2)) / q > 1.25 * floor


@pytest.mark.parametrize("wc", [0.0, 2000.0])
def test_a_load_that_breaks_away_holds_below_its_static_friction_and_slips_above(wc: float) -> None:
    # no loop force (kp, kv tiny), no motor friction: a constant force a0 pushes the motor side into a load at rest on
    # the up flank (rigid or compliant); the load's friction is mu al sliding, mu als at rest
    mu, al, als = 0.5, 4.0, 8.0
    common = {"kp": 1e-9, "kv": 1e-9, "fc": 0.0, "fs": 0.0, "veps": 1e-4, "mu": mu, "e": 0.0, "al": al, "s0": 1.0}
    common.update(c1=0.01, c2=0.01, wc=wc, zeta=0.5)

    def moved(a0: float, **kw: float) -> float:
        model = _light(OUTPUT_BACKLASH, **{**common, "a0": a0, **kw})
        return float(model.simulate(np.zeros(50), y0=0.0)[-1])  # 0.5 s

    between = 0.5 * mu * (al + als)  # above the sliding friction, below the static one
    # without a break-away the load slides off under the force; with it, it holds (creeps at about veps)
    assert moved(between) > 0.2 * 0.5 * (between - mu * al) / (1.0 + mu) * 0.5**2
    assert abs(moved(between, als=als, vls=0.1)) < 1e-3
    # above the static friction it slips; the break-away costs it a little of the way the load without one runs
    above = 1.5 * mu * als
    slipped, sliding = moved(above, als=als, vls=0.1), moved(above)
    assert slipped > 0.2 * 0.5 * (above - mu * als) / (1.0 + mu) * 0.5**2
    assert 0.8 * sliding < slipped < sliding


def test_a_load_that_breaks_away_is_in_the_kernels_and_round_trips() -> None:
    u = 0.1 * np.sin(np.arange(300) * 0.05)
    for wc in (0.0, 900.0):
        model = _model(OUTPUT_BACKLASH, mu=0.6, e=0.3, al=3.0, wc=wc, zeta=0.1, als=5.0, vls=0.02)
        assert model.breaks_away and tuple(model.params())[-2:] == ("als", "vls")
        assert ServoLoopModel.from_vector(OUTPUT_BACKLASH, 0.01, model.vector()) == model
        fast, slow = np.empty(u.size), np.empty(u.size)
        args = (model.vector(), False, u, 0.0, 0.01, model.substeps)
        simulate_kernel(*args, fast)
        python_version(simulate_kernel)(*args, slow)
        np.testing.assert_allclose(fast, slow, rtol=0, atol=1e-12)
        # it changes the free run, and the pair kernel gives it to the bit beside a load without it
        plain = dataclasses.replace(model, als=0.0, vls=0.0)
        assert np.max(np.abs(fast - plain.simulate(u))) > 1e-4 * model.play
        both = [np.empty(u.size), np.empty(u.size)]
        simulate_pair_kernel(model.vector(), plain.vector(), False, u, 0.0, 0.01, model.substeps, *both)
        assert np.array_equal(both[0], fast) and np.array_equal(both[1], plain.simulate(u))
    # at or below the sliding level it is off, bit for bit, and its fields are not written
    rigid = _model(OUTPUT_BACKLASH, mu=0.6, e=0.3, al=3.0)
    off = dataclasses.replace(rigid, als=2.0, vls=0.02)
    assert not off.breaks_away and tuple(off.params())[-1] == "al"
    np.testing.assert_array_equal(off.simulate(u), rigid.simulate(u))


def _exact_steps(m: np.ndarray, period: float, n: int) -> np.ndarray:
    """``n`` host periods of the linear system ``d[s1, s2, 1]/dt = m [s1, s2, 1]`` from rest, exactly (``expm``): the
    two states at each period's end."""
    from scipy.linalg import expm

    step = expm(m * period)
    at, out = np.eye(3), []
    for _ in range(n):
        at = step @ at
        out.append(at[:2, 2])
    return np.array(out)


def _far_step(model: ServoLoopModel, n: int, index: int) -> np.ndarray:
    """``n`` host periods of the loop stepped towards a set point far away (10 rad): the motor speed and state ``index``."""
    p = model.vector()
    state = np.empty(STATE_SIZE)
    initial_state(p, 0.0, state)
    got = []
    for _ in range(n):
        advance(p, False, state, 10.0, model.sample_period_s, model.substeps)
        got.append((state[2], state[index]))
    return np.array(got)


def test_a_velocity_filter_lags_the_loop_as_a_first_order_filter_should() -> None:
    # no friction, no play, no integrator: a set point far away clips the velocity command at vmax, a step of it.
    # The loop is then dv/dt = kv (vmax - vf), dvf/dt = (v - vf) / tv (vf = v without the filter): the motor speed
    # and the filtered one against that system's exact step response, each within the sub-step's error

    kv, vmax, period = 400.0, 2.0, 0.00025
    t = period * np.arange(1, 161)

    def exact(tv: float) -> np.ndarray:
        m = np.zeros((3, 3))
        if tv > 0.0:
            m[:2, :2], m[0, 2] = [[0.0, -kv], [1.0 / tv, -1.0 / tv]], kv * vmax
        else:  # the speed fed back is the speed itself
            m[:2, :2], m[:2, 2] = [[-kv, 0.0], [0.0, -kv]], kv * vmax
        return _exact_steps(m, period, t.size)

    for tv in (0.0, 0.002, 0.01):
        model = ServoLoopModel(OUTPUT_BACKLASH, period, kp=1000.0, kv=kv, vmax=vmax, veps=1e-3, tv=tv)
        assert np.max(np.abs(_far_step(model, t.size, 6) - exact(tv))) < 0.05 * vmax
    # the lag is far beyond that error: the loop with a 10 ms filter overshoots to twice the command, the plain one not
    assert np.max(exact(0.01)[:, 0]) > 2.0 * vmax and np.max(exact(0.0)[:, 0]) <= vmax


#: One load per kernel an opt-in term must reach: massless, rigid impacts, the compliant contact with a break-away.
_KERNEL_LOADS: tuple[dict[str, float], ...] = (
    {},
    {"mu": 0.6, "e": 0.3, "al": 3.0},
    {"mu": 0.6, "al": 3.0, "wc": 900.0, "zeta": 0.1, "als": 5.0, "vls": 0.02},
)


def _check_optional_term(plain: ServoLoopModel, on: ServoLoopModel, name: str, u: np.ndarray) -> None:
    """An opt-in term of the kernels (``name``, last of ``on``'s parameters): off to the bit, on in every kernel.

    A vector without it (an older model's) simulates to the bit as one with it at 0; on, it changes the free run,
    compiled as in Python, and the pair kernel gives both members to the bit, in either order.
    """
    assert on.names()[-1] == name and name not in plain.names()
    assert ServoLoopModel.from_vector(on.structure, 0.01, on.vector()) == on
    assert ServoLoopModel.from_dict(on.to_dict()) == on
    short = np.empty(u.size)
    simulate_kernel(plain.vector()[:-1], plain.feedback_load, u, 0.0, 0.01, plain.substeps, short)
    np.testing.assert_array_equal(plain.simulate(u, y0=0.0), short)
    fast, slow = np.empty(u.size), np.empty(u.size)
    args = (on.vector(), plain.feedback_load, u, 0.0, 0.01, plain.substeps)
    simulate_kernel(*args, fast)
    python_version(simulate_kernel)(*args, slow)
    np.testing.assert_allclose(fast, slow, rtol=0, atol=1e-12)
    assert np.max(np.abs(fast - short)) > 1e-2 * plain.play
    both = [np.empty(u.size), np.empty(u.size)]
    for first, second, want in ((on, plain, (fast, short)), (plain, on, (short, fast))):
        simulate_pair_kernel(first.vector(), second.vector(), plain.feedback_load, u, 0.0, 0.01, plain.substeps, *both)
        assert np.array_equal(both[0], want[0]) and np.array_equal(both[1], want[1])


@pytest.mark.parametrize("structure", [OUTPUT_BACKLASH, PLAY_IN_LOOP])
def test_a_velocity_filter_is_in_every_kernel_and_off_changes_nothing(structure: str) -> None:
    u = 0.1 * np.sin(np.arange(300) * 0.05)
    for load in _KERNEL_LOADS:
        plain = _model(structure, **load)
        _check_optional_term(plain, dataclasses.replace(plain, tv=0.02), "tv", u)
    # a vanishing time constant is the loop without the filter
    plain = _model(structure)
    np.testing.assert_allclose(dataclasses.replace(plain, tv=1e-12).simulate(u), plain.simulate(u), rtol=0, atol=1e-9)


def test_a_torque_lag_lags_the_loop_as_a_first_order_lag_should() -> None:
    # no friction, no play, no integrator: a set point far away clips the velocity command at vmax, a step of it.
    # The loop is then dv/dt = a, da/dt = (kv (vmax - v) - a) / tq (a = kv (vmax - v) without the lag): the motor
    # speed and the drive's torque against that system's exact step response, each within the sub-step's error

    kv, vmax, period = 400.0, 2.0, 0.00025
    t = period * np.arange(1, 161)

    def exact(tq: float) -> np.ndarray:
        m = np.zeros((3, 3))  # [v, a, 1]
        m[0, 1] = 1.0
        m[1, :] = [-kv / tq, -1.0 / tq, kv * vmax / tq]
        return _exact_steps(m, period, t.size)

    for tq in (0.001, 0.004):
        model = ServoLoopModel(OUTPUT_BACKLASH, period, kp=1000.0, kv=kv, vmax=vmax, veps=1e-3, tq=tq)
        got_arr, want = _far_step(model, t.size, 7), exact(tq)
        assert np.max(np.abs(got_arr[:, 0] - want[:, 0])) < 0.05 * vmax
        assert np.max(np.abs(got_arr[:, 1] - want[:, 1])) < 0.05 * kv * vmax
    # the lag is far beyond that error: the loop with a 4 ms lag overshoots by a fifth (damping ratio 0.4), the plain one not
    plain = ServoLoopModel(OUTPUT_BACKLASH, period, kp=1000.0, kv=kv, vmax=vmax, veps=1e-3)
    assert np.max(exact(0.004)[:, 0]) > 1.2 * vmax and np.max(_far_step(plain, t.size, 2)[:, 0]) <= vmax


@pytest.mark.parametrize("structure", [OUTPUT_BACKLASH, PLAY_IN_LOOP])
def test_a_torque_lag_is_in_every_kernel_and_off_changes_nothing(structure: str) -> None:
    u = 0.1 * np.sin(np.arange(300) * 0.05)
    for load in _KERNEL_LOADS:
        for tv in (0.0, 0.004):
            plain = _model(structure, **load, tv=tv)
            _check_optional_term(plain, dataclasses.replace(plain, tq=0.03), "tq", u)
    # a vanishing time constant is the loop without the lag (on the same sub-steps: the lag's own would be 48)
    plain = _model(structure)
    assert dataclasses.replace(plain, tq=1e-12).substeps == 48 and dataclasses.replace(plain, tq=0.01).substeps == 10
    vanishing = np.empty(u.size)
    simulate_kernel(
        dataclasses.replace(plain, tq=1e-12).vector(), plain.feedback_load, u, 0.0, 0.01, plain.substeps, vanishing
    )
    np.testing.assert_allclose(vanishing, plain.simulate(u, y0=0.0), rtol=0, atol=1e-9)
