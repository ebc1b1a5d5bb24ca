"""``servoid emulate feetech``: emulated Feetech STS servos (STS3215) on a pseudo-terminal."""

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
from servoid.drivers.servo_facts import SERVO_NAMES

DESCRIPTION = f"""\
Emulate Feetech STS servos (the STS3215 of LeRobot's SO-100/SO-101 arms:
its memory table and the SCS/STS protocol) on a pseudo-terminal that the
official Feetech SDK (scservo_sdk), and so the feetech:// driver, talks to
as to a URT-1 or Waveshare bus adapter. Several IDs share one bus (an arm:
--ids 1,2,3,4,5,6).

Behind every servo is --servo (default sts3215: the twin of an STS3215,
its motor, 0.6 deg of gear play, 12-bit magnetic encoder and position loop;
any of {", ".join(SERVO_NAMES)}, parameters overridden URL-style:
--servo 'sts3215?play_deg=1.0'), sampled at --rate: each Goal Position
written with the torque on is the next sample, and when the host is silent
for n periods the servo runs n samples on the held goal. Sample at the same
rate (servoid identify --rate); --rate 0 makes every goal one sample.
Present Position is the encoder (count + 2048, 4096 a turn), Present Speed
counts/s, Present Load 0.1 % of the duty, Present Current 6.5 mA a unit; the
signed entries are sign-magnitude (bit 15; Homing Offset bit 11, Load bit 10).

Emulated: PING, READ, WRITE, REG_WRITE/ACTION, RESET, SYNC_READ, SYNC_WRITE;
the status error byte (the servo's protections); Response Status Level;
Return Delay Time (2 us a unit); Lock (the EEPROM kept over a restart only
when unlocked). A packet with a bad checksum is dropped unanswered. The STS
has no communication watchdog, and neither has the emulator. The baud rate
is not modelled (a pty has none).

The emulator prints its port and a driver URL per servo (and one for all of
them), then serves until Ctrl-C.
"""

EPILOG = f"""\
examples:
  servoid emulate feetech                               # one servo, ID 1, sampled at {DEFAULT_RATE_HZ:g} Hz
  servoid emulate feetech --ids 1,2,3,4,5,6 --link /tmp/ttyARM   # an SO-101-like arm
  servoid emulate feetech --servo 'sts3215?play_deg=1.0'         # a worn gear
  servoid identify --driver 'feetech:///dev/pts/5?id=1,2,3,4,5,6'   # in another terminal
"""


def register(parser: argparse.ArgumentParser) -> None:
    parser.epilog = EPILOG
    parser.add_argument("--ids", type=ids_option(253), default=[1], metavar="ID[,ID...]",
                        help="servo IDs on the bus (default 1)")  # fmt: skip
    parser.add_argument("--return-delay-us", type=int, default=0, metavar="US",
                        help="initial Return Delay Time in us, even, 0..508 (default 0, the STS3215's factory "
                             "setting)")  # fmt: skip
    add_rate_and_servo_options(parser, "sts3215")
    add_link_option(parser)


def run(args: argparse.Namespace) -> int:
    from servoid.drivers.feetech.emulator import FeetechEmulator, feetech_url
    from servoid.drivers.servos import parse_servo

    period = period_s(args.rate)
    servo = parse_servo(args.servo if args.servo is not None else "sts3215")
    sampled = f"sampled at {args.rate:g} Hz" if args.rate else "one sample per goal"
    rate = f" --rate {args.rate:g}" if args.rate else ""

    def make() -> FeetechEmulator:
        return FeetechEmulator(args.ids, servo=servo, return_delay_us=args.return_delay_us, period_s=period,
                               on_event=print_event)  # fmt: skip

    def lines(port: str) -> list[str]:
        all_ids = [f"  all of them: {feetech_url(port, args.ids)}"] if len(args.ids) > 1 else []
        return [
            f"Feetech emulator on {os.path.realpath(port)} (SCS/STS protocol, STS3215, any baud rate, {sampled})",
            f"  behind each ID: {servo.describe()}",
            *(f"  servo {servo_id}: {feetech_url(port, servo_id)}" for servo_id in args.ids),
            *all_ids,
            f"try: servoid identify --driver '{feetech_url(port, args.ids)}'{rate}",
        ]

    return serve(make, args.link, lines)
