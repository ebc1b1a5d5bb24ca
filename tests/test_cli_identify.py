"""``servoid identify`` from the command line: the simulated servo and recordings, files, table and JSON."""

import json

import numpy as np
import pytest

from servoid.cli import main
from servoid.ident import PAPER_PLANT
from servoid.modelfile import load_model
from servoid.recording import read_recording


def run_json(capsys, *argv):
    code = main(["identify", "--json", *argv])
    out = capsys.readouterr().out
    return code, json.loads(out)  # exactly one JSON object, nothing else on stdout


def test_default_run_writes_everything(tmp_path, capsys):
    code, obj = run_json(capsys, "--out", str(tmp_path), "--samples", "3000")
    assert code == 0
    assert obj["method"] == "mrgia+oe" and obj["samples"] == 3000
    assert set(obj["model"]) == {"a", "b", "delay", "m1", "m2", "c1", "c2"}
    assert obj["max_relative_error"] < 1e-8  # noise-free
    for key in (
        "recording",
        "model",
        "convergence_plot",
        "fit_plot",
        "backlash_plot",
        "compare_plot",
        "resid_plot",
        "bode_plot",
    ):
        assert (tmp_path / obj["outputs"][key].split("/")[-1]).stat().st_size > 0
    saved = load_model(tmp_path / "model.json")
    assert saved.model.to_dict() == obj["model"]
    assert saved.fit_nrmse == pytest.approx(obj["fit_nrmse"])


def test_fit_nrmse_is_the_free_run_error_of_the_returned_model(tmp_path, capsys):
    from servoid.ident import BacklashModel, free_run, nrmse

    code, obj = run_json(capsys, "--out", str(tmp_path), "--samples", "2000", "--snr", "20", "--no-plots")
    rec = read_recording(tmp_path / "recording.csv")
    model = BacklashModel.from_dict(obj["model"])
    assert obj["operating_point"] == {"u": 0.0, "y": 0.0}  # the paper's record: the model exists in its coordinates
    y_hat = free_run(model, rec.u, y0=rec.y[0], delta0=obj["delta0"])
    assert obj["fit_nrmse"] == pytest.approx(nrmse(rec.y, y_hat), rel=1e-6)
    assert obj["fit_nrmse"] == pytest.approx(1 / 20, rel=0.15)


def test_identify_from_a_recording(tmp_path, capsys):
    code, first = run_json(capsys, "--out", str(tmp_path / "a"), "--samples", "2500", "--snr", "40", "--no-plots")
    code, second = run_json(
        capsys,
        "--data",
        str(tmp_path / "a" / "recording.csv"),
        "--out",
        str(tmp_path / "b"),
        "--epsilon",
        str(first["mrgia"]["epsilon"]),
        "--no-plots",
    )
    assert code == 0 and "truth" not in second
    np.testing.assert_allclose(second["model"]["c2"], PAPER_PLANT.c2, rtol=2e-2)
    np.testing.assert_allclose(second["fit_nrmse"], first["fit_nrmse"], rtol=0.05)


def test_table_output_has_units_and_the_truth(tmp_path, capsys):
    assert main(["identify", "--out", str(tmp_path), "--samples", "1500", "--no-plots", "--unit", "rad"]) == 0
    out = capsys.readouterr().out
    assert "rel. error" in out and "c1 + c2" in out and "rad" in out


@pytest.mark.parametrize(
    "content, args, fragment",
    [
        (None, [], "no such CSV file"),
        ("a,b\n1,2\n", [], "missing column(s) 'u', 'y'"),
        ("u,y\n" + "1,2\n" * 10 + "1,nan\n", [], "column 'y': 'nan' is not finite"),
        ("u,y\n" + "".join(f"{i},{i}\n" for i in range(20)), [], "too few"),
        ("u,y\n" + "".join(f"1,{i}\n" for i in range(200)), [], "input u is constant"),
        ("u,y\n1,2\n", ["--na", "0"], "na (=0) must be >= 1"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(tmp_path, capsys, content, args, fragment):
    path = tmp_path / "rec.csv"
    if content is not None:
        path.write_text(content)
    code = main(["identify", "--data", str(path), "--out", str(tmp_path / "o"), "--no-plots", *args])
    err = capsys.readouterr().err
    assert code == 2
    assert fragment in err
    assert err.count("\n") == 1 and "Traceback" not in err


def test_simulated_servo_rejects_other_orders(tmp_path, capsys):
    assert main(["identify", "--na", "3", "--out", str(tmp_path)]) == 2
    assert "apply to --data" in capsys.readouterr().err


def test_help_teaches(capsys):
    with pytest.raises(SystemExit):
        main(["identify", "--help"])
    out = capsys.readouterr().out
    for word in ("--data", "--snr", "--epsilon", "--rho-exponent", "examples", "dead zones", "unit of y"):
        assert word in out
