"""The physical servo twins: what 1 ms of servo time costs, and what identification makes of them.

Run: ``.venv/bin/python benchmarks/twins.py [--repeat 5] [--samples 6000] [--live-samples 5000]``.

Three tables; the first two one row per preset:

1. **Speed.** The firmware's rates and the sub-step, then the cost of
   ``Twin.advance(0.001)`` (one emulator period at 1 kHz, through the Python
   object: what an emulator pays), the compiled kernel alone for the same
   millisecond, and a floor measured in the same run: a bare call of a
   compiled no-op with the same arguments (numba's dispatch cost). Best of
   ``--repeat`` rounds of 2000 calls; the budget is 50 us per ms.
2. **Identification (offline).** Each twin, torque on, driven by a bounded
   white set point (uniform, +-0.1 rad, seeded) at 100 Hz, sampled as a host
   does (:meth:`Twin.sample`: read at the command's arrival, command latched
   at the drive's next tick); ``servoid.ident.identify`` with default
   settings (``MRGIAConfig()``: na 2, nb 0, delay 1, no structure flags) on
   (command, output encoder). Printed as they are: the true play, the
   identified ``c1 + c2``, its error, the fit's free-run NRMSE, and what the
   drive did meanwhile (shares of its ticks with saturated duty and with the
   current command at its limit, share of the time the motor was stuck,
   whether the online estimate settled or the drive faulted). Nothing here
   is tuned to make these numbers good.
3. **Every preset behind every transport**, identified as a user would:
   ``servoid identify --driver URL --json`` with its default settings
   (200 Hz, 5000 samples, seed 0, the default amplitude: the simulated
   servo's reference of 0.1 rad, else 0.2 in the driver's unit) against
   ``sim://NAME?clock=virtual``, the C firmware (``servoid emulate serial
   --servo NAME``, on a pty), the Dynamixel emulator (another process, on a
   pty), and the CiA 402 drive and the ODrive axis (``servoid emulate can
   --servo NAME`` in another process, over UDP multicast). Printed: the true
   play, the identified ``c1 + c2`` (at the output: the ODrive counts turns of
   its motor, so its figure is divided by the gear ratio), its error, the fit
   NRMSE, the share of late slots, and the twin's cost per ms from table 1.
   A run that ends in a fault (the ODrive's overspeed) says so.

The machine may be shared: the speed table is the best of the repeats, and
the late shares of table 3 depend on what else runs.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import os
import re
import signal
import socket
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np
from _table import table  # benchmarks/, on the path when a benchmark runs as a script

from servoid.cli import main as servoid_main
from servoid.drivers.twin import Twin, preset, preset_names
from servoid.drivers.twin._jit import jit
from servoid.drivers.twin.kernel import run
from servoid.errors import ServoidError
from servoid.ident import MRGIAConfig, identify

HOST_RATE_HZ = 100.0
AMPLITUDE_RAD = 0.1
CALLS = 2000


@jit
def _noop(
    phys: np.ndarray,
    fw: np.ndarray,
    state: np.ndarray,
    mem: np.ndarray,
    n_sub: int,
    noise_m: np.ndarray,
    noise_l: np.ndarray,
    noise_at: int,
) -> int:
    """The floor: a compiled function with the kernel's arguments that does nothing."""
    return noise_at


def best_per_call(fn, repeat: int) -> float:
    """Best mean time of one call over ``repeat`` rounds of CALLS calls, us."""
    best = np.inf
    for _ in range(repeat):
        start = time.perf_counter()
        for _ in range(CALLS):
            fn()
        best = min(best, (time.perf_counter() - start) / CALLS)
    return best * 1e6


def speed_row(name: str, repeat: int) -> list[str]:
    twin = Twin(preset(name), seed=1)
    twin.enable()
    twin.command(0.05)
    twin.advance(0.01)  # compile and settle
    per_ms = best_per_call(lambda: twin.advance(1e-3), repeat)
    phys, fw = twin.params.pack()
    state = twin._state.copy()  # the kernel alone, on a copy of the running state
    mem = twin._mem.copy()
    empty = np.zeros(0)
    n_sub = int(round(1e-3 / twin.params.substep_s))
    kernel = best_per_call(lambda: run(phys, fw, state, mem, n_sub, empty, empty, 0), repeat)
    _noop(phys, fw, state, mem, 0, empty, empty, 0)
    floor = best_per_call(lambda: _noop(phys, fw, state, mem, 0, empty, empty, 0), repeat)
    p = twin.params
    return [
        name,
        f"{p.control_rate_hz:g}",
        f"{p.current_rate_hz:g}",
        f"{p.substep_s * 1e6:.3g}",
        f"{n_sub}",
        f"{per_ms:.1f}",
        f"{kernel:.1f}",
        f"{floor:.2f}",
        f"{per_ms / floor:.0f}x",
        "yes" if per_ms <= 50.0 else "NO",
    ]


