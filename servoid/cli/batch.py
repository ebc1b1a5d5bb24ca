"""``servoid batch``: identify many recordings in parallel on Dask, into one table of every servo's play and its trend."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING, Any

from servoid.cli import _data, _model
from servoid.errors import ConfigError

if TYPE_CHECKING:  # pragma: no cover
    from servoid.batch import Done

# dask, NumPy and the identification are imported inside the handler: `servoid batch --help` starts without them.

ORDER = 15

HELP = "identify many recordings in parallel (Dask) into one table of play and its trend per servo"

DESCRIPTION = f"""\
Identify every recording given (files, or folders searched for the formats
servoid reads) in parallel: one model per recording and one table, fleet.csv
and fleet.parquet, with the servo's id, the recording's time, the play
(c1 + c2) and its 95 % interval, the model structure, the fit, whether the
play is identifiable, and the trend of the play per servo across recordings
(least-squares slope, play unit per day).

{_data.formats_help("Recordings: ", 0)}
The same reading options and model orders apply to every recording.

Servo id: a recording's '# servo_id:' (or '# servo:') line, else its file
name without a date and time (bam_xl330_2026-01-15_10h28m10.json is
bam_xl330). Time: a live recording's '# started:' line, a date and time in
its name, else the file's modification time.

Where it runs: local worker processes (--workers, default 2), or an existing
Dask cluster (--cluster tcp://HOST:PORT), whose workers must see the same
paths (a shared file system); --out is written here. Memory per local worker
is bounded by --memory-per-worker: a worker over it is restarted and its
recording reported, never the machine swapped out.

Resumable: each recording's row is saved in DIR/rows/ as it finishes and its
model in DIR/models/; run the same command again and recordings already done
are skipped (a recording that changed on disk, or failed, is identified
again). A recording that cannot be read or identified is reported in its row
(the error column) and on stderr; the others go on.
"""

EPILOG = """\
examples:
  servoid batch logs/ --out fleet
  servoid batch logs/*.csv --na 2 --nb 0 --delay 1 --out fleet --workers 4
  servoid batch /shared/logs --cluster tcp://10.0.0.5:8786 --out fleet
  servoid batch logs/ --columns u=goal,y=pos,t=time_ms --time-unit ms --out fleet
"""

#: Suffixes searched for in a folder given as a path (a folder holding a ROS 2 bag's metadata.yaml is one bag).
SEARCHED = (".csv", ".txt", ".mat", ".json", ".db3", ".mcap", ".bag")

#: Local workers by default.
DEFAULT_WORKERS = 2

#: Memory per local worker by default.
DEFAULT_MEMORY = "2GB"


def register(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    p = sub.add_parser(
        "batch", help=HELP, description=DESCRIPTION, epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )  # fmt: skip
    p.add_argument("paths", nargs="+", type=Path, metavar="PATH", help="recordings, or folders of recordings")
    _data.add_options(p)
    mdl = p.add_argument_group("model")
    _model.add_structure_options(mdl)
    est = p.add_argument_group("estimator")
    _model.add_rho_option(est)
    est.add_argument("--epsilon", type=float, default=0.0, metavar="E",
                     help="noise threshold on |y(k) - y(k-1)| of eqs (37)-(38), unit of y (default 0)")  # fmt: skip
    run = p.add_argument_group("where it runs")
    run.add_argument("--cluster", metavar="tcp://HOST:PORT", help="an existing Dask scheduler (default: local workers)")
    run.add_argument("--workers", type=int, default=DEFAULT_WORKERS, metavar="N",
                     help=f"local worker processes (default {DEFAULT_WORKERS})")  # fmt: skip
    run.add_argument("--memory-per-worker", default=DEFAULT_MEMORY, metavar="SIZE",
                     help=f"memory bound of each local worker, e.g. 2GB (default {DEFAULT_MEMORY})")  # fmt: skip
    out = p.add_argument_group("output")
    out.add_argument("--out", type=Path, default=Path("servoid-fleet"), metavar="DIR",
                     help="output folder (default ./servoid-fleet/)")  # fmt: skip
    out.add_argument("--json", action="store_true", help="print the table as one JSON object on stdout")
    p.set_defaults(handler=handle)


def recordings(paths: list[Path]) -> list[Path]:
    """The recordings named: files as given, folders searched (a ROS 2 bag folder is one recording), in order, once each."""
    found: list[Path] = []
    for p in paths:
        if p.is_dir() and not (p / "metadata.yaml").exists():
            inside = sorted(q for q in p.rglob("*") if q.is_file() and q.suffix.lower() in SEARCHED)
            bags = sorted(q.parent for q in p.rglob("metadata.yaml"))
            inside = [q for q in inside if not any(b in q.parents for b in bags)] + bags
            if not inside:
                raise ConfigError(f"{p}: no recordings in this folder (searched for {', '.join(SEARCHED)})")
            found.extend(inside)
        elif p.exists():
            found.append(p)
        else:
            raise ConfigError(f"{p}: no such file or folder")
    seen: set[Path] = set()
    return [p for p in found if not (p.resolve() in seen or seen.add(p.resolve()))]  # type: ignore[func-returns-value]


def _client(args: argparse.Namespace) -> Any:
    """A Dask client: of the cluster named, or of local worker processes (closed by the caller)."""
    try:
        from dask.distributed import Client, LocalCluster
    except ImportError:
        raise ConfigError("servoid batch needs Dask: pip install 'servoid[batch]'") from None
    if args.cluster is not None:
        if not args.cluster.startswith(("tcp://", "tls://", "inproc://", "ucx://")):
            raise ConfigError(f"--cluster {args.cluster!r} is not a scheduler address (tcp://HOST:PORT)")
        try:
            return Client(args.cluster, timeout="10s")  # type: ignore[no-untyped-call]
        except (OSError, TimeoutError) as exc:
            raise ConfigError(f"--cluster {args.cluster}: no Dask scheduler answers there ({exc})") from None
    if not 1 <= args.workers <= 256:
        raise ConfigError(f"--workers (={args.workers}) must be 1 to 256")
    from dask.utils import parse_bytes

    try:
        memory = parse_bytes(args.memory_per_worker)
    except (ValueError, TypeError):
        raise ConfigError(f"--memory-per-worker {args.memory_per_worker!r} is not a size such as 2GB") from None
    import logging

    # silence_logs: the nanny's notes on stopping its workers are not the user's business
    cluster = LocalCluster(  # type: ignore[no-untyped-call]
        n_workers=args.workers, threads_per_worker=1, processes=True, memory_limit=memory,
        dashboard_address=":0", silence_logs=logging.ERROR,
    )  # fmt: skip
    return Client(cluster)  # type: ignore[no-untyped-call]


def handle(args: argparse.Namespace) -> int:
    from servoid import batch
    from servoid.cli import _term
    from servoid.ident.online.mrgia import MRGIAConfig

    files = recordings(args.paths)
    config = MRGIAConfig(na=args.na, nb=args.nb, delay=args.delay, rho_exponent=args.rho_exponent,
                         epsilon=args.epsilon)  # fmt: skip
    options = _data.options(args)
    if args.out.exists() and not args.out.is_dir():
        raise ConfigError(f"--out {args.out}: exists and is not a folder")
    args.out.mkdir(parents=True, exist_ok=True)

    keys = {str(p): batch.recording_key(p) for p in files}
    done = batch.done_keys(args.out)
    todo = [p for p in files if keys[str(p)] not in done]
    if len(todo) < len(files):
        _term.warn(f"{len(files) - len(todo)} of {len(files)} recordings already done in {args.out}: skipped")
    failed = 0
    if todo:
        failed = _run(args, todo, options, config)
    table = batch.fleet_table(batch.load_rows(args.out, keys.values()))
    paths = batch.write_table(args.out, table)
    if args.json:
        from servoid.ident.serialise import json_ready

        _term.print_json(json_ready({"table": table, "files": {k: str(v) for k, v in paths.items()}}))
        return 0
    shown = [[r["servo_id"], r["time"] or "", _f(r["play"]), _interval(r), _f(r["fit_nrmse"]),
              _f(r["play_trend_per_day"]), "error" if r["error"] else "ok"] for r in table]  # fmt: skip
    _term.table(f"servoid batch: {len(table)} recordings ({failed} failed this run)",
                ["servo", "time", "play", "95 % interval", "fit NRMSE", "trend /day", ""], shown)  # fmt: skip
    for name, path in paths.items():
        _term.stdout.print(f"  {name:8s} {path}")
    return 0


def _run(args: argparse.Namespace, todo: list[Path], options: Any, config: Any) -> int:
    """Identify ``todo`` on Dask, saving each result as it arrives; return how many failed."""
    from dask.distributed import as_completed

    from servoid import batch
    from servoid.cli import _term

    failed = 0
    client = _client(args)
    try:
        futures = client.map(batch.identify_file, [str(p) for p in todo], options=options, config=config,
                             pure=False, retries=0)  # fmt: skip
        where = {f.key: p for f, p in zip(futures, todo)}
        with _term.progress("recordings", len(todo)) as bar:
            done = as_completed(futures)  # type: ignore[no-untyped-call]
            for n, future in enumerate(done, start=1):
                result = _outcome(future, where[future.key])
                batch.save_done(args.out, result)
                if result.row["error"] is not None:
                    failed += 1
                    _term.warn(f"{result.row['recording']}: {result.row['error']}")
                bar(n, len(todo))
    finally:
        cluster = getattr(client, "cluster", None)
        client.close()
        if cluster is not None:
            cluster.close()
    return failed


def _outcome(future: Any, path: Path) -> Done:
    """What a job returned, or its row with the error when the worker itself failed (killed over its memory)."""
    from servoid import batch

    try:
        out: Done = future.result()
        return out
    except Exception as exc:  # noqa: BLE001 - any worker failure is this recording's, reported in its row
        row = dict.fromkeys(batch.COLUMNS)
        row.update(recording=str(path), servo_id=batch.servo_id_of(path, {}), warnings="",
                   error=" ".join(f"{type(exc).__name__}: {exc}".split()))  # fmt: skip
        return batch.Done(batch.recording_key(path), row, None)


def _f(value: float | None) -> str:
    return "" if value is None else f"{value:.4g}"


def _interval(row: dict[str, Any]) -> str:
    if row["play_low"] is None or row["play_high"] is None:
        return ""
    return f"{row['play_low']:.4g} .. {row['play_high']:.4g}"
