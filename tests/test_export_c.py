"""The C header: it compiles with gcc -std=c99 -Wall -Wextra -Werror and agrees with Python sample by sample."""

import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from servoid.cli import main
from servoid.errors import ConfigError, ModelError
from servoid.export import export_model
from servoid.ident import BacklashModel
from servoid.ident.control.compensate import InverseParams, backlash_inverse
from servoid.modelfile import ModelFile

GCC = shutil.which("gcc")
pytestmark = pytest.mark.skipif(GCC is None, reason="gcc is not installed: the C header cannot be compiled here")

CFLAGS = ["-std=c99", "-Wall", "-Wextra", "-Werror", "-pedantic"]
CHECK_SOURCE = Path(__file__).parent / "c" / "check_inverse.c"

#: An identified-looking model: digits that do not round-trip by luck.
MODEL = BacklashModel(a=(0.4498731, 0.5502215), b=(0.7993807, 0.01234), delay=1, m2=1.5007712, c1=0.49831577,
                      c2=0.99935291)  # fmt: skip
BAND = 0.0371


def _content(**kw):
    base = dict(model=MODEL, output_unit="rad", input_unit="V", sample_period_s=0.002, band=BAND, noise_std=0.01,
                stderr={n: 1e-3 for n in MODEL.names}, source="serial:///dev/ttyUSB0?baud=1000000",
                servo={"model": "bench */ rig ??/", "serial": 42}, samples=20000, fit_nrmse=0.0234)  # fmt: skip
    base.update(kw)
    return ModelFile(**base)


def _compile(tmp_path: Path, source: Path, out: str = "prog") -> Path:
    exe = tmp_path / out
    proc = subprocess.run([GCC, *CFLAGS, "-I", str(tmp_path), str(source), "-o", str(exe)],
                          capture_output=True, text=True)  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    return exe


@pytest.fixture(scope="module")
def checker(tmp_path_factory) -> Path:
    """check_inverse.c built against two headers exported side by side (band BAND, and band 0)."""
    tmp = tmp_path_factory.mktemp("cheader")
    (tmp / "smooth.h").write_text(export_model(_content(), "c", name="smooth_axis"))
    (tmp / "naive.h").write_text(export_model(_content(), "c", name="naive_axis", band=0.0))
    return _compile(tmp, CHECK_SOURCE, "check_inverse")


def _reference(seed: int) -> np.ndarray:
    """Sines with noise (many small reversals), steps larger and smaller than the band, plateaus, a ramp."""
    rng = np.random.default_rng(seed)
    k = np.arange(800)
    sine = 0.9 * np.sin(2 * np.pi * k / 160) + rng.normal(0, 0.01, k.size)
    steps = np.repeat([0.0, 0.5, 0.48, 0.52, -0.7, -0.69, 0.3, 0.3], 25)
    ramp = np.linspace(-2.0, 3.0, 150)
    return np.concatenate([sine, steps, ramp, np.full(20, 3.0), ramp[::-1]])


def _run_c(exe: Path, which: str, y_d: np.ndarray, *start: float) -> np.ndarray:
    text = "\n".join(repr(float(v)) for v in y_d) + "\n"
    proc = subprocess.run([str(exe), which, *map(repr, start)], input=text, capture_output=True, text=True,
                          check=True)  # fmt: skip
    return np.array([float(v) for v in proc.stdout.split()])


@pytest.mark.parametrize("which, band", [("smooth", BAND), ("naive", 0.0)])
@pytest.mark.parametrize("start", [(0.1,), (0.1, -0.3), (-0.4, 0.2)])
def test_c_matches_python_sample_by_sample(checker, which, band, start):
    y_d = _reference(seed=len(start) + int(band > 0))
    c = _run_c(checker, which, y_d, *start)
    params = InverseParams.from_model(MODEL, band=band)
    py = backlash_inverse(params, y_d, y0=start[0], x0=start[1] if len(start) > 1 else None)
    assert c.shape == py.shape
    np.testing.assert_allclose(c, py, rtol=1e-12, atol=1e-12)
    # the sequence does exercise reversals inside and beyond the band
    assert np.count_nonzero(np.diff(np.sign(np.diff(y_d)))) > 100


def test_identify_then_export_c_compiles(tmp_path, capsys):
    """The issue's acceptance path: servoid identify, then servoid export --format c, then gcc."""
    run = tmp_path / "run"
    assert main(["identify", "--samples", "2000", "--snr", "40", "--no-plots", "--out", str(run)]) == 0
    header = tmp_path / "backlash.h"
    assert main(["export", str(run / "model.json"), "--format", "c", "--out", str(header)]) == 0
    text = header.read_text()
    assert "static const servoid_backlash_params servoid_axis" in text
    assert "servoid_backlash_inverse" in text and "band" in text
    source = tmp_path / "use.c"
    source.write_text(
        '#include "backlash.h"\n'
        "int main(void)\n{\n"
        "    servoid_backlash_state st;\n"
        "    servoid_backlash_reset(&st, 0.0);\n"
        "    return servoid_backlash_inverse(&servoid_axis, &st, 1.0) > 1.0 ? 0 : 1;\n"
        "}\n"
    )
    exe = _compile(tmp_path, source)
    assert subprocess.run([str(exe)]).returncode == 0  # rising: x_d = 1 + c1 > 1


def test_header_states_units_values_and_survives_hostile_strings():
    text = export_model(_content(), "c", name="left_wheel")
    assert "c1 [rad]" in text and "band [rad]" in text and "[rad per V]" in text
    assert "sample period 0.002 s" in text and "#define LEFT_WHEEL_SAMPLE_PERIOD_S 0.002" in text
    assert f"{MODEL.c1!r}, /* c1" in text and f"{BAND!r}  /* band" in text  # exact round-trip literals
    assert "c1 0.001" in text  # standard errors
    # the servo identity holds "*/" and a trigraph: neither may end the comment or splice lines
    assert "bench * / rig ? ?/" in text
    assert text.count("*/") == text.count("/*")


def test_name_must_be_a_c_identifier():
    with pytest.raises(ConfigError, match=r"name \(='2axis'\) must be a C identifier"):
        export_model(_content(), "c", name="2axis")


def test_effects_refused_unless_ignored(tmp_path, capsys):
    content = _content(extra={"effects": [{"name": "coulomb_friction"}, {"kind": "drift"}]})
    with pytest.raises(
        ModelError, match=r"2 extension\(s\) in 'effects' \(coulomb_friction, drift\).*--ignore-effects"
    ):
        export_model(content, "c")
    assert "servoid_backlash_inverse" in export_model(content, "c", ignore_effects=True)
    path = tmp_path / "model.json"
    path.write_text(content.to_json())
    assert main(["export", str(path), "--format", "c"]) == 2
    assert "--ignore-effects" in capsys.readouterr().err
    assert main(["export", str(path), "--format", "c", "--ignore-effects", "--out", str(tmp_path / "h.h")]) == 0
    assert "leaving out the model extension(s) coulomb_friction, drift" in capsys.readouterr().err
