"""The discrepancy workflow on records that hide a known effect, the CLI, and real data."""

import json
from pathlib import Path

import numpy as np
import pytest

from servoid.cli import main
from servoid.errors import ConfigError, ModelError
from servoid.extendedfile import load_extended_model
from servoid.ident import MRGIAConfig
from servoid.ident.diagnosis.diagnose import DiagnoseConfig, diagnose
from servoid.ident.diagnosis.hidden_effects import HIDDEN_STRENGTHS, hidden_effect_record
from servoid.ident.models.effects import CANDIDATE_NAMES, EFFECT_NAMES, EFFECTS, NONE
from servoid.ident.models.extended import simulate_extended
from servoid.recording import write_recording

SAMPLES = 6000
SNR = 40.0
CONFIG = DiagnoseConfig(identification=MRGIAConfig(na=2, nb=0, delay=1, rho_exponent=0.75))

#: Relative tolerance of the size estimate (extra_delay must be exact, extra_pole within 0.03 absolute).
SIZE_TOLERANCE = 0.03

CASES = [(NONE, None)] + [(name, v) for name, values in HIDDEN_STRENGTHS.items() for v in values]


def pair(effect, value, seed=11):
    train = hidden_effect_record(effect, value, samples=SAMPLES, seed=seed, snr=SNR)
    val = hidden_effect_record(effect, value, samples=SAMPLES, seed=seed + 1000, snr=SNR)
    return train, val


@pytest.mark.parametrize("effect, value", CASES, ids=[f"{e}-{v}" for e, v in CASES])
def test_the_hidden_effect_is_named_sized_and_closes_the_gap(effect, value):
    train, val = pair(effect, value)
    result = diagnose(train.u, train.y, val.u, val.y, CONFIG)
    assert result.effect == effect
    if effect == NONE:
        assert result.gap_after == result.gap_before
        assert result.gap_before < 1.2 / SNR  # the base model is at the noise floor
        return
    (name,) = EFFECTS[effect].parameters
    estimate = result.effect_parameters[name]
    if effect == "extra_pole":
        assert estimate == pytest.approx(value, abs=SIZE_TOLERANCE)
    else:
        assert estimate == pytest.approx(value, rel=SIZE_TOLERANCE)
    assert result.gap_after <= 0.6 * result.gap_before
    assert result.gap_after < 1.2 / SNR
    # the final model explains the validation record: its residual is white
    assert result.resid_after.white


def test_a_second_effect_is_found_after_the_first():
    from servoid.ident.models.extended import AppliedEffect, ExtendedModel
    from servoid.ident.paper import PAPER_INPUT_AMPLITUDE, PAPER_PLANT

    truth = ExtendedModel(PAPER_PLANT, (AppliedEffect("input_saturation", (1.5,)), AppliedEffect("dead_zone", (0.3,))))
    records = []
    for seed in (5, 6):
        rng = np.random.default_rng(seed)
        u = rng.uniform(-PAPER_INPUT_AMPLITUDE, PAPER_INPUT_AMPLITUDE, SAMPLES)
        y = simulate_extended(truth, u).y
        records.append((u, y + rng.normal(0, np.std(y) / SNR, SAMPLES)))
    result = diagnose(*records[0], *records[1], CONFIG)
    assert set(result.effects) == {"input_saturation", "dead_zone"}
    assert result.model.effect("dead_zone").values[0] == pytest.approx(0.3, rel=0.05)
    assert result.model.effect("input_saturation").values[0] == pytest.approx(1.5, rel=0.05)
    assert len(result.rounds) == 2 and result.gap_after < 1.2 / SNR


def test_unknown_candidates_are_refused():
    with pytest.raises(Exception, match="unknown effect 'backlash_width'"):
        DiagnoseConfig(identification=MRGIAConfig(), candidates=("backlash_width",))
    with pytest.raises(ConfigError, match="penalty"):
        DiagnoseConfig(identification=MRGIAConfig(), penalty=0)


# -- the command line ---------------------------------------------------------------


