"""Property-based fuzzing of every input path: exit 0 with a valid result, or exit 1/2 with one line -- never a traceback, never a hang.

Hypothesis generates, seeded (``derandomize``) and bounded in number:

* model files (a valid one with a leaf replaced, keys dropped or added,
  nesting, lone surrogates, numbers JSON has no room for) through
  ``servoid export`` in every format -- a header that comes out compiles;
* driver URLs (scheme, location, known and unknown options, odd values)
  through :func:`servoid.drivers.driver_from_url`, and the ``sim://`` ones
  that build through ``servoid identify --driver``;
* command lines of identify, excite, export and monitor, with values from
  pools that mix the valid (small: each run takes milliseconds) with the
  campaign's hostile ones (huge, negative, NaN, ``1e400``, markup, lone
  surrogates, existing files and folders);
* recordings through ``servoid identify --data`` and the readers
  (:mod:`servoid.readers`): CSV files with the reading options
  (``--columns``, ``--time-column``, ``--time-unit``), BAM JSON logs and
  MATLAB files, and the reading options on the command line at large.

The command line runs in this process (fast), under a timer that fails an
example taking more than :data:`HANG_S`; a few cases also run as real
subprocesses, to see stderr as a user does. A ``--json`` result must be
strict JSON (no NaN).
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import signal
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from servoid.cli import main
from servoid.drivers import driver_from_url
from servoid.errors import ServoidError
from servoid.ident import PAPER_PLANT
from servoid.modelfile import ModelFile, json_schema, load_model
from servoid.schema_check import SchemaUnsupported, first_problem

#: An example running longer than this is a hang (the slowest valid run here takes about a second).
HANG_S = 30.0

FUZZ = settings(derandomize=True, deadline=None, database=None, print_blob=False,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture,
                                       HealthCheck.data_too_large])  # fmt: skip


class Hang(Exception):
    """An example that did not finish in HANG_S."""


@contextlib.contextmanager
def _time_limit(seconds: float) -> Iterator[None]:
    def expired(signum: int, frame: Any) -> None:  # noqa: ARG001
        raise Hang(f"no result within {seconds} s")

    previous = signal.signal(signal.SIGALRM, expired)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


def _strict_json(text: str) -> Any:
    def refuse(name: str) -> None:
        raise AssertionError(f"--json wrote {name}, which is not JSON")

    return json.loads(text, parse_constant=refuse)


def run_cli(capsys: pytest.CaptureFixture[str], argv: list[str], cwd: Path) -> tuple[int, str, str]:
    """``servoid ARGV`` in this process; check the property; return (status, stdout, stderr)."""
    old = os.getcwd()
    os.chdir(cwd)
    try:
        with _time_limit(HANG_S):
            try:
                status = main(argv)
            except SystemExit as exc:  # argparse: --help, or its one-line error
                status = int(exc.code or 0)
    finally:
        os.chdir(old)
    out, err = capsys.readouterr()
    if status == 0:
        if "--json" in argv:
            _strict_json(out)
    else:
        assert status in (1, 2), (argv, status, err)
        lines = [line for line in err.splitlines() if line.strip()]
        assert len(lines) == 1 and lines[0].startswith("servoid"), (argv, err)
    assert "Traceback" not in err, (argv, err)
    return status, out, err


# ---- pools of values: the valid are small, the rest hostile ---------------------------------------
HOSTILE_TEXT = ["", " ", "[/]", "[bold]x[/bold]", "\udcff", "a\u202eb", "x" * 5000, "??/", "%s%n", "-1", "--", "nan"]
HOSTILE_NUMBERS = ["-1", "0", "nan", "inf", "-inf", "1e400", "1e-300", "10000000000", "1" * 5000, "0x10", "1e3", "abc"]


def _text() -> st.SearchStrategy[str]:
    return st.one_of(st.sampled_from(HOSTILE_TEXT), st.text(max_size=20))


def _number(valid: list[str]) -> st.SearchStrategy[str]:
    return st.one_of(st.sampled_from(valid), st.sampled_from(HOSTILE_NUMBERS))


@pytest.fixture(scope="module")
def workdir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A folder with a model file, a recording, an existing file and a folder for the fuzzed commands."""
    work = tmp_path_factory.mktemp("fuzz")
    model = ModelFile(model=PAPER_PLANT, input_unit="unit", output_unit="unit", sample_period_s=0.01)
    (work / "model.json").write_text(model.to_json(), encoding="utf-8")
    (work / "exists.txt").write_text("keep me\n")
    (work / "folder").mkdir()
    rows = "\n".join(f"{0.3 * math.sin(k / 7):.6f},{0.2 * math.sin((k - 3) / 7):.6f}" for k in range(400))
    (work / "rec.csv").write_text("u,y\n" + rows + "\n")
    u = [0.3 * math.sin(k / 7) for k in range(400)]
    y = [0.2 * math.sin((k - 3) / 7) for k in range(400)]
    entries = [{"timestamp": 0.01 * k, "goal_position": a, "position": b} for k, (a, b) in enumerate(zip(u, y))]
    (work / "bam.json").write_text(json.dumps({"motor": "mx106", "entries": entries}))
    scipy_io = pytest.importorskip("scipy.io")
    scipy_io.savemat(work / "rec.mat", {"u": u, "y": y, "t": [0.01 * k for k in range(400)],
                                        "log": [[0.01 * k, a, b] for k, (a, b) in enumerate(zip(u, y))]})  # fmt: skip
    return work


