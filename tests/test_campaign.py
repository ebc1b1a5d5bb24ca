"""The hostile-input campaign of issue 13, replayed: each class of input now ends in a clean error or a valid result.

One case per kind the campaign listed (tracebacks, hangs and memory
blow-ups, silent wrong answers), through the command line in this process,
with what servoid now says. The transports, the ways out and the security
findings have their own tests (``tests/drivers/test_dxl_driver.py``,
``test_can_udp.py``, ``test_watchdogs.py``, ``tests/test_security.py``).
The CSV reader's own validations (issue 16: a long field, time that does
not increase, a duplicated column) are the readers' (``servoid.readers``).
Run with ``-s`` to see what each case says.
"""

from __future__ import annotations

import json
import math
import os
import shutil
import subprocess
from pathlib import Path

import pytest

from servoid.cli import main
from servoid.ident import PAPER_PLANT
from servoid.modelfile import ModelFile


@pytest.fixture(scope="module")
def files(tmp_path_factory: pytest.TempPathFactory) -> Path:
    work = tmp_path_factory.mktemp("campaign")
    base = ModelFile(model=PAPER_PLANT, input_unit="unit", output_unit="unit").to_dict()

    def model(name: str, change, text: str | None = None) -> None:  # noqa: ANN001
        doc = json.loads(json.dumps(base))
        change(doc)
        (work / name).write_text(text if text is not None else json.dumps(doc, allow_nan=True))

    model("model.json", lambda d: None)
    model("deep.json", lambda d: None, "[" * 100_000 + "]" * 100_000)
    model("digits.json", lambda d: None, '{"schema": "servoid.model", "version": ' + "1" * 5000 + "}")
    model("m2.json", lambda d: None, json.dumps(base).replace('"m2": 1.5', '"m2": 1' + "0" * 400))
    model("nrmse.json", lambda d: d.update(fit_nrmse="x"))
    model("surrogate.json", lambda d: None, json.dumps(base).replace('"output": "unit"', '"output": "\\udcff"'))
    model("c1.json", lambda d: d["model"].update(c1=1e308))
    model("coefficients.json", lambda d: d["model"].update(b=[1e-4] * 20_000))
    model("delay.json", lambda d: d["model"].update(delay=10**9))
    model("bool.json", lambda d: d["model"].update(a=[True, 0.5]))
    model("nan.json", lambda d: d["model"].update(c2=math.nan))
    model("strings.json", lambda d: d.update(units={"input": "unit", "output": "mm ??/ \u202erad"}))
    (work / "exists.h").write_text("keep\n")
    (work / "folder").mkdir()
    u = [0.3 * math.sin(k / 7) + 0.2 * math.sin(k / 3.1) for k in range(400)]
    y = [0.2 * math.sin((k - 3) / 7) for k in range(400)]
    rows = [f"{a:.6f},{b:.6f}" for a, b in zip(u, y)]
    (work / "huge_y.csv").write_text("u,y\n" + "\n".join(rows[:100] + ["0.1,-1e300"] + rows[101:]) + "\n")
    (work / "unrelated.csv").write_text("u,y\n" + "\n".join(f"{a:.6f},{math.sin(k * 1.7) ** 3:.6f}"
                                                            for k, a in enumerate(u)) + "\n")  # fmt: skip
    (work / "long_field.csv").write_text("u,y\n" + "1" * 200_000 + ",2\n" + "\n".join(rows) + "\n")
    (work / "reversed.csv").write_text("t,u,y\n" + "\n".join(f"{(400 - k) * 0.01:.2f},{r}" for k, r in enumerate(rows)))
    (work / "constant.csv").write_text("t,u,y\n" + "\n".join(f"1.0,{r}" for r in rows))
    (work / "duplicated.csv").write_text("u,y,y\n" + "\n".join(f"{r},0" for r in rows))
    return work