@pytest.fixture(scope="module")
def csv_pair(tmp_path_factory):
    folder = tmp_path_factory.mktemp("rec")
    train, val = pair("dead_zone", 0.3, seed=21)
    for name, rec in (("a.csv", train), ("b.csv", val)):
        write_recording(
            folder / name, {"t": 0.01 * np.arange(SAMPLES), "u": rec.u, "y": rec.y}, metadata={"unit": "rad"}
        )
    return folder / "a.csv", folder / "b.csv"


def test_cli_json_is_one_object_with_the_agreed_keys(csv_pair, tmp_path, capsys):
    a, b = csv_pair
    code = main(
        [
            "diagnose",
            "--train",
            str(a),
            "--validate",
            str(b),
            "--na",
            "2",
            "--nb",
            "0",
            "--delay",
            "1",
            "--out",
            str(tmp_path),
            "--json",
        ]
    )
    obj = json.loads(capsys.readouterr().out)
    assert code == 0
    assert obj["effect"] == "dead_zone" and set(obj["effect_parameters"]) == {"width"}
    assert obj["effect_parameters"]["width"] == pytest.approx(0.3, rel=SIZE_TOLERANCE)
    assert obj["gap_after"] <= 0.6 * obj["gap_before"] and isinstance(obj["where"], str) and "%" in obj["where"]
    assert {c["effect"] for c in obj["candidates"]} == {
        *CANDIDATE_NAMES,
        NONE,
    }  # friction_stall is named from the loop model
    assert all({"effect", "gap", "score"} <= set(c) for c in obj["candidates"])
    model, content = load_extended_model(tmp_path / "model.json")
    assert model.effect_names[0] == "dead_zone" and content.output_unit == "rad"
    for key in ("fit_plot", "regimes_plot", "resid_plot", "candidates_plot"):
        assert Path(obj["outputs"][key]).stat().st_size > 0


def test_cli_table_names_the_effect_with_its_unit(csv_pair, tmp_path, capsys):
    a, b = csv_pair
    assert (
        main(
            [
                "diagnose",
                "--train",
                str(a),
                "--validate",
                str(b),
                "--out",
                str(tmp_path),
                "--no-plots",
                "--effects",
                "dead_zone,coulomb_friction",
            ]
        )
        == 0
    )
    out = " ".join(capsys.readouterr().out.split())  # rich wraps long lines
    assert "missing effect: dead_zone (width = 0.3" in out or "missing effect: dead_zone (width = 0.29" in out
    assert "where:" in out and "validation gap (free-run NRMSE): before" in out


@pytest.mark.parametrize(
    "content_b, args, fragment",
    [
        (None, [], "no such CSV file"),
        ("u,v\n1,2\n", [], "missing column(s) 'y'"),
        (
            "# unit: mm\nt,u,y\n" + "".join(f"{0.01 * i},{np.sin(i)},{np.cos(i)}\n" for i in range(500)),
            [],
            "differ in 'unit'",
        ),
        (
            "# unit: rad\nt,u,y\n" + "".join(f"{0.02 * i},{np.sin(i)},{np.cos(i)}\n" for i in range(500)),
            [],
            "differ in sample period",
        ),
        ("t,u,y\n0,1,2\n0.01,1,3\n", [], "validation record: 2 samples are too few"),
        ("t,u,y\n0,1,2\n", ["--effects", "stiction"], "--effects (='stiction') must list effects from"),
    ],
)
def test_cli_bad_or_mismatched_files_give_one_line(csv_pair, tmp_path, capsys, content_b, args, fragment):
    a, _ = csv_pair
    b = tmp_path / "b.csv"
    if content_b is not None:
        b.write_text(content_b)
    code = main(
        ["diagnose", "--train", str(a), "--validate", str(b), "--out", str(tmp_path / "o"), "--no-plots", *args]
    )
    err = capsys.readouterr().err
    assert code == 2, err
    assert fragment in err
    assert err.count("\n") == 1 and "Traceback" not in err


def test_help_teaches(capsys):
    with pytest.raises(SystemExit):
        main(["diagnose", "--help"])
    out = capsys.readouterr().out
    for word in ("--train", "--validate", "--penalty", "coulomb_friction", "extra_pole", "NRMSE", "examples"):
        assert word in out


