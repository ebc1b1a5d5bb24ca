"""Why the horn stage does not size the play on a live design (issues 15 and 12): the sines' acceleration and length.

Run: ``.venv/bin/python benchmarks/horn_live.py [--seeds 1 2] [--accels 8 16.5] [--seconds 20 40] [--live-seeds 0 1]
[--no-live]`` (about 5 minutes on a shared 2-core machine).

Offline, the horn stage (``ident/offline/horn_contact.py``) brought the STS3215 table rows
(``real_servos.py``: 40 s of gentle sines, peak accelerations 1-8 rad/s^2) within 10 %; on the live
design's records (``servoid identify --driver sim://...``: a third of 40 s at 0.15x the probe's
bandwidth, then the fast phase at 0.35x, 16.5 rad/s^2 on the STS3215) it does not. Two tables:

1. **Offline records of the STS3215 twin** at the live rate (200 Hz, the preset as ``sim://`` reads it,
   no added noise), gentle sines of amplitude 0.1 rad with peak accelerations up to ``--accels``
   (spread 8, as both designs), ``--seconds`` long: ``fit_loop(load=None)`` (the massless answer) and
   ``with_horn`` after it (as identification's second structure runs them), on the record and on its
   first 95 % (how far the answer moves when the record ends 5 % earlier).
2. **Live records** (``--live-seeds``, ``identify --driver "sim://PRESET?clock=virtual" --seed S``,
   the STS3215 and the XM430): the answer, then its play refitted alone, every other parameter held
   (:func:`~servoid.ident.monitoring.play_fit.fit_play`, the monitor's play fit), scored on the slow
   part and on the fast part's reversals by thirds of the set point's peak acceleration at each turn
   (the simulation runs through the record, the loss skips the rest): where the load coasts at the
   fastest turns the play read falls with the acceleration; where the motor's stall band inflates
   the slowest, it rises at the low end.

Printed as measured (the machine may be shared).
"""

from __future__ import annotations

import argparse
import dataclasses
import tempfile
from pathlib import Path

import numpy as np
from _table import table
from online import run  # benchmarks/, on the path when a benchmark runs as a script

from servoid.drivers.twin import Twin, preset
from servoid.excitation.generate import sample
from servoid.excitation.specs import GentleSpec
from servoid.ident.models.servo_loop import ServoLoopModel
from servoid.ident.monitoring.play_fit import fit_play
from servoid.ident.offline.horn_contact import with_horn
from servoid.ident.offline.loop_fit import fit_loop
from servoid.loop_compensation import loop_model
from servoid.modelfile import load_model
from servoid.recording import read_recording

RATE = 200.0
AMPLITUDE = 0.1
#: The share of a record the shorter fit sees.
SHORTER = 0.95


def _record(accel: float, seconds: float, seed: int) -> tuple[np.ndarray, np.ndarray]:
    """The STS3215 twin driven by gentle sines up to ``accel`` rad/s^2 for ``seconds`` at :data:`RATE`."""
    twin = Twin(preset("sts3215"), seed=seed)
    twin.enable()
    spec = GentleSpec(amplitude=AMPLITUDE, accel=accel / RATE**2, spread=8.0)
    rec = twin.sample(sample(spec, int(seconds * RATE), seed=seed + 1000), 1.0 / RATE)
    return np.asarray(rec.u, dtype=np.float64), np.asarray(rec.y, dtype=np.float64)


def _fits(u: np.ndarray, y: np.ndarray, truth: float) -> str:
    """The massless answer's play error, then the horn stage's (kept or not), on one record."""
    choice = fit_loop(u, y, 1.0 / RATE, load=None)
    horn = with_horn(u, y, 1.0 / RATE, choice)
    kept = "kept" if horn.model.compliant else "not kept"
    return f"{choice.play / truth - 1:+.1%} / {horn.play / truth - 1:+.1%} {kept}"


