"""The ``servoid`` command line.

Each subcommand lives in its own module of this package and is found at start
up: a module ``servoid/cli/<name>.py`` that defines ``ORDER`` (its place in
``--help``) and ``register(subparsers)``, which adds its parser and sets
``handler`` to a function ``(argparse.Namespace) -> int``. Modules whose name
starts with ``_`` are helpers. The handlers are thin: they parse into the same
config objects the API takes and call the libraries.

Starting fast: a command module imports only what its parser needs (plain
Python: the defaults, the paper's numbers, the effect names), and the
libraries inside its handler; and ``servoid CMD ...`` imports only the
module of CMD (the others stand in by name), so ``--help`` answers before
NumPy would have loaded (``benchmarks/startup.py``).

Exit status: 0 success; 2 bad input (a one-line message naming the problem,
never a traceback); 1 any other servoid error (a servo that stopped answering,
an estimator that diverged); 3 an alarm raised by ``servoid monitor
--fail-on-alarm``; 130 interrupted.

Before a handler runs, :func:`main` checks what every command takes alike:
each text argument is valid Unicode of bounded length, each number finite and
within :data:`servoid.limits.MAX_MAGNITUDE` (:func:`check_arguments`).
SIGTERM (``kill``, systemd, docker) and SIGHUP (a closed terminal) stop a
command as Ctrl-C does, so every way out switches the servo's torque off;
text that the terminal cannot show is escaped, never a UnicodeEncodeError.
"""

from __future__ import annotations

import argparse
import contextlib
import importlib
import math
import os
import pkgutil
import signal
import sys
import threading
from collections.abc import Iterator, Sequence
from types import FrameType, ModuleType
from typing import Any, NoReturn

from servoid import __version__, limits
from servoid.errors import ConfigError, DataError, ModelError, ServoidError

__all__ = ["main", "build_parser", "command_names", "Parser", "check_arguments", "STOP_SIGNALS", "COMPILE_NOTE"]

DESCRIPTION = """\
Identify servo drives with gear backlash while they run on the bench.

servoid excites a servo with a safe bounded signal, estimates a model online
(the MRGIA of Dong, Tan & Tan) from the streamed encoder readings, refines it
offline and exports the backlash parameters a compensator needs.
"""

EPILOG = """\
examples:
  servoid identify                      the paper's simulated servo, 5000 samples
  servoid identify --snr 43 --samples 20000
  servoid identify --data bench.csv --na 2 --nb 0 --delay 1 --unit rad
  servoid <command> --help              options of one command
"""

BAD_INPUT = (ConfigError, DataError, ModelError)

#: Said on stderr when numba starts compiling: the first run after an install compiles the kernels
#: (measured by benchmarks/startup.py on a 2-core machine), later runs load them from numba's cache.
COMPILE_NOTE = "compiling servoid's estimator once (numba, 15-30 s; later runs load it from the cache)..."

#: Signals that stop a command as Ctrl-C does (SIGKILL cannot be caught: the servo's own watchdog covers it).
STOP_SIGNALS = tuple(getattr(signal, name) for name in ("SIGTERM", "SIGHUP") if hasattr(signal, name))


class Parser(argparse.ArgumentParser):
    """An argument parser whose errors are one line (``servoid identify: error: ...``) and exit status 2."""

    def error(self, message: str) -> NoReturn:
        """Print ``message`` as one line naming the command, and exit with status 2."""
        flat = " ".join(message.split())
        self.exit(2, f"{self.prog}: error: {flat} (see {self.prog} --help)\n")


def command_names() -> list[str]:
    """The subcommands, found without importing them."""
    return sorted(info.name for info in pkgutil.iter_modules(__path__) if not info.name.startswith("_"))


def _command_modules(names: Sequence[str]) -> list[ModuleType]:
    mods = [importlib.import_module(f"{__name__}.{name}") for name in names]
    return sorted(mods, key=lambda m: (getattr(m, "ORDER", 100), m.__name__))


