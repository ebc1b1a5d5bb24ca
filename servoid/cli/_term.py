"""Terminal output for the command line: progress bars and tables on stderr/stdout via rich.

Everything meant for a human goes through here, so ``--json`` runs can keep
stdout for the one JSON object. The consoles never read markup in what they
print (a unit, a path, a driver URL are the user's text: ``--unit '[/]'`` is
a unit, not a closing tag); styles are given as styles. rich is imported on
first use (``stdout`` and ``stderr`` are made then), so that ``servoid
--help`` starts without it.
"""

from __future__ import annotations

import contextlib
import math
import os
import sys
import time
from collections.abc import Callable, Iterator, Sequence
from typing import TYPE_CHECKING, Any, TextIO

if TYPE_CHECKING:  # pragma: no cover
    from rich.console import Console

    #: The consoles for stdout and stderr, made on first use.
    stdout: Console
    stderr: Console

__all__ = ["stdout", "stderr", "progress", "live_progress", "table", "print_json", "warn"]

#: Least wall seconds between two drawings of a live bar on a terminal (:func:`live_progress`; a session calls it
#: every 0.25 s, so each call draws): at most 5 a second, against rich's 10 from a thread of its own.
REFRESH_EVERY_S = 0.2

#: Width when writing to a file or a pipe (a log, CI): rich would assume 80
#: columns and squeeze the tables; ``COLUMNS`` still wins when set.
PIPE_WIDTH = 160


def _console(stream: TextIO, *, to_stderr: bool) -> Console:
    from rich.console import Console

    # no file=: rich looks sys.stdout/stderr up at each write, so a stream
    # swapped later (pytest's capture, a redirect) is still the one written to
    width = None if stream.isatty() or os.environ.get("COLUMNS") else PIPE_WIDTH
    return Console(stderr=to_stderr, highlight=False, markup=False, width=width)


def __getattr__(name: str) -> Any:
    """``stdout`` and ``stderr``, made on first use."""
    if name not in ("stdout", "stderr"):
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    console = _console(sys.stdout if name == "stdout" else sys.stderr, to_stderr=name == "stderr")
    globals()[name] = console
    return console


def _console_named(name: str) -> Console:
    """``stdout`` or ``stderr`` from inside this module (a bare global name does not reach ``__getattr__``)."""
    made: Console | None = globals().get(name)
    return made if made is not None else __getattr__(name)


@contextlib.contextmanager
def progress(label: str, total: int, *, enabled: bool = True) -> Iterator[Callable[[int, int], None]]:
    """A progress bar on stderr; yields ``update(done, total)``. Disabled: a no-op callback."""
    if not enabled:
        yield lambda done, total: None
        return
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn

    columns = (TextColumn("{task.description}", markup=False), BarColumn(), MofNCompleteColumn(), TimeRemainingColumn())
    with Progress(*columns, console=_console_named("stderr"), transient=True) as bar:
        task = bar.add_task(label, total=total)

        def update(done: int, total: int) -> None:
            bar.update(task, completed=done, total=total)

        yield update


@contextlib.contextmanager
def live_progress(label: str, total: int | None) -> Iterator[Callable[[int, str], None]]:
    """A progress bar with a status line on stderr; yields ``update(done, text)``.

    rich's own refresh thread would build the bar ten times a second beside a live session's sampling
    loop, at the default priority and holding the interpreter lock the loop needs (off a terminal it
    set off the full garbage collection that held a live identify's loop 391 ms:
    :mod:`servoid.drivers.realtime`). So no thread: off a terminal (a pipe, a file, a test's capture,
    where rich shows none of a transient bar) a no-op callback; on one the bar is drawn by ``update``
    itself, on the caller's thread (a session's loop calls it every ``progress_every_s``, 0.25 s, just
    after a slot), at most every :data:`REFRESH_EVERY_S`.
    """
    console = _console_named("stderr")
    if not console.is_terminal:
        yield lambda done, text: None
        return
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn

    columns = (TextColumn("{task.description}", markup=False), BarColumn(), MofNCompleteColumn(),
               TextColumn("{task.fields[text]}", markup=False))  # fmt: skip
    with Progress(*columns, console=console, transient=True, auto_refresh=False) as bar:
        task = bar.add_task(label, total=total, text="")
        drawn = [-math.inf]  # when the bar was last drawn (time.monotonic)

        def update(done: int, text: str) -> None:
            bar.update(task, completed=done, text=text)
            now = time.monotonic()
            if now - drawn[0] >= REFRESH_EVERY_S:
                drawn[0] = now
                bar.refresh()

        yield update


def table(title: str, columns: Sequence[str], rows: Sequence[Sequence[Any]], *, console: Console | None = None) -> None:
    """Print a table; numbers are right-aligned."""
    from rich.table import Table
    from rich.text import Text

    tab = Table(title=Text(title), title_justify="left")
    for i, col in enumerate(columns):
        tab.add_column(Text(col), justify="left" if i == 0 else "right")
    for row in rows:
        tab.add_row(*(Text(str(c)) for c in row))
    (console or _console_named("stdout")).print(tab)


def print_json(obj: Any) -> None:
    """Write exactly one JSON object to stdout."""
    from servoid.ident.serialise import dumps

    sys.stdout.write(dumps(obj, indent=2) + "\n")
    sys.stdout.flush()


def warn(message: str) -> None:
    """A warning line on stderr."""
    from rich.text import Text

    _console_named("stderr").print(Text.assemble(("warning:", "yellow"), " ", message))