def offline_rows(accels: list[float], seconds: list[float], seeds: list[int]) -> list[list[str]]:
    truth = Twin(preset("sts3215")).truth.play_rad
    rows = []
    for accel in accels:
        for length in seconds:
            for seed in seeds:
                u, y = _record(accel, length, seed)
                m = int(SHORTER * u.size)
                rows.append([f"{accel:g}", f"{length:g}", str(seed), _fits(u, y, truth), _fits(u[:m], y[:m], truth)])
    return rows


def turn_accel(u: np.ndarray, period: float) -> np.ndarray:
    """Each sample's latest set-point turn's peak acceleration, unit/s^2 (NaN before the first turn).

    A turn is where the set point's steps change sign; a gentle sine's peak acceleration is at its turns.
    """
    step = np.sign(np.diff(u))
    turns = np.flatnonzero((step[1:] != 0) & (step[:-1] != 0) & (step[1:] != step[:-1])) + 1
    acc = np.full(u.size, np.nan)
    ends = [*turns[1:].tolist(), u.size]
    for k, end in zip(turns.tolist(), ends, strict=True):
        acc[k:end] = abs(u[k + 1] - 2.0 * u[k] + u[k - 1]) / period**2
    return acc


def live_rows(names: list[str], seeds: list[int]) -> list[list[str]]:
    rows = []
    for name in names:
        truth = Twin(preset(name)).truth.play_rad
        for seed in seeds:
            with tempfile.TemporaryDirectory() as tmp:
                out = Path(tmp) / "run"
                result, error, _ = run(f"sim://{name}?clock=virtual", None, out, seed)
                if result is None:
                    rows.append([name, str(seed), error, "", "", "", ""])
                    continue
                rec = read_recording(out / "recording.csv")
                period = 1.0 / float(result["acquisition"]["rate_hz"])
                held: ServoLoopModel = dataclasses.replace(
                    loop_model(load_model(out / "model.json")), sample_period_s=period
                )
            u, y = np.asarray(rec.u, dtype=np.float64), np.asarray(rec.y, dtype=np.float64)
            acc = turn_accel(u, period)
            fast = np.arange(u.size) >= int(result["slow_samples"])
            edges = np.quantile(acc[fast & np.isfinite(acc)], [1.0 / 3.0, 2.0 / 3.0])
            masks = [
                ~fast & np.isfinite(acc),
                fast & (acc <= edges[0]),
                fast & (acc > edges[0]) & (acc <= edges[1]),
                fast & (acc > edges[1]),
            ]
            plays = [f"{fit_play(u, y, m, held)[0].play / truth - 1:+.1%}" for m in masks]
            top = float(np.nanmax(acc[fast]))
            rows.append([name, str(seed), f"{held.play / truth - 1:+.1%} ({result['answer']['source']})",
                         *plays[:1], f"{plays[1]} / {plays[2]} / {plays[3]}",
                         f"{edges[0]:.1f} / {edges[1]:.1f} / {top:.1f}"])  # fmt: skip
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--accels", type=float, nargs="+", default=[8.0, 16.5], help="peak accelerations, rad/s^2")
    parser.add_argument("--seconds", type=float, nargs="+", default=[20.0, 40.0], help="record lengths, s")
    parser.add_argument("--live-seeds", type=int, nargs="+", default=[0, 1])
    parser.add_argument("--no-live", action="store_true", help="the offline table only")
    args = parser.parse_args()
    table(
        f"STS3215 twin at {RATE:g} Hz, gentle sines of {AMPLITUDE:g} rad: fit_loop(load=None) / with_horn, play error",
        ["accel rad/s^2", "s", "seed", "massless / horn", f"on the first {SHORTER:.0%}"],
        offline_rows(args.accels, args.seconds, args.seeds),
    )
    if not args.no_live:
        table(
            "identify --driver sim:// (virtual): the answer's play, then the play alone refitted (the loop held) "
            "on the slow part and on the fast part's turns by thirds of their peak acceleration",
            ["preset", "seed", "answer", "slow part", "fast: low / mid / top third", "thirds' upper ends rad/s^2"],
            live_rows(["sts3215", "xm430"], args.live_seeds),
        )
    print("done")


if __name__ == "__main__":
    main()