def build_parser(argv: Sequence[str] | None = None) -> argparse.ArgumentParser:
    """The argument parser with every subcommand registered.

    Parameters
    ----------
    argv : sequence of str, optional
        The arguments it will parse: when they name a command, only that
        command's module is imported and the others stand in by name (a
        faster start; the parse is the same).
    """
    parser = Parser(
        prog="servoid",
        description=DESCRIPTION,
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--version", action="version", version=f"servoid {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", title="commands")
    names = command_names()
    chosen = _chosen(argv, names)
    for mod in _command_modules([chosen] if chosen else names):
        mod.register(sub)
    for name in names:
        if name != chosen and chosen is not None:
            sub.add_parser(name)  # named, for argparse's list of choices; never parsed
    return parser


def _chosen(argv: Sequence[str] | None, names: Sequence[str]) -> str | None:
    """The command ``argv`` names: its first word, when it is one (options before it are the top level's)."""
    words = [a for a in (argv or ()) if not a.startswith("-")]
    return words[0] if words and words[0] in names else None


def check_arguments(args: argparse.Namespace) -> None:
    """What every command's arguments must be, checked before any work.

    Text (and paths) valid Unicode of at most :data:`~servoid.limits.MAX_TEXT_CHARS`
    characters: a lone surrogate (bytes of the command line that are not UTF-8)
    could be written to no file and shown on no terminal. Floats not NaN, and
    finite ones within :data:`~servoid.limits.MAX_MAGNITUDE` (an infinity,
    which ``1e400`` reads as, is left to the option: ``--max-step inf`` means
    no limit, ``--rate inf`` is refused by its command).

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line.

    Raises
    ------
    ConfigError
        Naming the option and its value.
    """
    for dest, value in vars(args).items():
        if dest in ("handler", "command", "kind"):
            continue
        name = "--" + dest.replace("_", "-")
        values = value if isinstance(value, list) else [value]
        for item in values:
            if isinstance(item, (str, os.PathLike)):
                limits.text(name, os.fspath(item))
            elif isinstance(item, float):
                if math.isnan(item):
                    raise ConfigError(f"{name} (=nan) must be a number")
                if math.isfinite(item):  # an infinity means "none" to some options (--max-step); the rest refuse it
                    limits.bounded_real(name, item)


@contextlib.contextmanager
def _stop_signals_as_interrupt() -> Iterator[None]:
    """SIGTERM and SIGHUP raise KeyboardInterrupt inside the block (the main thread only; restored after)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def interrupt(signum: int, frame: FrameType | None) -> None:  # noqa: ARG001 - a signal handler's signature
        raise KeyboardInterrupt(signal.Signals(signum).name)

    previous = {sig: signal.signal(sig, interrupt) for sig in STOP_SIGNALS}
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)


def _escaping_output() -> None:
    """Let stdout and stderr escape what they cannot encode (a lone surrogate in a path) instead of raising."""
    for stream in (sys.stdout, sys.stderr):
        reconfigure: Any = getattr(stream, "reconfigure", None)
        if reconfigure is not None:
            with contextlib.suppress(ValueError, OSError):
                reconfigure(errors="backslashreplace")


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; return the exit status."""
    _escaping_output()
    if argv is None:
        argv = sys.argv[1:]
    parser = build_parser(argv)
    args = parser.parse_args(argv)
    handler = getattr(args, "handler", None)
    if handler is None:
        print("servoid: error: name a command (servoid --help lists them)", file=sys.stderr)
        return 2
    from servoid.ident import _jit

    _jit.on_first_compile(lambda: print(f"servoid {args.command}: {COMPILE_NOTE}", file=sys.stderr, flush=True))
    try:
        check_arguments(args)
        with _stop_signals_as_interrupt():
            return int(handler(args) or 0)
    except BAD_INPUT as exc:
        print(f"servoid {args.command}: error: {_one_line(exc)}", file=sys.stderr)
        return 2
    except ServoidError as exc:
        print(f"servoid {args.command}: {type(exc).__name__}: {_one_line(exc)}", file=sys.stderr)
        return 1
    except KeyboardInterrupt as exc:
        why = f" ({exc.args[0]})" if exc.args else ""
        print(f"servoid {args.command}: interrupted{why}", file=sys.stderr)
        return 130


def _one_line(exc: BaseException) -> str:
    """The message on one line (a compiler's output, a vendor's multi-line error)."""
    return " | ".join(line.strip() for line in str(exc).splitlines() if line.strip())
