"""Does a slower turn of the set point soften the horn's bounce, and the play's bias with it? (issue 12; no).

Run: ``.venv/bin/python benchmarks/horn_turns.py [--presets sts3215,xm430] [--rates 20,50] [--seeds 1,2]
[--variants sines,sines_x0.5,back_off,crawl] [--back 2] [--no-identify]``.

On a servo whose loop closes around the play (the encoder on the horn) the horn
waits at each reversal while the loop drives the motor across the play; the
motor hits the other flank at a speed the loop's error sets, and the horn
bounces off it (the twins' lightly damped gear contact). The bounce is the
STS3215's -15 % (README, "what we learned"). This benchmark drives the horn
twins with ``real_servos.py``'s gentle sines and with variants that slow the
set point where the motor crosses the play, all of the same record length, and
measures on the twin's true state (sampled 8 times per host period):

* **impact speed**: the median relative speed of the motor side of the gear
  and the horn when the motor reaches the far flank after crossing the play,
  output rad/s;
* **rebound**: the median of how far the horn comes back into the play within
  50 ms of each such impact, a fraction of the play;
* identify's answer on the host record (no structure flags): the place, the
  gap, the fit against the record's floor (``real_servos.py``'s columns).

Variants (the set point; the twin as it is unless named):

``sines``
    ``real_servos.py``'s gentle sines (peak acceleration up to 8 rad/s^2).
``sines_x0.5``
    the same with half the peak acceleration (slower everywhere, fewer reversals).
``back_off``
    after each turn the sine runs on until it is ``--back`` plays past the peak,
    then holds there for a quarter of the segment's period and goes on: the
    loop drives the motor across the play with a bounded error.
``crawl``
    the same, but instead of holding the set point creeps on at 0.15 of the
    sine's speed there, then the sine resumes where it meets the creep's end.
``damping_x4``
    the sines on a twin whose gear damping is 4 times the preset's (a
    reference: how small the bounce must get before the bias goes).

Printed as measured; one run each (the machine may be shared).
"""

from __future__ import annotations

import argparse
import math
import warnings

import numpy as np
from _table import table
from real_servos import BANDWIDTH_HZ, DURATION_S, MAX_SAMPLES, NOISE_COUNTS, SINE_AMPLITUDE, answer_fit, run

from servoid.drivers.twin import Twin, preset
from servoid.excitation.generate import sample
from servoid.excitation.gentle import segments
from servoid.excitation.specs import GentleSpec

#: Physics samples per host period.
OVERSAMPLE = 8
#: How long after an impact a rebound is looked for, s.
REBOUND_WINDOW_S = 0.05
#: The crawl's speed, as a share of the sine's where it starts.
CRAWL_SHARE = 0.15
#: The hold or crawl, in periods of the segment's sine.
TURN_PERIODS = 0.25
VARIANTS = ("sines", "sines_x0.5", "back_off", "crawl", "damping_x4")


def _spec(name: str, rate_hz: float, accel_share: float = 1.0) -> GentleSpec:
    """``real_servos.py``'s gentle sines at ``rate_hz`` (their peak acceleration times ``accel_share``)."""
    return GentleSpec(amplitude=SINE_AMPLITUDE[name], accel=accel_share * 8.0 / rate_hz**2, spread=8.0)


def _turn_phase(k: int, x_ratio: float) -> float:
    """The phase (rad) in the half-period after turn ``k`` (``k`` even: a peak, odd: a trough) where ``sin`` is ``x_ratio``."""
    base = math.pi * (k - k % 2)
    return base + (math.pi - math.asin(x_ratio) if k % 2 == 0 else 2.0 * math.pi + math.asin(x_ratio))


def slowed_turns(spec: GentleSpec, n: int, seed: int, back: float, share: float) -> np.ndarray:
    """The gentle sines of ``spec`` with each turn slowed once the set point is ``back`` (unit of u) past it.

    From there the set point holds (``share`` 0) or creeps at ``share`` of the sine's speed for
    ``TURN_PERIODS`` of the segment's period, then the sine resumes where it meets that value.
    """
    out: list[np.ndarray] = []
    total, j = 0, 0
    while total < n:
        amp_a, f_a, length_a = segments(spec, seed, j, 1)
        amp, f, length = float(amp_a[0]), float(f_a[0]), int(length_a[0])
        w = 2.0 * math.pi * f
        steps = max(1, round(TURN_PERIODS / f))
        past = math.acos(max(-1.0, 1.0 - back / amp))  # phase from a turn to ``back`` past it
        pieces, t = [], 0.0
        for k in range(2 * spec.cycles):
            start = (math.pi / 2 + math.pi * k + past) / w
            if start >= length:
                break
            times = t + np.arange(0.0, math.floor(start - t) + 1.0)
            pieces.append(amp * np.sin(w * times))
            x0, v0 = pieces[-1][-1], amp * w * math.cos(w * times[-1])
            pieces.append(x0 + share * v0 * np.arange(1, steps + 1))
            t = _turn_phase(k, float(np.clip(pieces[-1][-1] / amp, -1.0, 1.0))) / w + 1.0
        pieces.append(amp * np.sin(w * (t + np.arange(0.0, max(0.0, math.floor(length - t))))))
        seg = spec.offset + np.concatenate(pieces)
        out.append(seg)
        total += seg.size
        j += 1
    return np.concatenate(out)[:n]


