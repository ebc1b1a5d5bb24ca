"""``servoid monitor``: watch a servo's backlash while it works, and raise an alarm when it wears out of bounds."""

from __future__ import annotations

import argparse
import itertools
import math
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

from servoid import limits
from servoid.cli import _live, _term
from servoid.drivers.model_plant import MODEL_AMPLITUDE
from servoid.errors import ConfigError
from servoid.excitation.monitor_input_names import CYCLE_STEPS, CYCLED, INPUTS, STEADY
from servoid.excitation.specs import SignalSpec, UniformSpec, format_spec, parse_spec
from servoid.ident.defaults import DEFAULT_PROCESS_NOISE
from servoid.ident.monitoring.alarms import AlarmRule, Bound
from servoid.monitor_config import EXIT_ALARM, MonitorConfig
from servoid.output_paths import output_dir, output_file

if TYPE_CHECKING:  # pragma: no cover
    from servoid.drivers.base import Driver
    from servoid.excitation.monitor_input import GridCount
    from servoid.ident.models.pseudo_wiener import BacklashModel
    from servoid.modelfile import ModelFile
    from servoid.monitor_loop import ReadingsGrid
    from servoid.monitor_run import MonitorProgress, MonitorResult

# The drivers, the estimator and the loop are imported inside run(): `servoid monitor --help` starts without them.

ORDER = 15

HELP = "watch a servo's backlash while it works; alarm when the dead zone, m2 or the fit leave their bounds"

DESCRIPTION = f"""\
Watch a servo's backlash while it runs, for as long as it runs: gears wear, the
dead zone grows, and a compensator tuned once drifts out of tune.

The servo follows an input (below) at --rate Hz. The MRGIA in random-walk mode
estimates the model online, starting from --model (the servo's model.json from
`servoid identify`), with a gain that never vanishes: the parameters are taken
as a random walk of variance --process-noise x (c1 + c2)^2 per update, and the
estimate updates only on samples where the output moved along a backlash line
(eq. 42). Every --check-every samples an alarm rule compares the dead zone
c1 + c2, the down-line slope m2 and the fit (free-run NRMSE over the last 5000
samples) with their bounds:

  raise  the estimate lies beyond a bound by more than --z standard deviations
         at --persist consecutive checks
  clear  it is back inside by 10 % of the band's width at --persist checks

An alarm prints a line starting with ALARM on stderr; with --fail-on-alarm the
run stops there and servoid exits with status {EXIT_ALARM}.

A model file whose answer is the servo-loop model (the play inside the loop,
structure.form servo_loop) is followed instead by its play alone: the file's
loop, its gains held, gets its play refitted on the first 10 s of servo time,
then the play alone on 1.6 s windows every 0.25 s; their scatter over the next
20 s sets a CUSUM's threshold for one false alarm in 10^8 samples on average.
--dead-zone bounds the play (a share P% is taken of the median play those
windows see); --persist, --z, --m2 and --fit do not apply
(benchmarks/monitor_loop.py). Its input, without
--operating and --excitation, is what that benchmark measured: the gentle
sines of the file's design (`servoid identify --driver` writes it) for the
first 10 s, then one steady sine at their largest amplitude and half their highest
acceleration (inside the driver's limits); a file without that design gets the
uniform noise below, and the header's "input:" line says which.

--input chooses that steady sine: "steady" (the default) keeps one amplitude;
"cycled" steps it a count / {CYCLE_STEPS} smaller each half-period over {CYCLE_STEPS} values, for a
file whose play sits inside the loop (a horn servo: XM430, STS3215). Why: a
horn servo's firmware closes its position loop on whole counts of the horn's
encoder, and a sine of one amplitude reverses at the same place on that count
grid every period, where the window plays read the play with a bias of their
own (7-9 % low on the XM430 and STS3215 twins' data files); cycled, every
window's reversals pass the same few places a count / {CYCLE_STEPS} apart and the bias
averages out (4-5 %). It is not the default because on the twins' live files
(what `servoid identify --driver` writes) it delayed the XM430's alarm after a
+20 % step from 1.25 to 4.25 s. The count is the encoder's, taken from the
readings the first fit used; where they show none (too few changes, a
continuous or noisy encoder) the steady sine runs, and a line says why. Where
the play sits outside the loop the loop closes on the motor's encoder, whose
grid the readings do not show: the cycle has nothing to average there.

The input: the servo's normal operating input (--operating SPEC, a trajectory
around the driver's centre), a small excitation superimposed on it
(--excitation SPEC), or both; the spec grammar is that of `servoid excite`.
Without either, uniform white noise of the simulated servo's reference
amplitude (else {MODEL_AMPLITUDE}). The MRGIA sees the backlash only where the
output moves by more than the noise from one sample to the next: a slow
trajectory alone says little about the dead zone (docs/monitor.md).

Outputs in --out: estimates.csv (a row every --every s: estimates, standard
deviations, fit, share of samples that updated, alarms), compensation.jsonl
(c1, c2, m2 and the smoothing band each time they moved by --compensation-step),
model.json (the latest estimate, for `servoid export`), events.jsonl (alarms,
recoveries, start and stop); --plot FILE.png is redrawn every --plot-every s.
Memory stays constant however long it runs. Ctrl-C ends the run (exit 0; the
outputs are complete).

Bounds: MIN,MAX in the servo's unit (m2 is unitless), or P% for +/- P % of the
model's value, or 'none'. Defaults: the dead zone and m2 within +/- 10 %.
"""

