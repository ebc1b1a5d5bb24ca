"""``servoid emulate dxl``: emulated ROBOTIS Dynamixel servos on a pseudo-terminal."""

from __future__ import annotations

import argparse
import os

from servoid.cli._emulate_bus import (
    add_link_option,
    add_rate_and_servo_options,
    ids_option,
    period_s,
    print_event,
    serve,
)
from servoid.cli._live import DEFAULT_RATE_HZ
from servoid.drivers.dynamixel import control_table as ct
from servoid.drivers.dynamixel._emulator_facts import CURRENT_GAIN, PWM_GAIN
from servoid.drivers.servo_facts import SERVO_NAMES

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


def register(parser: argparse.ArgumentParser) -> None:
    parser.epilog = EPILOG
    parser.add_argument(
        "--ids", type=ids_option(252), default=[1], metavar="ID[,ID...]", help="servo IDs on the bus (default 1)"
    )
    parser.add_argument("--return-delay-us", type=int, default=500, metavar="US",
                        help="initial Return Delay Time in us, even, 0..508 (default 500, the factory "
                             "setting; the dxl:// driver sets 0 unless told return_delay_us=keep)")  # fmt: skip
    parser.add_argument("--model-number", type=int, default=ct.MODEL_NUMBER.initial, metavar="N",
                        help=f"Model Number the servos report (default {ct.MODEL_NUMBER.initial}, XM430-W350)")  # fmt: skip
    add_rate_and_servo_options(parser, "xm430")
    add_link_option(parser)


def run(args: argparse.Namespace) -> int:
    from servoid.drivers.dynamixel.emulator import DynamixelEmulator, dxl_url
    from servoid.drivers.servos import parse_servo

    period = period_s(args.rate)
    servo = parse_servo(args.servo if args.servo is not None else "xm430")
    model = ct.MODEL_NAMES.get(args.model_number, f"model {args.model_number}")
    sampled = f"sampled at {args.rate:g} Hz" if args.rate else "one sample per goal"
    rate = f" --rate {args.rate:g}" if args.rate else ""

    def make() -> DynamixelEmulator:
        return DynamixelEmulator(args.ids, servo=servo, return_delay_us=args.return_delay_us,
                                 model_number=args.model_number, period_s=period, on_event=print_event)  # fmt: skip

    def lines(port: str) -> list[str]:
        return [
            f"Dynamixel emulator on {os.path.realpath(port)} (Protocol 2.0, {model}, any baud rate, {sampled})",
            f"  behind each ID: {servo.describe()}",
            *(f"  servo {servo_id}: {dxl_url(port, servo_id)}" for servo_id in args.ids),
            f"try: servoid identify --driver '{dxl_url(port, args.ids[0])}'{rate}",
        ]

    return serve(make, args.link, lines)
