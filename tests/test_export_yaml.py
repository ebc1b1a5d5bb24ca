"""ROS 2 YAML and JSON exports, and the ``servoid export`` command."""

import json
import re

import pytest
import yaml

from servoid.cli import main
from servoid.errors import ConfigError, ModelError
from servoid.export import FORMATS, export_model
from servoid.ident import PAPER_PLANT
from servoid.modelfile import ModelFile, load_model

ROS_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*\Z")


def _content(**kw):
    base = dict(model=PAPER_PLANT, output_unit="rad", input_unit="V", sample_period_s=0.002, band=0.03,
                stderr={"a1": 1e-4, "a2": float("nan"), "b0": 5e-4, "m2": 1e-3, "c1": 1e-3, "c2": 8e-4},
                servo={"model name": "XM430-W350", "firmware": 45, "ids": [1, "a"], "2nd": None, "flags": []},
                source="dxl:///dev/ttyUSB0?id=1", samples=5000, fit_nrmse=0.02)  # fmt: skip
    base.update(kw)
    return ModelFile(**base)


def _ros_types_only(node, path="ros__parameters"):
    """Every leaf is a ROS 2 parameter type: bool, int, float, str or a non-empty homogeneous array of one."""
    assert isinstance(node, dict) and node, path
    for key, value in node.items():
        assert ROS_NAME.match(key), f"{path}.{key}"
        if isinstance(value, dict):
            _ros_types_only(value, f"{path}.{key}")
        elif isinstance(value, list):
            assert value and len({type(v) for v in value}) == 1, f"{path}.{key} = {value!r}"
            assert isinstance(value[0], (bool, int, float, str)), f"{path}.{key}"
        else:
            assert isinstance(value, (bool, int, float, str)), f"{path}.{key} = {value!r}"


def test_yaml_is_a_ros2_parameter_file():
    text = export_model(_content(), "yaml", node="arm_controller")
    data = yaml.safe_load(text)
    assert list(data) == ["arm_controller"] and list(data["arm_controller"]) == ["ros__parameters"]
    params = data["arm_controller"]["ros__parameters"]
    _ros_types_only(params)
    assert params["backlash"] == {"m1": 1.0, "m2": 1.5, "c1": 0.5, "c2": 1.0, "band": 0.03}
    assert params["linear"] == {"a": [0.45, 0.55], "b": [0.8], "delay": 1}
    assert params["units"] == {"input": "V", "output": "rad", "time": "sample", "sample_period_s": 0.002}
    assert params["schema_version"] == 3 and params["identified"]["samples"] == 5000
    assert "a2" not in params["stderr"]  # NaN: not determined, left out (ROS 2 has no null)
    assert params["servo"] == {"model_name": "XM430-W350", "firmware": 45, "ids": ["1", "a"]}
    assert "# Units: backlash.c1, backlash.c2, backlash.band in rad" in text


@pytest.mark.parametrize("node", ["/**", "/robot/arm_controller", "arm"])
def test_yaml_node_names(node):
    assert node in yaml.safe_load(export_model(_content(), "yaml", node=node))


def test_yaml_rejects_bad_node_names_and_effects():
    with pytest.raises(ConfigError, match=r"node \(='my node'\) must be a ROS 2 node name"):
        export_model(_content(), "yaml", node="my node")
    with pytest.raises(ModelError, match="cannot express"):
        export_model(_content(extra={"effects": ["drift"]}), "yaml")


def test_json_export_upgrades_version_1_and_keeps_effects(tmp_path, capsys):
    v1 = json.loads(_content().to_json())
    v1["version"] = 1
    del v1["compensation"]
    v1["effects"] = [{"name": "drift"}]
    src = tmp_path / "old.json"
    src.write_text(json.dumps(v1))
    out = tmp_path / "new.json"
    assert main(["export", str(src), "--format", "json", "--out", str(out)]) == 0
    err = capsys.readouterr().err
    assert "schema version 1, which stores no smoothing band" in err and "0.03 rad" in err
    new = load_model(out)
    assert new.read_version == 3 and new.effects == [{"name": "drift"}]
    assert new.band == pytest.approx(0.02 * PAPER_PLANT.dead_zone)


def test_export_to_stdout_and_band_override(tmp_path, capsys):
    path = tmp_path / "model.json"
    path.write_text(_content().to_json())
    assert main(["export", str(path), "--format", "yaml", "--band", "0.01"]) == 0
    out = capsys.readouterr().out
    assert yaml.safe_load(out)["backlash_compensator"]["ros__parameters"]["backlash"]["band"] == 0.01
    assert main(["export", str(path), "--format", "json", "--name", "x"]) == 2
    assert "name do not apply to --format json" in capsys.readouterr().err
    assert main(["export", str(path), "--format", "c", "--band", "-1"]) == 2
    assert "band (=-1.0) must be >= 0" in capsys.readouterr().err


def test_export_help_explains_each_format(capsys):
    with pytest.raises(SystemExit):
        main(["export", "--help"])
    out = capsys.readouterr().out
    for fmt in FORMATS:
        assert f"  {fmt}   " in out
    for word in ("ros__parameters", "static const", "-std=c99", "smoothing band", "output unit", "examples",
                 "--ignore-effects", "diagnose.md"):  # fmt: skip
        assert word in out
