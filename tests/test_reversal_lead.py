"""The compensator for a play inside the loop: the reversal lead, in Python, in C, and in the commands."""

from __future__ import annotations

import json
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from servoid.cli import main
from servoid.export import export_model
from servoid.ident import BacklashModel
from servoid.ident._jit import python_version
from servoid.ident.control.reversal_lead import LEAD_STATE_SIZE, ReversalLead, lead_step, lead_study, simulate_lead
from servoid.ident.models.servo_loop import ServoLoopModel
from servoid.ident.models.structure_names import PLAY_IN_LOOP, SERVO_LOOP
from servoid.modelfile import ModelFile, save_model

LOOP = ServoLoopModel(structure=PLAY_IN_LOOP, sample_period_s=0.01, kp=20.0, kv=150.0, c1=0.004, c2=0.003)


def _content() -> ModelFile:
    black_box = BacklashModel(a=(-0.9,), b=(0.1,), delay=1, m2=1.0, c1=0.004, c2=0.003)
    return ModelFile(model=black_box, output_unit="rad", input_unit="rad", sample_period_s=0.01, band=0.001,
                     structure=PLAY_IN_LOOP, form=SERVO_LOOP, identifiable=True, play=LOOP.play,
                     loop=LOOP.params())  # fmt: skip


def _lead_python(lead: ReversalLead, r: np.ndarray, y: np.ndarray) -> np.ndarray:
    state = np.zeros(LEAD_STATE_SIZE)
    state[0] = r[0]
    step = python_version(lead_step)
    return np.array([step(lead.vector(), state, float(rk), float(yk)) for rk, yk in zip(r, y, strict=True)])


def test_the_lead_shortens_the_wait_at_fast_reversals() -> None:
    lead = ReversalLead.for_model(LOOP, threshold=0.0005)
    assert (lead.lead_up, lead.lead_down) == (LOOP.c1, LOOP.c2)
    fast = lead_study(LOOP, lead)[0]
    # the play's error against the same loop without play: a lead of the play makes the motor cross it sooner
    assert fast.rms_with < 0.8 * fast.rms_without
    assert fast.peak_with < fast.peak_without
    # without reversals nothing is added
    r = np.linspace(0.0, 0.1, 200)
    y, u = simulate_lead(LOOP, lead, r)
    np.testing.assert_array_equal(u, r)


def test_the_rule_leads_after_a_reversal_until_the_load_moves() -> None:
    lead = ReversalLead(lead_up=0.5, lead_down=0.25, threshold=0.1, max_samples=5)
    r = np.array([0.0, 1.0, 2.0, 1.5, 1.0, 0.5, 0.0, -0.5, -1.0, -1.5])
    y = np.array([0.0, 0.5, 1.5, 2.0, 2.0, 1.95, 1.8, 1.0, 0.0, -1.0])  # the load waits two samples, then moves
    u = _lead_python(lead, r, y)
    np.testing.assert_allclose(u - r, [0, 0, 0, -0.25, -0.25, -0.25, 0, 0, 0, 0])


@pytest.mark.skipif(shutil.which("gcc") is None, reason="gcc is not installed")
def test_the_c_header_is_the_same_rule(tmp_path: Path) -> None:
    (tmp_path / "lead.h").write_text(export_model(_content(), "c", name="horn"))
    (tmp_path / "check.c").write_text(
        '#include <stdio.h>\n#include "lead.h"\n'
        "int main(void) { double r, y; servoid_lead_state st; int first = 1;\n"
        '  while (scanf("%lf %lf", &r, &y) == 2) { if (first) { servoid_lead_reset(&st, r); first = 0; }\n'
        '    printf("%.17g\\n", servoid_reversal_lead(&horn, &st, r, y)); } return 0; }\n'
    )
    exe = tmp_path / "check"
    cc = subprocess.run([shutil.which("gcc") or "gcc", "-std=c99", "-Wall", "-Wextra", "-Werror", "-pedantic",
                         "-I", str(tmp_path), str(tmp_path / "check.c"), "-o", str(exe)],
                        capture_output=True, text=True)  # fmt: skip
    assert cc.returncode == 0, cc.stderr
    r = 0.03 * np.sin(np.arange(400) / 9.0)
    y, _ = simulate_lead(LOOP, None, r)
    text = "".join(f"{float(a)!r} {float(b)!r}\n" for a, b in zip(r, y, strict=True))
    run = subprocess.run([str(exe)], input=text, capture_output=True, text=True, check=True)
    c_out = np.array([float(v) for v in run.stdout.split()])
    lead = ReversalLead.for_model(LOOP, threshold=0.001)
    np.testing.assert_array_equal(c_out, _lead_python(lead, r, y))
    assert np.any(c_out != r)


def test_export_and_compensate_know_the_play_in_the_loop(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = save_model(tmp_path / "model.json", _content())
    assert main(["export", str(path), "--format", "yaml"]) == 0
    out, err = capsys.readouterr()
    assert "reversal_lead:" in out and "lead_up: 0.004" in out and "reversal lead" in err
    assert main(["compensate", str(path), "--json", "--no-plots"]) == 0
    study = json.loads(capsys.readouterr().out)
    assert study["compensator"] == "reversal_lead" and study["lead"]["lead_down"] == 0.003
    assert len(study["paths"]) == 3
