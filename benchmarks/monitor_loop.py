"""The monitor's servo-loop estimate on a wearing twin: tracking a growing play, the alarm after a step, false alarms.

Run: ``.venv/bin/python benchmarks/monitor_loop.py [--presets xm430 ...] [--full]`` (about 8 minutes
for the two default presets on a shared 2-core machine).

What ``servoid monitor`` runs for a model whose play sits in the loop: the
moving-window refit of the servo-loop model (:class:`servoid.ident.online.window.WindowRefit`),
started from the model file's loop (here: :func:`~servoid.ident.offline.loop_fit.fit_loop`
on 20 s of the unworn twin, as ``servoid identify`` would write it), on every
sample at the host's default rate (200 Hz), refitting the last ``--window`` s
every ``--every`` s; the alarm rule of ``servoid monitor``
(:class:`~servoid.ident.monitoring.alarms.Alarms`, ``--persist`` checks in a row,
2 standard deviations) on the play, one check per refit, against a bound at
+10 % of the median window play over the first 20 s of monitoring (the
monitor's own baseline: the model's play on a physical servo carries the
structure's bias, the same in every window, which an alarm on wear must not
see); the standard deviation is the scatter of those first window plays
(the estimate's own noise) -- the rule of
:class:`~servoid.ident.monitoring.loop_wear.LoopWearTracker`, replayed here on
the refits so that one run gives the alarm times of every rule setting. The twin is the physical one (``drivers/twin``),
driven by gentle sines (the excitation servoid designs for a play in the
loop), its play changed while it runs (:meth:`~servoid.drivers.twin.servo.Twin.set_play`)
every 0.05 s; servo time is virtual, so the run is as fast as the refits.

1. Tracking: the play grows by 50 % over the run (``--track`` s). RMS error of the
   window plays against the true play at each window's end, relative to the true
   play: raw (the model's bias on the twin included) and of the growth
   (estimate / first estimate against truth / first truth: what wear tracking needs).
2. Step: the play x1.2 at 30 s: servo seconds until the alarm.
3. False alarms: ``--quiet`` samples (default 100 000; ``--full`` 1 000 000) without wear: alarms raised.

Also the refit's cost (median and largest wall time per refit: what the worker
thread spends; it must stay under ``--every``). The machine may be shared.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np
from _table import table
from real_servos import SINE_AMPLITUDE  # benchmarks/, on the path when a benchmark runs as a script

from servoid.drivers.twin import Twin, preset
from servoid.excitation.generate import sample
from servoid.excitation.specs import GentleSpec
from servoid.ident.monitoring.alarms import AlarmRule, Alarms, Bound
from servoid.ident.monitoring.loop_wear import MONITOR_EVERY_S, MONITOR_WINDOW_S
from servoid.ident.offline.loop_fit import fit_loop
from servoid.ident.online.window import WindowConfig, WindowRefit

RATE = 200.0
CHUNK_S = 0.05
REFERENCE_S = 20.0
STEP_AT_S = 30.0


def _run(name: str, seconds: float, factor, args: argparse.Namespace, seed: int):  # type: ignore[no-untyped-def]
    """The reference model, then ``seconds`` of monitoring with the play at ``factor(t)`` times the new one."""
    twin = Twin(preset(name), seed=seed)
    twin.enable()
    play0 = twin.truth.play_rad
    n_ref = int(REFERENCE_S * RATE)
    n = int(seconds * RATE)
    spec = GentleSpec(amplitude=SINE_AMPLITUDE[name], accel=8.0 / RATE**2, spread=8.0)
    u = sample(spec, n_ref + n, seed=seed + 1000)
    ref = twin.sample(u[:n_ref], 1.0 / RATE)
    model = fit_loop(np.asarray(ref.u), np.asarray(ref.y), 1.0 / RATE).model
    config = WindowConfig(1.0 / RATE, window_s=args.window, every_s=args.every, first_s=args.window, burn_in_s=0.5)
    est = WindowRefit(config, start=model, background=False)
    chunk = int(CHUNK_S * RATE)
    truth = np.empty(n)
    for i in range(0, n, chunk):
        f = factor(i / RATE)
        twin.set_play(play0 * f)
        rec = twin.sample(u[n_ref + i : n_ref + i + chunk], 1.0 / RATE)
        truth[i : i + chunk] = play0 * f
        for ui, yi in zip(rec.u, rec.y, strict=True):
            est.update(float(ui), float(yi))
    result = est.result(final=False)
    t = np.array([r.t_s for r in result.history])
    plays = result.plays
    at = truth[np.minimum((t * RATE).astype(int) - 1, n - 1)]
    return model, t, plays, at, np.array([r.seconds for r in result.history])


def _alarms(t: np.ndarray, plays: np.ndarray, persist: int) -> list[float]:
    """Times the rule raised an alarm (bound +10 % of the first 20 s's median play, std their scatter)."""
    first = plays[t <= REFERENCE_S]
    std = float(np.std(first))
    rule = Alarms([Bound(quantity="play", high=1.1 * float(np.median(first)))], AlarmRule(persist=persist))
    raised = []
    for ti, p in zip(t, plays, strict=True):
        for ev in rule.check(int(ti * RATE), {"play": (float(p), std)}):
            if ev.raised:
                raised.append(float(ti))
    return raised


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--presets", nargs="+", default=["xm430", "cia402"])
    parser.add_argument(
        "--window", type=float, default=MONITOR_WINDOW_S, help="window, servo s (default: the tracker's)"
    )
    parser.add_argument(
        "--every", type=float, default=MONITOR_EVERY_S, help="refit period, servo s (default: the tracker's)"
    )
    parser.add_argument("--persist", type=int, default=3, help="checks in a row for an alarm (default 3)")
    parser.add_argument("--track", type=float, default=120.0, help="tracking run, servo s (default 120)")
    parser.add_argument("--quiet", type=int, default=100_000, help="samples of the run without wear")
    parser.add_argument("--full", action="store_true", help="1 000 000 samples without wear")
    args = parser.parse_args()
    quiet = 1_000_000 if args.full else args.quiet
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"machine load (1 min): {load:.2f} on {os.cpu_count()} cores", file=sys.stderr)
    rows = []
    for name in args.presets:
        started = time.perf_counter()
        model, t, plays, at, cost = _run(name, args.track, lambda s: 1.0 + 0.5 * s / args.track, args, 1)
        raw = float(np.sqrt(np.mean(((plays - at) / at) ** 2)))
        growth = float(np.sqrt(np.mean((plays / plays[0] - at / at[0]) ** 2)))
        _, ts, ps, _, _ = _run(name, 60.0, lambda s: 1.2 if s >= STEP_AT_S else 1.0, args, 2)
        raised = _alarms(ts, ps, args.persist)
        after = [x - STEP_AT_S for x in raised if x >= STEP_AT_S]
        before = [x for x in raised if x < STEP_AT_S]
        _, tq, pq, _, _ = _run(name, quiet / RATE, lambda s: 1.0, args, 3)
        false = len(_alarms(tq, pq, args.persist))
        rows.append([name, f"{model.play / at[0] - 1:+.1%}", f"{raw:.1%}", f"{growth:.1%}",
                     f"{after[0]:.2f}" if after else "none", str(len(before)), f"{false} in {quiet}",
                     f"{1e3 * np.median(cost):.0f} / {1e3 * np.max(cost):.0f}", f"{time.perf_counter() - started:.0f}"])  # fmt: skip
    table(
        f"monitor, servo-loop window refit (window {args.window:g} s, every {args.every:g} s, persist {args.persist}, "
        f"{RATE:g} Hz)",
        ["preset", "model play vs truth", "track RMS raw", "track RMS growth", "alarm after step s",
         "alarms before step", "false alarms", "refit ms med/max", "wall s"],
        rows,
    )  # fmt: skip


if __name__ == "__main__":
    main()
