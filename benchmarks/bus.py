"""Several servos on one bus: sample rate and late share with 1, 3 and 6 servos, and the play identified per joint.

Run:  .venv/bin/python benchmarks/bus.py [--seconds 2] [--rates 200 500 1000] [--samples 1000] [--rate 100] [--joints 6]

Table 1 (rate): the sampling session over ``dxl://...?id=1,..,n`` and
``feetech://...?id=1,..,n`` (the real SDKs' GroupSyncWrite + GroupSyncRead,
one of each per sample) against the emulators in a process of their own,
for ``--seconds`` at each rate: the rate answered, the share of slots not
exchanged on time (late, missed, timed out), and the group exchange's time
(median, 99th percentile). The servos run the pseudo-Wiener plant here, so
that the emulator's own cost is the protocol's (an emulator steps ``n``
twins one after the other in one process; real servos run in parallel): the
1-servo row is the floor, measured in the same run; the ``x floor`` column is
the exchange time over it.

Table 2 (identification): ``n`` emulated STS3215 twins (Feetech) and XM430
twins (Dynamixel) on one bus at ``--rate``, the joints excited
``sequential`` (one after the other, ``--samples`` each, the others holding)
and ``together`` (independent signals, ``--samples`` slots), by the gentle
sines ``servoid identify`` sends a bus by default: each joint identified from
its own usable samples as ``servoid identify`` does (:func:`servoid.ident.identify`
with the record's time: both places of the play); the answer's play against
the twin's true play (its ``play_rad``), where it sits, the black box's fit
over the record's floor and the verdict. The twins are mechanically independent, so ``together`` sees
no coupling here: the table measures what the bus timing does, not what an
arm's mechanics would (docs/feetech.md).

Table 3: the same, with the emulators taking each goal as one sample (one
period of the twin at 200 Hz, whatever the host's timing) and the session
using late samples without a guard window: what identification gives when
the host's scheduling is taken out (a missed slot still costs: the plant
does not step while the record holds the command).

The machine's load is printed before and after: on a shared 2-core machine
the late and missed shares are the scheduler's as much as the bus's.
"""

from __future__ import annotations

import argparse
import math
import os
import time
from typing import Any

import numpy as np
from _table import table  # benchmarks/, on the path when a benchmark runs as a script

from servoid.cli._live_bus import gentle_default
from servoid.drivers import driver_from_url
from servoid.drivers.dynamixel.emulator import EmulatorProcess as DxlProcess
from servoid.drivers.feetech.emulator import EmulatorProcess as FeetechProcess
from servoid.drivers.model_plant import MODEL_AMPLITUDE
from servoid.drivers.twin import preset
from servoid.errors import ServoidError
from servoid.excitation import parse_spec, sample
from servoid.ident import MRGIAConfig, identify
from servoid.session import SessionConfig, run_session
from servoid.session.joints import bus_excitation, joint_result

VENDORS: dict[str, tuple[Any, dict[str, Any], str]] = {
    "feetech": (FeetechProcess, {}, "sts3215"),
    "dxl": (DxlProcess, {"return_delay_us": 0}, "xm430"),
}
LATENCY_MS = 20  # reply timeouts 42 ms: a loaded host must not turn a slow emulator into timeouts


def _url(process: Any, ids: list[int]) -> str:
    one = process.url(ids[0], latency_ms=LATENCY_MS)
    return one.replace(f"id={ids[0]}", "id=" + ",".join(map(str, ids)))


def _excitation(joints: int, samples: int, mode: str, amplitude: float, seed: int) -> tuple[np.ndarray, list[slice]]:
    def make(index: int, n: int) -> np.ndarray:
        return np.random.default_rng(seed + index).uniform(-amplitude, amplitude, n)

    if joints == 1:
        return make(0, samples)[:, None], [slice(0, samples)]
    return bus_excitation(make, joints, samples, mode=mode)


def _session(url: str, u: np.ndarray, rate: float, *, clocked: bool = True) -> tuple[Any, str]:
    """The session's result (the partial one when it stopped on a fault) and the fault, if any.

    ``clocked=False``: the emulator takes each goal as one sample, so late samples show the
    plant as it is and may be used, without a guard window.
    """
    config = SessionConfig(period_s=1.0 / rate) if clocked else SessionConfig(period_s=1.0 / rate, use_late=True,
                                                                              guard_samples=0)  # fmt: skip
    try:
        with driver_from_url(url) as driver:
            return run_session(driver, u if u.shape[1] > 1 else u[:, 0], config), ""
    except ServoidError as exc:  # a stalled host (a Dynamixel's Bus Watchdog), a silent servo: a row says so
        return getattr(exc, "partial", None), f"stopped: {type(exc).__name__}"