def ident_row(name: str, samples: int, seed: int) -> list[str]:
    twin = Twin(preset(name), seed=seed)
    twin.enable()
    u = np.random.default_rng(seed).uniform(-AMPLITUDE_RAD, AMPLITUDE_RAD, samples)
    rec = twin.sample(u, 1.0 / HOST_RATE_HZ)
    play = twin.truth.play_rad
    counters = twin.counters
    fault = twin.read().fault
    limited = counters.current_limited_ticks / counters.ticks if counters.ticks else 0.0
    try:
        result = identify(rec.u, rec.y, MRGIAConfig())
    except ServoidError as exc:
        return [
            name,
            f"{play:.5f}",
            "failed",
            "-",
            "-",
            "-",
            "-",
            f"{counters.saturated_share:.2f}",
            f"{limited:.2f}",
            f"{counters.stuck_motor_s / counters.time_s:.2f}",
            str(exc)[:40],
        ]
    m = result.model
    width = m.c1 + m.c2
    return [
        name,
        f"{play:.5f}",
        f"{width:.5f}",
        f"{width - play:+.5f}",
        f"{(width - play) / play:+.1f}",
        f"{m.m2:.3f}",
        f"{result.fit_nrmse:.4f}",
        f"{counters.saturated_share:.2f}",
        f"{limited:.2f}",
        f"{counters.stuck_motor_s / counters.time_s:.2f}",
        fault or ("settled" if result.mrgia.settled else "not settled"),
    ]


# ---- table 3: every preset behind every transport, through servoid identify --driver ----------------------
@contextlib.contextmanager
def sim_url(name: str) -> Iterator[str]:
    yield f"sim://{name}?clock=virtual"


@contextlib.contextmanager
def serial_url(name: str) -> Iterator[str]:
    from servoid.drivers.serial.emulator import FirmwareEmulator, FirmwareOptions

    with FirmwareEmulator(FirmwareOptions(servo=name)) as emu:
        yield emu.url


@contextlib.contextmanager
def dxl_url(name: str) -> Iterator[str]:
    from servoid.drivers.dynamixel.emulator import EmulatorProcess

    with EmulatorProcess([1], return_delay_us=0, period_s=1 / LIVE_RATE_HZ, servo=name) as emu:
        yield emu.url(1)


def can_url(protocol: str) -> Callable[[str], contextlib.AbstractContextManager[str]]:
    @contextlib.contextmanager
    def start(name: str) -> Iterator[str]:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
            s.bind(("", 0))
            port = s.getsockname()[1]
        cmd = [sys.executable, "-m", "servoid", "emulate", "can", "--protocol", protocol, "--port", str(port),
               "--rate", f"{LIVE_RATE_HZ:g}", "--servo", name, "--quiet"]  # fmt: skip
        proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, text=True)
        try:
            url = proc.stdout.readline().strip() if proc.stdout else ""
            if not url.startswith("can://"):
                raise RuntimeError(f"the emulator did not start: {' '.join(cmd)}")
            yield url
        finally:
            # SIGTERM, not Ctrl-C: a benchmark started in the background (make bench &) passes on an ignored SIGINT
            proc.send_signal(signal.SIGTERM)
            try:
                proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                print(
                    f"(the emulator {' '.join(cmd[3:])} did not stop within 10 s of SIGTERM: killed)", file=sys.stderr
                )
                proc.kill()
                proc.wait()

    return start


#: servoid identify's default rate, at which the emulators on their own clock run.
LIVE_RATE_HZ = 200.0

LIVE: dict[str, Callable[[str], contextlib.AbstractContextManager[str]]] = {
    "sim": sim_url,
    "serial (C)": serial_url,
    "dxl": dxl_url,
    "cia402 (udp)": can_url("cia402"),
    "odrive (udp)": can_url("odrive"),
}


