"""Where servoid will write, checked before any work starts: one place for the checks and their messages.

A command that would fail to write its result after minutes of measuring, or
that would replace a file the user did not ask to replace, stops at once
with one line naming the option, the path and what to do:

* a file output (``export --out FILE``, ``excite --out``, ``--plot``) that
  exists is refused unless the command's overwrite flag (``--force``) is
  given; a directory there is refused always;
* an output folder (``identify --out DIR``) may exist (servoid replaces the
  files it writes there, by their fixed names) but must be a folder;
* a new link (``emulate --link PATH``) is never put over an existing path;
* every place written to must be writable: tried with a probe file that is
  removed at once (``os.access`` is no answer for root, nor on ``/proc``).
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Iterable
from pathlib import Path

from servoid.errors import ConfigError

__all__ = ["output_file", "output_dir", "new_link", "remove_own_link"]


def _nearest_existing(path: Path) -> Path:
    for candidate in (path, *path.parents):
        if os.path.lexists(candidate):
            return candidate
    return Path.cwd()


def _writable_folder(folder: Path, option: str, path: Path) -> None:
    """``folder`` (which exists, or whose nearest existing ancestor will hold it) takes new files."""
    base = _nearest_existing(folder)
    if not base.is_dir():
        raise ConfigError(f"{option} (={path}): {base} is a file, not a folder; choose another path")
    try:
        fd, probe = tempfile.mkstemp(dir=base, prefix=".servoid-write-test-")
    except OSError as exc:
        raise ConfigError(f"{option} (={path}): cannot write in {base} ({exc.strerror or exc})") from None
    os.close(fd)
    os.unlink(probe)


def output_file(path: str | os.PathLike[str], *, option: str, force: bool = False, force_flag: str = "--force") -> Path:
    """``path`` as a file servoid may write: not a folder, not existing unless ``force``, in a writable folder.

    Parameters
    ----------
    path : path-like
        The file the command will write.
    option : str
        The option that named it (``--out``), for the message.
    force : bool
        Whether the user asked to replace an existing file.
    force_flag : str
        The option that asks for it, named in the message.

    Raises
    ------
    ConfigError
        A folder, an existing file without ``force``, something else than a
        regular file at the path, or a folder servoid cannot write in.
    """
    p = Path(path)
    if p.is_dir():
        raise ConfigError(f"{option} (={p}) is a folder; name a file")
    if os.path.lexists(p):
        if not force:
            raise ConfigError(f"{option} (={p}) exists; add {force_flag} to replace it")
        if not p.is_file():
            raise ConfigError(f"{option} (={p}) exists and is not a regular file; not replacing it")
    _writable_folder(p.parent, option, p)
    return p


def output_dir(path: str | os.PathLike[str], *, option: str, files: Iterable[str] = ()) -> Path:
    """``path`` as a folder servoid may write ``files`` into (created later if it does not exist).

    Parameters
    ----------
    path : path-like
        The folder.
    option : str
        The option that named it (``--out``), for the message.
    files : iterable of str
        Names of the files the command writes there; none of them may be a folder.

    Raises
    ------
    ConfigError
        The path is a file, a file to be written is a folder, or the folder
        cannot be written in.
    """
    p = Path(path)
    if os.path.lexists(p) and not p.is_dir():
        raise ConfigError(f"{option} (={p}) exists and is not a folder; name a folder for the outputs")
    for name in files:
        if (p / name).is_dir():
            raise ConfigError(f"{option} (={p}): {p / name} is a folder, where servoid writes a file")
    _writable_folder(p, option, p)
    return p


def new_link(path: str | os.PathLike[str], *, option: str) -> Path:
    """``path`` as the place of a new symbolic link: nothing may exist there (not even a link).

    Parameters
    ----------
    path : path-like
        Where the link is to be made.
    option : str
        The option that named it (``--link``), for the message.

    Raises
    ------
    ConfigError
        Something exists at ``path``, or its folder does not exist or cannot be written in.
    """
    p = Path(path)
    if os.path.lexists(p):
        kind = "a link" if p.is_symlink() else ("a folder" if p.is_dir() else "a file")
        raise ConfigError(f"{option} (={p}) exists ({kind}); servoid replaces nothing: remove it or name another path")
    if not p.parent.is_dir():
        raise ConfigError(f"{option} (={p}): the folder {p.parent} does not exist")
    _writable_folder(p.parent, option, p)
    return p


def remove_own_link(path: str | os.PathLike[str], target: str) -> None:
    """Remove the link at ``path`` if it still points to ``target`` (what servoid made), else leave it.

    Parameters
    ----------
    path : path-like
        The link servoid made.
    target : str
        What it pointed to.
    """
    p = Path(path)
    try:
        if p.is_symlink() and os.readlink(p) == target:
            p.unlink()
    except OSError:
        pass
