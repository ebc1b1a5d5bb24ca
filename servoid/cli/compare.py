"""``servoid compare``: how well model files explain recordings, as MATLAB's ``compare`` and ``resid`` say it."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING, Any

from servoid.cli import _data, _term
from servoid.errors import ConfigError, DataError
from servoid.output_paths import output_dir, output_file

if TYPE_CHECKING:  # pragma: no cover
    from servoid.modelfile import ModelFile
    from servoid.recording import Recording

# The numerical libraries are imported inside run(): `servoid compare --help` starts without them.

ORDER = 25

HELP = "free-run fit %% of model files on recordings, resid checks, Bode and step of the linear block"

DESCRIPTION = f"""\
Simulate each model on each recording's input (free run: the measured output
is never fed back) and report the fit as MATLAB's compare does,
100 (1 - ||y - y_hat|| / ||y - mean(y)||) %: 100 % is perfect, 0 % no better
than y's mean. Then the resid checks: the residual's autocorrelation and its
cross-correlation with the input, with a 99 % band; a coloured residual (one
that fails the Ljung-Box test at 1 % over those lags; the band shows where)
means the model misses dynamics.

FILES: model files (a .json whose schema is servoid.model, as written by
servoid identify) and recordings, in any order; each model is compared on
each recording.

{_data.formats_help("Recordings: ", 0, ".")}
A live recording's lost or late samples are simulated through and left out of
the fit (shaded in the figure). The simulation starts as identify's does: the
linear block at rest, the backlash holding the first measured output. Model
extensions from servoid diagnose ("effects") are left out (said on stderr).

Outputs in --out: compare.png (measured against each model, residuals),
resid.png (the correlations and their band), bode.png (Bode and unit-step
response of each linear block, the play c1 + c2 beside it); with several
recordings, compare-N.png and resid-N.png for the N-th.
"""

EPILOG = f"""\
examples:
  servoid compare servoid-run/model.json validation.csv
  servoid compare old/model.json new/model.json bench.csv --out cmp/
  servoid compare model.json a.csv b.mat --columns u=qg,y=qm --json > fit.json
  servoid compare model.json log.csv --plot fit.png --force      (the overlay alone, to one file)
{_data.EXAMPLES.format(cmd="compare model.json").replace("--data ", "")}
"""


def register(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    p = sub.add_parser(
        "compare", help=HELP, description=DESCRIPTION, epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )  # fmt: skip
    p.add_argument("files", nargs="+", type=Path, metavar="FILES",
                   help="model files (model.json) and recordings, at least one of each")  # fmt: skip
    p.add_argument("--max-lag", type=int, default=25, metavar="N",
                   help="largest lag of the correlations, samples (default 25)")  # fmt: skip
    _data.add_options(p)
    out = p.add_argument_group("output")
    out.add_argument("--out", type=Path, default=Path("servoid-compare"), metavar="DIR",
                     help="folder of the figures (default ./servoid-compare/)")  # fmt: skip
    out.add_argument("--plot", type=Path, metavar="FILE.png",
                     help="write only the overlay figure (first recording), to this file, instead of --out")  # fmt: skip
    out.add_argument("--force", action="store_true", help="replace --plot if it exists (default: refuse)")
    out.add_argument("--json", action="store_true", help="print one JSON object on stdout and nothing else there")
    out.add_argument("--no-plots", action="store_true", help="write no figures")
    p.set_defaults(handler=run)


def is_model_file(path: Path) -> bool:
    """Whether ``path`` looks like a servoid model file: JSON whose first few kilobytes name the schema ``servoid.model``.

    Parameters
    ----------
    path : Path
        A file named on the command line.
    """
    from servoid.modelfile import SCHEMA

    if path.suffix.lower() != ".json" or not path.is_file():
        return False
    with open(path, "rb") as fh:
        head = fh.read(4096)
    return b'"schema"' in head and f'"{SCHEMA}"'.encode() in head


def _split(files: list[Path]) -> tuple[list[Path], list[Path]]:
    models = [f for f in files if is_model_file(f)]
    data = [f for f in files if f not in models]
    if not models or not data:
        missing = "model file (model.json, schema servoid.model)" if not models else "recording"
        raise ConfigError(f"compare needs at least one {missing} among FILES (got {', '.join(map(str, files))})")
    return models, data


def _check_pair(path: Path, content: ModelFile, data_path: Path, rec: Recording) -> None:
    """Refuse a model and a recording that do not go together: other units, another sample period."""
    for key, mine in (("unit", content.output_unit), ("input_unit", content.input_unit)):
        theirs = rec.metadata.get(key)
        if theirs is not None and mine != "unit" and theirs != mine:
            raise DataError(f"{path} is in {key} {mine!r}, {data_path} in {theirs!r}: convert one of them")
    from servoid.recording import periods_differ

    period, theirs_s = content.sample_period_s, rec.sample_period
    if periods_differ(period, theirs_s):
        raise DataError(
            f"{path} was identified at a sample period of {period:.6g} s, {data_path} is sampled at {theirs_s:.6g} s "
            f"(a model in samples cannot carry over; resample the recording)"
        )


def _names(paths: list[Path]) -> list[str]:
    """Each model's name: its path as given, made unique by its place when a path repeats."""
    names = [str(p) for p in paths]
    return [n if names.count(n) == 1 else f"{n} #{i + 1}" for i, n in enumerate(names)]


