"""model.json version 2: compensation section, effects passthrough, old and bad files, the JSON Schema."""

import json
import math
from importlib import resources

import jsonschema
import pytest

from servoid.cli import main
from servoid.errors import ConfigError, DataError
from servoid.ident import PAPER_PLANT
from servoid.ident.control.compensate import default_band
from servoid.modelfile import ModelFile, load_model, save_model

SCHEMA = json.loads(resources.files("servoid").joinpath("model.schema.json").read_text())


def _write(tmp_path, obj, name="m.json"):
    p = tmp_path / name
    p.write_text(json.dumps(obj) if not isinstance(obj, str) else obj)
    return p


def _v1(**overrides):
    """A model.json as servoid 0.1 wrote it (schema version 1, no compensation section)."""
    data = {
        "schema": "servoid.model", "version": 1, "model": PAPER_PLANT.to_dict(),
        "stderr": {"a1": 1e-4, "a2": 1e-4, "b0": 5e-4, "m2": 1e-3, "c1": 1e-3, "c2": 8e-4},
        "units": {"input": "V", "output": "rad", "time": "sample", "sample_period_s": 0.002},
        "method": "mrgia+oe", "fit_nrmse": 0.02,
        "identified": {"at": "2025-01-01T00:00:00Z", "source": "sim://paper", "samples": 5000,
                       "servoid_version": "0.1.0"},
        "servo": None,
    }  # fmt: skip
    data.update(overrides)
    return data


def test_version_2_roundtrip_keeps_band_noise_and_effects(tmp_path):
    effects = [{"name": "coulomb_friction", "params": {"fc": 0.1}}, "drift"]
    content = ModelFile(model=PAPER_PLANT, output_unit="rad", band=0.012, noise_std=0.004,
                        extra={"effects": effects, "vendor_note": "kept"})  # fmt: skip
    path = save_model(tmp_path / "model.json", content)
    data = json.loads(path.read_text())
    assert data["version"] == 3
    assert data["compensation"] == {"band": 0.012, "noise_std": 0.004}
    assert data["effects"] == effects and data["vendor_note"] == "kept"
    back = load_model(path)
    assert back.band == 0.012 and back.noise_std == 0.004 and back.read_version == 3
    assert back.effects == effects and back.effect_names() == ["coulomb_friction", "drift"]
    # written back unchanged
    save_model(tmp_path / "again.json", back)
    assert json.loads((tmp_path / "again.json").read_text())["effects"] == effects


def test_written_files_validate_against_the_published_json_schema(tmp_path):
    content = ModelFile(model=PAPER_PLANT, stderr={"a1": 0.1, "c1": float("nan")}, output_unit="counts",
                        sample_period_s=0.001, samples=100, fit_nrmse=0.1, noise_std=0.5,
                        servo={"model": "XM430", "id": 1}, extra={"effects": []})  # fmt: skip
    data = json.loads(save_model(tmp_path / "model.json", content).read_text())
    jsonschema.validate(data, SCHEMA)
    # an undetermined standard error is null: NaN is not JSON
    assert data["stderr"]["c1"] is None and "NaN" not in (tmp_path / "model.json").read_text()
    broken = dict(data, compensation={"band": -1.0})
    with pytest.raises(jsonschema.ValidationError):
        jsonschema.validate(broken, SCHEMA)


def test_identify_writes_version_2_with_band_set_from_the_residual(tmp_path, capsys):
    assert main(["identify", "--samples", "2500", "--snr", "30", "--no-plots", "--out", str(tmp_path)]) == 0
    data = json.loads((tmp_path / "model.json").read_text())
    jsonschema.validate(data, SCHEMA)
    content = load_model(tmp_path / "model.json")
    noise = content.noise_std
    # at SNR 30 the residual RMS is std(y) / 30, and std(y) of the paper's record is about 1.1
    assert noise == pytest.approx(1.1 / 30, rel=0.25)
    assert content.band == pytest.approx(default_band(content.model, noise_std=noise))
    assert content.band == pytest.approx(2 * noise)


def test_version_1_is_read_with_the_default_band(tmp_path):
    content = load_model(_write(tmp_path, _v1()))
    assert content.read_version == 1 and content.band is None
    assert content.compensation_band == pytest.approx(0.02 * PAPER_PLANT.dead_zone)
    assert content.output_unit == "rad" and content.sample_period_s == 0.002
    assert json.loads(content.to_json())["version"] == 3


def test_version_1_nan_stderr_reads_as_null(tmp_path):
    text = json.dumps(_v1()).replace('"c1": 0.001', '"c1": NaN')
    content = load_model(_write(tmp_path, text))
    assert content.stderr["c1"] is None


@pytest.mark.parametrize(
    "obj, fragment",
    [
        (
            {"schema": "servoid.model", "version": 4},
            "schema version 4 is newer than this servoid reads (versions 1, 2, 3); upgrade",
        ),
        ({"schema": "servoid.model", "version": 0}, "schema version 0 is older than any this servoid reads"),
        ({"schema": "servoid.model", "version": "2"}, "schema version '2' is not a version number"),
        ({"schema": "servoid.model"}, "schema version None is not a version number"),
        ({k: v for k, v in _v1(version=2).items()}, "missing field 'compensation' (required in version 2)"),
        (_v1(version=2, compensation={}), "missing field 'compensation.band'"),
        (_v1(version=2, compensation={"band": -0.1}), "compensation.band (=-0.1) must be >= 0"),
        (_v1(version=2, compensation={"band": "wide"}), "compensation.band (='wide') must be a real number"),
        (_v1(version=2, compensation={"band": 0.1, "noise_std": -1}), "compensation.noise_std (=-1) must be >= 0"),
        (_v1(version=2, compensation=[0.1]), "'compensation' must be an object, got list"),
        (_v1(effects={"name": "friction"}), "'effects' must be a list of model extensions (see docs/diagnose.md)"),
        (_v1(stderr={"c1": "small"}), "stderr.c1 (='small') must be a number or null"),
        (_v1(stderr=[1, 2]), "'stderr' must be an object or null, got list"),
        (_v1(units={"output": "rad", "sample_period_s": 0}), "units.sample_period_s (=0) must be a positive number"),
        (_v1(units="rad"), "'units' must be an object, got str"),
    ],
)
def test_bad_and_old_files_give_one_clear_line(tmp_path, obj, fragment):
    with pytest.raises(DataError) as info:
        load_model(_write(tmp_path, obj))
    message = str(info.value)
    assert fragment in message and "\n" not in message


def test_bad_file_through_the_cli_is_one_line_and_exit_2(tmp_path, capsys):
    path = _write(tmp_path, {"schema": "servoid.model", "version": 7})
    for argv in (["export", str(path), "--format", "c"], ["compensate", str(path), "--no-plots"]):
        assert main(argv) == 2
        err = capsys.readouterr().err
        assert "version 7 is newer" in err and err.count("\n") == 1


def test_band_validated_in_memory():
    with pytest.raises(ConfigError, match=r"band \(=-1\) must be >= 0"):
        ModelFile(model=PAPER_PLANT, band=-1)
    assert math.isclose(ModelFile(model=PAPER_PLANT, noise_std=0.5).compensation_band, 1.0)
