"""``servoid monitor`` on a wearing simulated servo: tracking, detection, false alarms, memory, cost.

Run: ``.venv/bin/python benchmarks/monitor.py`` (about two minutes on one core). Everything
runs through the real path: the simulated servo (``sim://``, virtual clock,
so no real-time waiting), the sampling session keeping no samples, the
wear estimator, the alarm rule and the files (:func:`servoid.monitor_run.run_monitor`),
at 1 kHz, checking every 100 samples and writing a row at every check.

The servo is ``sim://gear?snr=40``: the paper's linear block and
m2 = 1.5 with a new gear's dead zones c1 0.4, c2 0.6 (c1 + c2 = 1.0), driven
by the paper's uniform input (|u| <= 2.406), output noise at SNR 40
(std 0.0337). The monitor starts from the unworn model; its bounds are
c1 + c2 and m2 within +/- 10 % (0.9 .. 1.1 and 1.35 .. 1.65), its rule the
default (beyond a bound by more than 2 std at 5 checks in a row).

1. Tracking: c1 + c2 ramps from 1.0 to 1.5 over 200 000 samples (after
   20 000 at 1.0, then 100 000 at 1.5). RMS error of the estimate over the
   ramp, its lag, scatter and bias on the plateau (as in
   ``benchmarks/random_walk.py``: :func:`random_walk.ramp_figures`); the reported
   standard deviation; when the alarm came against the time the truth
   crossed the bound.
2. Detection: a gear swap multiplies c1 and c2 by 1.2 at sample 50 000
   (five seeds): samples from the swap to the alarm (``--fail-on-alarm``
   stops there).
3. False alarms: 1 000 000 samples without drift; the run's own alarms, and
   the same checks replayed through the rule with tighter bounds and
   without its margin or persistence (what the rule buys), with the step
   runs' detection delay for each rule.
4. Memory: resident set size over the 1 000 000-sample run, and Python's
   traced allocations (tracemalloc) over a 300 000-sample run.
5. Cost per sample: the whole monitor, the session with the simulated servo alone, the wear estimator alone.
6. Other servos and inputs: the bench servo (rad, c1 + c2 = 0.05 rad) under
   its uniform input, and under a slow operating trajectory with a small
   excitation on top; the same ramp by 1.5 (the lag is left out: with a
   bias that changes along the ramp it is not defined).
"""

from __future__ import annotations

import math
import resource
import statistics
import tempfile
import time
import tracemalloc
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
from random_walk import (  # benchmarks/random_walk.py: one definition of the figures
    AFTER,
    BEFORE,
    PLATEAU,
    RAMP,
    ramp_figures,
)

from servoid.drivers import driver_from_url
from servoid.drivers.model_plant import MODEL_PLANT
from servoid.excitation import UniformSpec, parse_spec, stream
from servoid.ident.models.wear import GEAR_PLANT
from servoid.ident.monitoring.alarms import AlarmRule, Alarms, Bound
from servoid.ident.monitoring.wear_estimator import WearEstimator, WearEstimatorConfig
from servoid.ident.paper import PAPER_INPUT_AMPLITUDE
from servoid.modelfile import ModelFile
from servoid.monitor_run import MonitorConfig, MonitorProgress, MonitorResult, read_estimates, run_monitor
from servoid.session import SessionConfig, run_session

RATE = 1000.0
CHECK = 100
GEAR = "sim://gear?snr=40&clock=virtual"
SWAP_AT, SWAP_RUN = 50_000, 60_000
QUIET = 1_000_000
SHARE = 0.10  # bounds: +/- 10 % of the model's c1 + c2 and m2


def bounds_for(model: Any, share: float = SHARE, unit: str = "") -> tuple[Bound, ...]:
    dz, m2 = model.dead_zone, model.m2
    return (Bound(quantity="dead_zone", low=dz * (1 - share), high=dz * (1 + share), label="dead zone", unit=unit),
            Bound(quantity="m2", low=m2 * (1 - share), high=m2 * (1 + share), label="m2"))  # fmt: skip