PATHS = ["model.json", "exists.txt", "folder", "missing.json", "rec.csv", "rec.mat", "bam.json", "no/such/dir/x",
         "/proc/x", ""]  # fmt: skip


# ---- model files ---------------------------------------------------------------------------------
JSON_LEAF = st.one_of(
    st.none(), st.booleans(), st.integers(min_value=-(10**500), max_value=10**500),
    st.floats(allow_nan=True, allow_infinity=True), st.sampled_from(HOSTILE_TEXT), st.text(max_size=8),
    st.lists(st.floats(allow_nan=False, width=32), max_size=70), st.just({}), st.just([True, 0.5]),
)  # fmt: skip


def _paths(doc: Any, prefix: tuple[Any, ...] = ()) -> list[tuple[Any, ...]]:
    found = [prefix]
    if isinstance(doc, dict):
        for key, value in doc.items():
            found += _paths(value, (*prefix, key))
    elif isinstance(doc, list):
        for i, value in enumerate(doc):
            found += _paths(value, (*prefix, i))
    return found


@st.composite
def model_documents(draw: st.DrawFn) -> str:
    doc = ModelFile(model=PAPER_PLANT, stderr={"a1": 1e-3}, servo={"model": "x"}).to_dict()
    for _ in range(draw(st.integers(1, 3))):
        where = draw(st.sampled_from(_paths(doc)))
        if not where:
            continue
        parent = doc
        for key in where[:-1]:
            parent = parent[key]
        action = draw(st.sampled_from(["replace", "drop", "add", "nest"]))
        if action == "replace":
            parent[where[-1]] = draw(JSON_LEAF)
        elif action == "drop" and isinstance(parent, dict):
            del parent[where[-1]]
        elif action == "add" and isinstance(parent, dict):
            parent[draw(_text())] = draw(JSON_LEAF)
        elif action == "nest":
            parent[where[-1]] = f"<nested {draw(st.sampled_from([2, 40, 5000]))}>"
    text = json.dumps(doc, allow_nan=True)
    for depth in (2, 40, 5000):  # nesting written as text: json.dumps itself would recurse too deep
        text = text.replace(f'"<nested {depth}>"', "[" * depth + "]" * depth)
    if draw(st.booleans()):
        text = text.replace('"unit"', draw(st.sampled_from(['"\\ud800"', '"[/]"', '"a\\u202eb"', '"??/"'])), 1)
    return text


@settings(FUZZ, max_examples=60)
@given(text=model_documents(), fmt=st.sampled_from(["c", "yaml", "json"]))
def test_model_files_through_export(capsys, workdir, text, fmt):
    path = workdir / "fuzzed.json"
    path.write_text(text, encoding="utf-8", errors="surrogatepass")
    status, out, _ = run_cli(capsys, ["export", str(path), "--format", fmt], workdir)
    if status == 0 and fmt == "json":
        path.write_text(out, encoding="utf-8")
        load_model(path)  # what export writes, servoid reads back
    if status == 0 and fmt == "c":
        _compiles(out, workdir)


