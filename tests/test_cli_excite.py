"""``servoid excite`` and ``servoid identify --excitation``."""

import json

import numpy as np
import pytest

from servoid.cli import main
from servoid.excitation import parse_spec, sample
from servoid.ident import PAPER_PLANT
from servoid.modelfile import ModelFile, save_model
from servoid.recording import read_recording


def run_json(capsys, *argv):
    code = main(list(argv) + ["--json"])
    captured = capsys.readouterr()
    return code, json.loads(captured.out)  # exactly one JSON object on stdout


def read_signal(path):
    lines = path.read_text().splitlines()
    meta = dict(line[2:].split(": ", 1) for line in lines if line.startswith("# ") and ": " in line)
    header = next(line for line in lines if not line.startswith("#")).split(",")
    data = np.loadtxt(path, delimiter=",", comments="#", skiprows=1 + len(meta), ndmin=2)
    return meta, header, data


def test_excite_writes_the_signal_the_plot_and_reports(tmp_path, capsys):
    out, plot = tmp_path / "s.csv", tmp_path / "s.png"
    code, obj = run_json(
        capsys,
        "excite",
        "prbs:amplitude=1.5,hold=3",
        "--samples",
        "3000",
        "--seed",
        "4",
        "--out",
        str(out),
        "--plot",
        str(plot),
        "--sample-period",
        "0.01",
    )
    assert code == 0 and plot.stat().st_size > 10_000
    meta, header, data = read_signal(out)
    assert header == ["t", "u"] and data.shape == (3000, 2)
    assert parse_spec(meta["spec"]) == parse_spec("prbs:amplitude=1.5,hold=3") and meta["seed"] == "4"
    np.testing.assert_array_equal(data[:, 1], sample("prbs:amplitude=1.5,hold=3", 3000, seed=4))
    np.testing.assert_allclose(data[:, 0], np.arange(3000) * 0.01)
    assert obj["model_source"].startswith("the paper's plant (default")
    assert obj["report"]["sufficient"] is True and obj["report"]["needed_order"] == 3
    assert obj["report"]["through_model"]["shares"]["up"] > 0.1


def test_excite_table_says_what_it_reports_through(tmp_path, capsys):
    code = main(["excite", "uniform:amplitude=0.3", "--out", str(tmp_path / "u.csv"), "--no-plot"])
    text = capsys.readouterr().out
    assert code == 0
    assert "the paper's plant (default" in text and "up / down / memory" in text and "gamma, beta" in text
    assert "insufficient" in text and "never leaves the memory zone" in text
    assert not (tmp_path / "excitation.png").exists()


def test_excite_through_a_model_file_an_inline_prior_or_none(tmp_path, capsys):
    model = PAPER_PLANT.__class__(a=(0.2,), b=(1.0,), delay=1, m2=1.0, c1=0.05, c2=0.05)
    path = save_model(tmp_path / "model.json", ModelFile(model=model))
    common = ["steps:amplitude=1,hold=2", "--samples", "2000", "--out", str(tmp_path / "s.csv"), "--no-plot", "--force"]
    _, from_file = run_json(capsys, "excite", *common, "--model", str(path))
    assert from_file["report"]["through_model"]["model"] == model.to_dict() and from_file["report"]["needed_order"] == 2
    _, inline = run_json(capsys, "excite", *common, "--prior", "a1=0.2,b0=1,m2=1,c1=0.05,c2=0.05")
    assert inline["report"]["through_model"] == from_file["report"]["through_model"]
    _, alone = run_json(capsys, "excite", *common, "--no-model")
    assert "through_model" not in alone["report"] and alone["model_source"] == "none"


def test_design_mode_proposes_a_signal_inside_the_limits(tmp_path, capsys):
    code, obj = run_json(
        capsys,
        "excite",
        "--design",
        "--range",
        "-3",
        "3",
        "--max-step",
        "1",
        "--dead-zone",
        "1.5",
        "--gain",
        "0.4",
        "--sample-period",
        "0.01",
        "--out",
        str(tmp_path / "d.csv"),
        "--no-plot",
    )
    assert code == 0
    spec = parse_spec(obj["design"]["spec"])
    assert spec.low >= -3 and spec.high <= 3 and spec.rate == 1.0
    assert obj["samples"] == obj["design"]["samples"] and obj["design"]["duration_s"] == pytest.approx(
        obj["samples"] * 0.01
    )
    assert obj["report"]["sufficient"]
    _, _, data = read_signal(tmp_path / "d.csv")
    assert np.max(np.abs(np.diff(data[:, 1]))) <= 1.0 and np.max(np.abs(data[:, 1])) <= 3.0


@pytest.mark.parametrize(
    "argv, fragment",
    [
        (["excite", "prbs:amplitude=1.5,hld=3"], "unknown key 'hld'; prbs keys: amplitude, offset, rate, hold, order"),
        (["excite", "sine:amplitude=1"], "valid kinds: uniform, prbs, steps, multisine, chirp, levels"),
        (["excite"], "give a SPEC"),
        (["excite", "--design", "--dead-zone", "1"], "--design needs --range"),
        (["excite", "--design", "--range", "-1", "1", "--dead-zone", "1.5", "--gain", "0.4"], "widen the range"),
        (["excite", "uniform:amplitude=1", "--prior", "a1=0.5,b0=1,c1=0.1"], "--prior: missing m2, c2"),
        (["excite", "uniform:amplitude=1", "--model", "nope.json"], "no such model file"),
        (["identify", "--excitation", "prbs:amplitude=1.5,hold=x"], "hold (='x') must be an integer"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(tmp_path, capsys, monkeypatch, argv, fragment):
    monkeypatch.chdir(tmp_path)
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert fragment in err and len(err.splitlines()) == 1


def test_identify_with_an_excitation_spec(tmp_path, capsys):
    code, obj = run_json(
        capsys,
        "identify",
        "--excitation",
        "steps:amplitude=2.4,hold=2",
        "--samples",
        "3000",
        "--snr",
        "43",
        "--out",
        str(tmp_path),
        "--no-plots",
    )
    assert code == 0
    assert "&excitation=steps:amplitude=2.4," in obj["source"]
    assert obj["max_relative_error"] < 0.02
    rec = read_recording(tmp_path / "recording.csv")
    assert "excitation=steps" in rec.metadata["source"]
    np.testing.assert_array_equal(rec.u, sample("steps:amplitude=2.4,hold=2", 3000, seed=0))


def test_identify_default_equals_the_papers_uniform_spec(tmp_path, capsys):
    from servoid.ident.paper import PAPER_INPUT_AMPLITUDE

    common = ["--samples", "1500", "--snr", "43", "--seed", "2", "--no-plots"]
    _, default = run_json(capsys, "identify", *common, "--out", str(tmp_path / "a"))
    _, explicit = run_json(
        capsys,
        "identify",
        *common,
        "--out",
        str(tmp_path / "b"),
        "--excitation",
        f"uniform:amplitude={PAPER_INPUT_AMPLITUDE!r}",
    )
    assert default["model"] == explicit["model"]
    assert "excitation=uniform:amplitude=2.40624" in default["source"]


def test_identify_rejects_an_excitation_for_a_recording(tmp_path, capsys):
    data = tmp_path / "r.csv"
    data.write_text("u,y\n" + "\n".join(f"{i % 3},{i % 2}" for i in range(100)) + "\n")
    assert main(["identify", "--data", str(data), "--excitation", "uniform:amplitude=1"]) == 2
    assert "a --data recording already holds its input" in capsys.readouterr().err
