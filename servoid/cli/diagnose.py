"""``servoid diagnose``: where the identified model and the measurement disagree, and which effect is missing."""

from __future__ import annotations

import argparse
import time
from pathlib import Path
from typing import TYPE_CHECKING

from servoid import limits
from servoid.cli import _data, _model, _term
from servoid.errors import ConfigError, DataError
from servoid.ident import defaults
from servoid.ident.models.effect_names import (
    CANDIDATE_NAMES,
    FLANK_REBOUND,
    FRICTION_STALL,
    LOOP_EFFECTS,
    NONE,
    SUMMARIES,
)
from servoid.output_paths import output_dir

if TYPE_CHECKING:  # pragma: no cover
    from servoid.recording import Recording

# The numerical libraries are imported inside run(): `servoid diagnose --help` starts without them.

ORDER = 20

HELP = "find where model and measurement disagree, name the missing effect, show the gap shrink"

_LIBRARY = "\n".join(f"  {name:17s} {summary}" for name, summary in SUMMARIES.items())

DESCRIPTION = f"""\
Identify the backlash model on a training recording, simulate it on a
validation recording (free run), and find where they disagree: the residual
broken down by direction of motion, reversals, input amplitude, velocity and
time, plus residual autocorrelation and cross-correlation with past inputs.

Then name the missing effect: every effect of the library is fitted jointly
with all model parameters on the training recording and scored on the
validation recording. An effect is accepted only if it cuts the validation
gap (free-run NRMSE = rms(y - y_hat)/std(y)) by more than --penalty per
extra parameter; otherwise the answer is '{NONE}'. The search repeats from the
extended model for a further effect (--max-effects).

The effects (parameters in the unit of u unless said):
{_LIBRARY}

When the recordings have time, the servo-loop model (position loop over a
velocity loop, the play in the loop or after it) is fitted with and without
its friction and scored the same way:
  {FRICTION_STALL:17s} {LOOP_EFFECTS[FRICTION_STALL]}
is named when the friction cuts the loop model's validation gap by more than 2 %
and the drive needs at least 5 % of a typical speed error to break away.
  {FLANK_REBOUND:17s} {LOOP_EFFECTS[FLANK_REBOUND]}
is named when the loop model's validation residual, signed by the direction of
motion and averaged over the load's departures from a flank, swings by at least
a tenth of the play within 50 ms, both ways at 4 standard errors.

{_data.formats_help("Recordings: ", 0, ". Both are read with the same options and must have the same sample period and units.")}

Outputs in --out: model.json (base model plus "effects"), diagnose_fit.png
(measured vs both models, residuals), diagnose_regimes.png (where the error
lies), diagnose_resid.png (correlation checks), diagnose_candidates.png.
"""

EPILOG = """\
examples:
  servoid diagnose --train a.csv --validate b.csv --na 2 --nb 0 --delay 1
  servoid diagnose --train a.csv --validate b.csv --na 2 --nb 1 --delay 1 --json > diagnosis.json
  servoid diagnose --train a.csv --validate b.csv --na 2 --nb 0 --delay 1 --effects coulomb_friction,dead_zone
  servoid diagnose --train DATA_EMPS.mat --validate DATA_EMPS_PULSES.mat --columns u=qg,y=qm --nb 1
  servoid diagnose --train bag_a/ --validate bag_b/ --topics y=/joint_states:wrist,u=/cmd
  python examples/real_data.py emps --out emps/    (the EMPS benchmark, converted and diagnosed)
"""