def rate_table(seconds: float, rates: list[float]) -> None:
    rows = []
    for vendor, (process, options, _) in VENDORS.items():
        floor: dict[float, float] = {}
        for n in (1, 3, 6):
            ids = list(range(1, n + 1))
            with process(ids, servo="model", **options) as emu:
                for rate in rates:
                    u, _ = _excitation(n, int(seconds * rate), "together", MODEL_AMPLITUDE, 0)
                    result, fault = _session(_url(emu, ids), u, rate)
                    if result is None or len(result) < 2:
                        rows.append([vendor, str(n), f"{rate:g}", fault, "", "", "", "", ""])
                        continue
                    acq = result.to_dict()
                    median = acq["exchange_median_s"] or math.nan
                    floor.setdefault(rate, median)
                    rows.append([vendor, str(n), f"{rate:g}", f"{acq['achieved_rate_hz']:.4g}",
                                 f"{100 * result.late_share:.1f}", f"{100 * result.counts['timeout'] / len(result):.1f}",
                                 f"{median * 1e6:.0f}", f"{(acq['exchange_p99_s'] or math.nan) * 1e6:.0f}",
                                 f"{median / floor[rate]:.2f}", fault])  # fmt: skip
    table("Table 1: one group exchange per sample (pseudo-Wiener plant behind each ID)",
          ["bus", "servos", "rate asked Hz", "answered Hz", "not on time %", "timeout %", "median us", "p99 us",
           "x floor", "note"], rows)  # fmt: skip


def _gentle(joints: int, samples: int, mode: str, rate: float, seed: int) -> tuple[np.ndarray, list[slice]]:
    """What ``servoid identify`` sends a bus by default: gentle sines (:func:`servoid.cli._live_bus.gentle_default`)."""
    spec = parse_spec(gentle_default(None, rate, "rad"))
    return bus_excitation(lambda index, n: sample(spec, n, seed=seed + index), joints, samples, mode=mode)


def identification_table(samples: int, rate: float, joints: int, *, clocked: bool = True) -> None:
    rows = []
    config = MRGIAConfig(na=2, nb=0, delay=1)
    for vendor, (process, options, servo) in VENDORS.items():
        truth = preset(servo).play_rad
        for mode in ("sequential", "together"):
            ids = list(range(1, joints + 1))
            with process(ids, servo=servo, period_s=1.0 / rate if clocked else None, **options) as emu:
                u, blocks = _gentle(joints, samples, mode, rate, 7)
                started = time.perf_counter()
                result, fault = _session(_url(emu, ids), u, rate, clocked=clocked)
                took = time.perf_counter() - started
            if result is None or len(result) < len(u):
                rows.append([vendor, mode, f"{took:.0f}", "all", "", "", "", "", "", fault or "no samples"])
                continue
            for index, servo_id in enumerate(ids):
                one = joint_result(result, index) if joints > 1 else result
                block = blocks[index]
                valid = result.valid[block] & np.isfinite(one.y[block])
                late = 100 * float(np.mean(result.status[block] != "ok"))
                row = [vendor, mode, f"{took:.0f}", str(servo_id), f"{late:.0f}",
                       f"{int(valid.sum())}/{block.stop - block.start}"]  # fmt: skip
                try:  # as servoid identify does: with the record's time, so both places of the play are fitted
                    found = identify(one.u[block], one.y[block], config, valid=valid, sample_period_s=1.0 / rate)
                except ServoidError as exc:
                    rows.append([*row, "-", f"{truth:.4g}", "-", "-", "-", str(exc)[:50]])
                    continue
                play = found.play
                verdict = "yes" if found.identifiable else "no: " + found.reason[:40]
                rows.append([*row, f"{play:.4g}", f"{truth:.4g}", f"{100 * (play - truth) / truth:+.0f}",
                             found.structure, f"{found.fit_nrmse / found.floor_nrmse:.2f}", verdict])  # fmt: skip
    title = (f"Table 2: the play identified per joint, {joints} twins on one bus at {rate:g} Hz (true play: the twin's)"
             if clocked else f"Table 3: as table 2, each goal one sample of the twins (their timing the host's "
             f"no more), late samples used, no guard; {rate:g} Hz asked")  # fmt: skip
    table(title,
          ["bus", "excitation", "session s", "joint", "not on time %", "usable", "play rad", "true rad", "error %",
           "play sits", "black box fit / floor", "identifiable"],
          rows)  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seconds", type=float, default=2.0, help="seconds per rate point of table 1")
    parser.add_argument("--rates", type=float, nargs="+", default=[200.0, 500.0, 1000.0])
    parser.add_argument("--samples", type=int, default=1000, help="samples per joint in table 2")
    parser.add_argument("--rate", type=float, default=100.0, help="sample rate of table 2, Hz")
    parser.add_argument("--joints", type=int, default=6, help="joints on the bus in table 2")
    args = parser.parse_args()
    print(f"load average before: {' '.join(f'{v:.2f}' for v in os.getloadavg())} ({os.cpu_count()} cores)")
    rate_table(args.seconds, args.rates)
    identification_table(args.samples, args.rate, args.joints)
    identification_table(args.samples, 200.0, args.joints, clocked=False)
    print(f"\nload average after: {' '.join(f'{v:.2f}' for v in os.getloadavg())}")


if __name__ == "__main__":
    main()