@settings(FUZZ, max_examples=150)
@given(text=model_documents(), version=st.sampled_from([1, 2]))
def test_the_schema_checker_agrees_with_jsonschema(text, version):
    jsonschema = pytest.importorskip("jsonschema")
    try:
        doc = json.loads(text)
    except (ValueError, RecursionError):
        return  # not a document: the file reader refuses it before any schema
    schema = json_schema(version)
    expected = jsonschema.Draft202012Validator(schema).is_valid(doc)
    assert (first_problem(doc, schema) is None) == expected, first_problem(doc, schema)


def test_the_schema_checker_refuses_keywords_it_does_not_apply():
    with pytest.raises(SchemaUnsupported, match="anyOf"):
        first_problem({}, {"anyOf": [{"type": "object"}]})
    assert first_problem(json.loads(ModelFile(model=PAPER_PLANT).to_json()), json_schema()) is None


def _compiles(header: str, where: Path) -> None:
    from shutil import which

    if which("gcc") is None:
        return
    (where / "h.h").write_text(header, encoding="utf-8")
    (where / "h.c").write_text('#include "h.h"\nint main(void) { return 0; }\n')
    done = subprocess.run(["gcc", "-std=c99", "-Wall", "-Wextra", "-Werror", "-c", "h.c", "-o", "/dev/null"],
                          cwd=where, capture_output=True, text=True)  # fmt: skip
    assert done.returncode == 0, done.stderr


# ---- driver URLs ---------------------------------------------------------------------------------
OPTION_KEYS = ["min", "max", "max_step", "amplitude", "centre", "guard", "snr", "noise", "drop", "seed", "clock",
               "play_deg", "id", "baud", "mode", "timeout", "watchdog", "protocol", "node", "port", "bind", "unit",
               "latency_ms", "return_delay_us", "endpoints", "host_node", "bogus", ""]  # fmt: skip
OPTION_VALUES = ["1", "0", "-1", "0.5", "virtual", "position", "cia402", "odrive", "nan", "inf", "1e400", "", "%zz",
                 "%00", "[/]", "\udcff", "10000000000", "127.0.0.1", "eth0", "keep"]  # fmt: skip


@st.composite
def urls(draw: st.DrawFn) -> str:
    scheme = draw(st.sampled_from(["sim", "serial", "dxl", "can", "http", "", "SIM"]))
    location = draw(st.sampled_from(["", "/dev/null", "/dev/ttyUSB9", "virtual/ch0", "udp_multicast/239.74.163.2",
                                     "//", "a b", "%2F", "\udcff", "xm430", "model", "odrive"]))  # fmt: skip
    options = draw(st.lists(st.tuples(st.sampled_from(OPTION_KEYS), st.sampled_from(OPTION_VALUES)), max_size=4))
    query = "&".join(f"{k}={v}" for k, v in options)
    sep = draw(st.sampled_from(["://", ":/", "", "://?"]))
    return f"{scheme}{sep}{location}" + (f"?{query}" if query else "")


@settings(FUZZ, max_examples=200)
@given(url=urls())
def test_driver_urls_build_or_say_why_in_one_line(url):
    try:
        driver = driver_from_url(url)
    except ServoidError as exc:
        assert "\n" not in str(exc) and str(exc)
        return
    assert not driver.is_open  # built, not opened: opening is the transport's business


@settings(FUZZ, max_examples=25)
@given(servo=st.sampled_from(["", "model", "xm430", "odrive", "gear", "x"]),
       options=st.lists(st.tuples(st.sampled_from(["snr", "noise", "drop", "seed", "play_deg", "min", "max", "max_step",
                                                    "amplitude", "guard", "latency", "timeout", "plant"]),
                                  st.sampled_from(["0", "1", "0.1", "-1", "40", "nan", "1e400", "bench", "x"])),
                        max_size=3))  # fmt: skip
def test_simulated_servo_urls_through_identify(capsys, workdir, servo, options):
    url = f"sim://{servo}?clock=virtual" + "".join(f"&{k}={v}" for k, v in options)
    run_cli(capsys, ["identify", "--driver", url, "--samples", "300", "--rate", "500", "--no-plots", "--json", "--no-probe",
                     "--out", str(workdir / "live")], workdir)  # fmt: skip


