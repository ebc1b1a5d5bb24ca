"""Online identification at real servo rates: probe, design, decimated MRGIA, verdict, on every twin x transport.

Run: ``.venv/bin/python benchmarks/online.py [--presets xm430 ...] [--transports sim ...] [--samples 12000]``.

Each run is ``servoid identify --driver URL --json --samples N`` with nothing
else (the probe, the design from it, the decimated online estimator, the
offline fit on the same slow record, the verdict), at identify's default rate
(200 Hz) against the transports of ``benchmarks/twins.py``. ``--samples``
defaults to 12 000: 60 s of servo time, the issue's budget. Printed as they
are, one row per run:

* ``probe s``: wall time of the probe (from the run's own table), ``k``: the
  decimation it chose, ``lost``: the share of unusable samples;
* ``online`` and ``refined``: the online estimate's ``c1 + c2`` and the
  refined fit's, at the output; ``err``: the online one against the twin's
  true play (the pseudo-Wiener model's play on a twin is not the twin's play:
  ``/work/notes/proto12`` finding 1; this column says how far);
* ``to 5 %``: servo seconds until the online ``c1 + c2`` stays within 5 % of
  its final value (replayed from the recording through the same decimated
  stream, which is deterministic), ``fit on/ref``: free-run NRMSE of the
  online model over that of the refined one on the same record;
* ``verdict``: the online verdict (``servoid.ident.online.verdict``) and its first reason;
* ``wall s``: the whole command, probe included.

Not measured here (not built): the monitor's tracking of a growing play on the
wearing twin. The machine may be shared: wall times depend on its load.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from _table import table
from twins import LIVE, outcome  # benchmarks/, on the path when a benchmark runs as a script

from servoid.cli import main as servoid_main
from servoid.cli._live import recording_valid
from servoid.drivers.twin.presets import preset, preset_names
from servoid.ident.online.decimate import decimate_record
from servoid.ident.online.mrgia import MRGIAConfig, run_mrgia
from servoid.recording import read_recording

#: Share of its final value the online play must stay within.
WITHIN = 0.05


def run(url: str, samples: int, out: Path) -> tuple[dict | None, str, float]:
    argv = ["identify", "--json", "--driver", url, "--samples", str(samples), "--out", str(out), "--no-plots"]
    stdout, stderr = io.StringIO(), io.StringIO()
    started = time.perf_counter()
    with contextlib.redirect_stdout(stdout), contextlib.redirect_stderr(stderr):
        code = servoid_main(argv)
    wall = time.perf_counter() - started
    if code != 0:
        return None, stderr.getvalue().strip().splitlines()[-1], wall
    return json.loads(stdout.getvalue()), "", wall


def seconds_to_within(out: Path, result: dict) -> float:
    """Servo seconds until the online play stays within WITHIN of its final value (replayed from the recording)."""
    rec = read_recording(out / "recording.csv")
    k = int(result["decimation"]["factor"])
    us, ys, vs, _ = decimate_record(rec.u, np.where(np.isfinite(rec.y), rec.y, 0.0), k, recording_valid(rec))
    mr = result["mrgia"]
    config = MRGIAConfig(na=len(result["model"]["a"]), nb=len(result["model"]["b"]) - 1, delay=result["model"]["delay"],
                         rho_exponent=mr["rho_exponent"], epsilon=mr["epsilon"])  # fmt: skip
    online = run_mrgia(us, ys, config, valid=vs)
    lay = config.theta_layout
    gaps = online.theta_history[:, lay.c1] + online.theta_history[:, lay.c2]
    final = gaps[-1]
    outside = np.flatnonzero(np.abs(gaps - final) > WITHIN * abs(final))
    slow = 0 if outside.size == 0 else int(outside[-1]) + 1
    return slow * k / float(result["acquisition"]["rate_hz"])


def row(name: str, transport: str, samples: int, out: Path) -> list[str]:
    params = preset(name)
    play = params.play_rad
    scale = params.gear_ratio if transport.startswith("odrive") and params.loop_encoder == "motor" else 1.0
    with LIVE[transport](name) as url:
        result, error, wall = run(url, samples, out)
    if result is None:
        return [name, transport, f"{play:.5f}", *["-"] * 8, f"{wall:.0f}", outcome(error)]
    online_gap = sum(result["mrgia"]["values"][c] for c in ("c1", "c2")) / scale
    refined_gap = (result["model"]["c1"] + result["model"]["c2"]) / scale
    verdict = result["online"]
    fit_ratio = (verdict["online_nrmse"] or float("nan")) / (verdict["refined_nrmse"] or float("nan"))
    why = "settled" if verdict["settled"] else "not: " + (verdict["reasons"][0][:40] if verdict["reasons"] else "?")
    probe = result["probe"]
    return [
        name, transport, f"{play:.5f}", f"{probe['samples'] / probe['rate_hz']:.1f}",
        str(result["decimation"]["factor"]), f"{result['lost']['share_unusable']:.2f}", f"{online_gap:.5f}",
        f"{refined_gap:.5f}", f"{(online_gap - play) / play:+.0%}", f"{seconds_to_within(out, result):.1f}",
        f"{fit_ratio:.2f}", f"{wall:.0f}", why,
    ]  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--presets", nargs="+", default=list(preset_names()))
    parser.add_argument("--transports", nargs="+", default=list(LIVE), choices=list(LIVE))
    parser.add_argument("--samples", type=int, default=12_000, help="samples per run (default 12000: 60 s at 200 Hz)")
    args = parser.parse_args()
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"machine load (1 min): {load:.2f} on {os.cpu_count()} cores", file=sys.stderr)
    with tempfile.TemporaryDirectory() as tmp:
        rows = [
            row(name, transport, args.samples, Path(tmp) / f"{name}-{i}")
            for name in args.presets
            for i, transport in enumerate(args.transports)
        ]
    table(
        f"servoid identify --driver URL --samples {args.samples} (probe, design, decimated MRGIA, verdict)",
        ["preset", "transport", "true play", "probe s", "k", "lost", "online", "refined", "err", "to 5 % s",
         "fit on/ref", "wall s", "verdict"],
        rows,
    )  # fmt: skip


if __name__ == "__main__":
    main()
