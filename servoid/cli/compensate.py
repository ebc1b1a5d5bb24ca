"""``servoid compensate``: prove on the simulated servo that the exported compensation compensates."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING, Any

from servoid import limits
from servoid.cli import _term
from servoid.errors import ConfigError
from servoid.output_paths import output_dir

if TYPE_CHECKING:  # pragma: no cover
    from servoid.ident.control.compensation_study import ArmSummary, CompensationStudy
    from servoid.ident.models.pseudo_wiener import BacklashModel
    from servoid.modelfile import ModelFile

# The study and the models are imported inside the functions that run: `servoid compensate --help` starts
# without the numerical libraries.

ORDER = 30

#: Samples per reference path: the study runs 5 paths x 3 arms x 17 models, each a closed loop
#: stepped in Python: 100 000 samples a path take about a quarter of an hour.
MAX_PATH_SAMPLES = 100_000

HELP = "track sines, steps and a triangle on the simulated servo with and without the backlash inverse"

DESCRIPTION = """\
Prove on the simulated servo that a model's compensation works, and how wrong
the model may be before it stops working.

The simulated servo (by default the model itself, or --plant) follows five
reference paths scaled to its dead zone s = c1 + c2: slow sines of amplitude
s/2 and 3s/2, a fast sine, steps from s down to s/5, and a triangle. Three
arms of the same controller track them:

  uncompensated  feedforward through the linear block (ZPETC, d samples of
                 preview) + integral feedback on the measured output
  naive          the same with the backlash inverse, band 0
  compensated    the same with the smoothed backlash inverse (--band)

The measurement is quantised to --resolution (and noisy with --noise-std), so
ratios are stated against what the encoder can resolve: a ratio marked >= has
its compensated error below the quantisation floor (q/sqrt(12) for RMS, q/2
for the peak). Then the controller's model is perturbed by -20, -10, +10 and
+20 % (the dead zones only, then every parameter) on the unchanged servo.

Reported per path: RMS and peak tracking error, the dead time after reversals
(samples from the reference having moved 2 % of its span in the new direction
to the output having done so), and motor travel (how far the backlash input
moved per unit of reference travel: a stuttering command drives it up).
Plots in --out: compensation.png and robustness.png.

A model whose play sits inside the position loop (structure play_in_loop,
a servo-loop model: an encoder on the load) gets its own compensator, the
reversal lead: at each reversal of the set point it adds c1 (up) or takes c2
(down) until the load has moved --band in the new direction (or for at most
3/kp seconds). compensate then simulates the servo-loop model on sines of 10
plays with periods of 30, 120 and 480 samples, with and without the lead, and
reports the play's error against the same loop without play.
"""

EPILOG = """\
examples:
  servoid compensate servoid-run/model.json
  servoid compensate model.json --plant paper          identified model against the true plant
  servoid compensate model.json --resolution 0.0015 --noise-std 0.002 --band 0.01
  servoid compensate model.json --json --no-plots > study.json
