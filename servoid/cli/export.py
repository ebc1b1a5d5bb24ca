"""``servoid export``: convert a model.json into what a controller reads (JSON, a C header, ROS 2 YAML)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from servoid.cli import _term
from servoid.errors import ConfigError
from servoid.export import FORMATS, export_model
from servoid.export.c_header import DEFAULT_NAME
from servoid.export.ros2_yaml import DEFAULT_NODE
from servoid.ident.models.structure_names import OUTPUT_BACKLASH
from servoid.modelfile import VERSION, load_model
from servoid.output_paths import output_file

ORDER = 20

HELP = "export the compensation parameters of a model.json as JSON, a C header or a ROS 2 YAML file"

DESCRIPTION = f"""\
Convert an identified model (model.json, written by servoid identify) into the
parameters a backlash compensator needs, in the format of the controller's world.

Formats (--format):
  json   {FORMATS["json"].summary}.
         A version-1 or -2 file comes out as version {VERSION}.
  c      {FORMATS["c"].summary}.
         `static const servoid_backlash_params NAME` (m2, c1, c2, band), the
         linear block as NAME_a, NAME_b, NAME_DELAY, and
         servoid_backlash_inverse(&NAME, &state, y_d) -> x_d, the backlash input
         (motor-side setpoint) that gives the wanted output y_d. C99; compiles
         with gcc -std=c99 -Wall -Wextra -Werror.
  yaml   {FORMATS["yaml"].summary}:
         NODE: ros__parameters: backlash.{{m2,c1,c2,band}}, linear.{{a,b,delay}},
         stderr, units, identified, servo.

A model whose play sits inside the position loop (structure play_in_loop, a
servo-loop model) gets the reversal lead instead of the backlash inverse: c
writes servoid_lead_params NAME (lead_up = c1, lead_down = c2, threshold =
the band, max_samples = 3/(kp T)) and servoid_reversal_lead(&NAME, &state,
r, y) -> u, the set point to send; yaml adds structure, servo_loop.{{kp, kv,
...}} and reversal_lead.{{lead_up, lead_down, threshold, max_samples}}; json
is the model file, whose structure.loop holds the loop's parameters.

Units: c1, c2 and the band are in the model's output unit (rad, counts or the
unit of the recording), stated in every format; time is in samples.

The smoothing band (--band, output unit): after a reversal of the wanted output
the inverse crosses the play while the output travels one band back, so short
reversals (overshoot, noise) do not throw the motor across the whole play.
Default: the model file's value (servoid identify sets it to the larger of 2 %
of c1 + c2 and 4 x the fit's residual noise). 0 gives the naive inverse.

Models with extensions (the "effects" list, see docs/diagnose.md) can be
exported as json only; --ignore-effects exports their plain backlash model in
the other formats.
"""

EPILOG = """\
examples:
  servoid export servoid-run/model.json --format c --out backlash.h
  servoid export model.json --format c --name left_wheel --out left_wheel.h
  servoid export model.json --format yaml --node arm_controller --out backlash.yaml
  servoid export model.json --format json --band 0.01 > model-v2.json
"""


def register(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    p = sub.add_parser(
        "export", help=HELP, description=DESCRIPTION, epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )  # fmt: skip
    p.add_argument("model", type=Path, metavar="MODEL", help="a model.json written by servoid identify")
    p.add_argument("--format", "-f", required=True, choices=sorted(FORMATS), help="output format (see above)")
    p.add_argument("--out", "-o", type=Path, metavar="FILE", help="write here (default: stdout)")
    p.add_argument("--force", action="store_true", help="replace --out if it exists (default: refuse)")
    p.add_argument("--not-identifiable", action="store_true",
                   help="export a model whose play servoid found not identifiable, with a warning (default: refuse; "
                        "its play may be absorbing dynamics the model misses)")  # fmt: skip
    p.add_argument("--band", type=float, metavar="B",
                   help="smoothing band of the inverse, output unit (default: the model file's)")  # fmt: skip
    p.add_argument("--name", metavar="NAME",
                   help=f"c: C identifier of the parameter constant (default {DEFAULT_NAME})")  # fmt: skip
    p.add_argument("--node", metavar="NODE",
                   help=f"yaml: ROS 2 node name, /namespace/name or /** (default {DEFAULT_NODE})")  # fmt: skip
    p.add_argument("--ignore-effects", action="store_true",
                   help="c, yaml: export the plain backlash model of a model with extensions, leaving them out")  # fmt: skip
    p.set_defaults(handler=run)


def run(args: argparse.Namespace) -> int:
    if args.out is not None:
        output_file(args.out, option="--out", force=args.force)
    content = load_model(args.model)
    if content.identifiable is False and not args.not_identifiable:
        raise ConfigError(
            f"{args.model}: the play is not identifiable ({content.reason or 'no reason stored'}); "
            "export refuses such a model (--not-identifiable exports it anyway)"
        )
    if content.identifiable is False:
        _term.warn(f"exporting a model whose play is not identifiable (--not-identifiable): {content.reason}")
    if content.structure != OUTPUT_BACKLASH:
        from servoid.loop_compensation import has_loop

        if has_loop(content):
            _term.warn(f"{args.model} holds the play inside the position loop: the compensator is the reversal lead "
                       "(c: servoid_reversal_lead; yaml: reversal_lead; json: structure.loop), not the backlash "
                       "inverse")  # fmt: skip
        else:
            _term.warn(f"{args.model} holds the structure {content.structure}: the backlash inverse written here is "
                       "for the output backlash (the play outside the loop)")  # fmt: skip
    if content.operating_point != (0.0, 0.0):
        u0, y0 = content.operating_point
        _term.warn(f"the model applies about the operating point u0 = {u0:.6g}, y0 = {y0:.6g} "
                   f"({content.input_unit}, {content.output_unit}): subtract them from the set point and the "
                   "position before the inverse, add u0 back to its output")  # fmt: skip
    if content.read_version is not None and content.read_version < 2 and args.band is None:
        _term.warn(
            f"{args.model} is schema version {content.read_version}, which stores no smoothing band; "
            f"using servoid's default {content.compensation_band:.4g} {content.output_unit} (set one with --band)"
        )
    if content.effects and args.ignore_effects and not FORMATS[args.format].expresses_effects:
        _term.warn(f"leaving out the model extension(s) {', '.join(content.effect_names())}: "
                   f"the {args.format} format cannot express them")  # fmt: skip
    text = export_model(
        content, args.format, ignore_effects=args.ignore_effects, source_name=args.model.name,
        band=args.band, name=args.name, node=args.node,
    )  # fmt: skip
    if args.out is None:
        sys.stdout.write(text)
        return 0
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(text, encoding="utf-8")
    _term.stderr.print(f"wrote {args.out} ({args.format}, band {content.compensation_band if args.band is None else args.band:.4g} "
                       f"{content.output_unit})")  # fmt: skip
    return 0
