"""The monitor's play estimate of a servo loop on the wearing twins: tracking a growing play, the alarm after a step, false alarms.

Run: ``.venv/bin/python benchmarks/monitor_loop.py [--presets xm430 ...] [--track 60] [--file live] [--full]`` (one table, every
twin preset by default; about 10 minutes, 40 with ``--full``, on a shared 2-core machine).

What ``servoid monitor`` runs for a model whose play sits in the loop, the
same object: :class:`~servoid.ident.monitoring.loop_wear.LoopWearTracker`
(here with ``background=False``: each refit inside the feed, as on a virtual
clock), started from the model file's loop (here: ``servoid identify --data`` on a
recording of 20 s (40 s where that file holds a horn sized on too short a record; ``--reference-s``) of the unworn twin, its ``model.json`` read back as ``servoid
monitor`` reads it: the loop, the play's interval, the identifiable flag; one
file per preset, from the tracking run's twin, used by all three runs, as a user
identifies once and monitors many times), fed every sample at the host's default
rate (200 Hz): the file's loop, its gains held, its play refitted on the first 10 s (``--free-loop``: the whole
loop, the code before), then the play alone
on 1.6 s windows every 0.25 s, their scatter over the next 20 s, then the
CUSUM against the bounds ``--dead-zone 10%`` sets (+/- 10 % of the model
file's play, moved to the median estimate). The twin is the physical one
(``drivers/twin``), driven by gentle sines (the excitation servoid designs
for a play in the loop), its play changed while it runs
(:meth:`~servoid.drivers.twin.servo.Twin.set_play`) every 0.05 s; servo time is
virtual, so a run is as fast as the refits.

1. Tracking: the play grows by 50 % over the run (``--track`` s). RMS error of the
   tracking estimate (the mean of the last 5 s of window plays) against the true
   play at each estimate, from the end of the baseline (30 s) on, relative to the
   true play: raw (the model's structural bias on the twin included) and of the
   growth (estimate / first estimate against truth / first truth: what wear
   tracking needs); and the raw RMS of the single window plays. The raw error
   split: its constant bias (the median of estimate / truth: the file's loop's,
   the same in every window, which ``--dead-zone P%`` re-baselines away), the
   RMS with the bias out (the monitor's own error), and that without the mean's
   lag (against the truth 2.5 s earlier: the window plays' scatter and gain).
2. Step: the play x1.2 at 40 s: servo seconds from the step to the alarm
   (``none`` when there was none in 20 s), and alarms before the step.
3. False alarms: ``--quiet`` samples (default 100 000; ``--full`` 1 000 000) without wear:
   alarms raised; beside it that run's baseline: the scatter of the window plays
   (and the CUSUM's sigma, its upper 95 % bound), their correlation time tau in
   estimates, the threshold h and the mean samples between false alarms it
   implies (Siegmund, the module text of ``cusum.py``).
4. Doubt: whether the tracking run's first refit of the whole loop moved the play
   outside the model file's 95 % interval, or the file calls its play not
   identifiable, with the first refit's play against the truth: ``servoid
   monitor`` then says so and, its bounds in %, re-baselines on that refit
   (:attr:`LoopWearTracker.doubt`).

``--file live``: the model file is what ``servoid identify --driver
"sim://PRESET?clock=virtual&seed=1"`` writes (the probe, then its designed
60 s run: a slow phase and gentle sines fitted to the probe's bandwidth, the
servo-loop model on the decimated record), the file a user who identifies
live has, instead of ``identify --data`` on the 20 s reference. Why both: on
the XM430 twin neither identification places the play (both files "not
identifiable", the two places fitting the record equally), and which place
the 20 s reference's winner takes turns with the seed and the encoder's
noise (seeds 1-3 without noise: outside +115 %, inside -8 %, outside
+210 %; with 0.3 count of noise, as ``real_servos.py`` records: inside
+12 %, outside +203 %, inside -7 %); the live file put it inside (-25 %).
The monitor's raw tracking and its false alarms follow the file's place (a
play outside the loop on the XM430: the window plays wander with the
sines' segments by -13 ... +28 %, one false alarm in 10^5 samples), so the
table is measured with both files, and the default stays the recording for
comparison with the tables before it (docs/monitor.md).

``--reference-s``: the length of that recording. Default: by the evidence of the file, as a user would
redo it: 20 s, then 40 s where that file holds the play in the loop on a compliant contact (the horn
stage's answer, which sizes its play only on about 40 s of sines: ``benchmarks/horn_live.py``,
docs/online.md, "The horn stage on live records"; on the STS3215 -23.4 % on 20 s, -1.6 % on 40 s). A
play outside the loop (CiA 402, ODrive) or a massless loop (the XM430's 20 s file) keeps 20 s: 40 s moved
the ODrive's raw tracking 0.3 -> 7.2 % and the XM430's file to a horn whose window plays cost 235-540 ms
an estimate, near or past the 250 ms between them. The table's reference column says which was used.

``--file-seed``: the twin seed of the unworn run the data file is identified on (default 1, the tables before).
On the horn twins the file's loop sets the level of every window play: with the seed-2 files (XM430 -7.5 %, STS3215
-1.0 % on 40 s) raw tracking read 21-25 % and 14-15 % where the seed-1 files read 8-16 % and 0.4-11 %
(docs/monitor.md, "the first fit with the file's loop held").

``--calibrate``: the window plays read relative to the model file's play (``LoopWearTracker(calibrate=True)``: the
first 2.5 s of counted window plays read the file's play, every later one that times its change since;
``servoid monitor``'s ``CALIBRATE``, off). It assumes the play is the file's while it calibrates, 12-15 s into the
run: ``--wear-from S`` holds the tracking run's play at the unworn one for its first ``S`` s, then grows it by 50 %
by the run's end (default 0: from the start, the tables before). docs/monitor.md, "The window plays read relative to
the file".

``--dither D``: the steady sine's amplitude drawn anew each period, log-uniform in ``[(1 - D) A, A]`` at the same peak
acceleration (:func:`~servoid.excitation.monitor_input.monitor_spec`'s ``dither``; default 0, one amplitude). The horn
twins' firmware closes its loop on whole counts of the horn's encoder, and a steady sine reverses at one place on that
grid, where the held loop reads the play with a bias of its own (docs/monitor.md, "the count grid").

``--cycle N``: the steady sine's amplitude steps deterministically, a count / N smaller each half-period over N values
(:func:`~servoid.excitation.monitor_input.cycled_sine`): every reversal side passes N places of the grid, and a window
of 1.6 s (about 3 reversals) holds the cycle's places as evenly as N allows. Default: ``servoid monitor``'s
(:func:`~servoid.excitation.monitor_input.default_input`): the steady sine, ``CYCLED_DEFAULT`` off (on, N =
``CYCLE_STEPS`` where the model file's play sits inside the loop); ``--cycle 4``: what ``servoid monitor --input
cycled`` runs; ``--cycle 0``: the steady sine of one amplitude, the input before (moncycle21). The count comes as ``servoid monitor`` takes it: from the readings of the monitor's own first fit, up to
the sample where the steady part starts (:func:`~servoid.excitation.monitor_input.grid_count`, the same samples
:class:`~servoid.monitor_loop.ReadingsGrid` keeps; mongrid20 took it from the reference's readings); where they show
none, the steady sine runs, and the input column says why.
``--whole-halves``: the cycle's half-periods of whole samples (:data:`~servoid.excitation.monitor_input.WHOLE_HALVES`,
off): of the length the peak acceleration gives, each peak falls at another place between two samples, sliding from
cycle to cycle, and the window plays beat with it; whole, the sampled cycle repeats (docs/monitor.md, moncyc22).
``--even-phases M``: the cycle's peaks pass M sample phases evenly (:data:`~servoid.excitation.monitor_input.EVEN_PHASES`,
off): the sampled pattern repeats after ``lcm(N, 2, M)`` half-periods (docs/monitor.md,
monphase22).

``--seeds``: the twin seeds of the step run (default 2); the alarm column gives one delay per seed.

``--track-seeds``: the twin seeds of the tracking run (default 1, the tables before); the raw and bias
columns give one number per seed, the other tracking columns are the first seed's. One draw says
little on the XM430 twin: with the same data file, seed 1 tracked 8.0 % raw, seeds 2 / 4 / 5 13.3-15.7 %
(docs/monitor.md, "what the XM430's tracking bias is made of").

``--input``: the monitoring input after the first fit (the first 10 s, the
whole loop's refit, stay the identification's gentle sines, whose segments of
many amplitudes and accelerations the loop's parameters need). ``sine``
(default): one segment kind, the identification's highest amplitude at half
its highest acceleration (4 rad/s^2, ``SINE_ACCEL_SHARE``; at 8 rad/s^2 the
XM430's windows saw +6 % of a +20 % step), a steady sine of 2.0-4.5 reversals
a second (2-5 in a window), built by :func:`servoid.excitation.monitor_input.monitor_spec`, as
``servoid monitor`` builds its default input for a servo-loop model file with a design.
The monitor drives the servo, so this is its choice: the window plays held at
one loop carry a bias that depends on the segment (on the XM430 twin held at
the wrong place +10 % on slow segments, +6 % on large ones; on the ODrive -4 %
on small ones, and its false alarm was 5 windows at -19 ... -21 % across the
junction of a large segment and one of 2.5 times the play), and gentle sines of many segments made that bias wander over
seconds: the 2 s scatter that set the alarm's delay, and every false alarm of
10^6 samples. One segment kind holds the bias still (the baseline takes it
out). ``ident``: the identification's sines throughout, the tables before.
``--min-reversals``: fewest reversals a window's readings must hold for its
play to count (``LoopWearTracker``'s rule; 0: every window, as before).

``--fresh``: the first fit searches both places of the play from scratch on the
monitor's first 10 s (``LoopWearTracker(fresh=True)``) instead of refitting the
file's loop: what a monitor could do when the file does not place the play.

Also the wall time per estimate (median / largest: what the worker thread spends;
it must stay under 0.25 s). The machine may be shared.
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import io
import math
import os
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
from _table import table
from real_servos import SINE_AMPLITUDE  # benchmarks/, on the path when a benchmark runs as a script

from servoid.cli import main as servoid_main
from servoid.drivers.twin import Twin, preset
from servoid.drivers.twin.presets import PRESETS
from servoid.excitation.generate import sample
from servoid.excitation.gentle import segment_end
from servoid.excitation.monitor_input import (
    CYCLE_STEPS,
    CYCLED,
    EVEN_PHASES,
    IDENT,
    MONITOR_INPUTS,
    SINE,
    SINE_ACCEL_SHARE,
    WHOLE_HALVES,
    GridCount,
    cycled_sine,
    default_input,
    grid_count,
    monitor_spec,
)
from servoid.ident.models.structure_names import PLAY_IN_LOOP
from servoid.ident.monitoring.alarms import Bound
from servoid.ident.monitoring.loop_wear import FIRST_FIT_S, MIN_REVERSALS, PLAY, TRACK_S, LoopWearTracker, PlayRow
from servoid.loop_compensation import loop_model
from servoid.modelfile import ModelFile, load_model
from servoid.monitor_loop import CALIBRATE, HOLD_LOOP, HORN_RECORD_S, short_horn
from servoid.recording import write_recording

RATE = 200.0
CHUNK_S = 0.05
REFERENCE_S = 20.0
STEP_AT_S = 40.0
#: The tracking estimate is scored from here on (the first fit and the scatter's baseline done).
SCORED_FROM_S = 30.0


def _excitation(name: str, n: int, seed: int) -> np.ndarray:
    """The gentle sines servoid designs for a play in the loop, ``n`` samples."""
    return sample(monitor_spec(IDENT, SINE_AMPLITUDE[name], 8.0 / RATE**2), n, seed=seed + 1000)


def _monitor_input(
    name: str, n: int, seed: int, kind: str, share: float = SINE_ACCEL_SHARE, dither: float = 0.0
) -> np.ndarray:
    """The monitoring input after the first fit (:data:`~servoid.excitation.monitor_input.MONITOR_INPUTS`), ``n`` samples.

    ``share``: the steady sine's peak acceleration over the identification's (``servoid monitor``'s
    :data:`~servoid.excitation.monitor_input.SINE_ACCEL_SHARE`; 1 before). ``dither``: the steady sine's amplitude
    drawn each period (:func:`~servoid.excitation.monitor_input.monitor_spec`; 0: one amplitude).
    """
    scale = share / SINE_ACCEL_SHARE if kind == SINE else 1.0
    spec = monitor_spec(kind, SINE_AMPLITUDE[name], scale * 8.0 / RATE**2, dither=dither if kind == SINE else 0.0)
    return sample(spec, n, seed=seed + 2000)


def _live_file(name: str, seed: int) -> ModelFile:
    """What ``servoid identify --driver`` writes for the unworn twin (the probe, then its designed 60 s run), virtual time."""
    with tempfile.TemporaryDirectory() as tmp:
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
            status = servoid_main(["identify", "--driver", f"sim://{name}?clock=virtual&seed={seed}", "--out",
                                   str(Path(tmp) / "run"), "--no-plots", "--json"])  # fmt: skip
        if status != 0:
            raise SystemExit(f"servoid identify --driver failed on the {name} twin ({status})")
        return load_model(Path(tmp) / "run" / "model.json")


def _model_file(name: str, seed: int, reference_s: float = REFERENCE_S) -> ModelFile:
    """What ``servoid identify --data`` writes for ``reference_s`` of the unworn twin (the run's first part)."""
    twin = Twin(preset(name), seed=seed)
    twin.enable()
    n_ref = int(reference_s * RATE)
    ref = twin.sample(_excitation(name, n_ref, seed), 1.0 / RATE)
    with tempfile.TemporaryDirectory() as tmp:
        data = write_recording(Path(tmp) / "reference.csv", {"t": np.arange(n_ref) / RATE, "u": ref.u, "y": ref.y},
                               metadata={"servoid recording": "", "input_unit": "rad", "unit": "rad"})  # fmt: skip
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
            status = servoid_main(["identify", "--data", str(data), "--out", str(Path(tmp) / "run"), "--no-plots",
                                   "--json"])  # fmt: skip
        if status != 0:
            raise SystemExit(f"servoid identify failed on the {name} twin's reference ({status})")
        return load_model(Path(tmp) / "run" / "model.json")


def _file_by_place(name: str, seed: int) -> tuple[ModelFile, float]:
    """The data file a user makes by the evidence of the first: :data:`REFERENCE_S`, then ``HORN_RECORD_S`` where that
    file's play sits in the loop on a compliant contact sized on a shorter record (``servoid monitor``'s note,
    :func:`~servoid.monitor_loop.short_horn`).

    Returns the file and its reference's length, s (the twin's history before monitoring).
    """
    file = _model_file(name, seed, REFERENCE_S)
    if short_horn(file) is not None:
        return _model_file(name, seed, HORN_RECORD_S), HORN_RECORD_S
    return file, REFERENCE_S


def _run(name: str, seconds: float, factor: Callable[[float], float], seed: int, file: ModelFile,  # type: ignore[no-untyped-def]
         chunk_s: float = CHUNK_S, fresh: bool = False, monitor_input: str = "ident", min_reversals: int = MIN_REVERSALS,
         share: float = SINE_ACCEL_SHARE, count_switch: bool = False, reference_s: float = REFERENCE_S,
         hold_loop: bool = HOLD_LOOP, calibrate: bool = CALIBRATE, dither: float = 0.0, cycle: int | None = None,
         whole: bool = WHOLE_HALVES, phases: int = EVEN_PHASES, progress: str = ""):  # fmt: skip
    """The twin's reference part (``reference_s``), then ``seconds`` of monitoring from ``file`` with the play at
    ``factor(t)`` times the new one.

    ``cycle``: the cycled sine's places (None: ``servoid monitor``'s default by the file's place; 0: one amplitude);
    its count from the readings before the steady part, taken when the feed reaches it (as the monitor's stream).
    ``whole``: its half-periods of whole samples (:data:`~servoid.excitation.monitor_input.WHOLE_HALVES`);
    ``phases``: the sample phases its peaks pass evenly (:data:`~servoid.excitation.monitor_input.EVEN_PHASES`).
    ``progress``: a label; every 100 000 samples a line on stderr with the alarms raised so far (a long quiet run
    stopped early still says how far it went without one).
    """
    twin = Twin(preset(name), seed=seed)
    twin.enable()
    play0 = twin.truth.play_rad
    n_ref = int(reference_s * RATE)
    n = int(seconds * RATE)
    u = _excitation(name, n_ref + n, seed)
    steady_s = 0.0
    if monitor_input != "ident":
        # the whole loop's first fit on the identification's input, to the end of its segment (as
        # servoid monitor: monitor_stream), then the monitoring input from the offset: no step
        ident = monitor_spec(IDENT, SINE_AMPLITUDE[name], 8.0 / RATE**2)
        cut = min(segment_end(ident, seed + 1000, n_ref + int(FIRST_FIT_S * RATE)), n_ref + n)
        u[cut:] = _monitor_input(name, n_ref + n - cut, seed, monitor_input, share, dither)
        steady_s = 0.0 if count_switch else (cut - n_ref) / RATE
    twin.sample(u[:n_ref], 1.0 / RATE)
    steps = (CYCLE_STEPS if default_input(file.structure) == CYCLED else 0) if cycle is None else cycle
    # the cycled sine: its count from the monitor's readings before the steady part (``servoid monitor``'s
    # ReadingsGrid), then the amplitude a count / steps smaller each half-period, from the sample ``cut`` on
    pending = steps > 0 and monitor_input == SINE and cut < n_ref + n
    readings: list[np.ndarray] = []
    grid: GridCount | None = None
    # as ``servoid monitor`` starts from a model file (servoid/cli/monitor.py, servoid/monitor_loop.py)
    model = dataclasses.replace(loop_model(file), sample_period_s=1.0 / RATE)
    bound = Bound(quantity=PLAY, low=0.9 * model.play, high=1.1 * model.play)  # --dead-zone 10%
    low, high = (math.nan if v is None else float(v) for v in file.play_interval)
    tracker = LoopWearTracker(model, [bound], background=False, rebase=True, interval=(low, high),
                              identifiable=file.identifiable, fresh=fresh, min_reversals=min_reversals,
                              steady_s=steady_s, hold_loop=hold_loop, calibrate=calibrate)  # fmt: skip
    chunk = int(chunk_s * RATE)
    truth = np.empty(n)
    for i in range(0, n, chunk):
        if progress and i and i % 100_000 == 0:
            print(f"{progress}: {i} samples, {len(_raised(tracker))} alarms raised", file=sys.stderr, flush=True)
        f = factor(i / RATE)
        twin.set_play(play0 * f)
        parts = [(n_ref + i, n_ref + min(i + chunk, n))]
        if pending and parts[0][1] > cut:  # the steady part starts in this chunk: its count first
            parts = [(parts[0][0], cut), (cut, parts[0][1])] if parts[0][0] < cut else parts
        for lo, hi in parts:
            if pending and lo >= cut:
                scale = share / SINE_ACCEL_SHARE
                steady = monitor_spec(SINE, SINE_AMPLITUDE[name], scale * 8.0 / RATE**2)
                grid = grid_count(np.concatenate(readings), float(steady.amplitude))
                if grid.found:
                    u[cut:] = cycled_sine(steady, grid.count, steps, n_ref + n - cut, whole=whole,
                                              phases=phases)  # fmt: skip
                pending, readings = False, []
            if lo >= hi:
                continue
            rec = twin.sample(u[lo:hi], 1.0 / RATE)
            if pending:
                readings.append(rec.y)
            for ui, yi in zip(rec.u.tolist(), rec.y.tolist(), strict=True):
                tracker.update(ui, yi)
        truth[i : i + chunk] = play0 * f
    tracker.result()
    rows: tuple[PlayRow, ...] = tracker.rows_since(0)
    t = np.array([r.window.t_s for r in rows])
    at = truth[np.minimum((t * RATE).astype(int) - 1, n - 1)]
    return model, tracker, rows, t, at, play0, grid


def _raised(tracker: LoopWearTracker) -> list[float]:
    return [e.sample / RATE for e in tracker.events if e.raised]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--presets", nargs="+", default=sorted(PRESETS), choices=sorted(PRESETS))
    parser.add_argument("--track", type=float, default=120.0, help="tracking run, servo s (default 120)")
    parser.add_argument("--quiet", type=int, default=100_000, help="samples of the run without wear")
    parser.add_argument("--full", action="store_true", help="1 000 000 samples without wear")
    parser.add_argument("--seeds", type=int, nargs="+", default=[2], help="twin seeds of the step run (default 2)")
    parser.add_argument(
        "--track-seeds", type=int, nargs="+", default=[1], help="twin seeds of the tracking run (default 1)"
    )
    parser.add_argument(
        "--file",
        choices=("data", "live"),
        default="data",
        help="the model file: identify --data on 20 s of the unworn twin (default), or identify --driver (probe, 60 s)",
    )
    parser.add_argument(
        "--reference-s",
        type=float,
        default=None,
        help=f"servo s of the unworn twin the data file is identified on (default: {REFERENCE_S:g}, then "
        f"{HORN_RECORD_S:g} where that file holds the play in the loop on a compliant contact, the horn stage's)",
    )
    parser.add_argument(
        "--fresh",
        action="store_true",
        help="the first fit searches both places of the play from scratch (not the file's loop)",
    )
    parser.add_argument(
        "--input",
        choices=sorted(MONITOR_INPUTS),
        default="sine",
        help="the monitoring input after the first fit (default sine; ident: the identification's)",
    )
    parser.add_argument(
        "--min-reversals",
        type=int,
        default=MIN_REVERSALS,
        help=f"fewest reversals for a window's play to count (default {MIN_REVERSALS}; 0: every window)",
    )
    parser.add_argument(
        "--accel-share",
        type=float,
        default=SINE_ACCEL_SHARE,
        help=f"the steady sine's peak acceleration over the identification's (default {SINE_ACCEL_SHARE:g}; 1 before)",
    )
    parser.add_argument(
        "--count-switch",
        action="store_true",
        help="windows that begin before the steady sine count (as before: no steady_s)",
    )
    parser.add_argument(
        "--free-loop",
        action="store_true",
        help="the first fit refits the whole loop (free, or the play held where that fits better: the code before "
        "servoid monitor's HOLD_LOOP) instead of the play alone on the file's loop",
    )
    parser.add_argument(
        "--dither",
        type=float,
        default=0.0,
        help="the steady sine's amplitude drawn each period in [(1 - D) A, A], its reversals spread over the loop "
        "encoder's count grid (default 0: one amplitude)",
    )
    parser.add_argument(
        "--cycle",
        type=int,
        default=None,
        help="the steady sine's amplitude a count / N smaller each half-period over N values (the count: the first "
        f"fit's readings' step, as servoid monitor takes it), its reversals on N places of the loop encoder's grid "
        f"(default: servoid monitor's, 0 unless its CYCLED_DEFAULT is on, then {CYCLE_STEPS} where the file's play sits "
        "in the loop; 0: one amplitude, the input before)",
    )
    parser.add_argument(
        "--whole-halves",
        action="store_true",
        help="the cycled sine's half-periods of whole samples, not of the length its peak acceleration gives "
        "(servoid monitor's WHOLE_HALVES, off)",
    )
    parser.add_argument(
        "--even-phases",
        type=int,
        default=EVEN_PHASES,
        metavar="M",
        help="the cycled sine's peaks pass M sample phases evenly (servoid monitor's EVEN_PHASES, 0: off)",
    )
    parser.add_argument("--file-seed", type=int, default=1, help="twin seed of the model file's reference (default 1)")
    parser.add_argument(
        "--calibrate",
        action="store_true",
        help="the window plays read relative to the model file's play (LoopWearTracker's calibrate; servoid monitor's "
        "CALIBRATE)",
    )
    parser.add_argument(
        "--wear-from",
        type=float,
        default=0.0,
        help="servo s of the tracking run before its play starts to grow (default 0; it then grows 50 %% by the end)",
    )
    args = parser.parse_args()
    quiet = 1_000_000 if args.full else args.quiet
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"machine load (1 min): {load:.2f} on {os.cpu_count()} cores", file=sys.stderr)
    rows = []
    opts = {"fresh": args.fresh, "monitor_input": args.input, "min_reversals": args.min_reversals,
            "share": args.accel_share, "count_switch": args.count_switch, "hold_loop": not args.free_loop,
            "calibrate": args.calibrate or CALIBRATE, "dither": args.dither,
            "cycle": 0 if args.dither > 0.0 and args.cycle is None else args.cycle,
            "whole": WHOLE_HALVES or args.whole_halves, "phases": args.even_phases}  # fmt: skip
    wear_from = args.wear_from
    if not 0.0 <= wear_from < args.track:
        raise SystemExit(f"--wear-from must lie in [0, --track), not {wear_from:g}")
    for name in args.presets:
        started = time.perf_counter()
        reference_s = REFERENCE_S if args.reference_s is None else args.reference_s
        if args.file == "live":
            file = _live_file(name, args.file_seed)
        elif args.reference_s is None:
            file, reference_s = _file_by_place(name, args.file_seed)
        else:
            file = _model_file(name, args.file_seed, reference_s)
        opts["reference_s"] = reference_s
        raws, biases = [], []  # per tracking seed; the other tracking columns are the first seed's
        grid: GridCount | None = None
        for track_seed in reversed(args.track_seeds):
            model, tracker, tr, t, at, play0, grid = _run(
                name,
                args.track,
                lambda s: 1.0 + 0.5 * max(0.0, s - wear_from) / (args.track - wear_from),
                track_seed,
                file,
                **opts,
            )
            sel = t >= SCORED_FROM_S
            mean = np.array([r.mean for r in tr])[sel]
            truth = at[sel]
            raws.insert(0, float(np.sqrt(np.mean((mean / truth - 1.0) ** 2))))
            biases.insert(0, float(np.median(mean / truth)) - 1.0)
        window = np.array([r.window.play for r in tr])[sel]
        bias = biases[0]
        growth = float(np.sqrt(np.mean((mean / mean[0] - truth / truth[0]) ** 2)))
        raw_window = float(np.sqrt(np.mean((window / truth - 1.0) ** 2)))
        # the raw error split: the constant bias (the file's loop's, the same in every window), then what is the
        # monitor's own (RMS with the bias out), and of that what is not the mean's lag (against the truth TRACK_S / 2
        # earlier: the mean of the last TRACK_S of window plays lags a growth by half of it)
        own = float(np.sqrt(np.mean((mean / truth / (1.0 + bias) - 1.0) ** 2)))
        earlier = play0 * (1.0 + 0.5 * np.maximum(0.0, t[sel] - TRACK_S / 2.0 - wear_from) / (args.track - wear_from))
        unlagged = mean / earlier / float(np.median(mean / earlier))
        scatter = float(np.sqrt(np.mean((unlagged - 1.0) ** 2)))
        cost = np.array([r.window.seconds for r in tr[1:]])
        counted = np.array([r.counted for r in tr[1:]])
        turns = np.array([r.window.reversals for r in tr[1:]])
        after, before = [], []  # the first alarm after the step per seed; alarms before it, all seeds
        for seed in args.seeds:
            _, step, _, _, _, _, _ = _run(name, STEP_AT_S + 20.0, lambda s: 1.2 if s >= STEP_AT_S else 1.0, seed, file,
                                       **opts)  # fmt: skip
            raised = _raised(step)
            after.append(next((f"{x - STEP_AT_S:.2f}" for x in raised if x >= STEP_AT_S), "none"))
            before += [x for x in raised if x < STEP_AT_S]
        _, calm, _, _, _, _, _ = _run(
            name,
            quiet / RATE,
            lambda s: 1.0,
            3,
            file,
            chunk_s=1.0,
            progress=f"{name} quiet",
            **opts,
        )
        base = calm.baseline()
        lo, hi = (v / play0 for v in tracker.interval)  # the file's, against the unworn play it was fitted on
        doubt = (f"{tr[0].window.play / at[0] - 1:+.0%}; {'' if file.identifiable else 'not '}identifiable, "
                 f"[{lo:.2f}, {hi:.2f}]x; {'doubt' if tracker.doubt else 'no doubt'}")  # fmt: skip
        place = "in the loop" if file.structure == PLAY_IN_LOOP else "outside the loop"
        if opts["calibrate"]:
            doubt += f"; scale {tracker.scale:.3f}"
        if args.input != SINE:
            kind = args.input
        elif grid is None:
            kind = "steady"
        elif grid.found:
            kind = f"cycled, count {grid.count:.4g} ({grid.readings} readings)"
        else:
            kind = f"steady: {grid.why}"
        rows.append([name, f"{model.play / play0 - 1:+.1%}, {place}, {reference_s:g} s", kind, doubt, " / ".join(f"{r:.1%}" for r in raws), " / ".join(f"{b:+.1%}" for b in biases) + f" / {own:.1%} / {scatter:.1%}", f"{growth:.1%}", f"{raw_window:.1%}",
                     " / ".join(after), str(len(before)), f"{len(_raised(calm))} in {quiet}",
                     f"{base['scatter'] / base['median']:.1%} ({base['std'] / base['median']:.1%}) / "
                     f"{base['tau']:.1f} / {base['h']:.1f} / "
                     f"{base['false_alarm_samples']:.1e}",
                     f"{counted.mean():.0%} / {np.median(turns):.0f}",
                     f"{1e3 * np.median(cost):.1f} / {1e3 * np.max(cost):.0f}", f"{time.perf_counter() - started:.0f}"])  # fmt: skip
    table(
        f"monitor, the play alone on {tracker.window.config.window_s:g} s windows every "
        f"{tracker.window.config.every_s:g} s, CUSUM at the bounds +/-10 % ({RATE:g} Hz)",
        ["preset", "model file play vs unworn truth, place, reference", "steady sine (first track seed)", "first refit vs truth then; file: identifiable, interval (x unworn truth); doubt", "track RMS raw (per track seed)", "raw = bias (file; per track seed) / own RMS / own without lag", "track RMS growth", "window RMS raw",
         "alarm after +20 % step s (per seed)", "alarms before step", "false alarms", "quiet: scatter (sigma) / tau / h / ARL0 samples",
         "windows counted / reversals (median)", "estimate ms med/max", "wall s"],
        rows,
    )  # fmt: skip


if __name__ == "__main__":
    main()