# -- real data (skipped where ../shared/data is absent) ------------------------------------

DATA = Path(__file__).resolve().parents[2] / "shared" / "data"
EMPS = DATA / "emps"
BAM = DATA / "bam" / "bam_xl330_raw_2026-01-15_10h28m10.json"


@pytest.mark.skipif(not (EMPS / "DATA_EMPS.mat").exists(), reason=f"EMPS data not found in {EMPS}")
def test_emps_reads_and_diagnoses():
    from servoid.readers import read_emps

    train = read_emps(EMPS / "DATA_EMPS.mat", decimate=10)
    val = read_emps(EMPS / "DATA_EMPS_PULSES.mat", decimate=10)
    assert len(train) == 2485 and train.metadata["unit"] == "m" and train.sample_period == pytest.approx(0.01, rel=1e-3)
    result = diagnose(
        train.u,
        train.y,
        val.u,
        val.y,
        DiagnoseConfig(identification=MRGIAConfig(na=2, nb=1, delay=1, rho_exponent=0.75)),
    )
    assert result.effect in EFFECT_NAMES and result.gap_after <= result.gap_before


@pytest.mark.skipif(not BAM.exists(), reason=f"BAM XL330 log not found at {BAM}")
def test_xl330_reads_and_diagnoses():
    from servoid.readers import read_bam

    rec = read_bam(BAM)
    assert len(rec) == 1124 and rec.metadata["unit"] == "rad"
    train, val = rec.split(0.67)
    config = DiagnoseConfig(identification=MRGIAConfig(na=2, nb=0, delay=1, rho_exponent=0.75))
    try:
        result = diagnose(train.u, train.y, val.u, val.y, config)
    except ModelError as exc:
        # a torque-limited static log (research study Q7): no model beats the mean, and diagnose says so
        assert "worse than predicting its mean" in str(exc)
        return
    assert result.effect in EFFECT_NAMES and result.gap_after <= result.gap_before and result.gap_after < 1.0


def _twin_pair(friction: float) -> tuple[tuple[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray], float]:
    """Training and validation records (12 s of gentle sines each) of the XM430 twin, its motor friction scaled."""
    from servoid.drivers.twin import Twin, preset
    from servoid.excitation.generate import sample
    from servoid.excitation.specs import GentleSpec

    base = preset("xm430")
    params = preset("xm430", load_encoder_cpr=4096, encoder_noise_counts=0.3,
                    motor_coulomb_nm=base.motor_coulomb_nm * friction,
                    motor_breakaway_nm=base.motor_breakaway_nm * friction)  # fmt: skip
    period = 1.0 / 70.0  # 20x the twin's loop bandwidth
    records = []
    for seed in (1, 2):
        twin = Twin(params, seed=seed)
        twin.enable()
        u = sample(GentleSpec(amplitude=0.1, accel=8.0 * period**2, spread=8.0), int(12.0 / period), seed=seed)
        rec = twin.sample(u, period)
        records.append((np.asarray(rec.u, dtype=float), np.asarray(rec.y, dtype=float)))
    return records[0], records[1], period


def test_a_drive_that_stalls_after_reversals_is_named_friction_stall_and_the_gap_shrinks():
    # the twin's motor friction x4: the velocity loop must overcome break-away after each reversal
    train, val, period = _twin_pair(4.0)
    result = diagnose(*train, *val, CONFIG, sample_period_s=period)
    loop = result.loop
    assert loop is not None and loop.named and result.effect == "friction_stall"
    assert loop.gap_with < 0.5 * loop.gap_without  # the servo-loop model's gap shrinks when friction is added
    assert loop.gap_with < result.gap_after  # and explains the record better than the black box with its effects
    assert result.effect_parameters["stall_band"] == loop.stall_band > 0.0
    assert json.loads(json.dumps(result.to_dict()))["loop_effect"]["effect"] == "friction_stall"


def test_a_drive_without_friction_is_not_named_friction_stall():
    train, val, period = _twin_pair(0.0)
    result = diagnose(*train, *val, CONFIG, sample_period_s=period)
    assert result.loop is not None and not result.loop.named and "friction_stall" not in result.effects
