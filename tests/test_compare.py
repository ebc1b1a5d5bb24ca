"""``compare``: free-run fit % as MATLAB reports it, resid's checks, the linear block's views, and ``servoid compare``."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest

from servoid.cli import main
from servoid.errors import ConfigError, DataError
from servoid.ident import PAPER_PLANT, MRGIAConfig, identify, simulate
from servoid.ident.diagnosis.compare import compare
from servoid.ident.diagnosis.residuals import residual_tests
from servoid.ident.models.linear_block import frequency_response, polynomials, step_response, to_control
from servoid.recording import write_recording

#: The paper's plant with a slower linear block: what a model of the wrong dynamics looks like.
SLOW = dataclasses.replace(PAPER_PLANT, a=(-0.3, 0.1), b=(0.32,))


def record(n=3000, snr=20.0, seed=0):
    u = np.random.default_rng(seed).uniform(-2.4, 2.4, n)
    return simulate(PAPER_PLANT, u, snr=snr, rng=seed + 100)


def matlab_fit(y, y_hat):
    return 100.0 * (1.0 - np.linalg.norm(y - y_hat) / np.linalg.norm(y - np.mean(y)))


def test_fit_is_matlabs_nrmse_fit_and_the_residual_says_which_model_misses_dynamics():
    sim = record()
    result = compare({"true": PAPER_PLANT, "slow": SLOW}, sim.u, sim.y)
    true, slow = result["true"], result["slow"]
    for fit in (true, slow):
        assert fit.fit_percent == pytest.approx(matlab_fit(sim.y, fit.y_hat), rel=1e-12)
    # the true plant leaves the measurement noise: fit 100 (1 - 1/SNR) %, a white residual
    assert true.fit_percent == pytest.approx(95.0, abs=0.5)
    assert not true.coloured and true.resid.independent_of_input
    assert slow.coloured and slow.coloured_warning().startswith("the residual of slow is coloured")
    assert result.best is true
    assert "'true' 9" in repr(result) and "<table>" in result._repr_html_()


def test_an_encoders_rounding_is_not_taken_for_missed_dynamics():
    count = 2 * np.pi / 4096  # a 12-bit encoder, in rad
    sim = record(snr=None)
    y = np.round(sim.y / count) * count  # the output held in the play keeps its rounding error: coloured
    result = compare({"true": PAPER_PLANT, "slow": SLOW}, sim.u, y)
    assert result["true"].resolution == pytest.approx(count, rel=1e-9)
    assert not result["true"].resid.white and not result["true"].coloured
    assert "resolution" in result["true"].verdict()
    assert result["slow"].coloured


def test_left_out_samples_are_simulated_through_and_not_scored():
    sim = record(snr=40.0)
    y = sim.y.copy()
    valid = np.ones(y.size, dtype=bool)
    valid[1000:1040] = False
    y[1000:1040] = np.nan  # lost: nothing was measured
    result = compare(PAPER_PLANT, sim.u, y, valid=valid)
    fit = result.fits[0]
    assert result.used == y.size - 40
    assert fit.fit_percent == pytest.approx(matlab_fit(sim.y[valid], fit.y_hat[valid]), rel=1e-12)
    assert np.isfinite(fit.y_hat).all() and not fit.coloured
    assert fit.resid.band == pytest.approx(residual_tests(sim.y - fit.y_hat, sim.u).band * np.sqrt(3000 / 2960))


def test_residual_tests_with_every_sample_valid_are_the_plain_tests():
    rng = np.random.default_rng(4)
    r, u = rng.normal(size=500), rng.normal(size=500)
    plain, masked = residual_tests(r, u), residual_tests(r, u, valid=np.ones(500, dtype=bool))
    np.testing.assert_allclose(masked.autocorrelation, plain.autocorrelation, rtol=1e-12)
    np.testing.assert_allclose(masked.cross_correlation, plain.cross_correlation, rtol=1e-12)


@pytest.mark.parametrize(
    ("kwargs", "error", "match"),
    [
        ({"models": {}}, ConfigError, "at least one model"),
        ({"y": np.zeros(10)}, DataError, "differ in shape"),
        ({"y": np.ones(100)}, DataError, "constant"),
        ({"y": np.r_[np.nan, np.ones(99)]}, DataError, r"y\[0\]"),
    ],
)
def test_bad_input_is_one_line_naming_it(kwargs, error, match):
    args = {"models": PAPER_PLANT, "u": np.linspace(-1, 1, 100), "y": np.linspace(0, 1, 100), **kwargs}
    with pytest.raises(error, match=match):
        compare(args.pop("models"), **args)


def test_the_linear_block_settles_at_its_gain_and_control_agrees():
    from scipy.signal import dlti, dstep

    x = step_response(PAPER_PLANT, 200)
    assert x[: PAPER_PLANT.delay].tolist() == [0.0] and x[-1] == pytest.approx(PAPER_PLANT.dc_gain, rel=1e-9)
    num, den = polynomials(PAPER_PLANT)
    np.testing.assert_allclose(dstep(dlti(num, den, dt=1.0), n=200)[1][0].ravel(), x, atol=1e-12)
    resp = frequency_response(PAPER_PLANT, lowest=1e-5)
    assert abs(resp.response[0]) == pytest.approx(PAPER_PLANT.dc_gain, rel=1e-6)
    tf = to_control(PAPER_PLANT, dt=0.002)
    assert tf.dt == 0.002 and complex(tf(1.0)).real == pytest.approx(PAPER_PLANT.dc_gain, rel=1e-12)
    with pytest.raises(ConfigError, match="dt"):
        to_control(PAPER_PLANT, dt=-1.0)


def test_identify_warns_of_a_coloured_residual_only_when_there_is_one():
    sim = record(n=2000, snr=30.0, seed=2)
    right = identify(sim.u, sim.y, MRGIAConfig(na=2, nb=0, delay=1))
    wrong = identify(sim.u, sim.y, MRGIAConfig(na=1, nb=0, delay=1))
    assert not [w for w in right.warnings if "coloured" in w]
    assert [w for w in wrong.warnings if "coloured" in w]


def run_cli(capsys, *argv):
    code = main(["compare", *argv])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def test_cli_fit_on_the_identification_record_is_the_model_files_fit(tmp_path, capsys):
    assert main(["identify", "--snr", "30", "--samples", "2000", "--out", str(tmp_path / "a"), "--no-plots"]) == 0
    assert main(["identify", "--snr", "30", "--samples", "2000", "--seed", "1", "--out", str(tmp_path / "b"),
                 "--na", "2", "--no-plots"]) == 0  # fmt: skip
    capsys.readouterr()
    model_a, model_b = tmp_path / "a" / "model.json", tmp_path / "b" / "model.json"
    code, out, _ = run_cli(capsys, str(model_a), str(model_b), str(tmp_path / "a" / "recording.csv"), "--json",
                           "--out", str(tmp_path / "cmp"))  # fmt: skip
    assert code == 0
    obj = json.loads(out)
    fits = {m["name"]: m for m in obj["records"][0]["models"]}
    own = json.loads(model_a.read_text())["fit_nrmse"]
    assert fits[str(model_a)]["fit_percent"] == pytest.approx(100 * (1 - own), rel=1e-9)
    assert fits[str(model_b)]["fit_percent"] < fits[str(model_a)]["fit_percent"]  # b has not seen this record
    for key in ("compare_plot", "resid_plot", "bode_plot"):
        assert (tmp_path / "cmp" / obj["outputs"][key].split("/")[-1]).stat().st_size > 0


def test_cli_refuses_what_cannot_be_compared(tmp_path, capsys):
    assert main(["identify", "--samples", "600", "--out", str(tmp_path / "a"), "--no-plots"]) == 0
    model = str(tmp_path / "a" / "model.json")
    sim = record(n=600)
    write_recording(tmp_path / "ms.csv", {"t": np.arange(600) * 0.001, "u": sim.u, "y": sim.y})
    capsys.readouterr()
    code, _, err = run_cli(capsys, model, "--no-plots")
    assert code == 2 and "at least one recording" in err and len(err.strip().splitlines()) == 1
    # the model was identified without a sample period: a recording in seconds is fine
    code, _, err = run_cli(capsys, model, str(tmp_path / "ms.csv"), "--no-plots")
    assert code == 0, err
    stamped = json.loads((tmp_path / "a" / "model.json").read_text())
    stamped["units"]["sample_period_s"] = 0.01
    (tmp_path / "p.json").write_text(json.dumps(stamped))
    code, _, err = run_cli(capsys, str(tmp_path / "p.json"), str(tmp_path / "ms.csv"), "--no-plots")
    assert code == 2 and "sample period of 0.01 s" in err and len(err.strip().splitlines()) == 1


def test_results_show_short_in_a_notebook_and_the_linear_block_goes_to_control(monkeypatch):
    from servoid.errors import MissingDependency
    from servoid.modelfile import ModelFile

    sim = record(n=1500, snr=40.0, seed=3)
    result = identify(sim.u, sim.y, MRGIAConfig())
    for obj in (result, result.mrgia, result.refinement, sim, result.model):
        assert len(repr(obj)) < 400 and "\n" not in repr(obj)  # never a dump of the arrays
    assert f"fit {100 * (1 - result.fit_nrmse):.2f} %" in repr(result)
    html = result._repr_html_()
    assert html.startswith("<table>") and html.count("<tr>") == 1 + len(result.model.names)
    content = ModelFile(model=result.model, sample_period_s=0.005)
    assert content.to_control().dt == 0.005
    assert "every 0.005 s" in repr(content)
    monkeypatch.setitem(__import__("sys").modules, "control", None)  # python-control not installed
    with pytest.raises(MissingDependency, match=r"pip install 'servoid\[control\]'"):
        result.to_control()


def test_cli_leaves_out_a_live_recordings_lost_samples(tmp_path, capsys):
    assert main(["identify", "--samples", "600", "--snr", "40", "--out", str(tmp_path / "a"), "--no-plots"]) == 0
    sim = record(n=600, snr=40.0, seed=6)
    lost = set(range(200, 212))
    rows = [f"{u:.9g},{'nan' if k in lost else f'{y:.9g}'},{'timeout' if k in lost else 'ok'}"
            for k, (u, y) in enumerate(zip(sim.u, sim.y))]  # fmt: skip
    (tmp_path / "live.csv").write_text("# guard_samples: 0\nu,y,status\n" + "\n".join(rows) + "\n")
    capsys.readouterr()
    code, out, err = run_cli(capsys, str(tmp_path / "a" / "model.json"), str(tmp_path / "live.csv"), "--json",
                             "--out", str(tmp_path / "cmp"))  # fmt: skip
    assert code == 0, err
    scored = json.loads(out)["records"][0]
    assert (scored["samples"], scored["used_samples"]) == (600, 588)
    assert 90 < scored["models"][0]["fit_percent"] < 100