def monitor(
    url: str,
    n: int,
    out: Path,
    *,
    model: Any = GEAR_PLANT,
    inputs: Any = None,
    seed: int = 1,
    stop_on_alarm: bool = False,
    on_progress: Callable[[MonitorProgress], None] | None = None,
    unit: str = "unit",
) -> tuple[MonitorResult, dict[str, np.ndarray], float]:
    """One monitoring run; returns the result, the rows of estimates.csv and the wall time per sample (s)."""
    with driver_from_url(url) as servo:
        config = MonitorConfig(
            estimator=WearEstimatorConfig(reference=model, noise_std=servo.noise_std), bounds=bounds_for(model, unit=unit),
            check_every=CHECK, row_every=CHECK, stop_on_alarm=stop_on_alarm,
        )  # fmt: skip
        if inputs is None:
            inputs = stream(UniformSpec(amplitude=servo.reference_amplitude), seed=seed, n=n)
        model_file = ModelFile(model=model, noise_std=servo.noise_std, output_unit=unit)
        started = time.perf_counter()
        result = run_monitor(servo, inputs, SessionConfig(period_s=1.0 / RATE), config, model_file=model_file,
                             out=out, truth_at=servo.truth_at, on_progress=on_progress)  # fmt: skip
        wall = (time.perf_counter() - started) / max(result.samples, 1)
    rows, _ = read_estimates(result.files["estimates"])
    return result, rows, wall


def figures(rows: dict[str, np.ndarray], total: int) -> dict[str, float]:
    """:func:`random_walk.ramp_figures` of a run's rows, and the median reported std on the plateau (relative)."""
    f = ramp_figures(rows["k"], rows["dead_zone"], rows["true_dead_zone"], total=total)
    plateau = rows["k"] >= total - PLATEAU
    f["reported"] = float(np.median(rows["dead_zone_std"][plateau])) / rows["true_dead_zone"][0]
    return f


def tracking(tmp: Path) -> None:
    n = BEFORE + RAMP + AFTER
    url = f"{GEAR}&drift=1.5&drift_samples={RAMP}&drift_start={BEFORE}"
    result, rows, wall = monitor(url, n, tmp / "drift")
    f = figures(rows, n)
    high = bounds_for(GEAR_PLANT)[0].high
    crossed = BEFORE + (high / GEAR_PLANT.dead_zone - 1.0) / 0.5 * RAMP
    alarm = result.first_alarm
    print(f"1. tracking c1 + c2 from 1.0 to 1.5 over {RAMP} samples at SNR 40 ({url})")
    print(f"   RMS error over the ramp        {f['rms']:.4f}")
    print(f"   lag of the estimate            {f['lag']:.0f} samples ({f['lag'] / RATE:.2f} s at {RATE:g} Hz)")
    print(
        f"   plateau: scatter / bias        {f['std']:.4f} / {f['bias']:+.4f} (relative)   reported std {f['reported']:.4f}"
    )
    if alarm is not None:
        truth = GEAR_PLANT.dead_zone * (1.0 + 0.5 * (alarm.sample - BEFORE) / RAMP)
        print(f"   alarm at c1 + c2 > {high:.3g}          truth crossed at sample {crossed:.0f}, alarm decided at "
              f"{alarm.sample} (+{alarm.sample - crossed:.0f}; truth then {truth:.4f}, estimate {alarm.value:.4f} "
              f"+/- {alarm.std:.4f})")  # fmt: skip
    print(f"   compensation updates           {result.compensation_updates} (one per 2 % of change)")
    print(f"   wall time                      {wall * 1e6:.1f} us per sample")
    print()


def _replay(rows: dict[str, np.ndarray], share: float, rule: AlarmRule) -> list[int]:
    """Samples at which the rule raises a dead-zone alarm over the recorded checks, bounds +/- share of 1.0."""
    dz = GEAR_PLANT.dead_zone
    alarms = Alarms([Bound(quantity="dead_zone", low=dz * (1 - share), high=dz * (1 + share))], rule)
    raised = []
    for k, v, s in zip(rows["k"], rows["dead_zone"], rows["dead_zone_std"]):
        raised += [int(k) for e in alarms.check(int(k), {"dead_zone": (float(v), float(s))}) if e.raised]
    return raised