"""


def register(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    p = sub.add_parser(
        "compensate", help=HELP, description=DESCRIPTION, epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )  # fmt: skip
    p.add_argument("model", type=Path, metavar="MODEL", help="a model.json written by servoid identify")
    sim = p.add_argument_group("simulated servo")
    sim.add_argument("--plant", metavar="paper|FILE",
                     help="the servo to simulate: 'paper' (the paper's plant) or another model.json "
                          "(default: MODEL itself, a perfect identification)")  # fmt: skip
    sim.add_argument(
        "--resolution",
        type=float,
        metavar="Q",
        help="encoder step in the output unit (default: 1 for counts, else (c1 + c2)/200)",
    )
    sim.add_argument(
        "--noise-std",
        type=float,
        metavar="S",
        help="Gaussian measurement noise, output unit (default: the noise the model file's band "
        "was set for, its compensation.noise_std, else 0)",
    )
    sim.add_argument("--seed", type=int, default=0, help="seed of the noise (default 0)")
    sim.add_argument("--samples", type=int, default=600, metavar="N", help="samples per path (default 600)")
    ctl = p.add_argument_group("controller")
    ctl.add_argument(
        "--band", type=float, metavar="B", help="smoothing band of the inverse, output unit (default: the model file's)"
    )
    ctl.add_argument(
        "--integral-gain",
        type=float,
        metavar="KI",
        help="integral gain per sample, same for every arm (default 1/(2 (P + 1)), P the preview)",
    )
    out = p.add_argument_group("output")
    out.add_argument("--out", type=Path, metavar="DIR", help="folder for the plots (default: MODEL's folder)")
    out.add_argument("--json", action="store_true", help="print one JSON object on stdout and nothing else there")
    out.add_argument("--no-plots", action="store_true", help="skip the PNG plots")
    p.set_defaults(handler=run)


def _plant(spec: str | None, content: ModelFile) -> tuple[BacklashModel, str]:
    from servoid.ident.paper import PAPER_PLANT
    from servoid.modelfile import load_model

    if spec is None:
        return content.model, "the model itself"
    if spec == "paper":
        return PAPER_PLANT, "the paper's plant"
    other = load_model(spec)
    if other.output_unit != content.output_unit:
        raise ConfigError(f"--plant {spec} is in {other.output_unit!r}, the model in {content.output_unit!r}")
    return other.model, spec


def _fmt(value: float) -> str:
    return f"{value:.3g}"


def _nominal_rows(study: CompensationStudy) -> list[list[str]]:
    rows = []
    for comp in study.comparisons:
        before, after = comp.uncompensated, comp.compensated
        rows.append([
            comp.reference.name,
            _fmt(before.metrics.rms_error), _fmt(after.metrics.rms_error), str(study.rms_improvement(before, after)),
            _fmt(before.metrics.peak_error), _fmt(after.metrics.peak_error), str(study.peak_improvement(before, after)),
            f"{before.metrics.dead_time:.1f}", f"{after.metrics.dead_time:.1f}",
        ])  # fmt: skip
    first, last = study.summary("uncompensated"), study.summary("compensated")
    rows.append([
        "all paths",
        _fmt(first.rms_error), _fmt(last.rms_error), str(study.rms_improvement(first, last)),
        _fmt(first.peak_error), _fmt(last.peak_error), str(study.peak_improvement(first, last)),
        f"{first.dead_time:.1f}", f"{last.dead_time:.1f}",
    ])  # fmt: skip
    return rows


def _robustness_rows(study: CompensationStudy) -> list[list[str]]:
    from servoid.ident.control.compensation_study import ARMS

    rows = []
    entries: list[tuple[str, dict[str, ArmSummary], str]] = [("nominal", {a: study.summary(a) for a in ARMS}, "")]
    entries += [(p.label, p.summaries, p.note) for p in study.perturbations]  # type: ignore[misc]
    for label, s, note in entries:
        if not s:
            rows.append([label, "diverged" if "diverged" in note else "invalid model", "", "", "", "", "", "", ""])
            continue
        rows.append([
            label,
            _fmt(s["uncompensated"].rms_error), _fmt(s["naive"].rms_error), _fmt(s["compensated"].rms_error),
            str(study.rms_improvement(s["uncompensated"], s["naive"])),
            str(study.rms_improvement(s["uncompensated"], s["compensated"])),
            _fmt(s["compensated"].peak_error),
            f"{s['naive'].motor_travel:.1f}", f"{s['compensated'].motor_travel:.1f}",
        ])  # fmt: skip
    return rows


def study_json(study: CompensationStudy, content: ModelFile, plant_name: str, paths: dict[str, str]) -> dict[str, Any]:
    """The ``--json`` object of ``servoid compensate``: the study's own dict with where it ran."""
    return {
        "model": content.model.to_dict(),
        "plant": plant_name,
        "units": {"output": content.output_unit, "time": "sample", "sample_period_s": content.sample_period_s},
        **study.to_dict(),
        "outputs": paths,
    }


def _run_lead(args: argparse.Namespace, content: ModelFile) -> int:
    """A play inside the loop: the reversal lead on the servo-loop model, against sending the set point as it is."""
    from servoid.ident.control.reversal_lead import STUDY_AMPLITUDE_PLAYS, lead_study
    from servoid.loop_compensation import loop_model, reversal_lead

    if args.plant is not None:
        raise ConfigError("--plant applies to the output backlash; this model holds the play inside the loop")
    model = loop_model(content)
    lead = reversal_lead(content, args.band)
    paths = lead_study(model, lead)
    unit = content.output_unit
    if args.json:
        _term.print_json({
            "structure": content.structure, "compensator": "reversal_lead", "lead": lead.to_dict(),
            "units": {"output": unit, "time": "sample", "sample_period_s": content.sample_period_s},
            "paths": [vars(p) for p in paths],
        })  # fmt: skip
        return 0
    out = _term.stdout
    out.print(f"servoid compensate: {args.model} holds the play inside the position loop (servo-loop model): the "
              f"compensator is the reversal lead, not the backlash inverse; errors in {unit}")  # fmt: skip
    out.print(f"lead +{lead.lead_up:.4g} / -{lead.lead_down:.4g} {unit} at each reversal of the set point, removed "
              f"when the load has moved {lead.threshold:.3g} {unit} or after {lead.max_samples} samples")  # fmt: skip
    _term.table(
        f"the play's error (against the same loop without play) on sines of {STUDY_AMPLITUDE_PLAYS:g} plays",
        ["period (samples)", "RMS without", "RMS with lead", "peak without", "peak with lead"],
        [[str(p.period), _fmt(p.rms_without), _fmt(p.rms_with), _fmt(p.peak_without), _fmt(p.peak_with)]
         for p in paths],
    )  # fmt: skip
    return 0