# ---- command lines -------------------------------------------------------------------------------
COMMON = {
    "--out": st.sampled_from(PATHS + ["out-dir"]),
    "--unit": _text(),
    "--seed": _number(["0", "3"]),
}
#: The reading options (servoid/cli/_data.py): valid for one format or another, and hostile.
READING = {
    "--columns": st.sampled_from(
        [
            "u=u,y=y",
            "u=goal_position,y=position",
            "u=log(:,2),y=log(:,3),t=log(:,1)",
            "t=none",
            "u=y,y=u",
            "u=u,u=y",
            "x=1",
            "u=",
            "=",
            "",
            ",,",
            "u=log(:,99)",
            "u=log(0,:)",
            "u=a.b.c",
            "[/]",
            "\udcff",
        ]
    ),
    "--time-column": st.sampled_from(["none", "t", "timestamp", "u", "time", "", "NONE"]),
    "--time-unit": st.sampled_from(["s", "ms", "ns", "h", ""]),
    "--topics": st.sampled_from(["y=/joint_states:j1,u=/cmd", "y=/a", "q=/x", "", "y=/a:1,u=/b:x.y"]),
}
COMMANDS: dict[str, tuple[list[str], dict[str, st.SearchStrategy[str] | None]]] = {
    "identify": (
        [],
        {
            "--samples": _number(["300", "1000"]),
            "--na": _number(["1", "2", "65"]),
            "--nb": _number(["0", "1"]),
            "--delay": _number(["1", "2", "10001"]),
            "--snr": _number(["43"]),
            "--rho-exponent": _number(["0.75", "1"]),
            "--epsilon": _number(["0", "0.01"]),
            "--excitation": st.sampled_from(
                [
                    "prbs:amplitude=1.5,hold=3",
                    "levels:amplitude=1,count=1000000000",
                    "uniform:amplitude=1e400",
                    "bogus:x=1",
                    "steps:amplitude=1,levels=3",
                    "[/]",
                ]
            ),
            "--data": st.sampled_from(PATHS),
            "--json": None,
            "--paper-algorithm": None,
            **READING,
            **COMMON,
        },
    ),  # fmt: skip
    "compare": (
        ["model.json", "rec.csv"],
        {
            "--max-lag": _number(["5", "25"]),
            "--plot": st.sampled_from(PATHS + ["p.png"]),
            "--force": None,
            "--json": None,
            "--out": st.sampled_from(PATHS + ["out-dir"]),
            **READING,
        },
    ),  # fmt: skip
    "excite": (
        ["prbs:amplitude=1,hold=2"],
        {
            "--samples": _number(["500"]),
            "--plot": st.sampled_from(PATHS + ["p.png"]),
            "--json": None,
            "--force": None,
            "--sample-period": _number(["0.01"]),
            "--model": st.sampled_from(PATHS),
            **COMMON,
        },
    ),  # fmt: skip
    "export": (
        ["model.json"],
        {
            "--format": st.sampled_from(["c", "yaml", "json", "xml"]),
            "--name": _text(),
            "--node": _text(),
            "--band": _number(["0.01"]),
            "--force": None,
            **COMMON,
        },
    ),  # fmt: skip
    "monitor": (
        [],
        {
            "--driver": st.sampled_from(["sim://?clock=virtual", "sim://model?clock=virtual&snr=40", "bogus://"]),
            "--model": st.sampled_from(PATHS),
            "--duration": _number(["0.2"]),
            "--rate": _number(["100"]),
            "--json": None,
            "--dead-zone": st.sampled_from(["10%", "0,1", "1,0", "x", "none"]),
            **COMMON,
        },
    ),  # fmt: skip
}


@st.composite
def command_lines(draw: st.DrawFn) -> list[str]:
    command = draw(st.sampled_from(sorted(COMMANDS)))
    positional, options = COMMANDS[command]
    argv = [command, *positional]
    chosen = draw(st.lists(st.sampled_from(sorted(options)), unique=True, max_size=5))
    if command == "monitor":
        chosen = sorted({*chosen, "--driver", "--model", "--duration"})
    for name in chosen:
        strategy = options[name]
        argv += [name] if strategy is None else [name, draw(strategy)]
    # runs that get through are kept short: no plots (matplotlib is not an input path), few samples
    if command == "identify":  # a --data recording has its own length
        argv += ["--no-plots"] + ([] if {"--samples", "--data"} & set(chosen) else ["--samples", "300"])
        argv += [] if "--out" in chosen else ["--out", "id-out"]
    if command == "compare":
        argv += ["--no-plots"]
    if command == "excite":
        argv += [] if "--no-plot" in chosen else ["--no-plot"]
        argv += [] if "--samples" in chosen else ["--samples", "500"]
    if draw(st.integers(0, 9)) == 0:
        argv.insert(draw(st.integers(0, len(argv))), draw(st.sampled_from(["--bogus", "-x", "--", "extra"])))
    return argv


