"""No NaN or Infinity reaches JSON: undetermined numbers are null (with a reason where it matters)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from servoid.cli import main
from servoid.ident.models.wear import GEAR_PLANT
from servoid.ident.monitoring.alarms import Bound
from servoid.ident.monitoring.wear_estimator import WearEstimator, WearEstimatorConfig
from servoid.ident.serialise import dumps, json_ready
from servoid.modelfile import ModelFile, save_model


def strict(text: str) -> object:
    """Parse as a strict reader would: NaN, Infinity and -Infinity are errors."""

    def refuse(name: str) -> object:
        raise ValueError(f"{name} is not JSON")

    return json.loads(text, parse_constant=refuse)


def test_dumps_turns_what_json_cannot_hold_into_null_and_plain_values():
    obj = {"nan": math.nan, "inf": -np.inf, "arr": np.array([1.0, np.nan]), "i": np.int64(3), "t": (1, 2.5),
           "b": np.bool_(True)}  # fmt: skip
    assert strict(dumps(obj)) == {"nan": None, "inf": None, "arr": [1.0, None], "i": 3, "t": [1, 2.5], "b": True}
    with pytest.raises(TypeError, match="to_dict"):
        json_ready({"x": object()})


def test_results_say_why_a_number_is_null():
    est = WearEstimator(WearEstimatorConfig(reference=GEAR_PLANT, fit_window=100))
    est.update(0.1, 0.0)
    d = strict(dumps(est.estimate().to_dict()))
    assert d["fit"] is None and "window" in d["fit_reason"]  # type: ignore[index]
    assert strict(dumps(Bound(quantity="fit", high=0.1).to_dict()))["low"] is None  # type: ignore[index]


def test_a_monitor_run_too_short_for_a_fit_prints_strict_json(tmp_path, capsys):
    model = save_model(tmp_path / "model.json", ModelFile(model=GEAR_PLANT, noise_std=0.0337, sample_period_s=0.001))
    code = main(["monitor", "--driver", "sim://gear?snr=40&clock=virtual", "--model", str(model),
                 "--duration", "0.5", "--fit", "0.05", "--json", "--out", str(tmp_path / "run")])  # fmt: skip
    out = capsys.readouterr().out
    summary = strict(out)
    assert code == 0 and summary["estimate"]["fit"] is None  # type: ignore[index]
    for line in (tmp_path / "run" / "events.jsonl").read_text().splitlines():
        strict(line)  # the bounds' open sides are null, not Infinity
    strict((tmp_path / "run" / "model.json").read_text())
