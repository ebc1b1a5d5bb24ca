"""servoid replaces no path it was not asked to, and runs no program it did not build.

Before: ``servoid emulate serial --link PATH`` deleted a file at PATH; when the
firmware cache could not be created, servoid ran whatever file sat at a
predictable name in ``$TMPDIR/servoid-<uid>`` (a planted script was executed).
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest

from servoid.cli import main
from servoid.drivers.serial import build

ROOT_ONLY = pytest.mark.skipif(os.getuid() != 0, reason="giving a file to another user needs root")
NOBODY = 65534


def _plant(path: Path, marker: Path) -> None:
    """A script at the firmware's name that leaves ``marker`` behind if anyone runs it."""
    path.write_text(f"#!/bin/sh\ntouch {marker}\necho port /dev/null; echo boot 0001; sleep 5\n")
    path.chmod(0o755)


@pytest.mark.parametrize("kind", ["serial", "dxl"])
def test_emulate_link_never_replaces_an_existing_path(tmp_path, capsys, kind):
    for existing in ("file", "link"):
        path = tmp_path / f"{kind}-{existing}"
        if existing == "file":
            path.write_text("precious\n")
        else:
            path.symlink_to(tmp_path / "elsewhere")
        assert main(["emulate", kind, "--link", str(path)]) == 2
        err = capsys.readouterr().err
        assert f"--link (={path}) exists" in err and "replaces nothing" in err and err.count("\n") == 1
        assert os.path.lexists(path)
        assert path.read_text() == "precious\n" if existing == "file" else path.is_symlink()


def test_the_firmware_removes_only_its_own_link(tmp_path):
    from servoid.drivers.serial.emulator import FirmwareEmulator, FirmwareOptions

    link = tmp_path / "tty"
    with FirmwareEmulator(FirmwareOptions(link=link)) as emu:
        assert link.is_symlink() and emu.port == str(link)
    assert not os.path.lexists(link)
    with FirmwareEmulator(FirmwareOptions(link=link)):
        link.unlink()
        link.symlink_to("/dev/null")  # someone put another link there meanwhile
    assert os.readlink(link) == "/dev/null"


@pytest.fixture()
def expected_name() -> str:
    return build.firmware_binary().name


@ROOT_ONLY
def test_a_planted_program_in_a_foreign_cache_is_never_run(tmp_path, monkeypatch, expected_name):
    monkeypatch.setenv("SERVOID_CACHE", str(tmp_path / "a-file" / "cache"))  # cannot be created
    (tmp_path / "a-file").write_text("")
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    monkeypatch.setattr(build, "_fresh_dir", build._fresh_dir.__wrapped__)  # a new fresh folder for this test
    shared = tmp_path / f"servoid-{os.getuid()}"
    shared.mkdir(mode=0o777)
    marker = tmp_path / "ran"
    _plant(shared / expected_name, marker)
    (shared / f"{expected_name}.sha256").write_text(build._sha256(shared / expected_name) + "\n")
    os.chown(shared, NOBODY, NOBODY)  # someone else's folder, with someone else's program in it
    binary = build.firmware_binary()
    assert binary.parent != shared and binary.parent.stat().st_mode & 0o777 == 0o700
    out = subprocess.run([str(binary), "--help"], capture_output=True, text=True, timeout=10)
    assert "usage" in (out.stdout + out.stderr).lower() and not marker.exists()


@ROOT_ONLY
def test_a_program_servoid_did_not_build_is_built_anew(tmp_path, monkeypatch, expected_name):
    cache = tmp_path / "cache"
    monkeypatch.setenv("SERVOID_CACHE", str(cache))
    cache.mkdir(mode=0o755)  # ours, but made with a loose umask: tightened
    marker = tmp_path / "ran"
    planted = cache / expected_name
    _plant(planted, marker)
    (cache / f"{expected_name}.sha256").write_text(build._sha256(planted) + "\n")  # even with a forged hash
    os.chown(planted, NOBODY, NOBODY)
    binary = build.firmware_binary()
    assert binary == planted and binary.stat().st_uid == os.getuid() and cache.stat().st_mode & 0o777 == 0o700
    subprocess.run([str(binary), "--help"], capture_output=True, timeout=10)
    assert not marker.exists()
    # ours, but altered after the build: its hash no longer matches, so it is built again
    binary.write_bytes(binary.read_bytes() + b"\0")
    assert build.firmware_binary() == binary and build._ours(binary)


def test_a_cache_that_is_a_symlink_is_not_used(tmp_path, monkeypatch):
    real = tmp_path / "real"
    real.mkdir(mode=0o700)
    (tmp_path / "cache").symlink_to(real)
    assert build.private_dir(tmp_path / "cache") is None and build.private_dir(real) == real


def test_the_cli_prints_no_traceback_for_a_link_in_a_missing_folder(tmp_path):
    done = subprocess.run([sys.executable, "-m", "servoid", "emulate", "dxl", "--link", str(tmp_path / "no" / "x")],
                          capture_output=True, text=True, timeout=60)  # fmt: skip
    assert done.returncode == 2 and "Traceback" not in done.stderr and done.stderr.count("\n") == 1