EPILOG = """\
examples:
  servoid identify --driver "sim://gear?snr=40&clock=virtual" --rate 1000 --samples 20000 --out gear
  servoid monitor --driver "sim://gear?snr=40&clock=virtual&drift=1.5&drift_samples=200000" \\
      --model gear/model.json --duration 300 --plot monitor.png
  servoid monitor --driver "sim://gear?snr=40&clock=virtual&swap_at=30000&swap_factor=1.2" \\
      --model gear/model.json --duration 60 --fail-on-alarm       (exit status 3)
  servoid monitor --driver serial:///dev/ttyUSB0 --model model.json --dead-zone 0.045,0.06 --m2 none \\
      --operating "levels:amplitude=0.5,count=4,dwell=2000" --excitation "uniform:amplitude=0.1"
"""


def register(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    p = sub.add_parser(
        "monitor", help=HELP, description=DESCRIPTION, epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )  # fmt: skip
    servo = p.add_argument_group("servo")
    servo.add_argument("--driver", metavar="URL", required=True,
                       help="the servo: sim://gear?snr=40, serial:///dev/ttyUSB0, can://..., dxl://... "
                            "(docs/drivers.md; sim:// wears with drift=, drift_samples=, swap_at=, swap_factor=)")  # fmt: skip
    servo.add_argument(
        "--model",
        metavar="MODEL.json",
        type=Path,
        required=True,
        help="the servo's model file (servoid identify): where the estimate starts, its unit and noise",
    )
    servo.add_argument("--rate", type=float, metavar="HZ",
                       help=f"sample rate in Hz (default: the model's times its live run's decimation, else "
                            f"{_live.DEFAULT_RATE_HZ:g}); a whole multiple k of the model's rate: the estimator runs "
                            "on every k-th sample, anti-aliased, at the rate its linear block was identified at")  # fmt: skip
    servo.add_argument("--duration", type=float, metavar="S", help="run this many seconds (default: until Ctrl-C)")
    servo.add_argument("--guard", type=int, metavar="N",
                       help="samples left out after one whose command the servo may have applied otherwise than "
                            "recorded: a timed-out exchange (the command or its reply lost), and for a device on its "
                            "own clock (Dynamixel, ODrive) a late or missed slot too (default 10)")  # fmt: skip
    servo.add_argument("--use-late", action="store_true", help="let the estimator use samples exchanged late")
    inp = p.add_argument_group("input")
    inp.add_argument("--operating", metavar="SPEC",
                     help="the servo's normal operating input around the driver's centre, e.g. "
                          "levels:amplitude=0.5,count=4,dwell=2000 (default: none)")  # fmt: skip
    inp.add_argument("--excitation", metavar="SPEC",
                     help="excitation added to it, e.g. uniform:amplitude=0.05 (default: without --operating, "
                          "for a servo-loop model with a design the identification's sines, then a steady sine; "
                          "else uniform noise of the driver's reference amplitude; with --operating, none)")  # fmt: skip
    inp.add_argument("--input", choices=INPUTS, metavar="|".join(INPUTS),
                     help="the servo-loop monitor's steady sine after the first fit: 'steady' (the default) keeps one "
                          f"amplitude; 'cycled' steps it over {CYCLE_STEPS} places of the encoder's count grid, which a "
                          "horn servo's firmware closes its loop on (see above)")  # fmt: skip
    inp.add_argument("--seed", type=int, default=0, help="seed of the input (default 0)")
    al = p.add_argument_group("alarms")
    al.add_argument(
        "--dead-zone",
        default="10%",
        metavar="MIN,MAX|P%",
        help="bounds on c1 + c2, servo's unit, or +/- P %% of the model's (default 10%%)",
    )
    al.add_argument(
        "--m2",
        default="10%",
        metavar="MIN,MAX|P%",
        help="bounds on the down-line slope m2, or +/- P %% of the model's (default 10%%)",
    )
    al.add_argument(
        "--fit",
        type=float,
        metavar="MAX",
        help="largest free-run NRMSE of the recent window, e.g. 0.1 (default: not checked)",
    )
    al.add_argument(
        "--persist",
        type=int,
        default=AlarmRule.persist,
        metavar="N",
        help=f"consecutive checks a bound must be left (or regained) (default {AlarmRule.persist})",
    )
    al.add_argument(
        "--z",
        type=float,
        default=AlarmRule.z,
        metavar="Z",
        help=f"standard deviations beyond a bound before it counts as left (default {AlarmRule.z:g})",
    )
    al.add_argument(
        "--check-every",
        type=int,
        default=MonitorConfig.check_every,
        metavar="N",
        help=f"samples between checks (default {MonitorConfig.check_every})",
    )
    al.add_argument(
        "--fail-on-alarm", action="store_true", help=f"stop at the first alarm and exit with status {EXIT_ALARM}"
    )
    est = p.add_argument_group("estimator")
    est.add_argument("--process-noise", type=float, default=DEFAULT_PROCESS_NOISE, metavar="Q",
                     help="random-walk variance of the parameters per update, relative to (c1 + c2)^2: larger "
                          f"follows wear faster and scatters more (default {DEFAULT_PROCESS_NOISE:g})")  # fmt: skip
    est.add_argument("--epsilon", type=float, metavar="E",
                     help="noise threshold on |y(k) - y(k-1)| of eqs (37)-(38), servo's unit "
                          "(default: from the model's noise_std, else the simulated servo's noise)")  # fmt: skip
    out = p.add_argument_group("output")
    out.add_argument("--out", type=Path, default=Path("servoid-monitor"), metavar="DIR",
                     help="output folder (default ./servoid-monitor/)")  # fmt: skip
    out.add_argument(
        "--every",
        type=float,
        default=1.0,
        metavar="S",
        help="seconds between rows of estimates.csv (default 1; at least one check)",
    )
    out.add_argument("--compensation-step", type=float, default=MonitorConfig.compensation_step, metavar="SHARE",
                     help="relative change of c1 + c2 or m2 that writes new compensation parameters "
                          f"(default {MonitorConfig.compensation_step:g})")  # fmt: skip
    out.add_argument("--plot", type=Path, metavar="FILE.png", help="a live plot, redrawn every --plot-every s")
    out.add_argument("--force", action="store_true", help="replace --plot if it exists (default: refuse)")
    out.add_argument(
        "--plot-every",
        type=float,
        default=MonitorConfig.plot_every_s,
        metavar="S",
        help=f"seconds between redraws of --plot (default {MonitorConfig.plot_every_s:g})",
    )
    out.add_argument("--json", action="store_true", help="print one JSON summary on stdout at the end")
    p.set_defaults(handler=run)


def parse_bounds(text: str, *, quantity: str, label: str, reference: float, unit: str = "") -> Bound | None:
    """``MIN,MAX``, ``P%`` (+/- P % of ``reference``) or ``none``; the option's name in every error."""
    option = "--" + quantity.replace("_", "-")
    value = text.strip()
    if value.lower() == "none":
        return None
    if value.endswith("%"):
        try:
            share = float(value[:-1]) / 100.0
        except ValueError:
            raise ConfigError(f"{option} (={text!r}) must be MIN,MAX, P% or none") from None
        if not (math.isfinite(share) and 0.0 < share < 1.0):
            raise ConfigError(f"{option} (={text!r}): P must lie in (0, 100) %")
        low, high = reference * (1.0 - share), reference * (1.0 + share)
    else:
        parts = value.split(",")
        try:
            low, high = (float(v) for v in parts)
        except ValueError:
            raise ConfigError(f"{option} (={text!r}) must be MIN,MAX (two numbers), P% or none") from None
        if not (math.isfinite(low) and math.isfinite(high) and low < high):
            raise ConfigError(f"{option} (={text!r}) must have finite MIN < MAX")
    return Bound(quantity=quantity, low=low, high=high, label=label, unit=unit)


def _bounds(args: argparse.Namespace, model_file: ModelFile, unit: str) -> tuple[Bound, ...]:
    model = model_file.model
    found = [
        parse_bounds(
            args.dead_zone, quantity="dead_zone", label="dead zone c1 + c2", reference=model.dead_zone, unit=unit
        ),
        parse_bounds(args.m2, quantity="m2", label="m2", reference=model.m2),
    ]
    if args.fit is not None:
        if not (math.isfinite(args.fit) and args.fit > 0):
            raise ConfigError(f"--fit (={args.fit:g}) must be a positive NRMSE, e.g. 0.1")
        found.append(Bound(quantity="fit", high=args.fit, label="fit"))
    return tuple(b for b in found if b is not None)


def _period(args: argparse.Namespace, model_file: ModelFile) -> tuple[float, int]:
    """The session's sample period in seconds and the factor the wear estimator decimates it by.

    The estimator runs at the rate the model was identified at (its linear block holds only
    there); the session samples that rate times a whole factor: ``--rate``, or by default the
    live run's own (``decimation.factor`` in the model file, the design from the probe).
    """
    period = model_file.sample_period_s
    if args.rate is None:
        if not period:
            return 1.0 / _live.DEFAULT_RATE_HZ, 1
        stated = (model_file.extra.get("decimation") or {}).get("factor", 1)
        factor = stated if isinstance(stated, int) and 1 <= stated <= 1000 else 1
        return period / factor, factor
    rate = args.rate
    if not (math.isfinite(rate) and 0 < rate <= 20_000):
        raise ConfigError(f"--rate (={rate:g}) must lie in (0, 20000] Hz")
    if not period:
        return 1.0 / float(rate), 1
    factor = round(rate * period)
    if factor < 1 or abs(rate * period - factor) > 0.01 * rate * period:
        raise ConfigError(
            f"--rate (={rate:g} Hz) differs from the rate the model was identified at ({1.0 / period:g} Hz) and is not "
            "a whole multiple of it: its linear block holds only at that rate, where the estimator runs on every "
            "k-th sample; give a multiple, leave --rate out, or identify again at this rate"
        )
    return 1.0 / float(rate), int(factor)


def _truth_at(driver: Driver) -> Callable[[int], BacklashModel] | None:
    """The true model by sample, for a simulated pseudo-Wiener plant (a twin has none: it is not such a model)."""
    from servoid.drivers.simulated import SimulatedServo

    if isinstance(driver, SimulatedServo) and driver.truth is not None:
        return driver.truth_at  # type: ignore[return-value]  # not None for a model plant
    return None


def _input_specs(args: argparse.Namespace, driver: Driver) -> tuple[SignalSpec | None, SignalSpec | None]:
    from servoid.drivers.simulated import SimulatedServo

    operating = None if args.operating is None else parse_spec(args.operating)
    if args.excitation is not None:
        excitation: SignalSpec | None = parse_spec(args.excitation)
    elif operating is None:
        excitation = UniformSpec(
            amplitude=driver.reference_amplitude if isinstance(driver, SimulatedServo) else MODEL_AMPLITUDE
        )
    else:
        excitation = None
    return operating, excitation


def _inputs(args: argparse.Namespace, driver: Driver, total: int | None) -> tuple[Iterator[float], dict[str, str]]:
    """The commands of the run (``total`` of them, or endless) and their ``# key: value`` description."""
    operating, excitation = _input_specs(args, driver)
    inputs = commands(driver.limits.centre, operating, excitation, seed=args.seed)
    if total is not None:
        inputs = itertools.islice(inputs, total)
    meta = {"operating": format_spec(operating) if operating else "none",
            "excitation": format_spec(excitation) if excitation else "none", "seed": str(args.seed)}  # fmt: skip
    return inputs, meta


def commands(
    centre: float, operating: SignalSpec | None, excitation: SignalSpec | None, *, seed: int
) -> Iterator[float]:
    """The endless command: ``centre + operating(k) + excitation(k)`` (each seeded, the second with ``seed + 1``)."""
    from servoid.excitation import stream

    parts: list[Iterator[float]] = [itertools.repeat(centre)]
    if operating is not None:
        parts.append(stream(operating, seed=seed))
    if excitation is not None:
        parts.append(stream(excitation, seed=seed + 1))
    return (math.fsum(values) for values in zip(*parts))


def _noise(args: argparse.Namespace, model_file: ModelFile, identity: dict[str, Any]) -> tuple[float, float | None]:
    """``(noise_std, epsilon)`` for the wear estimator."""
    if args.epsilon is not None:
        if not (math.isfinite(args.epsilon) and args.epsilon >= 0):
            raise ConfigError(f"--epsilon (={args.epsilon:g}) must be >= 0 (servo's unit)")
        return 0.0, args.epsilon
    if model_file.noise_std is not None:
        return model_file.noise_std, None
    noise = identity.get("noise_std")
    return (float(noise) if isinstance(noise, (int, float)) else 0.0), None


def run(args: argparse.Namespace) -> int:
    from servoid.drivers import driver_from_url
    from servoid.ident.models.structure_names import OUTPUT_BACKLASH
    from servoid.ident.monitoring.wear_estimator import WearEstimatorConfig
    from servoid.loop_compensation import has_loop
    from servoid.modelfile import load_model
    from servoid.monitor_run import run_monitor
    from servoid.session import SessionConfig

    if args.duration is not None:
        limits.bounded_real("--duration", args.duration, limit=limits.MAX_DURATION_S)
    limits.seed("--seed", args.seed)
    output_dir(args.out, option="--out")
    if args.plot is not None:
        output_file(args.plot, option="--plot", force=args.force)
    model_file = load_model(args.model)
    loop = has_loop(model_file)  # the servo-loop model: followed by its window refit, not the MRGIA
    if not loop and model_file.structure != OUTPUT_BACKLASH:
        raise ConfigError(
            f"{args.model} holds the structure {model_file.structure} (the play inside the position loop) without "
            f"its servo-loop model (structure.loop): the MRGIA tracks the {OUTPUT_BACKLASH} structure only"
        )
    if model_file.operating_point != (0.0, 0.0):
        _term.warn(f"{args.model} applies about an operating point {model_file.operating_point}: the monitor "
                   "tracks the servo's own coordinates, so its dead zones are shifted by the offset")  # fmt: skip
    if model_file.effects:
        _term.warn(f"{args.model} has model extensions ({', '.join(model_file.effect_names())}); "
                   "the monitor tracks the plain backlash model")  # fmt: skip
    period, factor = _period(args, model_file)
    rate = 1.0 / period
    total = None
    if args.duration is not None:
        if not (math.isfinite(args.duration) and args.duration > 0):
            raise ConfigError(f"--duration (={args.duration:g}) must be > 0 seconds")
        total = max(1, round(args.duration * rate))
    if args.check_every < 1:
        raise ConfigError(f"--check-every (={args.check_every}) must be >= 1 sample")
    if not (math.isfinite(args.every) and args.every > 0):
        raise ConfigError(f"--every (={args.every:g}) must be > 0 seconds")
    rule = AlarmRule(persist=args.persist, z=args.z)
    row_every = max(1, round(args.every * rate / args.check_every)) * args.check_every
    if args.input is not None and not loop:
        raise ConfigError(f"--input (={args.input}) chooses the steady sine of the servo-loop monitor; {args.model} "
                          "holds no servo-loop model (the MRGIA follows it on --operating / --excitation)")  # fmt: skip
    if args.input is not None and (args.operating is not None or args.excitation is not None):
        raise ConfigError(f"--input (={args.input}) chooses the monitor's own steady sine; it does not apply with "
                          "--operating or --excitation")  # fmt: skip
    driver = driver_from_url(args.driver)
    if loop:
        with driver:
            return _run_loop(args, driver, model_file, period, total)
    with driver:
        unit = driver.position_unit.unit
        noise_std, epsilon = _noise(args, model_file, driver.identity)
        config = MonitorConfig(
            estimator=WearEstimatorConfig(reference=model_file.model, noise_std=noise_std, epsilon=epsilon,
                                  process_noise=args.process_noise),
            bounds=_bounds(args, model_file, unit), rule=rule, check_every=args.check_every, row_every=row_every,
            compensation_step=args.compensation_step, stop_on_alarm=args.fail_on_alarm, plot_every_s=args.plot_every,
            factor=factor,
        )  # fmt: skip
        inputs, meta = _inputs(args, driver, total)
        _announce_start(args, driver, config, rate, total, meta)
        started = time.perf_counter()
        with _term.live_progress("monitor", total) as bar:
            result = run_monitor(
                driver, inputs, SessionConfig(period_s=period, use_late=args.use_late, guard_samples=args.guard), config,
                model_file=model_file, out=args.out, total=total, truth_at=_truth_at(driver),
                on_event=_print_event, on_progress=_progress(bar, unit), plot=args.plot, metadata=meta,
            )  # fmt: skip
    elapsed = time.perf_counter() - started
    if args.json:
        _term.print_json(_summary_json(result, model_file, unit))
    else:
        _print_summary(result, model_file, unit, elapsed)
    return _exit_status(result)


def _exit_status(result: Any) -> int:
    """0, or :data:`EXIT_ALARM` (with the line that says so) when the run stopped on an alarm."""
    if result.stopped == "alarm":
        first = result.first_alarm
        assert first is not None
        _term.stderr.print(
            f"servoid monitor: stopped on alarm (exit {EXIT_ALARM}): {first.message()}", markup=False, soft_wrap=True
        )
        return EXIT_ALARM
    return 0


def _run_loop(args: argparse.Namespace, driver: Driver, model_file: ModelFile, period: float, total: int | None) -> int:
    """Monitor a servo-loop model file: its play followed by the window refit (:mod:`servoid.monitor_loop`)."""
    import dataclasses

    from servoid.drivers.clock import VirtualClock
    from servoid.drivers.simulated import SimulatedServo
    from servoid.loop_compensation import loop_model
    from servoid.monitor_loop import HORN_RECORD_S, run_loop_monitor, short_horn
    from servoid.session import SessionConfig

    unit = driver.position_unit.unit
    if model_file.output_unit not in (unit, "unit"):
        raise ConfigError(f"the model is in {model_file.output_unit!r} and {driver.describe()} reports {unit!r}: "
                          "monitor with a model identified in the servo's unit")  # fmt: skip
    # the loop's parameters are in seconds: the same loop at the session's period
    start = dataclasses.replace(loop_model(model_file), sample_period_s=period)
    bound = parse_bounds(args.dead_zone, quantity="dead_zone", label="play c1 + c2", reference=start.play, unit=unit)
    simulated = driver if isinstance(driver, SimulatedServo) else None
    twin = simulated is not None and simulated.twin_truth is not None

    def true_play(k: int) -> float:
        assert simulated is not None
        truth = simulated.twin_truth_at(k)
        return math.nan if truth is None else truth.play_rad

    inputs, meta, steady, grid = _loop_inputs(args, driver, model_file, period, total)
    if not args.json:
        length = "until Ctrl-C" if total is None else f"{total} samples ({total * period:g} s)"
        _term.stderr.print(f"servoid monitor: {driver.describe()} at {1.0 / period:g} Hz, {length}; the servo-loop "
                           f"model ({model_file.structure}), its play {start.play:.4g} {unit} followed on short "
                           f"windows; bound {bound.describe() if bound else 'none'}; writing to {args.out}/",
                           markup=False, soft_wrap=True)  # fmt: skip
        _term.stderr.print(f"  input: {meta['input']}", markup=False, soft_wrap=True)
        short = short_horn(model_file)
        if short is not None:
            _term.stderr.print(f"  note: the file's play in the loop on a compliant contact was sized on {short:.1f} s "
                               f"of record; identification's horn stage needs about {HORN_RECORD_S:g} s, so its play "
                               "is chance: wear is judged against the monitor's own baseline, and for its raw play "
                               f"identify the servo again on {HORN_RECORD_S:g} s", markup=False, soft_wrap=True)  # fmt: skip
    started = time.perf_counter()
    with _term.live_progress("monitor", total) as bar:

        def update(p: Any) -> None:
            bar(p.done, f"late {100 * p.late_share:.1f} %")

        result = run_loop_monitor(
            driver, inputs, SessionConfig(period_s=period, use_late=args.use_late, guard_samples=args.guard),
            start=start, model_file=model_file, bounds=() if bound is None else (bound,), out=args.out,
            stop_on_alarm=args.fail_on_alarm, rebase=args.dead_zone.strip().endswith("%"),
            wait=simulated is not None and isinstance(simulated.clock, VirtualClock),
            true_play=true_play if twin else None, on_event=_print_event, on_progress=update, metadata=meta,
            steady_s=steady * period, grid=grid,
        )  # fmt: skip
    elapsed = time.perf_counter() - started
    if result.stopped == "refused":
        from servoid.monitor_loop import refusal

        raise ConfigError(refusal(result.doubt or "the model file's play is off"))
    if args.json:
        _term.print_json({**result.to_dict(), "unit": unit, "structure": model_file.structure,
                          "start_play": start.play, "input": meta["input"], "input_kind": _ran(meta, result.grid)})  # fmt: skip
    else:
        _term.stderr.print(f"servoid monitor: {result.samples} samples ({elapsed:.1f} s of wall time), {result.refits} "
                           f"estimates ({result.dropped} left out); play now {result.play:.4g} +/- "
                           f"{result.play_std:.2g} {unit} (from {start.play:.4g}); alarms raised "
                           f"{sum(e.raised for e in result.events)}", markup=False, soft_wrap=True)  # fmt: skip
        for name, path in result.files.items():
            _term.stderr.print(f"  {name:13s} {path}", markup=False, soft_wrap=True)
    return _exit_status(result)


def _ran(meta: dict[str, str], grid: GridCount | None) -> str | None:
    """Which steady sine ran (``steady`` or ``cycled``; None: not the monitor's own input)."""
    kind = meta.get("input_kind")
    if kind == CYCLED and grid is not None and not grid.found:
        return STEADY  # the readings showed no count
    return kind


def _loop_inputs(args: argparse.Namespace, driver: Driver, model_file: ModelFile, period: float,
                 total: int | None) -> tuple[Iterator[float], dict[str, str], int, ReadingsGrid | None]:  # fmt: skip
    """The servo-loop monitor's commands, their description (``input``: the line the header prints), the sample
    where the steady sine begins (0 without it: the input does not change) and the cycled sine's count source.

    The steady sine is ``--input``'s, by default :func:`~servoid.excitation.monitor_input.default_input`'s: the steady
    sine, the input before, bit for bit (the cycled one only where the file's play sits inside the loop and
    ``CYCLED_DEFAULT`` is on, which it is not).

    Without ``--operating`` and ``--excitation``: what ``benchmarks/monitor_loop.py`` measured, the
    identification's gentle sines for the first fit, then one steady sine at their largest amplitude
    and half their highest acceleration (:func:`~servoid.excitation.monitor_input.monitor_stream`), from the model
    file's design (:func:`~servoid.monitor_loop.design_sines`; for a play outside the loop at most the design's
    slow phase's acceleration, at the same frequency), inside the driver's range and rate limit; a file without that design gets the MRGIA monitor's default, and the line says why.
    """
    from servoid.excitation.gentle import segment_end, segments
    from servoid.excitation.monitor_input import IDENT, SINE, default_input, monitor_spec, monitor_stream
    from servoid.ident.monitoring.loop_wear import FIRST_FIT_S
    from servoid.monitor_loop import ReadingsGrid, design_sines

    unit = driver.command_unit.unit
    sines = None if args.operating is not None or args.excitation is not None else design_sines(model_file, period)
    if sines is None:
        inputs, meta = _inputs(args, driver, total)
        line = f"operating {meta['operating']}, excitation {meta['excitation']}"
        if args.operating is None and args.excitation is None:
            line += (f" ({args.model} holds no gentle-sines design from `servoid identify --driver`, so not the "
                     "steady sine the monitor measured best with: give --excitation to choose)")  # fmt: skip
            if args.input is not None:
                line += f"; --input {args.input} applies only to that steady sine"
        return inputs, {**meta, "input": line}, 0, None
    limits = driver.limits
    amplitude = min(sines[0], limits.high - limits.centre, limits.centre - limits.low)
    accel, coast = sines[1], sines[2]
    first = int(round(FIRST_FIT_S / period))
    ident = monitor_spec(IDENT, amplitude, accel, offset=limits.centre, rate=limits.max_step)
    sine = monitor_spec(SINE, amplitude, accel, offset=limits.centre, rate=limits.max_step, coast=coast)
    kind = args.input or default_input(model_file.structure)
    grid = ReadingsGrid(float(sine.amplitude), CYCLE_STEPS) if kind == CYCLED else None
    inputs = monitor_stream(amplitude, accel, first, seed=args.seed, offset=limits.centre, rate=limits.max_step,
                            coast=coast, count=grid, steps=CYCLE_STEPS)  # fmt: skip
    if total is not None:
        inputs = itertools.islice(inputs, total)
    hz = float(segments(sine, args.seed, 0, 1)[1][0]) / period
    steady = float(sine.accel or accel)  # (set by the spec: never None)
    cut = segment_end(ident, args.seed, first)  # where monitor_stream switches: the sines back at the offset
    line = (f"the identification's gentle sines (+/-{amplitude:.4g} {unit}, peak acceleration up to "
            f"{accel / period**2:.4g} {unit}/s^2) for the first fit's {first * period:g} s and to the end of "
            f"their segment ({cut * period:.3g} s), then one steady sine "
            f"+/-{sine.amplitude:.4g} {unit} at {hz:.3g} Hz ({2 * hz:.3g} reversals a second, peak acceleration "
            f"{steady / period**2:.4g} {unit}/s^2{_coast_note(coast, steady)}){_cycle_note(kind, args.input)}, from "
            f"{args.model}'s design; --excitation to choose another")  # fmt: skip
    then = format_spec(sine)
    if grid is not None:
        then += (f", cycled: its amplitude a count / {CYCLE_STEPS} smaller each half-period over {CYCLE_STEPS} "
                 "values (the count: the first fit's readings' step; events.jsonl's input event)")  # fmt: skip
    meta = {"operating": "none", "excitation": f"{format_spec(ident)} for {cut} samples, then {then}",
            "seed": str(args.seed), "input": line, "input_kind": kind}  # fmt: skip
    return inputs, meta, cut, grid


def _cycle_note(kind: str, chosen: str | None) -> str:
    """The header's words on the steady sine's kind (``--input``) and why it is the default."""
    why = "chosen by --input" if chosen is not None else "the default"
    if kind == CYCLED:
        return (f", cycled: its amplitude a count / {CYCLE_STEPS} smaller each half-period over {CYCLE_STEPS} "
                f"values, the count from the first fit's readings ({why}; --input steady for one amplitude)")  # fmt: skip
    return f", one amplitude ({why}; --input cycled to step it over the encoder's count grid)"


def _coast_note(coast: float, accel: float) -> str:
    """Why the steady sine's acceleration is what it is when the file's slow phase bounds it."""
    if math.isfinite(coast) and coast <= accel * (1.0 + 1e-9):
        return ": the design's slow phase's, where the file's play outside the loop was sized"
    return ""


def _announce_start(args: argparse.Namespace, driver: Driver, config: MonitorConfig, rate: float,
                    total: int | None, meta: dict[str, str]) -> None:  # fmt: skip
    if args.json:
        return
    length = "until Ctrl-C" if total is None else f"{total} samples ({total / rate:g} s)"
    bounds = "; ".join(f"{b.label} {b.describe()}" for b in config.bounds) or "none"
    err = _term.stderr
    err.print(
        f"servoid monitor: {driver.describe()} at {rate:g} Hz, {length}; writing to {args.out}/",
        markup=False,
        soft_wrap=True,
    )
    err.print(
        f"  input     operating {meta['operating']}, excitation {meta['excitation']}", markup=False, soft_wrap=True
    )
    if config.factor > 1:
        err.print(f"  estimator at the model's {rate / config.factor:g} Hz: 1 in {config.factor} samples, anti-aliased",
                  markup=False, soft_wrap=True)  # fmt: skip
    err.print(f"  bounds    {bounds}", markup=False, soft_wrap=True)
    err.print(f"  rule      beyond a bound by > {config.rule.z:g} std at {config.rule.persist} checks in a row, "
              f"one check every {config.check_every} samples", markup=False, soft_wrap=True)  # fmt: skip


def _print_event(kind: str, line: str) -> None:
    if kind == "alarm":
        _term.stderr.print(line, style="bold red", markup=False, soft_wrap=True)
    elif kind in ("clear", "recovery", "restart", "doubt", "input"):
        _term.stderr.print(line, style="yellow", markup=False, soft_wrap=True)
    else:
        _term.stderr.print(line, style="dim", markup=False, soft_wrap=True)


def _progress(bar: Callable[[int, str], None], unit: str) -> Callable[[MonitorProgress], None]:
    def update(p: MonitorProgress) -> None:
        text = f"late {100 * p.late_share:.1f} %"
        e = p.estimate
        if e is not None:
            fit = "-" if math.isnan(e.fit) else f"{e.fit:.3g}"
            text += f" | c1 + c2 {e.dead_zone:.4g} +/- {e.dead_zone_std:.2g} {unit}, m2 {e.m2:.4g}, fit {fit}"
        text += " | alarms: " + (", ".join(p.active) if p.active else "none")
        bar(p.done, text)

    return update


def _print_summary(result: MonitorResult, model_file: ModelFile, unit: str, elapsed: float) -> None:
    e = result.estimate
    ref = model_file.model
    rows = []
    for name, start in zip(e.names, ref.values()):
        rows.append([name, f"{start:.6g}", f"{e.value(name):.6g}", f"{e.std_of(name):.2g}"])
    rows.append(["c1 + c2", f"{ref.dead_zone:.6g}", f"{e.dead_zone:.6g}", f"{e.dead_zone_std:.2g}"])
    _term.table(f"servoid monitor: {result.samples} samples", ["parameter", "model", "now", "std"], rows,
                console=_term.stderr)  # fmt: skip
    out = _term.stderr
    counts = result.counts
    out.print(f"slots: ok {counts['ok']}, late {counts['late']}, missed {counts['missed']}, timeout "
              f"{counts['timeout']} ({elapsed:.1f} s of wall time)", markup=False, soft_wrap=True)  # fmt: skip
    fit = "-" if math.isnan(e.fit) else f"{e.fit:.4g}"
    out.print(f"fit (free-run NRMSE, recent) {fit}; recoveries {result.recoveries}; restarts {result.restarts}; "
              f"compensation updates {result.compensation_updates}", markup=False, soft_wrap=True)  # fmt: skip
    raised = [ev for ev in result.events if ev.raised]
    out.print(f"alarms raised {len(raised)}" + (f", still active: {', '.join(a.bound.label for a in result.active)}"
                                                 if result.active else ""), markup=False, soft_wrap=True)  # fmt: skip
    if result.stopped == "interrupted":
        out.print(f"interrupted after {result.samples} samples; the outputs are complete", markup=False, soft_wrap=True)
    for name, path in result.files.items():
        out.print(f"  {name:13s} {path}", markup=False, soft_wrap=True)


def _summary_json(result: MonitorResult, model_file: ModelFile, unit: str) -> dict[str, Any]:
    """The ``--json`` summary: the result's own dict, with the unit and the model the monitor started from."""
    return {**result.to_dict(), "unit": unit, "model": model_file.model.to_dict()}
