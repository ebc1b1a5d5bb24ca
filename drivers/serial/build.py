"""Compile the reference firmware for the host, once, into a cache.

The C sources ship with servoid (``firmware/*.c``, ``firmware/host/*.c``);
the first emulator start compiles them with the system's C compiler (``$CC``,
else ``gcc``, else ``cc``) into ``$SERVOID_CACHE`` (default
``~/.cache/servoid``), named by a hash of the sources, the compiler and the
flags, so an edited source or another compiler builds anew and concurrent
first starts do not trip over each other (each writes its own temporary file
and renames it into place).
"""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import tempfile
from pathlib import Path

from servoid.errors import DriverError, MissingDependency

__all__ = ["FIRMWARE_DIR", "firmware_sources", "firmware_binary", "cache_dir", "CFLAGS"]

FIRMWARE_DIR = Path(__file__).resolve().parent / "firmware"

#: Strict C99 with warnings as errors, so the firmware stays portable; no
#: contraction of a*b+c into FMA, so the plant rounds as NumPy does.
CFLAGS = ("-std=c99", "-O2", "-Wall", "-Wextra", "-Wpedantic", "-Werror", "-ffp-contract=off")


def firmware_sources() -> list[Path]:
    """The C files of the host build: the portable core and the host HAL."""
    return sorted(FIRMWARE_DIR.glob("*.c")) + sorted((FIRMWARE_DIR / "host").glob("*.c"))


def _headers() -> list[Path]:
    return sorted(FIRMWARE_DIR.glob("*.h")) + sorted((FIRMWARE_DIR / "host").glob("*.h"))


def cache_dir() -> Path:
    """Where compiled firmware is kept (``$SERVOID_CACHE``, else ``$XDG_CACHE_HOME/servoid``, else ``~/.cache/servoid``)."""
    if os.environ.get("SERVOID_CACHE"):
        return Path(os.environ["SERVOID_CACHE"])
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "servoid"


def _compiler() -> str:
    for candidate in (os.environ.get("CC"), "gcc", "cc"):
        if candidate and shutil.which(candidate):
            return str(shutil.which(candidate))
    raise MissingDependency(
        "the emulated serial servo runs the reference firmware, built with a C compiler, and none was found "
        "(set CC, or install gcc: apt-get install gcc)"
    )


def firmware_binary() -> Path:
    """Path of the compiled host firmware, building it first if needed.

    Raises
    ------
    MissingDependency
        No C compiler.
    DriverError
        The compiler failed (its message is included).
    """
    cc = _compiler()
    digest = hashlib.sha256()
    for part in (cc, *CFLAGS):
        digest.update(part.encode() + b"\0")
    for path in firmware_sources() + _headers():
        digest.update(path.name.encode() + b"\0" + path.read_bytes())
    target_dir = cache_dir()
    try:
        target_dir.mkdir(parents=True, exist_ok=True)
    except OSError:
        target_dir = Path(tempfile.gettempdir()) / f"servoid-{os.getuid()}"
        target_dir.mkdir(parents=True, exist_ok=True)
    target = target_dir / f"servoid-bench-fw-{digest.hexdigest()[:16]}"
    if target.exists():
        return target
    tmp = target.with_name(f"{target.name}.{os.getpid()}.tmp")
    cmd = [cc, *CFLAGS, "-o", str(tmp), *map(str, firmware_sources()), "-lm"]
    done = subprocess.run(cmd, capture_output=True, text=True)
    if done.returncode != 0:
        tmp.unlink(missing_ok=True)
        raise DriverError(f"building the firmware failed ({' '.join(cmd)}):\n{done.stderr.strip()}")
    os.replace(tmp, target)
    return target
