"""``servoid identify``: identify a backlash servo from the simulated servo or a recording."""

from __future__ import annotations

import argparse
import dataclasses
import time
from pathlib import Path
from typing import TYPE_CHECKING

from servoid import limits, readings_side
from servoid.cli import _data, _live, _live_bus, _model, _term
from servoid.errors import ConfigError
from servoid.ident.paper import PAPER_INPUT_AMPLITUDE, PAPER_INPUT_VARIANCE
from servoid.output_paths import output_dir

if TYPE_CHECKING:  # pragma: no cover
    from servoid.ident.online.mrgia import MRGIAConfig
    from servoid.identify_outputs import Record

# The numerical libraries are imported inside the functions that run: `servoid identify --help`
# must start without them (benchmarks/startup.py).

ORDER = 10

#: Records at least this long get a progress bar.
PROGRESS_FROM = 100_000

HELP = "identify a backlash model (simulated servo, a recording, or a live servo)"

DESCRIPTION = f"""\
Identify a servo with output backlash: a linear block (orders na, nb, delay d)
followed by a backlash with up-line slope 1, down-line slope m2 and dead zones
c1, c2 (the pseudo-Wiener model of Dong, Tan & Tan). The MRGIA estimates the
model online, sample by sample; an output-error fit then refines it offline.

Where the record comes from:
  (default)      the simulated servo of the paper's Section 4 (a1 .45, a2 .55,
                 b0 .8, d 1, m2 1.5, c1 .5, c2 1) driven by uniform bounded
                 white noise of variance {PAPER_INPUT_VARIANCE} (|u| <= {PAPER_INPUT_AMPLITUDE:.3f}),
                 or by --excitation SPEC (see `servoid excite --help`)
{_data.formats_help("  --data FILE    a recording: ", 17)}
  --driver URL   a live servo (sim://: a twin, sim://model the model; serial://, can://, dxl://), excited at
                 --rate Hz; the recording is written as it is measured

--excitation file:PATH[:COLUMN] replays a recorded input (a CSV column, u
unless named, or a .mat variable) on the simulated or the live servo: the
values are sent as they are, after a check that they are finite and, on a
live servo, inside its limits; --samples takes the first N of them.

Outputs in --out: recording.csv, model.json, convergence.png (each parameter
against samples, true values dashed when known), fit.png (measured against
simulated output), backlash.png (the identified loop), and what servoid
compare draws on this record: compare.png (free-run fit %), resid.png (the
residual's correlations and their 99 % band; a residual that fails the
Ljung-Box test at 1 % is coloured, said on stderr and in the verdict) and bode.png (Bode and step of the linear block).

Noise: with output noise, set --epsilon to about 0.8 x the noise standard
deviation of y (E|v| for Gaussian noise); for the simulated servo it is set
from --snr automatically. Units: c1 and c2 come out in the unit of y.
"""

EPILOG = f"""\
examples:
  servoid identify
  servoid identify --snr 43 --samples 20000 --seed 3
  servoid identify --snr 43 --excitation prbs:amplitude=1.5,hold=3
  servoid identify --data bench.csv --na 2 --nb 1 --delay 2 --epsilon 0.004 --unit rad
{_data.EXAMPLES.format(cmd="identify")}
  servoid identify --excitation file:excitation.csv --snr 40    (replay a signal on the simulated servo)
  servoid identify --json --no-plots > result.json
  servoid identify --driver "sim://xm430?snr=40" --rate 500 --samples 5000
  servoid identify --driver "sim://model?clock=virtual" --rate 500   (the estimator's own plant)
  servoid identify --driver serial:///dev/pts/5 --rate 200   (after: servoid emulate serial)
"""