RULES = [("raw: z 0, persist 1", AlarmRule(z=0.0, persist=1)), ("z 0, persist 5", AlarmRule(z=0.0, persist=5)),
         ("z 2, persist 1", AlarmRule(z=2.0, persist=1)), ("z 2, persist 5 (default)", AlarmRule())]  # fmt: skip


def detection(tmp: Path) -> list[dict[str, np.ndarray]]:
    print(
        f"2. detecting a gear swap: c1 + c2 x 1.2 at sample {SWAP_AT}, bound +10 %, stop at the alarm "
        "(checks every 100 samples)"
    )
    delays, runs = [], []
    for seed in range(5):
        url = f"{GEAR}&seed={seed}&swap_at={SWAP_AT}&swap_factor=1.2"
        result, _, _ = monitor(url, SWAP_RUN, tmp / f"swap{seed}", stop_on_alarm=True, seed=seed + 10)
        alarm = result.first_alarm
        delay = math.nan if alarm is None else alarm.sample - SWAP_AT
        delays.append(delay)
        since = "-" if alarm is None else f"{alarm.since - SWAP_AT}"
        print(
            f"   seed {seed}: alarm {delay:.0f} samples after the swap (out of bounds from +{since}); "
            f"stopped: {result.stopped}"
        )
        # the same servo without stopping, rows at every check, for the rule table
        _, rows, _ = monitor(url, SWAP_RUN, tmp / f"swap{seed}-all", seed=seed + 10)
        runs.append(rows)
    print(
        f"   median {statistics.median(delays):.0f} samples, worst {max(delays):.0f} "
        f"({statistics.median(delays) / RATE * 1e3:.0f} / {max(delays) / RATE * 1e3:.0f} ms at {RATE:g} Hz)"
    )
    print()
    return runs


