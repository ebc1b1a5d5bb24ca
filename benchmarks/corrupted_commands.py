"""Identified play when 0.5 % of the commands arrive corrupted, against the same transport without corruption.

Run:  .venv/bin/python benchmarks/corrupted_commands.py [--samples 4000] [--rate 500] [--seeds 3] [--share 0.005]

Transports (the real drivers against the emulators, each with the estimator's
own plant behind it (``servo="model"``,
:data:`servoid.drivers.model_plant.MODEL_PLANT`), where an exact
identification is possible and so every error is the link's):

* ``serial``: the serial:// driver (pyserial) against the reference firmware
  on a pty; each byte the firmware receives has a bit flipped with the
  probability that corrupts ``--share`` of the set-point requests (22-byte
  frames): the firmware drops a frame whose CRC fails, so the set point is
  lost and no reply comes;
* ``dxl``: the dxl:// driver (dynamixel-sdk) against the Dynamixel emulator
  in a process of its own, on its own clock at ``--rate``; each byte of the
  instruction packets is flipped likewise (a SYNC_WRITE of the goal is 14
  bytes, a READ 14): a corrupted goal is dropped by the servo, unanswered.

Each run: ``--samples`` of uniform noise (seeded) through the sampling session
at ``--rate``, then :func:`servoid.ident.identify` on the samples the session
marked usable. Reported, per transport and condition, over ``--seeds`` seeds:
the share of commands corrupted (counted by the device), the samples used,
and the largest relative error of the play (c1, c2) and of all parameters
against the plant (median and worst). The clean runs are the floor, measured
in the same run. On a shared machine, late slots vary; the corrupted share
does not.
"""

from __future__ import annotations

import argparse
import contextlib
import time
from collections.abc import Iterator

import numpy as np
from _table import table  # benchmarks/, on the path when a benchmark runs as a script

from servoid.drivers import driver_from_url
from servoid.drivers.model_plant import MODEL_AMPLITUDE, MODEL_PLANT
from servoid.ident import BacklashModel, MRGIAConfig, identify
from servoid.session import SessionConfig, run_session

#: Bytes of a set-point request of the serial protocol (``123 S -1234 4567*CRC\n``) and of a Dynamixel
#: instruction packet (SYNC_WRITE of one 4-byte goal, or the READ): what one corrupted command spans.
FRAME_BYTES = {"serial": 22, "dxl": 16}


def per_byte(share: float, frame_bytes: int) -> float:
    """The bit-flip probability per byte that corrupts ``share`` of the frames of ``frame_bytes`` bytes."""
    return 1.0 - (1.0 - share) ** (1.0 / frame_bytes)


@contextlib.contextmanager
def serial(flip: float, seed: int) -> Iterator[tuple[str, object]]:
    from servoid.drivers.serial.emulator import FirmwareEmulator, FirmwareOptions

    with FirmwareEmulator(FirmwareOptions(servo="model", flip_rx=flip, seed=seed)) as emu:
        yield f"{emu.url}?timeout=0.004", emu


@contextlib.contextmanager
def dxl(flip: float, seed: int, rate: float) -> Iterator[tuple[str, object]]:
    from servoid.drivers.dynamixel.emulator import EmulatorProcess

    with EmulatorProcess(
        [1], servo="model", return_delay_us=0, period_s=1 / rate, flip_rx=flip, flip_tx=0.0, seed=seed
    ) as emu:
        yield emu.url(1, latency_ms=2), emu


def run_one(kind: str, share: float, seed: int, samples: int, rate: float) -> dict[str, float]:
    flip = per_byte(share, FRAME_BYTES[kind]) if share else 0.0
    link = serial(flip, seed) if kind == "serial" else dxl(flip, seed, rate)
    noise = np.random.default_rng(seed).uniform(-MODEL_AMPLITUDE, MODEL_AMPLITUDE, samples)
    with link as (url, _emu), driver_from_url(url) as servo:
        u = servo.limits.centre + noise
        before = _device_rejects(kind, servo)
        result = run_session(servo, u, SessionConfig(period_s=1.0 / rate))
        corrupted = _device_rejects(kind, servo) - before
    valid = result.valid
    first = int(np.argmax(valid))
    ident = identify(result.u[first:], result.y[first:], MRGIAConfig(na=2, nb=0, delay=1), valid=valid[first:])
    model: BacklashModel = ident.model
    play = max(abs(model.c1 - MODEL_PLANT.c1) / MODEL_PLANT.c1, abs(model.c2 - MODEL_PLANT.c2) / MODEL_PLANT.c2)
    return {
        "corrupted": corrupted / samples,
        "used": float(valid.mean()),
        "play": play,
        "all": model.max_relative_error(MODEL_PLANT),
    }


def _device_rejects(kind: str, servo: object) -> int:
    """Frames the device threw away as corrupted, as far as the host can tell."""
    if kind == "serial":
        return int(servo.status()["rx_bad"])  # type: ignore[attr-defined]
    # the servo answers no corrupted SYNC_WRITE: only a read-back of the goal shows it
    return int(getattr(servo.stats, "unconfirmed", -(10**9)))  # type: ignore[attr-defined]


def _share(value: float) -> str:
    return "not seen" if value < 0 else f"{100 * value:.2f} %"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--samples", type=int, default=4000)
    parser.add_argument("--rate", type=float, default=500.0)
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--share", type=float, default=0.005, help="share of corrupted commands (default 0.005)")
    parser.add_argument("--transports", nargs="+", default=["serial", "dxl"], choices=sorted(FRAME_BYTES))
    args = parser.parse_args()
    rows = []
    started = time.perf_counter()
    for kind in args.transports:
        for share in (0.0, args.share):
            runs = [run_one(kind, share, seed, args.samples, args.rate) for seed in range(args.seeds)]
            play = np.array([r["play"] for r in runs])
            every = np.array([r["all"] for r in runs])
            rows.append([
                kind, f"{100 * share:.1f} %", _share(np.mean([r["corrupted"] for r in runs])),
                f"{100 * np.mean([r['used'] for r in runs]):.1f} %",
                f"{np.median(play):.2e} / {play.max():.2e}", f"{np.median(every):.2e} / {every.max():.2e}",
            ])  # fmt: skip
    table(
        f"Corrupted commands: {args.samples} samples at {args.rate:g} Hz, {args.seeds} seeds per row "
        f"({time.perf_counter() - started:.0f} s)",
        ["transport", "asked", "corrupted (device)", "samples used", "play rel. err (median / worst)",
         "all params (median / worst)"],
        rows,
    )  # fmt: skip


if __name__ == "__main__":
    main()