# (campaign class, command line, exit status, what stderr says; None: exit 0 and this on stderr or stdout)
CASES = [
    ("deeply nested JSON (RecursionError)", ["export", "deep.json", "--format", "c"], 2,
     "nested deeper than a model file can be (at most 32 levels)"),
    ("integer over 4300 digits", ["export", "digits.json", "--format", "c"], 2, "a number has more digits"),
    ("m2 = 10**400 (OverflowError)", ["export", "m2.json", "--format", "c"], 2,
     "model.m2 (an integer of about 401 digits) must lie within +/-1e+100"),
    ('fit_nrmse = "x" (format error)', ["export", "nrmse.json", "--format", "c"], 2,
     "fit_nrmse (='x') must be a number or null"),
    ("lone surrogate in a unit, model file", ["export", "surrogate.json", "--format", "yaml"], 2,
     "units.output (='\\udcff') is not valid Unicode text"),
    ("lone surrogate in a unit, command line", ["identify", "--unit", "\udcff", "--samples", "300"], 2,
     "--unit (='\\udcff') is not valid Unicode text"),
    ("--unit '[/]' (MarkupError)", ["identify", "--unit", "[/]", "--samples", "300", "--no-plots", "--out", "run"], 0,
     "c1 + c2 = "),
    ("--out names an existing file", ["identify", "--out", "exists.h", "--samples", "300"], 2,
     "--out (=exists.h) exists and is not a folder"),
    ("--out names a directory", ["export", "model.json", "--format", "c", "--out", "folder"], 2,
     "--out (=folder) is a folder; name a file"),
    ("--out names an unwritable place", ["export", "model.json", "--format", "c", "--out", "/proc/x.h"], 2,
     "--out (=/proc/x.h): cannot write in /proc"),
    ("--out replaces a file", ["export", "model.json", "--format", "c", "--out", "exists.h"], 2,
     "--out (=exists.h) exists; add --force to replace it"),
    ("--samples 10000000000", ["identify", "--samples", "10000000000"], 2,
     "--samples (=10000000000) must be <= 10000000 (servoid's limit on a record's length)"),
    ("y = -1e300", ["identify", "--data", "huge_y.csv"], 2, "y[100] (=-1e+300) lies beyond +/-1e+100"),
    ("--rho-exponent 1e-300 (ZeroDivisionError)", ["identify", "--rho-exponent", "1e-300", "--samples", "300"], 2,
     "rho_exponent (=1e-300) must be >= 1e-06"),
    ("c1 = 1e308", ["compensate", "c1.json", "--no-plots"], 2, "model.c1 (=1e+308) must lie within +/-1e+100"),
    ("compensate --seed -1", ["compensate", "model.json", "--seed", "-1"], 2,
     "--seed (=-1) must lie in 0 .. 2**64 - 1"),
    ("monitor --duration 1e20", ["monitor", "--driver", "sim://", "--model", "model.json", "--duration", "1e20"], 2,
     "--duration (=1e+20) must lie within +/-1e+07"),
    ("export of 20 000 coefficients (hang, 6.4 GB)", ["export", "coefficients.json", "--format", "c"], 2,
     "model.b (its length, nb + 1) (=20000) must be <= 64"),
    ("compensate with delay = 1e9 (23 GB)", ["compensate", "delay.json", "--no-plots"], 2,
     "model.delay (=1000000000) must be <= 10000"),
    ("--excitation levels:...,count=1e9 (23 GB)", ["identify", "--excitation", "levels:amplitude=1,count=1000000000"], 2,
     "count (=1000000000) must be <= 100000 (servoid's limit on an excitation's levels)"),
    ("fit with NRMSE ~ 1, y unrelated to u", ["identify", "--data", "unrelated.csv", "--no-plots", "--out", "run2"], 0,
     "NOT IDENTIFIABLE: only 0 reversals of the output"),
    ("model breaking the schema: a = [true, 0.5]", ["export", "bool.json", "--format", "c"], 2,
     "model.a[0] (=True) must be a number"),
    ("model with NaN", ["export", "nan.json", "--format", "json"], 2, "model.c2 (=nan) must be finite"),
    ("export --name int", ["export", "model.json", "--format", "c", "--name", "int"], 2,
     "name (='int') is a C keyword"),
]  # fmt: skip


def _run(argv: list[str], where: Path) -> int:
    old = os.getcwd()
    os.chdir(where)
    try:
        return main(argv)
    finally:
        os.chdir(old)


@pytest.mark.parametrize(("kind", "argv", "status", "says"), CASES, ids=[c[0] for c in CASES])
def test_each_campaign_class_ends_in_one_clean_line_or_a_valid_result(files, capsys, kind, argv, status, says):
    got = _run(argv, files)
    out, err = capsys.readouterr()
    assert got == status, err
    assert says in (err + out), err
    if status:
        assert err.count("\n") == 1 and "Traceback" not in err
    print(f"\n| {kind} | {err.strip() if status else 'exit 0: ' + says + '...'} |")


def test_exported_strings_with_trigraphs_and_bidi_controls_compile_with_werror(files, capsys):
    if shutil.which("gcc") is None:
        pytest.skip("no C compiler")
    assert main(["export", str(files / "strings.json"), "--format", "c", "--force", "--out", str(files / "s.h")]) == 0
    header = (files / "s.h").read_text()
    assert "<U+202E>" in header and "??/" not in header
    (files / "s.c").write_text('#include "s.h"\nint main(void) { return 0; }\n')
    done = subprocess.run(["gcc", "-std=c99", "-Wall", "-Wextra", "-Werror", "-c", "s.c", "-o", "/dev/null"],
                          cwd=files, capture_output=True, text=True)  # fmt: skip
    assert done.returncode == 0, done.stderr


@pytest.mark.parametrize(
    ("name", "says"),
    [
        ("long_field.csv", "field larger than field limit"),
        ("reversed.csv", "time must increase strictly"),
        ("constant.csv", "repeats the one before"),
        ("duplicated.csv", "column 'y' appears 2 times in the header"),
    ],
)
def test_recordings_the_reader_must_refuse(files, capsys, name, says):
    got = _run(["identify", "--data", name, "--no-plots", "--out", "run3"], files)
    err = capsys.readouterr().err
    assert got == 2 and err.count("\n") == 1 and "Traceback" not in err, err
    assert says in err, err