@settings(FUZZ, max_examples=60)
@given(argv=command_lines())
def test_command_lines(capsys, workdir, argv):
    (workdir / "exists.txt").write_text("keep me\n")
    run_cli(capsys, argv, workdir)
    if "--force" not in argv:
        assert (workdir / "exists.txt").read_text() == "keep me\n"  # no existing file replaced without --force


# ---- CSV recordings through the command line ------------------------------------------------------
CELLS = ["0", "1.5", "-2", "nan", "inf", "-1e300", "1e400", "", "x", "1" * 400, "0x1F", " 3 ", '"4"']


@st.composite
def recordings(draw: st.DrawFn) -> str:
    header = draw(st.sampled_from(["u,y", "t,u,y", "y,u", "u,u,y", "u", "u,y,t", "", "# unit: rad\nu,y"]))
    columns = max(1, header.split("\n")[-1].count(",") + 1)
    kind = draw(st.sampled_from(["clean", "mostly clean", "hostile"]))  # clean files reach identification
    rows = []
    for k in range(draw(st.integers(0, 200))):  # identifying na=2 takes at least 61
        if kind == "clean" or (kind == "mostly clean" and draw(st.integers(0, 9))):
            cells = [f"{k * 0.01:.2f}", f"{math.sin(k / 5):.5f}", f"{math.sin((k - 2) / 5):.5f}"][:columns]
        else:
            cells = [draw(st.sampled_from(CELLS)) for _ in range(draw(st.integers(columns - 1, columns + 1)))]
        rows.append(",".join(cells))
    return header + "\n" + "\n".join(rows) + ("\n" if draw(st.booleans()) else "")


#: Reading options a CSV takes, for the fuzzed files (the command lines above try the others on it).
CSV_OPTIONS = [["--time-column", "none"], ["--time-unit", "ms"], ["--columns", "u=y,y=u"], ["--columns", "t=u"],
               ["--columns", "y=t"], ["--time-column", "y"]]  # fmt: skip


@settings(FUZZ, max_examples=50)
@given(text=recordings(), na=st.sampled_from(["1", "2"]),
       options=st.lists(st.sampled_from(CSV_OPTIONS), max_size=2, unique_by=lambda o: o[0]))  # fmt: skip
def test_csv_recordings_through_identify(capsys, workdir, text, na, options):
    path = workdir / "fuzzed.csv"
    path.write_text(text, encoding="utf-8")
    argv = ["identify", "--data", str(path), "--na", na, "--no-plots", "--json", "--out", "csv-out"]
    run_cli(capsys, argv + [word for option in options for word in option], workdir)


# ---- the other formats: BAM logs and MATLAB files through the readers ----------------------------
BAM_VALUE = st.one_of(
    st.floats(-10, 10), st.floats(allow_nan=False, allow_infinity=False), st.integers(-(10**400), 10**400),
    st.none(), st.booleans(), st.sampled_from(HOSTILE_TEXT), st.lists(st.floats(-1, 1), max_size=2), st.just({}),
)  # fmt: skip
BAM_FIELDS = ["timestamp", "goal_position", "position", "speed"]


@st.composite
def bam_logs(draw: st.DrawFn) -> str:
    kind = draw(st.sampled_from(["clean", "one bad entry", "hostile"]))  # clean logs reach identification
    entries: list[Any] = []
    for k in range(draw(st.integers(0, 200))):
        if kind != "hostile" or draw(st.integers(0, 2)):
            entries.append({"timestamp": k * 0.01, "goal_position": math.sin(k / 5), "position": math.sin((k - 2) / 5),
                            "speed": math.cos(k / 5)})  # fmt: skip
        elif draw(st.integers(0, 9)):
            entries.append(draw(st.dictionaries(st.sampled_from(BAM_FIELDS), BAM_VALUE, max_size=4)))
        else:
            entries.append(draw(BAM_VALUE))
    if kind == "one bad entry" and entries:
        entry = dict(entries[draw(st.integers(0, len(entries) - 1))])
        entry[draw(st.sampled_from(BAM_FIELDS))] = draw(BAM_VALUE)
        entries[draw(st.integers(0, len(entries) - 1))] = entry
    shape = draw(st.sampled_from(["log", "log", "log", "entries only", "a list", "no entries", "entries not a list"]))
    doc: Any = {
        "log": {"motor": draw(st.sampled_from(["mx106", "[/]", "\u202e"])), "entries": entries},
        "entries only": {"entries": entries},
        "a list": entries,
        "no entries": {"motor": "mx106"},
        "entries not a list": {"entries": {"0": entries[:1]}},
    }[shape]
    return json.dumps(doc)


