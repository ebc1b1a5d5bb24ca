"""Throughput of ``servoid batch``: 1 and 2 local workers, a running LocalCluster of 2, against identify() in a plain loop.

Run: ``.venv/bin/python benchmarks/fleet.py`` (20 recordings of 10^4
samples, a few minutes on a busy 2-core machine); ``--full`` runs the
issue's 200 recordings.

Rows (wall time of the whole command, so cluster start-up counts for the
local rows; best of ``--repeat``):

``identify() loop (floor)``
    The same recordings read and identified one after the other in this
    process, no Dask: what one worker can do at best.
``batch --workers 1`` / ``--workers 2``
    The command with local worker processes (starting them included).
``batch --cluster (LocalCluster, 2 workers)``
    The command against a cluster already running (start-up excluded), as
    on a lab's cluster.

Speed-up per worker: throughput over the floor's, divided by the workers.
On a 2-core machine shared with others' runs, two workers cannot reach 2x.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import logging
import os
import sys
import tempfile
import time
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path

import numpy as np
from _table import table  # benchmarks/, on the path when a benchmark runs as a script

from servoid.batch import identify_file
from servoid.cli import main as cli
from servoid.ident import PAPER_PLANT, MRGIAConfig, simulate
from servoid.readers import ReadOptions
from servoid.recording import write_recording


def make_fleet(folder: Path, recordings: int, samples: int) -> None:
    """``recordings`` CSV recordings of the paper's plant, 10 servos, the play growing night by night."""
    rng = np.random.default_rng(18)
    for i in range(recordings):
        servo, night = i % 10, i // 10
        play = 1.5 * (1.0 + 0.01 * night) * (1.0 + 0.05 * servo)
        sim = simulate(
            replace(PAPER_PLANT, c1=0.4 * play, c2=0.6 * play), rng.uniform(-3, 3, samples), snr=40.0, rng=rng
        )
        started = f"2026-03-{1 + night % 28:02d}T02:00:00+0000"
        write_recording(folder / f"j{servo}-n{night:03d}.csv", {"u": sim.u, "y": sim.y},
                        metadata={"servo_id": f"j{servo}", "started": started, "unit": "rad"})  # fmt: skip


@contextlib.contextmanager
def quiet_teardown() -> Iterator[None]:
    """distributed's loggers (and asyncio's, tornado's) at CRITICAL while a cluster closes.

    Closing the scheduler ends the comms its workers and clients still hold;
    distributed logs each end as a ``CommClosedError`` traceback
    (dask/distributed#7192): its notes on its own teardown, printed after the
    table, not a failure of the run (the runs' own errors stop the benchmark).
    """
    loggers = [logging.getLogger(name) for name in ("distributed", "asyncio", "tornado")]
    levels = [log.level for log in loggers]
    for log in loggers:
        log.setLevel(logging.CRITICAL)
    try:
        yield
    finally:
        for log, level in zip(loggers, levels):
            log.setLevel(level)


def timed_cli(argv: list[str]) -> float:
    t0 = time.perf_counter()
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        code = cli(argv)
    if code != 0:
        raise SystemExit(f"servoid {' '.join(argv)} failed with {code}")
    return time.perf_counter() - t0


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--recordings", type=int, default=20)
    parser.add_argument("--samples", type=int, default=10_000)
    parser.add_argument("--repeat", type=int, default=1)
    parser.add_argument("--full", action="store_true", help="the issue's 200 recordings")
    args = parser.parse_args()
    n = 200 if args.full else args.recordings
    from dask.distributed import LocalCluster

    with tempfile.TemporaryDirectory() as tmp:
        data = Path(tmp) / "fleet"
        data.mkdir()
        make_fleet(data, n, args.samples)
        files = sorted(data.glob("*.csv"))
        config = MRGIAConfig(epsilon=0.0)
        identify_file(str(files[0]), ReadOptions(), config)  # compiled and warm

        def loop() -> float:
            t0 = time.perf_counter()
            for f in files:
                identify_file(str(f), ReadOptions(), config)
            return time.perf_counter() - t0

        runs: dict[str, tuple[float, int]] = {"identify() loop (floor)": (min(loop() for _ in range(args.repeat)), 1)}
        for workers in (1, 2):
            best = min(timed_cli(["batch", str(data), "--workers", str(workers), "--out", f"{tmp}/w{workers}-{r}"])
                       for r in range(args.repeat))  # fmt: skip
            runs[f"batch --workers {workers}"] = (best, workers)
        # silence_logs: the worker processes' own loggers, which log the same teardown
        cluster = LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0",
                               silence_logs=logging.CRITICAL)  # fmt: skip
        try:
            timed_cli(["batch", str(files[0]), "--cluster", cluster.scheduler_address, "--out", f"{tmp}/warm"])
            best = min(timed_cli(["batch", str(data), "--cluster", cluster.scheduler_address,
                                  "--out", f"{tmp}/c-{r}"]) for r in range(args.repeat))  # fmt: skip
            runs["batch --cluster (LocalCluster, 2 workers)"] = (best, 2)
        finally:
            with quiet_teardown():
                cluster.close()  # type: ignore[no-untyped-call]
    floor_rate = n / runs["identify() loop (floor)"][0]
    rows = []
    for name, (seconds, workers) in runs.items():
        rate = n / seconds
        rows.append([name, f"{seconds:.1f}", f"{rate:.2f}", f"{rate * args.samples / 1e3:.0f}",
                     f"{rate / floor_rate / workers:.2f}"])  # fmt: skip
    load = os.getloadavg()[0]
    table(f"servoid batch, {n} recordings of {args.samples} samples (load average {load:.2f} on {os.cpu_count()} "
          "cores, shared with others' runs)",
          ["run", "seconds", "recordings/s", "k samples/s", "speed-up per worker"], rows)  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