def false_alarms(tmp: Path, step_runs: list[dict[str, np.ndarray]]) -> tuple[list[tuple[int, float]], float]:
    memory: list[tuple[int, float]] = []
    marks = iter([*range(0, QUIET, QUIET // 4), QUIET - 1000])
    mark = [next(marks)]

    def sample_memory(p: MonitorProgress) -> None:
        if p.done >= mark[0]:
            memory.append((p.done, _rss_mb()))
            mark[0] = next(marks, QUIET * 10)

    result, rows, wall = monitor(GEAR, QUIET, tmp / "quiet", on_progress=sample_memory)
    dz = rows["dead_zone"] / GEAR_PLANT.dead_zone
    m2 = rows["m2"] / GEAR_PLANT.m2
    settled = rows["k"] >= 10_000
    print(f"3. false alarms over {QUIET} samples without drift ({GEAR})")
    print(f"   alarms raised by the run (c1 + c2 and m2 within +/- 10 %): {sum(e.raised for e in result.events)}")
    print(f"   c1 + c2 / 1.0: range {dz[settled].min():.4f} .. {dz[settled].max():.4f}, scatter "
          f"{np.std(dz[settled]):.4f}, reported std {np.median(rows['dead_zone_std'][settled]):.4f}")  # fmt: skip
    print(
        f"   m2 / 1.5:      range {m2[settled].min():.4f} .. {m2[settled].max():.4f}, scatter {np.std(m2[settled]):.4f}"
    )
    print("   the same 10 000 checks replayed (false alarms on c1 + c2 per bound), and the swap's detection delay:")
    shares = (0.015, 0.02, 0.03, 0.05, 0.10)
    head = "".join(f"{'+/-' + format(s * 100, 'g') + ' %':>9s}" for s in shares)
    print(f"   {'rule':26s}{head}   {'swap delay (median, worst)':>28s}")
    for label, rule in RULES:
        counts = "".join(f"{len(_replay(rows, s, rule)):9d}" for s in shares)
        delays = []
        for r in step_runs:
            hits = [k for k in _replay(r, SHARE, rule) if k >= SWAP_AT]
            delays.append(hits[0] - SWAP_AT if hits else math.nan)
        print(f"   {label:26s}{counts}   {statistics.median(delays):14.0f} {max(delays):8.0f} samples")
    print()
    return memory, wall


def memory_table(tmp: Path, rss: list[tuple[int, float]]) -> None:
    print("4. memory")
    print("   resident set size over the 1 000 000-sample run: " + ", ".join(f"{mb:.1f} MB at {k}" for k, mb in rss))
    traced: list[tuple[int, float]] = []
    marks = iter((1_000, 100_000, 200_000, 299_000))
    mark = [next(marks)]

    def sample(p: MonitorProgress) -> None:
        if p.done >= mark[0]:
            traced.append((p.done, tracemalloc.get_traced_memory()[0] / 1e6))
            mark[0] = next(marks, 10**9)

    tracemalloc.start()
    try:
        monitor(GEAR, 300_000, tmp / "traced", on_progress=sample)
    finally:
        tracemalloc.stop()
    print("   Python allocations (tracemalloc) over 300 000 samples: "
          + ", ".join(f"{mb:.2f} MB at {k}" for k, mb in traced))  # fmt: skip
    print()


def cost_table(monitor_wall: float) -> None:
    n = 100_000
    with driver_from_url(GEAR) as servo:
        u = stream(UniformSpec(amplitude=PAPER_INPUT_AMPLITUDE), seed=1, n=n)
        started = time.perf_counter()
        run_session(servo, u, SessionConfig(period_s=1.0 / RATE), keep_samples=False)
        session = (time.perf_counter() - started) / n
    estimator = WearEstimator(WearEstimatorConfig(reference=GEAR_PLANT, noise_std=0.0337))
    rng = np.random.default_rng(0)
    uu, yy = rng.uniform(-2.4, 2.4, n), rng.normal(0.0, 1.0, n)
    estimator.update(0.0, 0.0)
    started = time.perf_counter()
    for a, b in zip(uu, yy):
        estimator.update(a, b)
    alone = (time.perf_counter() - started) / n
    print("5. cost per sample (wall time, this machine)")
    print(f"   the whole monitor (1 000 000-sample run)      {monitor_wall * 1e6:6.1f} us")
    print(f"   the session with the simulated servo alone     {session * 1e6:6.1f} us")
    print(f"   the wear estimator alone (MRGIA step + fit)      {alone * 1e6:6.1f} us")
    print()


def other_servos(tmp: Path) -> None:
    n = BEFORE + RAMP + AFTER
    print(
        "6. other servos and inputs: c1 + c2 ramped by 1.5 over 200 000 samples, SNR 40 (errors relative to the unworn c1 + c2)"
    )
    print(f"   {'servo and input':62s} {'RMS':>7s} {'std':>7s} {'bias':>8s}")
    cases = [
        ("bench servo (rad), uniform +/-0.2 rad", None),
        ("bench servo, operating multisine +/-0.15 rad + uniform +/-0.05", "multisine:amplitude=0.15,bands=0.002-0.02,period=5000"),
    ]  # fmt: skip
    for label, operating in cases:
        url = f"sim://model?snr=40&clock=virtual&drift=1.5&drift_samples={RAMP}&drift_start={BEFORE}"
        if operating is None:
            inputs = stream(UniformSpec(amplitude=0.2), seed=1, n=n)
        else:
            op = stream(parse_spec(operating), seed=2, n=n)
            inputs = (a + b for a, b in zip(op, stream(UniformSpec(amplitude=0.05), seed=1, n=n)))
        _, rows, _ = monitor(url, n, tmp / label.split(",")[0].replace(" ", "_") / str(operating is None),
                             model=MODEL_PLANT, inputs=inputs, unit="rad")  # fmt: skip
        f = figures(rows, n)
        print(f"   {label:62s} {f['rms']:7.4f} {f['std']:7.4f} {f['bias']:+8.4f}")
    print()


def _rss_mb() -> float:
    with open("/proc/self/statm") as fh:
        return int(fh.read().split()[1]) * resource.getpagesize() / 1e6


def main() -> None:
    with tempfile.TemporaryDirectory() as name:
        tmp = Path(name)
        tracking(tmp)
        step_runs = detection(tmp)
        rss, wall = false_alarms(tmp, step_runs)
        memory_table(tmp, rss)
        cost_table(wall)
        other_servos(tmp)


if __name__ == "__main__":
    main()