@settings(FUZZ, max_examples=40)
@given(text=bam_logs(), options=st.lists(st.sampled_from([["--columns", "u=speed"], ["--time-column", "none"],
                                                          ["--time-unit", "ms"], ["--columns", "y=goal_position"]]),
                                         max_size=2, unique_by=lambda o: o[0]))  # fmt: skip
def test_bam_logs_through_identify(capsys, workdir, text, options):
    path = workdir / "fuzzed_bam.json"
    path.write_text(text, encoding="utf-8")
    argv = ["identify", "--data", str(path), "--no-plots", "--json", "--out", "bam-out"]
    run_cli(capsys, argv + [word for option in options for word in option], workdir)


MAT_VALUE = st.one_of(
    st.lists(st.floats(-1, 1), min_size=0, max_size=60), st.lists(st.floats(), min_size=1, max_size=5),
    st.lists(st.lists(st.floats(-1, 1), min_size=3, max_size=3), min_size=1, max_size=40), st.text(max_size=5),
    st.floats(), st.just([1e300, 0.0, 1.0]), st.just([[1 + 2j, 0j]]), st.just({"position": [0.1, 0.2, 0.3]}),
)  # fmt: skip


@st.composite
def mat_files(draw: st.DrawFn) -> tuple[dict[str, Any], list[str]]:
    """Variables of a MATLAB file, and the reading options that name them (mostly right, one changed at times)."""
    n = draw(st.integers(3, 200))
    u = [math.sin(k / 5) for k in range(n)]
    y = [math.sin((k - 2) / 5) for k in range(n)]
    t = [0.01 * k for k in range(n)]
    layout = draw(st.sampled_from(["vectors", "vectors without t", "a matrix", "a struct"]))
    if layout == "vectors":
        variables: dict[str, Any] = {"u": u, "y": y, "t": t}
        options: list[str] = []
    elif layout == "vectors without t":
        variables, options = {"u": u, "y": y}, []
    elif layout == "a matrix":
        variables = {"log": [list(row) for row in zip(t, u, y)]}
        options = ["--columns", "t=log(:,1),u=log(:,2),y=log(:,3)"]
    else:
        variables = {"s": {"goal": u, "position": y}}
        options = ["--columns", "u=s.goal,y=s.position"]
    for name in draw(st.lists(st.sampled_from(["u", "y", "t", "log", "s"]), max_size=2, unique=True)):
        variables[name] = draw(MAT_VALUE)  # one variable hostile
    extra = draw(st.sampled_from([[], [], ["--time-column", "none"], ["--time-unit", "ms"], ["--topics", "y=/a,u=/b"],
                                  ["--columns", "u=log(:,9),y=log(0,:)"]]))  # fmt: skip
    return variables, options + extra


@settings(FUZZ, max_examples=40)
@given(drawn=mat_files())
def test_mat_files_through_identify(capsys, workdir, drawn):
    scipy_io = pytest.importorskip("scipy.io")
    variables, options = drawn
    path = workdir / "fuzzed.mat"
    try:
        scipy_io.savemat(path, variables)
    except (TypeError, ValueError):
        return  # not something a MATLAB file can hold
    run_cli(capsys, ["identify", "--data", str(path), "--no-plots", "--json", "--out", "mat-out", *options], workdir)


# ---- as a user sees it: real processes ---------------------------------------------------------
@pytest.mark.parametrize(
    "argv",
    [
        ["identify", "--samples", "10000000000"],
        ["export", "model.json", "--format", "c", "--name", "int", "--unit", "[/]"],
    ],
    ids=["too many samples", "a C keyword"],
)
def test_as_a_process_the_error_is_one_line_and_no_traceback(workdir, argv):
    done = subprocess.run([sys.executable, "-m", "servoid", *argv], cwd=workdir, capture_output=True, text=True,
                          timeout=120)  # fmt: skip
    assert done.returncode == 2 and done.stdout == ""
    assert done.stderr.count("\n") == 1 and done.stderr.startswith("servoid") and "Traceback" not in done.stderr
