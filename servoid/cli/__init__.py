"""The ``servoid`` command line.

Each subcommand lives in its own module of this package and is found at start
up: a module ``servoid/cli/<name>.py`` that defines ``ORDER`` (its place in
``--help``) and ``register(subparsers)``, which adds its parser and sets
``handler`` to a function ``(argparse.Namespace) -> int``. Modules whose name
starts with ``_`` are helpers. The handlers are thin: they parse into the same
config objects the API takes and call the libraries.

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


def _command_modules() -> list[ModuleType]:
    mods = []
    for info in pkgutil.iter_modules(__path__):
        if not info.name.startswith("_"):
            mods.append(importlib.import_module(f"{__name__}.{info.name}"))
    return sorted(mods, key=lambda m: (getattr(m, "ORDER", 100), m.__name__))


def build_parser() -> argparse.ArgumentParser:
    """The argument parser with every subcommand registered."""
    parser = argparse.ArgumentParser(
        prog="servoid",
        description=DESCRIPTION,
        epilog=EPILOG,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--version", action="version", version=f"servoid {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", title="commands")
    for mod in _command_modules():
        mod.register(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; return the exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)
    handler = getattr(args, "handler", None)
    if handler is None:
        parser.print_help(sys.stderr)
        return 2
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
