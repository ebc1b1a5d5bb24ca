"""``servoid excite``: generate an excitation signal, report whether it will do, or design one."""

from __future__ import annotations

import argparse
import math
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from servoid import limits
from servoid.cli import _term
from servoid.errors import ConfigError
from servoid.excitation.specs import KINDS, SignalSpec, format_spec, grammar, parse_spec
from servoid.ident.models.structure_names import OUTPUT_BACKLASH, PLAY_IN_LOOP, STRUCTURES
from servoid.output_paths import output_file

if TYPE_CHECKING:  # pragma: no cover
    from servoid.excitation.design import Design
    from servoid.excitation.report import ExcitationReport, Verdict
    from servoid.ident.models.pseudo_wiener import BacklashModel

# The numerical libraries are imported inside the functions that run: `servoid excite --help` starts without them.

ORDER = 5

HELP = "generate an excitation signal and report whether it will identify the servo"

DESCRIPTION = f"""\
Generate a bounded excitation signal, write it to CSV, and report before a
single sample is sent whether it will identify the servo: its order of
persistent excitation, and, run through a model (the paper's plant unless
--model or --prior says otherwise), the share of samples on the up line, the
down line and in the memory zone of the backlash, the crossings of the play,
and the gamma, beta (Lemma 1) and condition of the MRGIA's information matrix.

SPEC is kind:key=value,... ; every kind takes
  amplitude  half-width of the bound around offset, unit of u (required)
  offset     operating point, unit of u (default 0); the signal starts there
  rate       largest change per sample, unit of u (default inf: no limit)
and its own keys, shown with their defaults (time in samples, frequency in
cycles per sample, 0 to 0.5; docs/excitation.md explains every key):
{grammar()}
Every sample stays inside [offset - amplitude, offset + amplitude], also
under the rate limit.

--design proposes a signal instead: from the command range (--range), the
largest step per sample (--max-step), the settling time (--settle, with
--sample-period) and a rough prior (--dead-zone and --gain, or a whole model
with --model / --prior), the smallest amplitude that reaches every zone, and
how many samples to record. It fails with the reason when the limits make
that impossible.
"""

EPILOG = """\
examples:
  servoid excite prbs:amplitude=1.5,hold=3
  servoid excite multisine:amplitude=2,bands=0.01-0.2 --samples 8000 --json
  servoid excite uniform:amplitude=0.5 --out weak.csv          (flagged: inside the play)
  servoid excite steps:amplitude=2,hold=4,rate=0.5 --model servoid-run/model.json
  servoid excite --design --range -3 3 --max-step 0.5 --dead-zone 1.5 --gain 0.4
  servoid excite --design --range -0.5 0.5 --dead-zone 0.004 --structure play_in_loop --sample-period 0.014
  servoid identify --excitation prbs:amplitude=1.5,hold=3     (use a spec to identify)
"""

#: The prior when none is given: said so on every run.
DEFAULT_PRIOR_NOTE = "the paper's plant (default; give --model or --prior for your servo)"