def run(args: argparse.Namespace) -> int:
    from servoid.ident.control.compensation_study import CHANGES, FAMILIES, compensation_study, default_resolution
    from servoid.ident.control.references import amplitude_limit, reference_suite
    from servoid.ident.control.tracking import Sensor
    from servoid.modelfile import load_model

    limits.bounded_count("--samples", args.samples, limit=MAX_PATH_SAMPLES, what="a reference path's length")
    limits.seed("--seed", args.seed)
    if not args.no_plots:
        output_dir(args.out if args.out is not None else args.model.parent, option="--out",
                   files=("compensation.png", "robustness.png"))  # fmt: skip
    content = load_model(args.model)
    from servoid.ident.models.structure_names import PLAY_IN_LOOP
    from servoid.loop_compensation import has_loop

    if content.structure == PLAY_IN_LOOP and has_loop(content):
        return _run_lead(args, content)
    plant, plant_name = _plant(args.plant, content)
    slowest = max(content.model.delay, plant.delay)
    if args.samples < 4 * slowest:
        raise ConfigError(f"--samples (={args.samples}) must be at least 4 x the delay ({slowest} samples): "
                          "the paths must outlast the delay many times over for the errors to mean anything")  # fmt: skip
    if content.effects:
        _term.warn(f"the simulated servo leaves out the model extension(s) {', '.join(content.effect_names())}")
    resolution = default_resolution(plant, content.output_unit) if args.resolution is None else args.resolution
    noise = args.noise_std if args.noise_std is not None else (content.noise_std or 0.0)
    sensor = Sensor(resolution=resolution, noise_std=noise, seed=args.seed)
    band = content.compensation_band if args.band is None else args.band
    limit = amplitude_limit(plant)
    if limit is not None and limit < 0.5 * plant.dead_zone:
        _term.warn(f"the backlash lines cross close to 0: the paths are capped at amplitude {limit:.3g}")
    refs = reference_suite(plant, samples=args.samples)
    total = 1 + len(FAMILIES) * len(CHANGES)
    with _term.progress("compensation study", total, enabled=not args.json) as bar:
        study = compensation_study(plant, content.model, band=band, integral_gain=args.integral_gain,
                                   sensor=sensor, references=refs, progress=bar)  # fmt: skip
    paths: dict[str, str] = {}
    if not args.no_plots:
        from servoid import plots

        out_dir = args.out if args.out is not None else args.model.parent
        tracking = plots.plot_tracking(study, output_unit=content.output_unit)
        paths["tracking_plot"] = str(plots.save(tracking, out_dir / "compensation.png"))
        robustness = plots.plot_robustness(study, output_unit=content.output_unit)
        paths["robustness_plot"] = str(plots.save(robustness, out_dir / "robustness.png"))
    if args.json:
        _term.print_json(study_json(study, content, plant_name, paths))
        return 0
    unit = content.output_unit
    out = _term.stdout
    out.print(
        f"servoid compensate: {args.model} on the simulated servo ({plant_name}); errors in {unit}, "
        f"dead time in samples"
        + (f" (1 sample = {content.sample_period_s * 1e3:.3g} ms)" if content.sample_period_s else "")
    )
    out.print(
        f"controller: ZPETC feedforward with {study.preview} sample(s) of preview + integral feedback "
        f"k_i = {study.integral_gain:.3g}/sample; inverse band {study.band:.3g} {unit}"
    )
    out.print(f"encoder resolution q = {resolution:.3g} {unit} (RMS floor q/sqrt(12) = {study.rms_floor:.2g}), "
              f"noise std {sensor.noise_std:.3g} {unit}; ratios marked >= are limited by the resolution")  # fmt: skip
    _term.table(
        "nominal model (unc.: uncompensated, inv.: smoothed inverse; dead time in samples)",
        ["path", "RMS unc", "RMS inv", "ratio", "peak unc", "peak inv", "ratio", "dead unc", "dead inv"],
        _nominal_rows(study),
    )  # fmt: skip
    _term.table(
        "robustness: controller's model perturbed, servo unchanged, all paths (travel: motor / reference)",
        ["model", "RMS unc", "RMS naive", "RMS inv", "ratio naive", "ratio inv", "peak inv", "travel naive",
         "travel inv"],
        _robustness_rows(study),
    )  # fmt: skip
    for name, path in paths.items():
        out.print(f"  {name:16s} {path}")
    return 0
