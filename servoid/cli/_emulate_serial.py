"""``servoid emulate serial``: the reference firmware, built for this machine, serving a pseudo-terminal."""

from __future__ import annotations

import argparse
import signal
import time

from servoid.cli import _term
from servoid.drivers.model_plant import MODEL_PLANT
from servoid.errors import ConfigError
from servoid.ident.paper import PAPER_PLANT
from servoid.output_paths import new_link

DESCRIPTION = """\
Build the reference firmware of the serial bench controller (C, in
servoid/drivers/serial/firmware/) for this machine with the system's C
compiler (once; cached in ~/.cache/servoid), link it to a simulated motor and
gear with backlash, and run it on a pseudo-terminal. It prints the port; in
another terminal:

  servoid identify --driver serial:///dev/pts/N

The plant is the bench servo (a1 -0.8, a2 0.15, b0 0.35, delay 1, m2 1,
c1 0.02 rad, c2 0.03 rad) seen through a 16-bit encoder; --plant paper gives
the paper's Section 4 plant instead (excite it with --amplitude 2.4).
The protocol is in docs/serial-protocol.md. Runs until Ctrl-C.
"""

PLANTS = {"bench": MODEL_PLANT, "paper": PAPER_PLANT}


def register(p: argparse.ArgumentParser) -> None:
    p.add_argument("--plant", choices=sorted(PLANTS), default="bench", help="simulated plant (default bench)")
    p.add_argument("--cpr", type=int, default=65536, metavar="COUNTS",
                   help="encoder counts per revolution (default 65536)")  # fmt: skip
    p.add_argument("--noise", type=float, default=0.0, metavar="RAD",
                   help="encoder noise standard deviation in rad (default 0)")  # fmt: skip
    p.add_argument("--link", metavar="PATH",
                   help="also make PATH a symlink to the port (a stable name); PATH must not exist: nothing is "
                        "replaced, and the link is removed at exit if it still points to the port")  # fmt: skip
    faults = p.add_argument_group("fault injection")
    faults.add_argument("--flip", type=float, default=0.0, metavar="P",
                        help="probability per byte of a flipped bit, both directions (default 0)")  # fmt: skip
    faults.add_argument("--drop", type=float, default=0.0, metavar="P",
                        help="probability that a reply is lost (default 0)")  # fmt: skip
    faults.add_argument("--seed", type=int, default=0, help="seed of the noise and the faults (default 0)")


def _interrupt(signum: int, frame: object) -> None:
    raise KeyboardInterrupt


def run(args: argparse.Namespace) -> int:
    from servoid.drivers.serial.emulator import FirmwareEmulator, FirmwareOptions

    for name in ("flip", "drop"):
        value = getattr(args, name)
        if not 0.0 <= value <= 1.0:
            raise ConfigError(f"--{name} (={value!r}) must lie in [0, 1]")
    if args.link is not None:
        new_link(args.link, option="--link")
    options = FirmwareOptions(
        model=PLANTS[args.plant], counts_per_rev=args.cpr, noise=args.noise, seed=args.seed,
        flip_tx=args.flip, flip_rx=args.flip, drop=args.drop, link=args.link,
    )  # fmt: skip
    out = _term.stdout
    with FirmwareEmulator(options) as emu:
        out.print(f"servoid emulate serial: firmware servoid-bench/1.0 (boot {emu.boot_id:04x}) on {emu.port}")
        m = options.model
        out.print(f"  plant    {args.plant}: a={m.a} b={m.b} delay={m.delay} m2={m.m2:g} c1={m.c1:g} c2={m.c2:g} rad, "
                  f"encoder {args.cpr} counts/rev")  # fmt: skip
        out.print(f"  url      {emu.url}")
        amplitude = "" if args.plant == "bench" else " --amplitude 2.4"
        out.print(f"  try      servoid identify --driver {emu.url}{amplitude}")
        out.print("Ctrl-C to stop.", highlight=False)
        signal.signal(signal.SIGTERM, _interrupt)  # `kill` stops it as cleanly as Ctrl-C
        try:
            while emu.running:
                time.sleep(0.2)
                for line in emu.events():  # the watchdog dropping the torque, as the firmware says it
                    _term.stderr.print(line, soft_wrap=True)
        except KeyboardInterrupt:
            pass
        status = "stopped" if emu.running else "the firmware exited"
    out.print(f"servoid emulate serial: {status}")
    return 0
