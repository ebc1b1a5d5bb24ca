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
"""

from __future__ import annotations

import argparse
import importlib
import pkgutil
import sys
from collections.abc import Sequence
from types import ModuleType

from servoid import __version__
from servoid.errors import ConfigError, DataError, ModelError, ServoidError

__all__ = ["main", "build_parser"]

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
    parser = argparse.ArgumentParser(
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


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; return the exit status."""
    if argv is None:
        argv = sys.argv[1:]
    parser = build_parser(argv)
    args = parser.parse_args(argv)
    handler = getattr(args, "handler", None)
    if handler is None:
        parser.print_help(sys.stderr)
        return 2
    from servoid.ident import _jit

    _jit.on_first_compile(lambda: print(f"servoid {args.command}: {COMPILE_NOTE}", file=sys.stderr, flush=True))
    try:
        return int(handler(args) or 0)
    except BAD_INPUT as exc:
        print(f"servoid {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except ServoidError as exc:
        print(f"servoid {args.command}: {type(exc).__name__}: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print(f"servoid {args.command}: interrupted", file=sys.stderr)
        return 130
