"""``servoid emulate serial``: the reference firmware, built for this machine, serving a pseudo-terminal."""

from __future__ import annotations

import argparse
import signal
import time

from servoid.cli import _term
from servoid.drivers.servo_facts import SERVO_NAMES
from servoid.errors import ConfigError
from servoid.output_paths import new_link

DESCRIPTION = """\
Build the reference firmware of the serial bench controller (C, in
servoid/drivers/serial/firmware/) for this machine with the system's C
compiler (once; cached in ~/.cache/servoid), link it to a simulated servo
behind its HAL, and run it on a pseudo-terminal. It prints the port; in
another terminal:

  servoid identify --driver serial:///dev/pts/N

The servo (--servo) is by default the xm430 twin: the firmware's own
position loop (firmware/loop.c, the XM430's PID on the horn encoder, at its
own 4 kHz) drives the twin's motor, gear with play, load and 12-bit
encoder (firmware/host/twin_sim.c, the C port of servoid's twin, equal to
it sample for sample) -- the structure of a bench board with an H-bridge and
a geared motor. Any of {names} runs, twin parameters overridden URL-style
(--servo 'sts3215?play_deg=1'); --servo model is the pseudo-Wiener bench
plant (a1 -0.8, a2 0.15, b0 0.35, delay 1, m2 1, c1 0.02 rad, c2 0.03 rad)
through a --cpr-count encoder, --servo paper the paper's Section 4 plant
(excite it with --amplitude 2.4). The protocol is in
docs/serial-protocol.md. Runs until Ctrl-C.
""".format(names=", ".join(SERVO_NAMES))


def register(p: argparse.ArgumentParser) -> None:
    p.add_argument("--servo", metavar="NAME[?K=V&...]",
                   help="the servo behind the firmware's HAL: a twin preset with overrides, or model (default xm430)")  # fmt: skip
    p.add_argument("--plant", help=argparse.SUPPRESS)  # gone: a one-line error names --servo
    p.add_argument("--cpr", type=int, default=None, metavar="COUNTS",
                   help="with --servo model: encoder counts per revolution (default 65536); a twin has its own")  # fmt: skip
    p.add_argument("--noise", type=float, default=0.0, metavar="RAD",
                   help="encoder noise standard deviation in rad (default 0; a twin: its output encoder's)")  # fmt: skip
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
    from servoid.drivers.servos import parse_servo

    for name in ("flip", "drop"):
        value = getattr(args, name)
        if not 0.0 <= value <= 1.0:
            raise ConfigError(f"--{name} (={value!r}) must lie in [0, 1]")
    if args.plant is not None:
        name = {"bench": "model"}.get(args.plant, args.plant)
        raise ConfigError(f"--plant (={args.plant}) is gone: the servo behind the firmware is --servo {name}")
    servo = parse_servo(args.servo)
    if args.link is not None:
        new_link(args.link, option="--link")
    options = FirmwareOptions(
        servo=servo, counts_per_rev=args.cpr, noise=args.noise, seed=args.seed,
        flip_tx=args.flip, flip_rx=args.flip, drop=args.drop, link=args.link,
    )  # fmt: skip
    out = _term.stdout
    with FirmwareEmulator(options) as emu:
        out.print(f"servoid emulate serial: firmware servoid-bench/1.0 (boot {emu.boot_id:04x}) on {emu.port}")
        out.print(f"  servo    {servo.describe()}, encoder {options.counts_per_turn} counts/rev")
        out.print(f"  url      {emu.url}")
        amplitude = f" --amplitude {servo.amplitude:g}"
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
