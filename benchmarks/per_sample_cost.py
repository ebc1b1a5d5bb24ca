"""Per-sample cost of the hot paths: ``MRGIA.update`` and the sampling session's loop.

Run: ``.venv/bin/python benchmarks/per_sample_cost.py`` (about half a minute).
``--before PYTHON`` also runs this script under another interpreter (the venv
of another checkout, e.g. ``../main/.venv/bin/python``) and prints both
columns side by side; that run writes its caches to a temporary folder, never
into the other checkout.

Rows (microseconds per sample, best of ``--repeat`` runs in each of
``--rounds`` rounds, the two checkouts taking turns, so that a busy machine's
slow spells drop out of both alike):

``MRGIA.update``
    One online step on the paper's plant at SNR 43 (the estimator alone).
``driver.exchange (floor)``
    The simulated servo on a virtual clock, exchanged in a plain loop: what
    any session must pay per sample. The session rows below are measured in
    the same run and compared with it.
``session, no listener``
    :func:`run_session` over the same servo with nothing listening.
``session + MRGIA``
    The same with the online estimator fed.
``session + MRGIA + recording``
    The same, also writing the recording (a flushed CSV row per sample).

The session rows minus the floor are the session's own cost.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from _table import table  # benchmarks/, on the path when a benchmark runs as a script

from servoid.drivers import driver_from_url
from servoid.ident import MRGIA, PAPER_PLANT, MRGIAConfig, noise_epsilon, simulate
from servoid.session import SessionConfig, run_session

URL = "sim://model?clock=virtual&snr=40&seed=1"
PERIOD_S = 1e-3


def update_cost(samples: int, repeat: int) -> float:
    rng = np.random.default_rng(0)
    u = rng.uniform(-2.4, 2.4, samples)
    sim = simulate(PAPER_PLANT, u, snr=43.0, rng=rng)
    ul, yl = sim.u.tolist(), sim.y.tolist()
    config = MRGIAConfig(epsilon=noise_epsilon(sim.noise_std), rho_exponent=0.75)
    best = np.inf
    for _ in range(repeat):
        est = MRGIA(config)
        est.update(ul[0], yl[0])  # compiled before the clock starts
        t0 = time.perf_counter_ns()
        for a, b in zip(ul, yl):
            est.update(a, b)
        best = min(best, (time.perf_counter_ns() - t0) / samples)
    return best / 1e3


def exchange_cost(u: np.ndarray, repeat: int) -> float:
    best = np.inf
    for _ in range(repeat):
        with driver_from_url(URL) as servo:
            servo.set_sample_period(PERIOD_S)
            servo.enable()
            t0 = time.perf_counter_ns()
            for v in u:
                servo.exchange(v)
            best = min(best, (time.perf_counter_ns() - t0) / u.size)
    return best / 1e3


def session_cost(u: np.ndarray, repeat: int, *, estimator: bool, recording: bool) -> float:
    best = np.inf
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(repeat):
            kwargs: dict[str, object] = {}
            if estimator:
                kwargs["estimator"] = MRGIA(MRGIAConfig())
            if recording:
                kwargs["recording"] = Path(tmp) / f"rec{i}.csv"
            with driver_from_url(URL) as servo:
                t0 = time.perf_counter_ns()
                result = run_session(servo, u, SessionConfig(period_s=PERIOD_S), **kwargs)
                elapsed = time.perf_counter_ns() - t0
            assert len(result) == u.size
            best = min(best, elapsed / u.size)
    return best / 1e3


def measure(samples: int, repeat: int) -> dict[str, float]:
    u = np.random.default_rng(2).uniform(-0.2, 0.2, samples)
    session_cost(u[:200], 1, estimator=True, recording=True)  # compile everything first
    return {
        "MRGIA.update": update_cost(samples, repeat),
        "driver.exchange (floor)": exchange_cost(u, repeat),
        "session, no listener": session_cost(u, repeat, estimator=False, recording=False),
        "session + MRGIA": session_cost(u, repeat, estimator=True, recording=False),
        "session + MRGIA + recording": session_cost(u, repeat, estimator=True, recording=True),
    }


def run_elsewhere(python: str, samples: int, repeat: int) -> dict[str, float]:
    """This script under another interpreter, from an empty folder, caches kept out of its checkout."""
    with tempfile.TemporaryDirectory() as tmp:
        env = {**os.environ, "NUMBA_CACHE_DIR": tmp, "PYTHONDONTWRITEBYTECODE": "1"}
        out = subprocess.run(
            [python, str(Path(__file__).resolve()), "--json", "--samples", str(samples), "--repeat", str(repeat)],
            cwd=tmp, env=env, capture_output=True, text=True, check=True,
        )  # fmt: skip
    return json.loads(out.stdout)  # type: ignore[no-any-return]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--samples", type=int, default=20_000)
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--rounds", type=int, default=3, help="rounds, the checkouts taking turns (default 3)")
    parser.add_argument(
        "--before", metavar="PYTHON", help="also measure under this interpreter (another checkout's venv)"
    )
    parser.add_argument("--json", action="store_true", help="print the figures as one JSON object")
    args = parser.parse_args()
    before: dict[str, float] | None = None
    now: dict[str, float] = {}
    for _ in range(1 if args.json else max(1, args.rounds)):
        if args.before:
            other = run_elsewhere(args.before, args.samples, args.repeat)
            before = other if before is None else {k: min(v, before[k]) for k, v in other.items()}
        this = measure(args.samples, args.repeat)
        now = this if not now else {k: min(v, now[k]) for k, v in this.items()}
    if args.json:
        print(json.dumps(now))
        return
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    cols = ["us per sample", "this checkout"]
    if before is not None:
        cols = ["us per sample", "before", "this checkout", "change"]
    rows = []
    floor = now["driver.exchange (floor)"]
    for name, value in now.items():
        row = [name]
        if before is not None:
            row += [f"{before[name]:.2f}"]
        row += [f"{value:.2f}"]
        if before is not None:
            row += [f"{100 * (value / before[name] - 1):+.0f} %"]
        rows.append(row)
    title = (f"per-sample cost, best of {args.rounds} x {args.repeat} runs of {args.samples} samples "
             f"(load average {load:.2f} on {os.cpu_count()} cores; the session rows include the floor "
             f"of {floor:.2f} us)")  # fmt: skip
    table(title, cols, rows)


if __name__ == "__main__":
    sys.exit(main())
