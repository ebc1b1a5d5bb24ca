"""The pillars install as subpackages of `servoid` from a regular (non-editable) wheel."""

import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.slow
def test_wheel_installs_every_package(tmp_path):
    subprocess.run(
        [
            sys.executable,
            "-m",
            "pip",
            "wheel",
            "--no-deps",
            "--no-build-isolation",
            "-q",
            "-w",
            str(tmp_path),
            str(ROOT),
        ],
        check=True,
        capture_output=True,
        cwd=tmp_path,
    )
    wheel = next(tmp_path.glob("servoid-*.whl"))
    site = tmp_path / "site"
    subprocess.run(
        [sys.executable, "-m", "pip", "install", "--no-deps", "-q", "--target", str(site), str(wheel)],
        check=True,
        capture_output=True,
    )
    code = (
        "import servoid, servoid.ident, servoid.drivers, servoid.excitation, servoid.cli, pathlib;"
        "assert 'site' in servoid.ident.__file__, servoid.ident.__file__;"
        "from servoid.ident import run_mrgia, PAPER_PLANT;"
        "print(all((pathlib.Path(p.__file__).parent / 'py.typed').exists() "
        "for p in (servoid, servoid.ident, servoid.drivers, servoid.excitation)))"
    )
    # run from the empty tmp dir so the repository is not on sys.path
    out = subprocess.run(
        [sys.executable, "-c", code],
        cwd=tmp_path,
        env={"PYTHONPATH": str(site), "PATH": ""},
        capture_output=True,
        text=True,
    )
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "True"
    # every package directory in the source tree is in the wheel
    import zipfile

    names = zipfile.ZipFile(wheel).namelist()
    # data files the exporters read at run time
    for data in ("servoid/export/templates/backlash_compensator.h", "servoid/model.schema.json"):
        assert data in names, data
    # the serial servo's firmware sources, which `servoid emulate serial` compiles
    for source in (ROOT / "drivers" / "serial" / "firmware").rglob("*.[ch]"):
        rel = source.relative_to(ROOT / "drivers").as_posix()
        assert f"servoid/drivers/{rel}" in names, rel
    for pillar in ("ident", "drivers", "excitation"):
        for init in (ROOT / pillar).rglob("__init__.py"):
            rel = init.relative_to(ROOT / pillar).as_posix()
            assert f"servoid/{pillar}/{rel}" in names
