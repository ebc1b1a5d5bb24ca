"""``model.json``: round trip, bad files named, versions."""

import json

import pytest

from servoid.errors import DataError, ModelError
from servoid.ident import PAPER_PLANT
from servoid.modelfile import ModelFile, load_model, save_model


def test_roundtrip(tmp_path):
    content = ModelFile(
        model=PAPER_PLANT,
        stderr={"c1": 0.001},
        output_unit="rad",
        source="sim://paper",
        samples=5000,
        fit_nrmse=0.02,
        sample_period_s=0.002,
    )
    p = save_model(tmp_path / "model.json", content)
    data = json.loads(p.read_text())
    assert data["schema"] == "servoid.model" and data["version"] == 3
    assert data["model"] == {"a": [0.45, 0.55], "b": [0.8], "delay": 1, "m1": 1.0, "m2": 1.5, "c1": 0.5, "c2": 1.0}
    back = load_model(p)
    assert back.model == PAPER_PLANT
    assert back.stderr == {"c1": 0.001} and back.output_unit == "rad" and back.samples == 5000
    assert back.identified_at.endswith("Z")


def _write(tmp_path, obj):
    p = tmp_path / "m.json"
    p.write_text(json.dumps(obj) if not isinstance(obj, str) else obj)
    return p


@pytest.mark.parametrize(
    "obj, fragment",
    [
        ("{not json", "not a JSON file"),
        ({"schema": "other"}, "not a servoid model file (schema 'other'"),
        ([1, 2], "not a servoid model file"),
        ({"schema": "servoid.model", "version": 9}, "version 9 is newer"),
        ({"schema": "servoid.model", "version": 0}, "version 0 is older than any this servoid reads"),
        ({"schema": "servoid.model", "version": 1, "units": {}, "identified": {}}, "missing field 'model'"),
    ],
)
def test_bad_files(tmp_path, obj, fragment):
    with pytest.raises(DataError) as info:
        load_model(_write(tmp_path, obj))
    assert fragment in str(info.value)


def test_invalid_model_inside(tmp_path):
    data = ModelFile(model=PAPER_PLANT).to_dict()
    data["model"]["c2"] = -1.0
    with pytest.raises(ModelError, match=r"c2 \(=-1.0\) must be > 0"):
        load_model(_write(tmp_path, data))
