"""Sample rate, late share and identification per transport: Dynamixel over a pty, CiA 402 and ODrive on CAN.

Run:  .venv/bin/python benchmarks/transports_rate.py [--seconds 3] [--samples 4000] [--rates 100 500 1000]

Transports (the real drivers, against the emulators):

* ``dxl / pty``: the dxl:// driver (dynamixel-sdk) against the Dynamixel
  emulator in a process of its own, on a pseudo-terminal, sampled on its own
  clock at the session's rate;
* ``cia402 / virtual``, ``odrive / virtual``: the can:// drivers (canopen,
  python-can) against the simulated drives on python-can's ``virtual`` bus, in
  this process (a virtual bus reaches only its own process);
* ``cia402 / udp``, ``odrive / udp``: the same drives in another process
  (``servoid emulate can``), over python-can's ``udp_multicast`` interface.

Table 1: the sampling session (:func:`servoid.session.run_session`, the loop
``servoid identify --driver`` runs) at each rate for ``--seconds``: the rate
answered, the share of ok / late / missed / timed-out slots, and the exchange
time (median, 99th percentile).

Table 2: ``servoid identify --driver URL --rate 500 --json`` on each
transport and on the simulated servo (``sim://model?clock=virtual``, the same
plant in simulated time), with the same seeded excitation: the largest
relative error of the online MRGIA's and of the refined parameters against
MODEL_PLANT, and the share of samples used.

The machine's load is printed before and after: on a shared 2-core machine the
late and missed shares are the scheduler's as much as the link's.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import os
import signal
import socket
import subprocess
import sys
import tempfile
import time
import uuid
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np
from _table import table  # benchmarks/, on the path when a benchmark runs as a script

from servoid.cli import main as servoid_main
from servoid.drivers import driver_from_url
from servoid.drivers.model_plant import MODEL_AMPLITUDE, MODEL_PLANT
from servoid.ident import BacklashModel
from servoid.session import SessionConfig, run_session

IDENTIFY_RATE_HZ = 500.0


# ---- the transports: each yields the driver URL of an emulated servo sampled at `rate` ----------------
@contextlib.contextmanager
def dxl_pty(rate: float) -> Iterator[str]:
    from servoid.drivers.dynamixel.emulator import EmulatorProcess

    with EmulatorProcess([1], return_delay_us=0, period_s=1 / rate, servo="model") as emu:
        yield emu.url(1)


@contextlib.contextmanager
def can_virtual(protocol: str, rate: float) -> Iterator[str]:
    from servoid.drivers.can._bus import BusAddress
    from servoid.drivers.can.simulated import simulated_drive

    options = {"period_s": 1 / rate} if protocol == "odrive" else {}
    bus = BusAddress("virtual", f"bench-{uuid.uuid4().hex[:8]}")
    with simulated_drive(protocol, bus=bus, servo="model", **options) as drive:
        yield drive.url()


@contextlib.contextmanager
def can_udp(protocol: str, rate: float) -> Iterator[str]:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.bind(("", 0))
        port = s.getsockname()[1]
    cmd = [sys.executable, "-m", "servoid", "emulate", "can", "--protocol", protocol, "--port", str(port),
           "--rate", f"{rate:g}", "--quiet", "--servo", "model"]  # fmt: skip
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, text=True)
    try:
        url = proc.stdout.readline().strip() if proc.stdout else ""
        if not url.startswith("can://"):
            raise RuntimeError(f"the emulator did not start: {' '.join(cmd)}")
        yield url
    finally:
        proc.send_signal(signal.SIGINT)
        proc.wait(timeout=10)


TRANSPORTS: dict[str, Callable[[float], contextlib.AbstractContextManager[str]]] = {
    "dxl / pty": dxl_pty,
    "cia402 / virtual": lambda rate: can_virtual("cia402", rate),
    "cia402 / udp": lambda rate: can_udp("cia402", rate),
    "odrive / virtual": lambda rate: can_virtual("odrive", rate),
    "odrive / udp": lambda rate: can_udp("odrive", rate),
}


# ---- measurements ---------------------------------------------------------------------------------
def session_row(name: str, rate: float, seconds: float, seed: int) -> list[str]:
    u = np.random.default_rng(seed).uniform(-MODEL_AMPLITUDE, MODEL_AMPLITUDE, int(rate * seconds))
    with TRANSPORTS[name](rate) as url, driver_from_url(url) as servo:
        result = run_session(servo, u, SessionConfig(period_s=1 / rate))
    n = len(result)
    share = {k: f"{100 * v / n:.2f} %" for k, v in result.counts.items()}
    exchange = result.exchange_s[np.isfinite(result.exchange_s)] * 1e6
    return [name, f"{rate:g}", f"{result.achieved_rate_hz:.1f}", share["ok"], share["late"], share["missed"],
            share["timeout"], f"{np.median(exchange):.0f}", f"{np.percentile(exchange, 99):.0f}"]  # fmt: skip


def identify_json(url: str, samples: int, out: Path) -> dict:
    argv = ["identify", "--json", "--driver", url, "--rate", f"{IDENTIFY_RATE_HZ:g}", "--samples", str(samples),
            "--seed", "4", "--out", str(out), "--no-plots"]  # fmt: skip
    stdout, stderr = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(stdout), contextlib.redirect_stderr(stderr):
        code = servoid_main(argv)
    if code != 0:
        raise RuntimeError(f"servoid {' '.join(argv)} failed: {stderr.getvalue().strip()}")
    return json.loads(stdout.getvalue())


def identification_row(name: str, url: str, samples: int, out: Path) -> list[str]:
    result = identify_json(url, samples, out)
    refined = BacklashModel.from_dict(result["model"]).max_relative_error(MODEL_PLANT)
    mrgia = BacklashModel.from_dict(result["mrgia"]["model"]).max_relative_error(MODEL_PLANT)
    counts = result["acquisition"]["counts"]
    return [name, f"{IDENTIFY_RATE_HZ:g}", f"{counts['ok']}/{samples}", f"{mrgia:.2e}", f"{refined:.2e}",
            f"{result['fit_nrmse']:.2e}"]  # fmt: skip


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seconds", type=float, default=3.0, help="length of each session of table 1, s (default 3)")
    parser.add_argument(
        "--samples", type=int, default=4000, help="samples of each identification of table 2 (default 4000)"
    )
    parser.add_argument("--rates", type=float, nargs="+", default=[100.0, 500.0, 1000.0], help="rates of table 1, Hz")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()

    load_before = os.getloadavg()
    started = time.perf_counter()
    timing = [session_row(name, rate, args.seconds, args.seed) for name in TRANSPORTS for rate in args.rates]
    table(
        f"1. sampling session per transport ({args.seconds:g} s per run; exchange in us)",
        ["transport", "asked Hz", "answered Hz", "ok", "late", "missed", "timeout", "exchange p50", "p99"],
        timing,
    )
    with tempfile.TemporaryDirectory() as tmp:
        ident = [identification_row("sim (virtual time)", "sim://model?clock=virtual", args.samples, Path(tmp) / "sim")]
        for name, transport in TRANSPORTS.items():
            with transport(IDENTIFY_RATE_HZ) as url:
                ident.append(identification_row(name, url, args.samples, Path(tmp) / name.replace(" / ", "-")))
    table(
        f"2. servoid identify --driver URL --rate {IDENTIFY_RATE_HZ:g}: MODEL_PLANT from {args.samples} samples "
        "(max relative parameter error)",
        ["transport", "Hz", "ok samples", "MRGIA", "refined", "fit NRMSE"],
        ident,
    )
    load_after = os.getloadavg()
    print(
        f"\nload average (1/5/15 min) before {load_before[0]:.2f}/{load_before[1]:.2f}/{load_before[2]:.2f}, "
        f"after {load_after[0]:.2f}/{load_after[1]:.2f}/{load_after[2]:.2f} on {os.cpu_count()} cores; "
        f"{time.perf_counter() - started:.0f} s"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