def register(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    p = sub.add_parser(
        "identify", help=HELP, description=DESCRIPTION, epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )  # fmt: skip
    src = p.add_argument_group("record")
    src.add_argument("--data", metavar="FILE", type=Path,
                     help="identify from this recording (CSV, .mat, ROS bag, BAM .json) instead of the simulated servo")  # fmt: skip
    src.add_argument("--samples", type=int, metavar="N",
                     help=f"samples of the simulated or live run (default {_live.DEFAULT_SAMPLES}; a live run designed from "
                          f"its probe: {_live.DEFAULT_LIVE_S:g} s, {_live.DEFAULT_LIVE_WHY} (--seconds); a replayed "
                          "file: its length)")  # fmt: skip
    src.add_argument(
        "--seed", type=int, default=0, help="seed of the input (and noise) of the simulated or live run (default 0)"
    )
    src.add_argument("--snr", type=float, metavar="SNR",
                     help="output noise of the simulated servo: sqrt(var(y)/var(noise)); the paper uses 43 "
                          "(default: noise-free)")  # fmt: skip
    src.add_argument("--excitation", metavar="SPEC",
                     help="input of the simulated or live servo, e.g. prbs:amplitude=1.5,hold=3 or "
                          "multisine:amplitude=2,bands=0.01-0.2, or file:PATH[:COLUMN] to replay one "
                          "(default: the paper's uniform noise)")  # fmt: skip
    src.add_argument("--unit", metavar="UNIT",
                     help="unit of y (rad, counts, mm, ...); default from the recording's '# unit:' line")  # fmt: skip
    _data.add_options(p)
    _live.add_options(p)
    _live_bus.add_options(p)
    mdl = p.add_argument_group("model")
    _model.add_structure_options(mdl, selectable=True)
    est = p.add_argument_group("estimator")
    _model.add_rho_option(est)
    est.add_argument("--epsilon", type=float, metavar="E",
                     help="noise threshold on |y(k) - y(k-1)| of eqs (37)-(38), unit of y "
                          "(default: from --snr for the simulated servo, else 0)")  # fmt: skip
    est.add_argument(
        "--paper-algorithm",
        action="store_true",
        help="run the MRGIA exactly as printed: no projection, no recovery from a stuck run",
    )
    est.add_argument("--no-refine", action="store_true", help="skip the output-error refinement")
    out = p.add_argument_group("output")
    out.add_argument("--out", type=Path, default=Path("servoid-run"), metavar="DIR",
                     help="output folder (default ./servoid-run/)")  # fmt: skip
    out.add_argument("--json", action="store_true", help="print one JSON object on stdout and nothing else there")
    out.add_argument("--strict", action="store_true",
                     help="exit 1 when the play is not identifiable (the outputs are written all the same)")  # fmt: skip
    out.add_argument("--no-plots", action="store_true", help="skip the PNG plots")
    p.set_defaults(handler=run)


def _orders(args: argparse.Namespace) -> dict[str, int]:
    """The orders given on the command line, the defaults for those left to the data."""
    from servoid.ident import defaults

    given = {"na": args.na, "nb": args.nb, "delay": args.delay}
    fallback = {"na": defaults.NA, "nb": defaults.NB, "delay": defaults.DELAY}
    return {k: fallback[k] if v is None else v for k, v in given.items()}


def _selected(args: argparse.Namespace) -> tuple[str, ...]:
    """The orders to choose from the data: those not given (none for the simulated paper servo or a live run)."""
    if args.data is None:
        return ()
    return tuple(name for name in ("na", "nb", "delay") if getattr(args, name) is None)


def _config(args: argparse.Namespace, epsilon: float) -> MRGIAConfig:
    from servoid.ident.online.mrgia import MRGIAConfig

    orders = _orders(args)
    return MRGIAConfig(
        na=orders["na"], nb=orders["nb"], delay=orders["delay"], rho_exponent=args.rho_exponent, epsilon=epsilon,
        project=not args.paper_algorithm, recover=not args.paper_algorithm,
    )  # fmt: skip


def _simulated(args: argparse.Namespace) -> tuple[Record, MRGIAConfig]:
    import numpy as np

    from servoid.excitation import UniformSpec, format_spec, parse_spec, sample
    from servoid.ident.models.simulate import simulate
    from servoid.ident.online.mrgia import noise_epsilon
    from servoid.ident.paper import PAPER_PLANT
    from servoid.identify_outputs import Record
    from servoid.readers.excitation_file import is_file_spec, read_excitation

    if tuple(_orders(args).values()) != (PAPER_PLANT.na, PAPER_PLANT.nb, PAPER_PLANT.delay):
        raise ConfigError(
            "the simulated servo is the paper's plant (na=2, nb=0, delay=1); "
            "--na/--nb/--delay apply to --data recordings"
        )
    if is_file_spec(args.excitation):
        replay = read_excitation(args.excitation)
        u = replay.first(args.samples)
        described = replay.describe
    else:
        spec = UniformSpec(amplitude=PAPER_INPUT_AMPLITUDE) if args.excitation is None else parse_spec(args.excitation)
        u = sample(spec, args.samples or _live.DEFAULT_SAMPLES, seed=args.seed)
        described = format_spec(spec)
    # The noise continues default_rng(seed)'s stream after the input's draws, as
    # when the input was drawn here: the default run is unchanged.
    noise_bits = np.random.PCG64(args.seed)
    noise_bits.advance(u.size)
    sim = simulate(PAPER_PLANT, u, snr=args.snr, rng=np.random.Generator(noise_bits))
    source = f"sim://paper?samples={u.size}&seed={args.seed}" + (f"&snr={args.snr:g}" if args.snr else "")
    source += f"&excitation={described}"
    record = Record(
        u=sim.u, y=sim.y, source=source, truth=PAPER_PLANT, output_unit=args.unit or "unit",
        input_unit="unit", extra={"y_clean": sim.y_clean},
    )  # fmt: skip
    eps = args.epsilon if args.epsilon is not None else noise_epsilon(sim.noise_std)
    return record, _config(args, eps)


def _from_file(args: argparse.Namespace) -> tuple[Record, MRGIAConfig]:
    from servoid.identify_outputs import Record

    rec = _data.read(args.data, args)
    unit = args.unit or rec.metadata.get("unit", "unit")
    record = Record(
        u=rec.u, y=rec.y, t=rec.t, source=str(args.data), output_unit=unit,
        input_unit=rec.metadata.get("input_unit", "unit"), valid=_live.recording_valid(rec),
        readings=readings_side.of(rec.metadata),
    )  # fmt: skip
    return record, _config(args, args.epsilon if args.epsilon is not None else 0.0)


def get_record(args: argparse.Namespace) -> tuple[Record, MRGIAConfig]:
    """The record to identify and the estimator's settings (built once), from the command line."""
    _check_sizes(args)
    if args.data is None:
        _refuse_reading_options(args)
    if args.driver is not None:
        return _live.live_record(args, lambda epsilon: _config(args, epsilon))
    if args.data is not None:
        if args.excitation is not None:
            raise ConfigError("--excitation drives the simulated servo; a --data recording already holds its input")
        if args.samples is not None:
            raise ConfigError("--samples sets the length of a simulated or live run; a --data recording has its own")
        return _from_file(args)
    return _simulated(args)


def _refuse_reading_options(args: argparse.Namespace) -> None:
    given = [f"--{name.replace('_', '-')}" for name in ("columns", "time_column", "time_unit", "topics")
             if getattr(args, name) is not None]  # fmt: skip
    if given:
        raise ConfigError(f"{', '.join(given)} say(s) how to read a --data recording; there is none")


def _check_sizes(args: argparse.Namespace) -> None:
    """The record's length, the orders, the delay and the seed within servoid's limits, before any work."""
    if args.samples is not None:
        limits.bounded_count("--samples", args.samples, limit=limits.MAX_SAMPLES, what="a record's length")
    limits.orders(*_orders(args).values(), prefix="--")
    limits.seed("--seed", args.seed)


def run(args: argparse.Namespace) -> int:
    from servoid.ident.identify import identify
    from servoid.ident.offline._threads import stopping
    from servoid.identify_outputs import OUTPUT_FILES, result_json, summary_rows, twin_truth, write_outputs

    output_dir(args.out, option="--out", files=OUTPUT_FILES.values())
    args = _live.with_length(args)
    if _live_bus.names_several(args.driver):  # several servos of one bus: a model per joint
        _check_sizes(args)
        _refuse_reading_options(args)
        return _live_bus.run(args, lambda epsilon: _config(args, epsilon))
    began = time.perf_counter()  # (at or before the live run's start: its wall budget counts from there)
    record, config = get_record(args)
    # the wall budget cut the live run's servo-loop search with no online estimate: the black box alone, withheld
    unanswered = ((record.live or {}).get("budget") or {}).get("unanswered")
    started = time.perf_counter()
    # a live run on a real clock: identification's fits stop within the wall budget (the outputs' seconds kept)
    stop = _live.identify_stop(record, began)
    with (
        _term.progress("MRGIA", record.u.size, enabled=record.u.size >= PROGRESS_FROM and record.online is None) as bar,
        stopping(stop),
    ):
        result = identify(record.u, record.y, config, refine_model=not args.no_refine,
                          record_every=_live.history_every(record.u.size), progress=bar, valid=record.valid,
                          online=record.online, select=_selected(args),
                          sample_period_s=record.sample_period_s, loop=record.loop,
                          readings=record.readings, servo_loop=not unanswered)  # fmt: skip
    if unanswered:
        result = dataclasses.replace(result, verdict=dataclasses.replace(
            result.verdict, identifiable=False, reasons=(unanswered, *result.verdict.reasons)))  # fmt: skip
    elapsed = time.perf_counter() - started
    for w in result.warnings:
        _term.warn(w)
    record = _live.with_verdict(record, result, quiet=args.json)
    if record.live:
        record = dataclasses.replace(
            record, live={**record.live, "wall_s": {**record.live.get("wall_s", {}), "identify": elapsed}}
        )
    if stop is not None and stop.fired and record.live:  # in the JSON's budget.cut too (warned above, in the verdict)
        budget = record.live["budget"]
        cut = [*(budget.get("cut") or ()), _live.IDENTIFY_CUT]
        record = dataclasses.replace(record, live={**record.live, "budget": {**budget, "cut": cut}})
    paths = write_outputs(args.out, record, result, plots=not args.no_plots)
    status = 1 if args.strict and not result.identifiable else 0
    if args.json:
        _term.print_json(result_json(record, result, paths))
        return status
    cols, rows = summary_rows(result, record.truth)
    _term.table(f"servoid identify: {record.source} ({result.samples} samples, {elapsed:.2f} s)", cols, rows)
    out = _term.stdout
    if result.mrgia_nrmse is not None:
        out.print(f"free-run NRMSE  MRGIA: {result.mrgia_nrmse:.4g}", end="")
        out.print(f"   {result.method}: {result.fit_nrmse:.4g}" if result.refinement is not None else "")
    if record.truth is not None:
        out.print(
            f"max relative parameter error ({result.method}): {result.model.max_relative_error(record.truth):.3g}"
        )
    out.print(f"dead zone c1 + c2 = {result.model.dead_zone:.6g} {record.output_unit}, "
              f"down-line slope m2 = {result.model.m2:.6g}")  # fmt: skip
    twin = twin_truth(record)
    if twin is not None:
        out.print(f"the twin {twin['name']}: true play {twin['play_rad']:.6g} rad at the output; its loop closes on "
                  f"the {twin['loop_encoder']} encoder, the output is read on the {twin['output_encoder']} encoder")  # fmt: skip
    if not result.operating_point.is_zero:
        out.print(f"about the operating point u0 = {result.operating_point.u:.6g}, y0 = {result.operating_point.y:.6g} "
                  "(the dead zones do not exist in the record's own coordinates)")  # fmt: skip
    if result.orders is not None:
        out.print(result.orders.describe())
    out.print(result.headline())
    said = (record.live or {}).get("answer")
    if said:
        out.print(f"  {said['line']}")
    if result.loop is None and not result.identifiable:
        out.print("  the servo-loop model (the play inside the loop) was not fitted: the output backlash is the only "
                  "structure tried")  # fmt: skip
    factor = (record.live or {}).get("decimation", {}).get("factor", 1)
    if result.loop is not None and factor > 1 and record.written_to is not None:
        out.print(f"  the servo-loop model ran on the online estimator's record (1 in {factor} samples); "
                  f"servoid identify --data {record.written_to} fits it at the session's rate")  # fmt: skip
    for name, path in paths.items():
        out.print(f"  {name:17s} {path}")
    if status:
        _term.warn("--strict: the play is not identifiable; exit 1")
    return status
