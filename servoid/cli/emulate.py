"""``servoid emulate KIND``: start a servo emulator so every driver path can be tried without hardware.

Each kind lives in its own module ``servoid/cli/_emulate_<kind>.py`` defining
``register(parser)`` (adds the kind's options to its sub-parser) and
``run(args) -> int``; its one-line help is in :data:`KINDS`. A kind's module
(and its vendor library) is imported only when that kind is asked for, so
``servoid emulate --help`` starts at once; a kind whose library is missing
says which extra to install.
"""

from __future__ import annotations

import argparse
import importlib
from collections.abc import Sequence
from typing import Any

ORDER = 50

#: kind -> (module, one line for --help), in the order shown by --help
KINDS = {
    "serial": ("servoid.cli._emulate_serial",
               "the serial bench servo: reference C firmware + a simulated servo behind its HAL on a pseudo-terminal"),
    "can": ("servoid.cli._emulate_can", "a simulated CAN servo drive (CANopen CiA 402 or ODrive CAN Simple)"),
    "dxl": ("servoid.cli._emulate_dxl", "ROBOTIS Dynamixel X-series servos (Protocol 2.0) on a pseudo-terminal"),
    "feetech": ("servoid.cli._emulate_feetech", "Feetech STS servos (STS3215, SCS/STS protocol) on a pseudo-terminal"),
}  # fmt: skip
DESCRIPTION = """\
Start an emulated servo, with a servo behind it (a physical twin by default;
--servo NAME[?K=V&...] picks another twin, its parameters, or the
pseudo-Wiener model), and print where to reach it (a pseudo-terminal, a CAN
channel). In another terminal, point a driver at it, for example:

  servoid emulate serial          # prints e.g. serial:///dev/pts/5
  servoid identify --driver serial:///dev/pts/5

The emulator runs until Ctrl-C. It takes real-time priority (SCHED_FIFO,
above a live identify's sampling loop) where the system permits it (root,
CAP_SYS_NICE, or an RLIMIT_RTPRIO), as the emulators a live session starts
do, and runs at normal priority otherwise; dxl, feetech and can say which.
"""


class _KindParser(argparse.ArgumentParser):
    """A kind's parser whose options come from its module, imported when this kind is parsed (or its --help asked)."""

    module_name: str | None = None

    def parse_known_args(  # type: ignore[override]
        self, args: Sequence[str] | None = None, namespace: argparse.Namespace | None = None
    ) -> tuple[argparse.Namespace, list[str]]:
        if self.module_name is not None:
            name, self.module_name = self.module_name, None
            module = _import_kind(name, self)
            if hasattr(module, "DESCRIPTION"):
                self.description = module.DESCRIPTION
            module.register(self)
            self.set_defaults(handler=module.run)
        return super().parse_known_args(args, namespace)


def _import_kind(name: str, parser: argparse.ArgumentParser) -> Any:
    from servoid.drivers.registry import extra_for

    try:
        return importlib.import_module(name)
    except ModuleNotFoundError as exc:
        missing = (exc.name or "").split(".")[0]
        extra = extra_for(missing)
        if extra is None:
            raise
        parser.error(f"this emulator needs the module {missing!r}: pip install 'servoid[{extra}]'")


def register(sub: argparse._SubParsersAction) -> None:  # type: ignore[type-arg]
    p = sub.add_parser(
        "emulate", help="start a servo emulator (serial firmware, CAN drive, Dynamixel, Feetech)",
        description=DESCRIPTION, formatter_class=argparse.RawDescriptionHelpFormatter,
    )  # fmt: skip
    kinds = p.add_subparsers(dest="kind", metavar="KIND", title="emulators", parser_class=_KindParser)
    kinds.required = True
    for kind, (module_name, summary) in KINDS.items():
        kp = kinds.add_parser(kind, help=summary, description=summary,
                              formatter_class=argparse.RawDescriptionHelpFormatter)  # fmt: skip
        kp.module_name = module_name
