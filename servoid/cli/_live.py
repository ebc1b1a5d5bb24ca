"""``servoid identify --driver URL``: identify a live servo through any driver.

The excitation (``--excitation SPEC``, else uniform white noise of
``--amplitude``; around the driver's ``centre``, ``--samples`` long, seeded
by ``--seed``) runs through the
sampling session at ``--rate``; the recording is written to
``OUT/recording.csv`` as samples arrive; the online MRGIA runs meanwhile and
the progress line shows it. The record then goes through the same
identification and outputs as an offline run, with the late, missed and
timed-out samples left out (:func:`servoid.session.usable`).
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from servoid.cli import _term
from servoid.drivers.model_plant import MODEL_AMPLITUDE
from servoid.errors import ConfigError

if TYPE_CHECKING:  # pragma: no cover
    import numpy as np

    from servoid.drivers.base import Limits
    from servoid.ident.models.pseudo_wiener import BacklashModel
    from servoid.ident.online.mrgia import MRGIAConfig, MRGIAResult
    from servoid.identify_outputs import Record
    from servoid.recording import Recording
    from servoid.session import SessionProgress, SessionResult

# The libraries a run needs are imported inside the functions that run it, so that the
# commands' --help (which add_options serves) starts without them.

__all__ = ["add_options", "live_record", "recording_valid", "session_rows", "excitation"]

#: Default sample rate of a live run, Hz.
DEFAULT_RATE_HZ = 200.0

#: Samples of a simulated or live run when --samples is not given.
DEFAULT_SAMPLES = 5000


def add_options(parser: argparse.ArgumentParser) -> None:
    """The options of a live run (a group of ``servoid identify``)."""
    live = parser.add_argument_group("live servo")
    live.add_argument("--driver", metavar="URL",
                      help="identify this servo live: sim://?snr=40, serial:///dev/ttyUSB0, can://..., dxl://... "
                           "(see docs/drivers.md); --samples, --seed set the excitation")  # fmt: skip
    live.add_argument("--rate", type=float, default=DEFAULT_RATE_HZ, metavar="HZ",
                      help=f"sample rate of the live run in Hz (default {DEFAULT_RATE_HZ:g})")  # fmt: skip
    live.add_argument("--amplitude", type=float, metavar="A",
                      help="half-width of the uniform excitation, in the driver's unit "
                           f"(default: the simulated servo's reference, else {MODEL_AMPLITUDE} for the bench servo)")  # fmt: skip
    live.add_argument("--guard", type=int, metavar="N",
                      help="samples left out after one whose command the servo may have applied otherwise than "
                           "recorded: a timed-out exchange (the command or its reply lost), and for a device on its "
                           "own clock (Dynamixel, ODrive) a late or missed slot too; the next samples carry that "
                           "error (default 10)")  # fmt: skip
    live.add_argument(
        "--use-late", action="store_true", help="let the estimator use samples exchanged late (default: leave them out)"
    )


def excitation(args: argparse.Namespace, amplitude: float, limits: Limits, unit: str = "") -> np.ndarray:
    """The input of a live run.

    ``--excitation file:...`` replays a file's commands as they are, after
    checking them against the driver's ``limits``; a spec (``--excitation
    SPEC``) runs around ``limits.centre``; else uniform noise ``centre +/-
    amplitude``. ``--samples`` long (a file: all of it by default).
    """
    from servoid.excitation import UniformSpec, parse_spec, sample
    from servoid.readers.excitation_file import is_file_spec, read_excitation

    if args.excitation is not None and args.amplitude is not None:
        raise ConfigError("give --amplitude or --excitation (whose spec has its own amplitude), not both")
    if is_file_spec(args.excitation):
        replay = read_excitation(args.excitation)
        replay.check_within(limits.low, limits.high, limits.max_step, unit=unit)
        u: np.ndarray = replay.first(args.samples)
        return u
    spec = parse_spec(args.excitation) if args.excitation is not None else UniformSpec(amplitude=amplitude)
    return limits.centre + sample(spec, args.samples or DEFAULT_SAMPLES, seed=args.seed)


def recording_valid(rec: Recording) -> np.ndarray | None:
    """The samples of a recording to identify from (:func:`servoid.session.samples.recording_usable`)."""
    from servoid.session.samples import recording_usable

    return recording_usable(rec)


def live_record(args: argparse.Namespace, make_config: Callable[[float], MRGIAConfig]) -> tuple[Record, MRGIAConfig]:
    """Run the excitation through ``args.driver`` with the MRGIA online; return the record and the settings.

    ``make_config(epsilon)`` builds the estimator's settings from the command
    line, once: the record carries the online run's result
    (:attr:`Record.online`), which identification refines rather than runs again.
    """
    if args.data is not None:
        raise ConfigError("give --driver or --data, not both")
    if args.snr is not None:
        raise ConfigError("--snr sets the noise of the built-in simulation; for the simulated servo put it in the URL: "
                          "--driver 'sim://?snr=40'")  # fmt: skip
    if not (math.isfinite(args.rate) and 0 < args.rate <= 20_000):
        raise ConfigError(f"--rate (={args.rate:g}) must lie in (0, 20000] Hz")
    if args.samples is not None and args.samples < 1:
        raise ConfigError(f"--samples (={args.samples}) must be >= 1")
    from servoid.drivers import driver_from_url
    from servoid.drivers.simulated import SimulatedServo
    from servoid.ident.online.mrgia import MRGIA, noise_epsilon
    from servoid.identify_outputs import OUTPUT_FILES
    from servoid.session import SessionConfig, run_session
    from servoid.session.listeners import EstimatorFeed

    driver = driver_from_url(args.driver)
    quiet = args.json
    with driver:
        identity = driver.identity
        noise = identity.get("noise_std")
        if args.epsilon is not None:
            epsilon = args.epsilon
        else:
            epsilon = noise_epsilon(noise) if isinstance(noise, (int, float)) else 0.0
        simulated = driver if isinstance(driver, SimulatedServo) else None
        amplitude = args.amplitude if args.amplitude is not None else (
            simulated.reference_amplitude if simulated is not None else MODEL_AMPLITUDE)  # fmt: skip
        if not (math.isfinite(amplitude) and amplitude > 0):
            raise ConfigError(f"--amplitude (={amplitude:g}) must be > 0")
        u = excitation(args, amplitude, driver.limits, driver.command_unit.unit)
        estimator_config = make_config(epsilon)
        online = EstimatorFeed(MRGIA(estimator_config), record_every=history_every(u.size))
        config = SessionConfig(period_s=1.0 / args.rate, use_late=args.use_late, guard_samples=args.guard)
        path = args.out / OUTPUT_FILES["recording"]
        meta = {"amplitude": repr(amplitude), "seed": str(args.seed), "excitation": args.excitation or "uniform",
                "servo": _flat(identity)}  # fmt: skip
        if not quiet:
            _term.stderr.print(f"servoid identify: {driver.describe()} at {args.rate:g} Hz, {u.size} samples "
                               f"({u.size / args.rate:.1f} s), +/-{amplitude:g} {driver.command_unit.unit}; "
                               f"recording to {path}")  # fmt: skip
        with _term.live_progress("live", u.size) as bar:

            def update(p: SessionProgress) -> None:
                bar(p.done, _status_text(p, driver.position_unit.unit))

            result = run_session(
                driver, u, config, recording=path, metadata=meta, listeners=[online],
                on_progress=None if quiet else update,
            )  # fmt: skip
    if not quiet:
        cols, rows = session_rows(result)
        _term.table(f"session: {driver.describe()}", cols, rows, console=_term.stderr)
    if result.stopped == "interrupted":
        _term.warn(f"interrupted after {len(result)} samples; they are in {path} "
                   f"(identify them with: servoid identify --data {path})")  # fmt: skip
        raise KeyboardInterrupt
    if result.estimator_error:
        _term.warn(f"online estimation stopped early: {result.estimator_error}")
    truth = simulated.truth if simulated is not None else None
    record = _record(result, driver.describe(), identity, truth, path, online.mrgia_result())
    return record, estimator_config


def history_every(samples: int) -> int:
    """Every how many samples the MRGIA's history is kept: at most 20 000 rows for the convergence plot."""
    return max(1, samples // 20_000)


def _record(
    result: SessionResult,
    source: str,
    identity: dict[str, Any],
    truth: BacklashModel | None,
    path: Path,
    online: MRGIAResult | None,
) -> Record:
    import numpy as np

    from servoid.identify_outputs import Record

    valid = result.valid
    if not valid.any():
        raise ConfigError(f"no sample of {source} was usable ({result.counts}); the recording is in {path}")
    # the free-run simulation starts at the first measured sample; the online run, which began
    # before it, then no longer matches the record, and identification runs the MRGIA itself
    first = int(np.argmax(valid))
    unit = result.unit
    return Record(
        u=result.u[first:], y=result.y[first:], t=result.t[first:], source=source, input_unit=unit,
        output_unit=unit, truth=truth, servo=identity, written_to=path, valid=valid[first:],
        acquisition=acquisition(result), online=online if first == 0 else None,
    )  # fmt: skip


def acquisition(result: SessionResult) -> dict[str, Any]:
    """How a live record was sampled, for ``--json`` (:meth:`SessionResult.to_dict`)."""
    return result.to_dict()


def session_rows(result: SessionResult) -> tuple[list[str], list[list[str]]]:
    """The session summary table: one row per quantity."""
    acq = acquisition(result)
    counts = result.counts
    n = max(len(result), 1)
    rows = [["rate", f"{acq['rate_hz']:g} Hz asked, {acq['achieved_rate_hz']:.4g} Hz answered"]]
    for status in ("ok", "late", "missed", "timeout"):
        rows.append([status, f"{counts[status]} ({100.0 * counts[status] / n:.2f} %)"])
    if acq["exchange_median_s"] is not None:
        rows.append(["exchange", f"median {acq['exchange_median_s'] * 1e6:.0f} us, "
                                 f"99 % {acq['exchange_p99_s'] * 1e6:.0f} us"])  # fmt: skip
    rows.append(["frames rejected / stale", f"{acq['frames_rejected']} / {acq['replies_stale']}"])
    if acq["commands_unconfirmed"]:
        rows.append(["commands not confirmed", str(acq["commands_unconfirmed"])])
    rows.append(["commands clamped", str(acq["commands_clamped"])])
    return ["", "value"], rows


def _status_text(p: SessionProgress, unit: str) -> str:
    text = f"late {100 * p.late_share:.1f} %"
    if p.estimate:
        shown = ", ".join(f"{k} {v:.4g}" for k, v in p.estimate.items())
        text += f" | {shown} ({unit})"
    return text


def _flat(identity: dict[str, Any]) -> str:
    return ", ".join(f"{k}={v}" for k, v in identity.items() if not isinstance(v, dict))