def register(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    p = sub.add_parser(
        "diagnose", help=HELP, description=DESCRIPTION, epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )  # fmt: skip
    rec = p.add_argument_group("recordings")
    rec.add_argument("--train", required=True, type=Path, metavar="A", help="training recording (all fitting)")
    rec.add_argument("--validate", required=True, type=Path, metavar="B",
                     help="validation recording (scores only, never fitted)")  # fmt: skip
    rec.add_argument("--unit", metavar="UNIT", help="unit of y (default: the recordings' '# unit:' line)")
    _data.add_options(p)
    mdl = p.add_argument_group("base model")
    _model.add_structure_options(mdl)
    _model.add_rho_option(mdl)
    mdl.add_argument("--epsilon", type=float, default=defaults.EPSILON, metavar="E",
                     help=f"MRGIA noise threshold on |y(k) - y(k-1)|, unit of y (default {defaults.EPSILON:g})")  # fmt: skip
    sel = p.add_argument_group("effects")
    sel.add_argument("--effects", metavar="A,B", help=f"effects to try (default all: {','.join(CANDIDATE_NAMES)})")
    sel.add_argument("--penalty", type=float, default=defaults.DEFAULT_PENALTY, metavar="P",
                     help=f"relative cut of the validation gap each extra parameter must buy "
                          f"(default {defaults.DEFAULT_PENALTY}: {100 * defaults.DEFAULT_PENALTY:g} %%)")  # fmt: skip
    sel.add_argument("--max-effects", type=int, default=defaults.MAX_EFFECTS, metavar="N",
                     help=f"effects added one after the other (default {defaults.MAX_EFFECTS})")  # fmt: skip
    sel.add_argument("--reversal-window", type=int, default=defaults.REVERSAL_WINDOW, metavar="K",
                     help=f"samples after a reversal that count as 'just after' (default {defaults.REVERSAL_WINDOW})")  # fmt: skip
    out = p.add_argument_group("output")
    out.add_argument("--out", type=Path, default=Path("servoid-diagnose"), metavar="DIR",
                     help="output folder (default ./servoid-diagnose/)")  # fmt: skip
    out.add_argument("--json", action="store_true", help="print one JSON object on stdout and nothing else there")
    out.add_argument("--no-plots", action="store_true", help="skip the PNG plots")
    p.set_defaults(handler=run)


def _candidates(text: str | None) -> tuple[str, ...]:
    if text is None:
        return CANDIDATE_NAMES
    names = tuple(n.strip() for n in text.split(",") if n.strip())
    unknown = [n for n in names if n not in CANDIDATE_NAMES]
    if unknown or not names:
        raise ConfigError(f"--effects (={text!r}) must list effects from: {', '.join(CANDIDATE_NAMES)}")
    return names


def check_pair(train: Recording, validate: Recording) -> None:
    """Refuse recordings that cannot be compared: different units or sample periods.

    Raises
    ------
    DataError
        Naming both values.
    """
    for key in ("unit", "input_unit"):
        a, b = train.metadata.get(key), validate.metadata.get(key)
        if a is not None and b is not None and a != b:
            raise DataError(f"the recordings differ in '{key}': {train.path} has {a!r}, {validate.path} has {b!r}")
    from servoid.recording import periods_differ

    ta, tb = train.sample_period, validate.sample_period
    if periods_differ(ta, tb):
        raise DataError(
            f"the recordings differ in sample period: {train.path} {ta:.6g} s, {validate.path} {tb:.6g} s "
            f"(a model in samples cannot carry over; resample one of them)"
        )


def run(args: argparse.Namespace) -> int:
    from servoid.diagnose_outputs import DIAGNOSE_FILES, candidate_rows, diagnosis_json, write_diagnosis_outputs
    from servoid.ident.diagnosis.diagnose import DiagnoseConfig, diagnose
    from servoid.ident.online.mrgia import MRGIAConfig

    limits.orders(args.na, args.nb, args.delay, prefix="--")
    output_dir(args.out, option="--out", files=DIAGNOSE_FILES.values())
    train = _data.read(args.train, args)
    validate = _data.read(args.validate, args)
    check_pair(train, validate)
    config = DiagnoseConfig(
        identification=MRGIAConfig(na=args.na, nb=args.nb, delay=args.delay, rho_exponent=args.rho_exponent,
                                   epsilon=args.epsilon),
        candidates=_candidates(args.effects), penalty=args.penalty, max_effects=args.max_effects,
        reversal_window=args.reversal_window,
    )  # fmt: skip
    output_unit = args.unit or train.metadata.get("unit", "unit")
    input_unit = train.metadata.get("input_unit", "unit")
    started = time.perf_counter()
    with _term.progress(
        "candidates", len(config.candidates) * config.max_effects, enabled=not args.json and _term.stderr.is_terminal
    ) as bar:
        done = [0]

        def step(name: str) -> None:
            done[0] += 1
            bar(done[0], len(config.candidates) * config.max_effects)

        period = train.sample_period if train.sample_period is not None else validate.sample_period
        result = diagnose(train.u, train.y, validate.u, validate.y, config, progress=step, sample_period_s=period)
    elapsed = time.perf_counter() - started
    for w in result.identification.warnings:
        _term.warn(f"base identification: {w}")
    source = f"{args.train} (validated on {args.validate})"
    paths = write_diagnosis_outputs(args.out, result, train, validate, source=source, input_unit=input_unit,
                                    output_unit=output_unit, plots=not args.no_plots)  # fmt: skip
    if args.json:
        _term.print_json(diagnosis_json(result, paths, units={"input": input_unit, "output": output_unit}))
        return 0
    cols, rows = candidate_rows(result)
    _term.table(f"servoid diagnose: {len(train)} training + {len(validate)} validation samples ({elapsed:.1f} s)",
                cols, rows)  # fmt: skip
    out = _term.stdout
    out.print(f"where: {result.where}")
    out.print(f"base model: {result.resid_before.summary()}")
    said = {e.name: f"{e.name} (" + ", ".join(f"{k} = {v:.4g} {_unit(e.name, k, input_unit)}".rstrip()
                                              for k, v in e.parameters.items()) + ")"
            for e in result.model.effects}  # fmt: skip
    if result.loop is not None:
        said[result.loop.effect] = f"{result.loop.effect} (stall band {result.loop.stall_band:.4g} {output_unit})"
        if result.loop.rebound is not None:
            said[FLANK_REBOUND] = f"{FLANK_REBOUND} (swing {result.loop.rebound.swing:.2f} of the play)"
    out.print(f"missing effect: {', '.join(said[name] for name in result.effects) or NONE}")
    out.print(f"validation gap (free-run NRMSE): before {result.gap_before:.4g}, after {result.gap_after:.4g} "
              f"({result.gap_after / result.gap_before:.2f} x)")  # fmt: skip
    out.print(result.loop.line(output_unit) if result.loop is not None else
              f"{FRICTION_STALL}: not looked for (the servo-loop model needs the recordings' sample period, "
              "at least 200 samples and a coloured residual to explain)")  # fmt: skip
    if result.loop is not None:
        out.print(result.loop.rebound_line(output_unit))
    for name, path in paths.items():
        out.print(f"  {name:17s} {path}")
    return 0


def _unit(effect: str, parameter: str, input_unit: str) -> str:
    from servoid.ident.models.effects import EFFECTS

    unit = dict(zip(EFFECTS[effect].parameters, EFFECTS[effect].units))[parameter]
    return input_unit if unit == "u" else unit