def register(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    p = sub.add_parser(
        "excite", help=HELP, description=DESCRIPTION, epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )  # fmt: skip
    p.add_argument(
        "spec", nargs="?", metavar="SPEC", help=f"the signal, kind:key=value,... (kinds: {', '.join(KINDS)})"
    )
    sig = p.add_argument_group("signal")
    sig.add_argument("--samples", type=int, metavar="N", help="samples to generate (default 5000, or the design's)")
    sig.add_argument("--seed", type=int, default=0, help="seed of the random kinds (default 0)")
    sig.add_argument("--sample-period", type=float, metavar="S",
                     help="sample period in seconds: adds a t column, durations and a time axis")  # fmt: skip
    sig.add_argument("--unit", default="unit", help="unit of u, for the CSV and the plot (default 'unit')")
    mdl = p.add_argument_group("model to report through (default: the paper's plant)")
    src = mdl.add_mutually_exclusive_group()
    src.add_argument(
        "--model", type=Path, metavar="model.json", help="an identified model (servoid identify writes one)"
    )
    src.add_argument(
        "--prior",
        metavar="a1=..,b0=..,delay=1,m2=..,c1=..,c2=..",
        help="a prior model given inline (a1.. and b0.. as many as the orders; delay defaults to 1)",
    )
    src.add_argument("--no-model", action="store_true", help="report on the signal alone")
    des = p.add_argument_group("design (propose a signal instead of SPEC)")
    des.add_argument("--design", action="store_true", help="propose a signal from the limits and a rough prior")
    des.add_argument("--range", nargs=2, type=float, metavar=("LO", "HI"),
                     help="command range of the servo, unit of u (required with --design)")  # fmt: skip
    des.add_argument("--max-step", type=float, default=math.inf, metavar="S",
                     help="largest change of u per sample (default: any)")  # fmt: skip
    des.add_argument(
        "--settle", type=float, metavar="S", help="seconds the servo needs to follow a step (needs --sample-period)"
    )
    des.add_argument("--dead-zone", type=float, metavar="W", help="rough play c1 + c2, unit of y")
    des.add_argument("--gain", type=float, metavar="G", help="rough steady-state gain from u to y (default 1)")
    des.add_argument("--m2", type=float, default=1.0, help="rough down-line slope (default 1)")
    des.add_argument(
        "--structure",
        choices=STRUCTURES,
        default=OUTPUT_BACKLASH,
        help=f"where the play sits (default {OUTPUT_BACKLASH}); {PLAY_IN_LOOP} for an encoder on the load "
        "(Dynamixel, Feetech horn): gentle sines",
    )
    des.add_argument(
        "--load-decel",
        type=float,
        metavar="A",
        help="deceleration the load's own friction gives it, unit of y per s^2 (gentle sines stay below it)",
    )
    des.add_argument("--probe", type=Path, metavar="MODEL.json",
                     help="a model.json of servoid identify --driver: its probe caps the amplitude below where the drive "
                          "saturated and sets the hold (and --sample-period) as the live design does")  # fmt: skip
    out = p.add_argument_group("output")
    out.add_argument("--out", type=Path, default=Path("excitation.csv"), metavar="FILE.csv",
                     help="where to write the signal (default ./excitation.csv)")  # fmt: skip
    out.add_argument("--plot", type=Path, default=Path("excitation.png"), metavar="FILE.png",
                     help="where to save the plot (default ./excitation.png)")  # fmt: skip
    out.add_argument("--no-plot", action="store_true", help="skip the plot")
    out.add_argument("--force", action="store_true", help="replace --out and --plot if they exist (default: refuse)")
    out.add_argument("--json", action="store_true", help="print one JSON object on stdout and nothing else there")
    p.set_defaults(handler=run)


def _consecutive(values: dict[str, float], prefix: str, first: int) -> list[float]:
    """Pop ``prefix<first>``, ``prefix<first+1>``, ... while they are there."""
    out: list[float] = []
    while f"{prefix}{first + len(out)}" in values:
        out.append(values.pop(f"{prefix}{first + len(out)}"))
    return out


def _prior_model(text: str) -> BacklashModel:
    """A model from ``a1=..,a2=..,b0=..,delay=1,m2=..,c1=..,c2=..``."""
    from servoid.ident.models.pseudo_wiener import BacklashModel

    usage = "give --prior a1=..,b0=..,delay=1,m2=..,c1=..,c2=.. (a1.. and b0.. as many as the orders)"
    values: dict[str, float] = {}
    for item in filter(None, (part.strip() for part in text.split(","))):
        key, eq, value = item.partition("=")
        try:
            values[key.strip()] = float(value)
        except ValueError:
            raise ConfigError(f"--prior: {item!r} must be key=number; {usage}") from None
    a = _consecutive(values, "a", 1)
    b = _consecutive(values, "b", 0)
    delay = values.pop("delay", 1.0)
    missing = [k for k in ("m2", "c1", "c2") if k not in values] + ([] if a else ["a1"]) + ([] if b else ["b0"])
    if missing:
        raise ConfigError(f"--prior: missing {', '.join(missing)}; {usage}")
    extra = sorted(set(values) - {"m2", "c1", "c2"})
    if extra:
        raise ConfigError(f"--prior: unknown or non-consecutive key(s) {', '.join(extra)}; {usage}")
    if not float(delay).is_integer():
        raise ConfigError(f"--prior: delay (={delay:g}) must be a whole number of samples")
    return BacklashModel(a=tuple(a), b=tuple(b), delay=int(delay), m2=values["m2"], c1=values["c1"], c2=values["c2"])


def _model(args: argparse.Namespace) -> tuple[BacklashModel | None, str]:
    """The model to report through and where it came from."""
    from servoid.ident.paper import PAPER_PLANT
    from servoid.modelfile import load_model

    if args.no_model:
        return None, "none"
    if args.model is not None:
        return load_model(args.model).model, str(args.model)
    if args.prior is not None:
        return _prior_model(args.prior), "--prior"
    return PAPER_PLANT, DEFAULT_PRIOR_NOTE


def _probe_limits(args: argparse.Namespace) -> dict[str, float]:
    """What ``--probe`` adds to the servo's limits: the amplitude cap, the hold as a settling time, the period.

    The same rules as the live design (:func:`servoid.ident.online.probe_design.design_live`).
    """
    if args.probe is None:
        return {}
    from servoid.ident.online.probe import ProbeResult
    from servoid.ident.online.probe_design import amplitude_cap, design_live
    from servoid.modelfile import load_model

    section = load_model(args.probe).extra.get("probe")
    if not isinstance(section, dict):
        raise ConfigError(f"--probe {args.probe} has no probe section: give a model.json of servoid identify --driver "
                          "run without --no-probe")  # fmt: skip
    probe = ProbeResult.from_dict(section)
    if args.settle is not None:
        raise ConfigError("give --settle or --probe (which sets the hold from the loop's bandwidth), not both")
    period = args.sample_period if args.sample_period is not None else 1.0 / probe.rate_hz
    hold = design_live(probe, 1.0 / period).hold
    return {"max_amplitude": amplitude_cap(probe)[0], "sample_period_s": period, "settle_s": hold * period}


def _design(args: argparse.Namespace) -> tuple[Design, str]:
    from servoid.excitation.design import Prior, ServoLimits, design

    if args.spec is not None:
        raise ConfigError("give SPEC or --design, not both")
    if args.no_model:
        raise ConfigError("--design needs a prior: --dead-zone and --gain, --model or --prior")
    if args.range is None:
        raise ConfigError("--design needs --range LO HI: the command range of the servo, unit of u")
    lo, hi = args.range
    servo = ServoLimits(
        **{"position_min": lo, "position_max": hi, "max_step": args.max_step, "sample_period_s": args.sample_period,
           "settle_s": args.settle, **_probe_limits(args)},
    )  # fmt: skip
    rough = args.dead_zone is not None or args.gain is not None
    if rough and (args.model is not None or args.prior is not None):
        raise ConfigError("give --dead-zone/--gain or a whole model (--model, --prior), not both")
    if rough:
        if args.dead_zone is None:
            raise ConfigError("--design with a rough prior needs --dead-zone W (the play c1 + c2, unit of y)")
        prior = Prior(
            dead_zone=args.dead_zone, gain=1.0 if args.gain is None else args.gain, m2=args.m2,
            structure=args.structure, load_decel=args.load_decel,
        )  # fmt: skip
        source = f"rough prior: play {args.dead_zone:g}, gain {prior.gain:g}, m2 {args.m2:g}"
    else:
        model, source = _model(args)
        assert model is not None
        prior = Prior(model=model, structure=args.structure, load_decel=args.load_decel)
    return design(prior, servo, seed=args.seed, samples=args.samples), source


def _report_rows(spec: SignalSpec, report: ExcitationReport, seed: int, period: float | None) -> list[list[str]]:
    sig = report.signal
    order = f">= {sig.pe_order}" if sig.pe_order == sig.pe_max_order else str(sig.pe_order)
    need = report.needed_order
    rows = [
        ["samples", f"{sig.samples}" + (f" ({sig.samples * period:.4g} s)" if period else "")],
        ["seed", str(seed)],
        ["bound", f"[{spec.low:.6g}, {spec.high:.6g}]"],
        ["range used", f"[{sig.minimum:.6g}, {sig.maximum:.6g}]"],
        ["largest step", f"{sig.max_step:.4g} per sample" + (f" (limit {spec.rate:g})" if spec.rate_limited else "")],
        ["crest factor", f"{sig.crest_factor:.3g}"],
        ["direction reversals of u", str(sig.reversals)],
        ["excitation order", order + (f" (needs {need})" if need else "")],
    ]
    if need:
        rows.append([f"condition of R_{need}", f"{sig.pe_condition[need - 1]:.3g}"])
    tm = report.through_model
    if tm is not None:
        rows += [
            [
                "up / down / memory",
                f"{100 * tm.share_up:.1f}% / {100 * tm.share_down:.1f}% / {100 * tm.share_memory:.1f}%",
            ],
            ["crossings of the play", str(tm.line_switches)],
            ["direction reversals of x", str(tm.reversals)],
            ["x span / play c1 + c2", f"{tm.x_span:.4g} / {tm.model.dead_zone:.4g}"],
            ["MRGIA updates (Phi = 1)", f"{100 * tm.update_share:.1f}% of samples"],
            ["gamma, beta (Lemma 1)", f"{tm.gamma:.3g}, {tm.beta:.3g}"],
            ["trace (1/n) sum h'h", f"{tm.trace:.3g}"],
            ["condition beta/gamma", f"{tm.condition:.3g}"],
            ["collinearity (scaled)", f"{tm.collinearity:.3g}, weakest {tm.weakest}"],
        ]
    return rows


def _print_verdicts(verdicts: Sequence[Verdict]) -> None:
    from rich.text import Text

    colour = {"ok": "green", "warning": "yellow", "insufficient": "red"}
    for v in verdicts:
        _term.stdout.print(Text.assemble((f"{v.level:12s}", colour[v.level]), " ", v.message))


def run(args: argparse.Namespace) -> int:
    import numpy as np
    from rich.text import Text

    from servoid.excitation import sample
    from servoid.excitation.report import assess, worst_level
    from servoid.recording import write_recording

    output_file(args.out, option="--out", force=args.force)
    if not args.no_plot:
        output_file(args.plot, option="--plot", force=args.force)
    if args.samples is not None:
        limits.bounded_count("--samples", args.samples, limit=limits.MAX_SAMPLES, what="a signal's length")
    limits.seed("--seed", args.seed)
    if args.sample_period is not None and not args.sample_period > 0:
        raise ConfigError(f"--sample-period (={args.sample_period}) must be > 0 seconds")
    proposal: Design | None = None
    model: BacklashModel | None
    if args.design:
        proposal, model_source = _design(args)
        spec, model, samples = proposal.spec, proposal.model, proposal.samples
    else:
        if args.spec is None:
            raise ConfigError(f"give a SPEC (kinds: {', '.join(KINDS)}; e.g. prbs:amplitude=1.5,hold=3) or --design")
        spec = parse_spec(args.spec)
        model, model_source = _model(args)
        samples = args.samples or 5000
    u = sample(spec, samples, seed=args.seed)
    report = proposal.report if proposal is not None else assess(u, model=model)
    verdicts = proposal.verdicts if proposal is not None else report.verdicts

    columns: dict[str, Any] = {}
    if args.sample_period:
        columns["t"] = np.arange(samples) * args.sample_period
    columns["u"] = u
    meta = {"servoid excitation": "", "spec": format_spec(spec), "seed": args.seed, "input_unit": args.unit}
    paths = {"signal": str(write_recording(args.out, columns, metadata=meta))}
    if not args.no_plot:
        from servoid.plots import save
        from servoid.plots.excitation import plot_excitation

        fig = plot_excitation(
            u, report, bounds=(spec.low, spec.high), sample_period_s=args.sample_period,
            input_unit="" if args.unit == "unit" else args.unit, title=spec.kind, level=worst_level(verdicts),
        )  # fmt: skip
        paths["plot"] = str(save(fig, args.plot))

    if args.json:
        obj: dict[str, Any] = {
            "spec": format_spec(spec), "seed": args.seed, "samples": samples,
            "sample_period_s": args.sample_period, "model_source": model_source,
            "report": report.to_dict(), "outputs": paths,
        }  # fmt: skip
        # a design judges only the verdicts that apply to its prior
        obj["report"].update(
            verdict=worst_level(verdicts), sufficient=worst_level(verdicts) != "insufficient",
            verdicts=[v.to_dict() for v in verdicts],
        )  # fmt: skip
        if proposal is not None:
            obj["design"] = {"spec": format_spec(proposal.spec), "samples": proposal.samples,
                             "duration_s": proposal.duration_s, "reasons": list(proposal.reasons)}  # fmt: skip
        _term.print_json(obj)
        return 0
    out = _term.stdout
    if proposal is not None:
        out.print(Text.assemble("proposed: ", (format_spec(spec), "bold")), soft_wrap=True)
        for reason in proposal.reasons:
            out.print(f"  - {reason}")
    out.print(f"signal: {format_spec(spec)}", soft_wrap=True)
    out.print(f"through: {model_source if model is not None else 'no model (the signal alone)'}")
    _term.table(
        f"servoid excite: {spec.kind}", ["quantity", "value"], _report_rows(spec, report, args.seed, args.sample_period)
    )
    _print_verdicts(verdicts)
    for name, path in paths.items():
        out.print(f"  {name:8s} {path}")
    return 0