def run(args: argparse.Namespace) -> int:
    from servoid.cli._live import recording_valid
    from servoid.compare_outputs import COMPARE_FILES, coloured_warnings, write_compare_plots
    from servoid.ident.diagnosis.compare import compare
    from servoid.modelfile import load_model

    model_paths, data_paths = _split(list(args.files))
    if args.max_lag < 1:
        raise ConfigError(f"--max-lag (={args.max_lag}) must be >= 1")
    plots = not args.no_plots
    if plots and args.plot is not None:
        output_file(args.plot, option="--plot", force=args.force)
    elif plots:
        output_dir(args.out, option="--out", files=COMPARE_FILES.values())
    contents = [load_model(p) for p in model_paths]
    names = _names(model_paths)
    for name, content in zip(names, contents):
        if content.effects:
            _term.warn(f"{name}: comparing its linear block and backlash; its effects "
                       f"({', '.join(content.effect_names())}) are left out")  # fmt: skip
    first = contents[0]
    records = [_data.read(p, args) for p in data_paths]
    for data_path, rec in zip(data_paths, records):
        for path, content in zip(model_paths, contents):
            _check_pair(path, content, data_path, rec)
    results: list[dict[str, Any]] = []
    paths: dict[str, str] = {}
    for i, (data_path, rec) in enumerate(zip(data_paths, records)):
        # each model starts as its file says (its own record's initial state: a guess on another record, which
        # shapes only the first samples) in its own coordinates (the operating point)
        starts = {n: (c.delta0, c.operating_point) for n, c in zip(names, contents)}
        comparison = compare({n: c.model for n, c in zip(names, contents)}, rec.u, rec.y, valid=recording_valid(rec),
                             max_lag=args.max_lag, starts=starts)  # fmt: skip
        for w in coloured_warnings(comparison):
            _term.warn(f"{data_path}: {w}")
        output_unit = rec.metadata.get("unit", first.output_unit)
        if plots and args.plot is not None and i == 0:
            from servoid import plots as _plots

            fig = _plots.plot_compare(comparison, t=rec.t, output_unit=output_unit)
            paths["compare_plot"] = str(_plots.save(fig, args.plot))
        elif plots and args.plot is None:
            suffix = f"-{i + 1}" if len(records) > 1 else ""
            written = write_compare_plots(
                args.out, comparison, t=rec.t, sample_period_s=rec.sample_period or first.sample_period_s,
                input_unit=rec.metadata.get("input_unit", first.input_unit), output_unit=output_unit,
                suffix=suffix, bode=i == 0,
            )  # fmt: skip
            # one Bode figure for all records; the others per record (compare_plot_2, ...)
            paths.update({k if k == "bode_plot" else f"{k}{suffix.replace('-', '_')}": v for k, v in written.items()})
        results.append({"source": str(data_path), **comparison.to_dict()})
        if not args.json:
            cols, rows = comparison.rows()
            left = f", {comparison.samples - comparison.used} left out" if comparison.valid is not None else ""
            _term.table(f"servoid compare: {data_path} ({comparison.samples} samples{left}), free run", cols, rows)
    if args.json:
        models = {n: {"path": str(p), "sample_period_s": c.sample_period_s,
                      "units": {"input": c.input_unit, "output": c.output_unit}}
                  for n, p, c in zip(names, model_paths, contents)}  # fmt: skip
        _term.print_json({"models": models, "records": results, "outputs": paths})
        return 0
    for key, written_to in paths.items():
        _term.stdout.print(f"  {key:17s} {written_to}")
    return 0