def identify_live(url: str, samples: int, out: Path) -> tuple[dict | None, str]:
    """``servoid identify --driver URL --json`` with its defaults: the result, or None and the error line."""
    argv = ["identify", "--json", "--driver", url, "--samples", str(samples), "--out", str(out), "--no-plots"]
    stdout, stderr = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(stdout), contextlib.redirect_stderr(stderr):
        code = servoid_main(argv)
    if code != 0:
        return None, stderr.getvalue().strip().splitlines()[-1]
    return json.loads(stdout.getvalue()), ""


def outcome(error: str) -> str:
    """A failed run in a few words: the error's kind, what the device said, the sample it stopped at."""
    text = error.removeprefix("servoid identify: ").removeprefix("error: ")
    kind = text.split(":", 1)[0] if re.match(r"^[A-Z]\w+:", text) else "error"
    said = re.search(
        r"\((\w+) error\)|(EMCY 0x[0-9A-F]{4})|axis error 0x[0-9A-F]+ \((\w+)\)|(hardware error: [\w ,]+?) \("
        r"|(output stage turned itself off)",
        text,
    )
    at = re.search(r"stopped at sample (\d+)", text)
    if said is None:
        return text[:70]
    what = next(g for g in said.groups() if g)
    return f"{kind}: {what}" + (f" at sample {at.group(1)}" if at else "")


def live_row(name: str, transport: str, samples: int, cost_us: str, out: Path) -> list[str]:
    params = preset(name)
    play = params.play_rad
    # the ODrive counts turns of its loop encoder's shaft: the motor's, unless the loop is on the load
    scale = params.gear_ratio if transport.startswith("odrive") and params.loop_encoder == "motor" else 1.0
    with LIVE[transport](name) as url:
        result, error = identify_live(url, samples, out)
    if result is None:
        return [name, transport, f"{play:.5f}", "-", "-", "-", "-", "-", cost_us, outcome(error)]
    m = result["model"]
    width = (m["c1"] + m["c2"]) / scale
    online = "settled" if result["mrgia"].get("settled") else "not settled"
    return [
        name,
        transport,
        f"{play:.5f}",
        f"{width:.5f}",
        f"{width - play:+.5f}",
        f"{(width - play) / play:+.1f}",
        f"{result['fit_nrmse']:.3f}",
        f"{result['acquisition']['late_share']:.2f}",
        cost_us,
        online,
    ]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5, help="timing rounds (best is kept)")
    parser.add_argument("--samples", type=int, default=6000, help="host samples per identification")
    parser.add_argument(
        "--live-samples", type=int, default=5000, help="samples of each run of table 3 (default 5000, identify's)"
    )
    parser.add_argument("--presets", nargs="+", default=list(preset_names()), help="presets of table 3 (default all)")
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args()
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"machine load (1 min): {load:.2f} on {os.cpu_count()} cores; times are the best of {args.repeat} rounds")

    rows = [speed_row(name, args.repeat) for name in preset_names()]
    cost = {row[0]: row[5] for row in rows}
    table(
        "Cost of servo time (Twin.advance(0.001), i.e. an emulator at 1 kHz)",
        [
            "preset",
            "control Hz",
            "current Hz",
            "sub-step us",
            "sub-steps/ms",
            "us per ms",
            "kernel us",
            "floor us",
            "x floor",
            "<= 50 us",
        ],
        rows,
    )

    rows = [ident_row(name, args.samples, args.seed) for name in preset_names()]
    table(
        f"Offline identification: white set point +-{AMPLITUDE_RAD} rad at {HOST_RATE_HZ:g} Hz, "
        f"{args.samples} samples, identify(u, y, MRGIAConfig())",
        [
            "preset",
            "true play rad",
            "c1+c2 rad",
            "error rad",
            "rel. error",
            "m2",
            "fit NRMSE",
            "duty sat.",
            "current lim.",
            "motor stuck",
            "online",
        ],
        rows,
    )

    with tempfile.TemporaryDirectory() as tmp:
        live = [
            live_row(name, transport, args.live_samples, cost[name], Path(tmp) / f"{name}-{i}")
            for name in args.presets
            for i, transport in enumerate(LIVE)
        ]
    table(
        f"Every preset x transport: servoid identify --driver URL with its defaults ({LIVE_RATE_HZ:g} Hz, "
        f"{args.live_samples} samples); dead zone at the output, rad",
        ["preset", "transport", "true play", "c1+c2", "error", "rel. error", "fit NRMSE", "late", "us per ms",
         "online / outcome"],
        live,
    )  # fmt: skip


if __name__ == "__main__":
    main()
