"""The horn stage (:mod:`servoid.ident.offline.horn_contact`) on the servo-loop model's own simulations.

A light horn on a compliant, lightly damped gear contact (the play in the loop) rebounds off the
flank the motor hits; the massless fit books that as less play (here -11 ... -14 %, one seed +42 %).
The stage, run where the rebound is named, keeps its answer only where it validates better: on
these seeds it gives the play back on 2 of 3 (-13.0 -> +0.6 %, +42.0 -> +12.1 %); on the third its
first stage (the horn fitted with the massless loop held) loses the play and the answer stays. A
massless record names no rebound and is left as it is.
"""

from __future__ import annotations

import numpy as np

from servoid.excitation.generate import sample
from servoid.excitation.specs import GentleSpec
from servoid.ident.models.servo_loop import ServoLoopModel
from servoid.ident.models.structure_names import PLAY_IN_LOOP
from servoid.ident.offline import horn_contact as hc
from servoid.ident.offline import loop_fit as lf
from servoid.ident.offline.horn_contact import REASON, with_horn
from servoid.ident.offline.loop_fit import fit_loop

#: 20x an STS3215-like loop's bandwidth, s.
PERIOD = 1.0 / 140.0
#: Record length, s.
SECONDS = 40.0
#: An STS3215-like loop (the values a fit of the twin gives) with the play in the loop.
LOOP = dict(kp=28.7, kv=47.9, fc=11.0, fs=14.1, vs=0.03, veps=0.003, c1=0.0052, c2=0.0052)
#: 4096 counts a turn.
Q = 2.0 * np.pi / 4096


def _record(seed: int, seconds: float = SECONDS, **horn: float) -> tuple[np.ndarray, np.ndarray, ServoLoopModel]:
    """Gentle sines through the model (``horn``: its ``mu``, ``al``, ``wc``, ``zeta``), 0.3 count of noise, 4096 counts."""
    model = ServoLoopModel(structure=PLAY_IN_LOOP, sample_period_s=PERIOD, **LOOP, **horn)
    u = sample(GentleSpec(amplitude=0.1, accel=8.0 * PERIOD**2, spread=8.0), int(seconds / PERIOD), seed=seed)
    y = model.simulate(u) + np.random.default_rng(seed).normal(0.0, 0.3 * Q, u.size)
    return u, np.round(y / Q) * Q, model


def test_the_horn_stage_gives_back_play_a_rebounding_horn_hides_or_leaves_the_answer(monkeypatch):
    # the stage's two fits and refit; its profile over the play (passes here too, at twice the time: 55 s against
    # 26 s at load 5) has its own test below
    monkeypatch.setattr(hc, "PLAY_PROFILE", ())
    kept = 0
    for seed in (1, 2, 3):
        u, y, model = _record(seed, mu=0.026, al=20.0, wc=775.0, zeta=0.078)
        choice = fit_loop(u, y, PERIOD, load=None)
        horn = with_horn(u, y, PERIOD, choice)
        assert choice.structure == PLAY_IN_LOOP
        massless, found = choice.play / model.play - 1.0, horn.play / model.play - 1.0
        if not horn.model.compliant:  # not kept (it did not validate better): the massless answer as it was
            assert horn.play == choice.play and horn.reasons == choice.reasons
            continue
        kept += 1
        assert abs(found) < 0.15 and abs(found) < abs(massless)
        assert REASON in horn.reasons and horn.fit_nrmse < choice.fit_nrmse
        low, high = horn.play_interval
        mirror = 2.0 * horn.play - choice.play  # the correction as uncertain as it is large
        assert low <= min(horn.play, choice.play, mirror) and high >= max(horn.play, choice.play, mirror)
    assert kept >= 1


def test_a_massless_record_is_left_as_it_is():
    u, y, _ = _record(3)
    choice = fit_loop(u, y, PERIOD, load=None)
    assert with_horn(u, y, PERIOD, choice) is choice


def test_a_record_with_gaps_gets_the_stage_and_about_the_gapless_answer():
    """3 % of the readings lost (NaN, as a live session leaves them): the stage fits through them.

    A 10 s record (seed 2, where the stage keeps the horn without gaps: on 10 s records it keeps it
    on 3 of seeds 1-5, the validation being short) from the same massless answer: gapless -1.7 %,
    with the gaps -3.5 % (seeds 4 / 5: -4.2 / -1.1 % gapless, not kept / -0.3 % with the gaps).
    """
    u, y, model = _record(2, seconds=10.0, mu=0.026, al=20.0, wc=775.0, zeta=0.078)
    choice = fit_loop(u, y, PERIOD, load=None)
    gapless = with_horn(u, y, PERIOD, choice)
    keep = np.random.default_rng(2).random(u.size) > 0.03
    gaps = with_horn(u, np.where(keep, y, np.nan), PERIOD, choice, keep)
    assert gapless.model.compliant and gaps.model.compliant and REASON in gaps.reasons
    assert abs(gaps.play - gapless.play) < 0.05 * model.play
    assert (
        np.isfinite(gaps.fit_nrmse) and np.all(np.isfinite(gaps.play_interval)) and np.all(np.isfinite(gaps.simulated))
    )


def test_the_profile_over_the_play_leaves_a_play_held_short_of_the_truth(monkeypatch):
    """A horn model whose play is held 15 % short (the rest at the truth): the profile's point above it costs less."""
    u, y, model = _record(1, seconds=5.0, mu=0.026, al=20.0, wc=775.0, zeta=0.078)
    monkeypatch.setattr(hc, "PLAY_PROFILE", (0.85, 1.17))
    d = dict(hc._values(model), play=0.85 * model.play)
    free = lf._free(PLAY_IN_LOOP, False) + hc.HORN
    kept = np.ones(u.size, dtype=bool)
    a_scale = 0.1 * LOOP["kv"] * float(np.std(np.diff(y))) / PERIOD
    found, spent = hc._profiled(u, y, PERIOD, d, kept, a_scale, False, free)
    assert spent > 0 and found is not d
    assert abs(found["play"] / model.play - 1.0) < 0.15
    assert lf._cost(u, y, PERIOD, PLAY_IN_LOOP, found, kept) < lf._cost(u, y, PERIOD, PLAY_IN_LOOP, d, kept)
    monkeypatch.setattr(hc, "PLAY_PROFILE", ())
    assert hc._profiled(u, y, PERIOD, d, kept, a_scale, False, free) == (d, 0)
