"""``servoid emulate KIND``: start a servo emulator so every driver path can be tried without hardware.

Each kind lives in its own module ``servoid/cli/_emulate_<kind>.py`` defining
``HELP`` (one line), ``register(parser)`` (adds the kind's options to its
sub-parser) and ``run(args) -> int``. A kind whose module is absent is simply
not offered.
"""

from __future__ import annotations

import argparse
import importlib

ORDER = 50

#: kind -> module, in the order shown by --help
KINDS = {
    "serial": "servoid.cli._emulate_serial",
    "can": "servoid.cli._emulate_can",
    "dxl": "servoid.cli._emulate_dxl",
}

DESCRIPTION = """\
Start an emulated servo, with the backlash plant behind it, and print where
to reach it (a pseudo-terminal, a CAN channel). In another terminal, point a
driver at it, for example:

  servoid emulate serial          # prints e.g. serial:///dev/pts/5
  servoid identify --driver serial:///dev/pts/5

The emulator runs until Ctrl-C.
"""


def register(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    p = sub.add_parser(
        "emulate", help="start a servo emulator (serial firmware, CAN drive, Dynamixel)",
        description=DESCRIPTION, formatter_class=argparse.RawDescriptionHelpFormatter,
    )  # fmt: skip
    kinds = p.add_subparsers(dest="kind", metavar="KIND", title="emulators")
    kinds.required = True
    for kind, module_name in KINDS.items():
        try:
            module = importlib.import_module(module_name)
        except ModuleNotFoundError as exc:
            if exc.name == module_name:
                continue
            raise
        kp = kinds.add_parser(kind, help=module.HELP, description=getattr(module, "DESCRIPTION", module.HELP),
                              formatter_class=argparse.RawDescriptionHelpFormatter)  # fmt: skip
        module.register(kp)
        kp.set_defaults(handler=module.run)
