"""Starting fast: --help loads no numerical or vendor library, the packages load lazily, the first compile is said.

Times are in ``benchmarks/startup.py``; these tests check the causes, which
do not depend on how busy the machine is.
"""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap

import pytest

import servoid.drivers
import servoid.excitation
import servoid.ident
from servoid.cli import command_names

#: What --help must not import: each costs from 0.1 s (rich, NumPy) to a second (numba, SciPy, matplotlib).
HEAVY = ("numpy", "scipy", "numba", "llvmlite", "matplotlib", "rich", "serial", "can", "canopen", "dynamixel_sdk",
         "scservo_sdk", "msgpack", "rosbags", "h5py", "pandas", "yaml")  # fmt: skip


def _loaded_by(argv: list[str]) -> tuple[int, list[str]]:
    code = textwrap.dedent(f"""
        import json, sys
        from servoid.cli import main
        try:
            main({argv!r})
        except SystemExit as exc:
            status = exc.code
        heavy = sorted({{m.split(".")[0] for m in sys.modules}} & set({HEAVY!r}))
        print(json.dumps([status, heavy]), file=sys.stderr)
    """)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    status, heavy = json.loads(out.stderr.strip().splitlines()[-1])
    return status, heavy


@pytest.mark.parametrize("argv", [["--help"], *([name, "--help"] for name in command_names()),
                                  ["emulate", "feetech", "--help"]], ids=" ".join)  # fmt: skip
def test_help_loads_no_heavy_library(argv):
    status, heavy = _loaded_by(argv)
    assert status == 0 and heavy == []


def test_the_packages_load_their_names_on_first_use():
    for package in (servoid.ident, servoid.excitation, servoid.drivers):
        assert set(package.__all__) == set(package._EXPORTS), package.__name__
        for name in package.__all__:
            assert getattr(package, name) is not None
    import importlib

    importlib.import_module("servoid.ident.identify")  # the submodule of the same name as the function
    assert callable(servoid.ident.identify) and servoid.ident.identify.__module__ == "servoid.ident.identify"
    from servoid.ident.models.effect_names import CANDIDATE_NAMES
    from servoid.ident.models.effects import EFFECTS

    assert tuple(EFFECTS) == CANDIDATE_NAMES


def test_the_first_compilation_is_announced_and_the_cached_one_is_not(tmp_path):
    pytest.importorskip("numba")
    (tmp_path / "kernel_mod.py").write_text(
        textwrap.dedent("""
        from servoid.ident._jit import jit

        @jit
        def twice(x: float) -> float:
            return 2.0 * x
    """)
    )
    code = textwrap.dedent("""
        from servoid.ident import _jit
        _jit.on_first_compile(lambda: print("compiling"))
        import kernel_mod
        print(kernel_mod.twice(2.0))
    """)
    env = {"PYTHONPATH": str(tmp_path), "NUMBA_CACHE_DIR": str(tmp_path / "cache"), "PATH": ""}
    first = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, cwd=tmp_path)
    second = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, cwd=tmp_path)
    assert first.stdout.split() == ["compiling", "4.0"], first.stderr
    assert second.stdout.split() == ["4.0"], second.stderr


def test_a_missing_vendor_library_names_the_extra():
    code = textwrap.dedent("""
        import sys
        sys.modules["dynamixel_sdk"] = None  # as if dynamixel-sdk were not installed
        from servoid.cli import main
        main(["emulate", "dxl", "--help"])
    """)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert out.returncode == 2 and "pip install 'servoid[dxl]'" in out.stderr and "Traceback" not in out.stderr


def test_the_command_line_and_the_python_api_share_their_defaults():
    from servoid.cli import build_parser
    from servoid.cli.identify import _config, _selected
    from servoid.ident import MRGIAConfig
    from servoid.ident.diagnosis.diagnose import DiagnoseConfig
    from servoid.ident.monitoring.wear_estimator import WearEstimatorConfig
    from servoid.ident.paper import PAPER_PLANT

    identify = build_parser(["identify"]).parse_args(["identify"])
    api = MRGIAConfig()
    assert identify.rho_exponent == api.rho_exponent
    # the orders default to "chosen from the data" on a recording; where nothing is chosen, the API's
    assert (identify.na, identify.nb, identify.delay) == (None, None, None) and _selected(identify) == ()
    cfg = _config(identify, 0.0)
    for name in ("na", "nb", "delay", "rho_exponent"):
        assert getattr(cfg, name) == getattr(api, name), name
    diagnose = build_parser(["diagnose"]).parse_args(["diagnose", "--train", "a", "--validate", "b"])
    config = DiagnoseConfig(identification=api)
    for name in ("penalty", "max_effects", "reversal_window"):
        assert getattr(diagnose, name) == getattr(config, name), name
    assert (diagnose.epsilon, diagnose.rho_exponent) == (api.epsilon, api.rho_exponent)
    monitor = build_parser(["monitor"]).parse_args(["monitor", "--driver", "sim://", "--model", "m.json"])
    assert monitor.process_noise == WearEstimatorConfig(reference=PAPER_PLANT).process_noise
