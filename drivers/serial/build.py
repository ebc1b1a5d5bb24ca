"""Compile the reference firmware for the host, once, into a cache.

The C sources ship with servoid (``firmware/*.c``, ``firmware/host/*.c``);
the first emulator start compiles them with the system's C compiler (``$CC``,
else ``gcc``, else ``cc``) into ``$SERVOID_CACHE`` (default
``~/.cache/servoid``), named by a hash of the sources, the compiler and the
flags, so an edited source or another compiler builds anew and concurrent
first starts do not trip over each other (each writes its own temporary file
and renames it into place).

servoid runs only what it built itself. The cache must be a private folder:
created owner-only (0700), or, when it exists, checked -- a real folder (not
a symlink), owned by this user, writable by nobody else (servoid tightens
its own folder's mode, never another's), in a parent nobody else can
rename it in (or one with the sticky bit, like /tmp). A folder that fails
is not used: next comes ``$TMPDIR/servoid-<uid>`` under the same checks,
and last a fresh private folder of this process (``mkdtemp``), removed at
exit. Beside each binary lies the SHA-256 of what was built; a binary is
run only when it is a regular file owned by this user, writable by nobody
else, and still has that hash -- anything else is built again.
"""

from __future__ import annotations

import atexit
import functools
import hashlib
import os
import shutil
import stat
import subprocess
import tempfile
from pathlib import Path

from servoid.errors import DriverError, MissingDependency

__all__ = ["FIRMWARE_DIR", "firmware_sources", "firmware_binary", "cache_dir", "private_dir", "CFLAGS"]

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


def _writable_by_others(mode: int) -> bool:
    return bool(mode & (stat.S_IWGRP | stat.S_IWOTH))


def private_dir(path: Path) -> Path | None:
    """``path`` as a folder only this user can change (created 0700), or None where that cannot be made sure.

    Parameters
    ----------
    path : Path
        The folder.
    """
    try:
        path.mkdir(mode=0o700, parents=True, exist_ok=True)
        info = os.lstat(path)
        if not stat.S_ISDIR(info.st_mode) or info.st_uid != os.getuid():
            return None  # a symlink, a file, or someone else's folder
        if info.st_mode & 0o077:
            os.chmod(path, 0o700)  # our own folder, made with a looser umask: tighten it
            if os.lstat(path).st_mode & 0o077:
                return None
        parent = os.stat(path.parent)
        if _writable_by_others(parent.st_mode) and not parent.st_mode & stat.S_ISVTX:
            return None  # someone else could rename our folder away and put theirs in its place
    except OSError:
        return None
    return path


@functools.lru_cache(maxsize=1)
def _fresh_dir() -> Path:
    """A private folder of this process alone, removed at exit."""
    path = Path(tempfile.mkdtemp(prefix="servoid-fw-"))
    atexit.register(shutil.rmtree, path, ignore_errors=True)
    return path


def _build_dir() -> Path:
    for candidate in (cache_dir(), Path(tempfile.gettempdir()) / f"servoid-{os.getuid()}"):
        if private_dir(candidate) is not None:
            return candidate
    return _fresh_dir()


def _sha256(path: Path) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 16), b""):
            digest.update(chunk)
    return digest.hexdigest()


def _ours(binary: Path) -> bool:
    """Whether ``binary`` is what servoid built: a regular file of ours, writable by nobody else, with its hash."""
    try:
        info = os.lstat(binary)
        recorded = binary.with_name(binary.name + ".sha256").read_text(encoding="ascii").strip()
    except (OSError, UnicodeDecodeError):
        return False
    if not stat.S_ISREG(info.st_mode) or info.st_uid != os.getuid() or _writable_by_others(info.st_mode):
        return False
    return _sha256(binary) == recorded


def firmware_binary() -> Path:
    """Path of the compiled host firmware, building it first if needed (see the module docstring).

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
    target = _build_dir() / f"servoid-bench-fw-{digest.hexdigest()[:16]}"
    if _ours(target):
        return target
    tmp = target.with_name(f"{target.name}.{os.getpid()}.tmp")
    cmd = [cc, *CFLAGS, "-o", str(tmp), *map(str, firmware_sources()), "-lm"]
    done = subprocess.run(cmd, capture_output=True, text=True)
    if done.returncode != 0:
        tmp.unlink(missing_ok=True)
        raise DriverError(f"building the firmware failed ({' '.join(cmd)}):\n{done.stderr.strip()}")
    os.chmod(tmp, 0o700)
    recorded = target.with_name(f"{target.name}.sha256.{os.getpid()}.tmp")
    recorded.write_text(_sha256(tmp) + "\n", encoding="ascii")
    os.replace(tmp, target)
    os.replace(recorded, target.with_name(target.name + ".sha256"))
    return target
