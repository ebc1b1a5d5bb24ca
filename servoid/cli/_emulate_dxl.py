"""``servoid emulate dxl``: emulated ROBOTIS Dynamixel servos on a pseudo-terminal."""

from __future__ import annotations

import argparse
import os
import signal
import time
from pathlib import Path

from servoid.cli._live import DEFAULT_RATE_HZ
from servoid.drivers.dynamixel import control_table as ct
from servoid.drivers.dynamixel._emulator_facts import CURRENT_GAIN, PWM_GAIN
from servoid.drivers.servo_facts import SERVO_NAMES
from servoid.errors import ConfigError
from servoid.output_paths import new_link, remove_own_link

DESCRIPTION = f"""\
Emulate ROBOTIS Dynamixel X-series servos (Protocol 2.0, XM430-W350 control
table) on a pseudo-terminal that the official dynamixel-sdk, and so the dxl://
driver, talks to as to a U2D2 adapter. Several IDs share one bus.

Behind every servo is --servo (default xm430: the twin of a Dynamixel
XM430-W350, its motor, gear play, horn encoder and position PID at its own
rate; any of {", ".join(SERVO_NAMES)}, twin parameters
overridden URL-style: --servo 'xm430?play_deg=0.8'), sampled at --rate: like
a real servo, whose loop runs on its own clock, it takes each goal written
with the torque on as the next sample (one period of servo time), and when
the host is silent for n periods it runs n samples on the held goal. Sample
at the same rate (servoid identify --rate), or the plant seen is another
one; --rate 0 makes every goal one sample, whatever the time between them.
A twin reports in the control table's units: Present Position its horn
encoder (count + 2048, 4096 a turn), Present Velocity its velocity estimate
(0.229 rpm), Present Current its winding current (2.69 mA), Present PWM its
duty (885 = 100 %); Torque Enable switches its drive stage (off: it coasts).
A twin runs the position modes (3, 4, 5) only. With --servo model (the
pseudo-Wiener bench plant, in rad):
  position mode   input = goal position, (count - 2048) x 2 pi / 4096 rad
  current mode    input = goal current x {CURRENT_GAIN:g} rad/A
  pwm mode        input = goal PWM x {PWM_GAIN:g} rad/%

Emulated: PING, READ, WRITE, REG_WRITE/ACTION, SYNC_READ, SYNC_WRITE,
BULK_READ, BULK_WRITE, REBOOT, FACTORY_RESET; status packets with the error
byte; Status Return Level; Return Delay Time (2 us a unit); the EEPROM locked
while the torque is on; the Realtime Tick (ms). The baud rate is not modelled
(a pty has none): any baud the driver asks for works.

The emulator prints its port and a driver URL per servo, then serves until
Ctrl-C.
"""

EPILOG = f"""\
examples:
  servoid emulate dxl                        # one servo, ID 1, sampled at {DEFAULT_RATE_HZ:g} Hz
  servoid emulate dxl --ids 1,2,3 --link /tmp/ttyDXL
  servoid emulate dxl --rate 500
  servoid emulate dxl --servo 'xm430?play_deg=0.8'   # a worn gear
  servoid emulate dxl --servo sts3215                # another servo behind the same protocol
  servoid identify --driver 'dxl:///dev/pts/5?id=1&baud=1000000' --rate 500    # in another terminal
"""


def _ids(text: str) -> list[int]:
    try:
        ids = [int(part) for part in text.replace(" ", "").split(",") if part]
    except ValueError:
        raise argparse.ArgumentTypeError(f"--ids (={text!r}) must be servo IDs separated by commas, e.g. 1,2") from None
    if not ids or any(not 0 <= i <= 252 for i in ids) or len(set(ids)) != len(ids):
        raise argparse.ArgumentTypeError(f"--ids (={text!r}) must be distinct servo IDs in 0..252")
    return ids