def set_points(name: str, rate_hz: float, seed: int, variant: str, back_plays: float) -> np.ndarray:
    """The variant's set point, ``real_servos.py``'s record length."""
    n = int(min(DURATION_S * rate_hz, MAX_SAMPLES))
    if variant in ("sines", "damping_x4"):
        return sample(_spec(name, rate_hz), n, seed=seed + 1000)
    if variant == "sines_x0.5":
        return sample(_spec(name, rate_hz, 0.5), n, seed=seed + 1000)
    back = back_plays * preset(name).play_rad
    share = 0.0 if variant == "back_off" else CRAWL_SHARE
    return slowed_turns(_spec(name, rate_hz), n, seed + 1000, back, share)


def impacts(gap: np.ndarray, play: float, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """Impact speeds (output rad/s) and rebounds (fraction of the play) from the gear's true gap.

    ``gap`` is the motor side of the gear minus the horn (output rad), sampled every ``dt``: an
    impact is the first sample in contact with a flank other than the last one touched.
    """
    half = 0.5 * play
    side = np.where(gap >= half, 1, np.where(gap <= -half, -1, 0))
    speed = np.gradient(gap, dt)
    window = round(REBOUND_WINDOW_S / dt)
    touched = side[np.nonzero(side)]
    at = np.nonzero(side)[0][1:][np.diff(touched) != 0]
    rebound = [max(0.0, float(np.max(half - side[i] * gap[i : i + window]))) / play for i in at]
    return np.abs(speed[at]), np.asarray(rebound)


def row(name: str, mult: float, seed: int, variant: str, back_plays: float, fit: bool) -> list[str]:
    """One record: its impacts and, with ``fit``, identify's answer on the host samples."""
    over: dict[str, object] = {"encoder_noise_counts": NOISE_COUNTS, "load_encoder_cpr": 4096}
    if variant == "damping_x4":
        over["gear_damping_nms"] = 4.0 * preset(name).gear_damping_nms
    twin = Twin(preset(name, **over), seed=seed)
    twin.enable()
    rate = mult * BANDWIDTH_HZ[name]
    u = set_points(name, rate, seed, variant, back_plays)
    rec = twin.sample(np.repeat(u, OVERSAMPLE), 1.0 / (rate * OVERSAMPLE))
    play = twin.truth.play_rad
    speeds, rebounds = impacts(rec.true_gear_side_rad - rec.true_load_rad, play, 1.0 / (rate * OVERSAMPLE))
    cells = [name, f"{mult:g}x", str(seed), variant, str(u.size), str(speeds.size),
             f"{float(np.median(speeds)):.3f}", f"{float(np.median(rebounds)):.3f}"]  # fmt: skip
    if not fit:
        return cells
    y = np.asarray(rec.y)[::OVERSAMPLE]  # the host's readings: the same as sampling at the host's rate
    result, seconds = run(u, y, 1.0 / rate)
    floor = twin.truth.output_rad_per_count * math.sqrt(1.0 / 12.0 + NOISE_COUNTS**2) / float(np.std(y))
    return [*cells, result.structure, f"{100 * (result.play / play - 1):+.1f} %", f"{answer_fit(result) / floor:.2f}",
            f"{seconds:.1f}"]  # fmt: skip


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--presets", default="sts3215,xm430", help="comma-separated horn presets")
    ap.add_argument("--rates", default="20,50", help="comma-separated rates, multiples of the loop bandwidth")
    ap.add_argument("--seeds", default="1,2", help="comma-separated twin seeds")
    ap.add_argument("--variants", default=",".join(VARIANTS), help=f"comma-separated, of {', '.join(VARIANTS)}")
    ap.add_argument("--back", type=float, default=2.0, help="back_off and crawl: plays past the turn (default 2)")
    ap.add_argument("--no-identify", action="store_true", help="the impacts only (seconds, not minutes)")
    args = ap.parse_args()
    warnings.filterwarnings("ignore", category=RuntimeWarning)
    rows = []
    for variant in args.variants.split(","):
        if variant not in VARIANTS:
            raise SystemExit(f"variant (={variant!r}) must be one of {', '.join(VARIANTS)}")
        for name in args.presets.split(","):
            for mult in args.rates.split(","):
                for seed in args.seeds.split(","):
                    rows.append(row(name, float(mult), int(seed), variant, args.back, not args.no_identify))
                    print(" | ".join(rows[-1]), flush=True)
    cols = ["preset", "rate", "seed", "set point", "samples", "impacts", "impact rad/s", "rebound / play"]
    if not args.no_identify:
        cols += ["structure", "gap", "fit/floor", "s"]
    table("Impacts at the far flank after crossing the play (median) and identify's answer", cols, rows)


if __name__ == "__main__":
    main()