def _interrupt(signum: int, frame: object) -> None:
    raise KeyboardInterrupt


def _print_event(line: str) -> None:
    """A servo's own decision (Bus Watchdog, torque off), with the monotonic time a watching process can compare."""
    print(f"{line} (monotonic {time.monotonic():.6f} s)", flush=True)


def register(parser: argparse.ArgumentParser) -> None:
    parser.epilog = EPILOG
    parser.add_argument("--ids", type=_ids, default=[1], metavar="ID[,ID...]", help="servo IDs on the bus (default 1)")
    parser.add_argument("--return-delay-us", type=int, default=500, metavar="US",
                        help="initial Return Delay Time in us, even, 0..508 (default 500, the factory "
                             "setting; the dxl:// driver sets 0 unless told return_delay_us=keep)")  # fmt: skip
    parser.add_argument("--model-number", type=int, default=ct.MODEL_NUMBER.initial, metavar="N",
                        help=f"Model Number the servos report (default {ct.MODEL_NUMBER.initial}, XM430-W350)")  # fmt: skip
    parser.add_argument("--rate", type=float, default=DEFAULT_RATE_HZ, metavar="HZ",
                        help=f"the servos' own sample rate, Hz: sample them at this rate (default {DEFAULT_RATE_HZ:g}, "
                             "that of servoid identify; 0: one sample per goal)")  # fmt: skip
    parser.add_argument("--servo", metavar="NAME[?K=V&...]",
                        help="the servo behind each ID: a twin preset with overrides, or model (default xm430)")  # fmt: skip
    parser.add_argument("--link", type=Path, metavar="PATH",
                        help="also make PATH a symbolic link to the pseudo-terminal (a stable name for scripts); "
                             "PATH must not exist: nothing is replaced")  # fmt: skip


def run(args: argparse.Namespace) -> int:
    from servoid.drivers.dynamixel.emulator import DynamixelEmulator, dxl_url
    from servoid.drivers.servos import parse_servo

    if not (args.rate >= 0 and args.rate < float("inf")):
        raise ConfigError(f"--rate (={args.rate:g}) must be >= 0 Hz (0: one sample per goal)")
    period_s = 1.0 / args.rate if args.rate else None
    servo = parse_servo(args.servo if args.servo is not None else "xm430")
    link: Path | None = args.link
    if link is not None:
        new_link(link, option="--link")
    emulator = DynamixelEmulator(args.ids, servo=servo, return_delay_us=args.return_delay_us,
                                 model_number=args.model_number, period_s=period_s, on_event=_print_event)  # fmt: skip
    try:
        if link is not None:
            os.symlink(emulator.port, link)
        port = str(link) if link is not None else emulator.port
        model = ct.MODEL_NAMES.get(args.model_number, f"model {args.model_number}")
        sampled = f"sampled at {args.rate:g} Hz" if args.rate else "one sample per goal"
        print(f"Dynamixel emulator on {emulator.port} (Protocol 2.0, {model}, any baud rate, {sampled})", flush=True)
        print(f"  behind each ID: {servo.describe()}", flush=True)
        for servo_id in args.ids:
            print(f"  servo {servo_id}: {dxl_url(port, servo_id)}", flush=True)
        rate = f" --rate {args.rate:g}" if args.rate else ""
        print(f"try: servoid identify --driver '{dxl_url(port, args.ids[0])}'{rate}", flush=True)
        print("serving until Ctrl-C", flush=True)
        # `kill` stops it as cleanly as Ctrl-C (a shell starts background jobs with Ctrl-C ignored)
        signal.signal(signal.SIGTERM, _interrupt)
        try:
            emulator.serve_forever()
        except KeyboardInterrupt:
            pass
        print(f"stopped: {emulator.stats.received} packets received, {emulator.stats.replies} answered", flush=True)
        return 0
    finally:
        emulator.close()
        if link is not None:
            remove_own_link(link, emulator.port)
