"""``servoid emulate can``: a simulated CAN drive (CiA 402 or ODrive) in a process of its own."""

from __future__ import annotations

import argparse
import json
import signal
import sys
import threading
import time
from pathlib import Path
from types import FrameType

from servoid.cli._live import DEFAULT_RATE_HZ
from servoid.drivers.can._bus import UDP_GROUP, UDP_PORT, BusAddress
from servoid.drivers.can._sim_facts import SIM_COUNTS_PER_REV, SIM_RATED_TORQUE_MNM
from servoid.drivers.can.driver import DEFAULT_NODES, PROTOCOLS
from servoid.drivers.servo_facts import SERVO_NAMES
from servoid.errors import ConfigError
from servoid.output_paths import output_file

DESCRIPTION = f"""\
Start a simulated CAN servo drive with a servo behind it, and print the
can:// URL that reaches it. By default it listens on python-can's
udp_multicast interface (group {UDP_GROUP}, port {UDP_PORT}), so that a driver
in another process -- another terminal, servoid identify, a benchmark -- can
talk to it as to a drive on a real bus.

  cia402   a CANopen CiA 402 drive: SDO server, NMT, PDOs mapped by the
           master, the 402 state machine, cyclic synchronous position (8)
           mode, EMCY on faults; rated torque {SIM_RATED_TORQUE_MNM} mNm (0x6076)
  odrive   an ODrive axis speaking CAN Simple: heartbeat, Set_Axis_State,
           Set_Controller_Mode, Set_Input_Pos / Set_Input_Torque,
           Get_Encoder_Estimates, Get_Error, Get_Version, Clear_Errors

The servo (--servo, default the twin of the protocol: cia402 = a maxon
EPOS4-class drive with a motor encoder, a planetary gear and a load encoder;
odrive = an ODrive v3.6 with a reducer, motor and load encoder) is any of
{", ".join(SERVO_NAMES)}, with twin parameters overridden
URL-style: --servo 'cia402?play_arcmin=3&load_inertia_kgm2=0.05'.
  cia402 twin   0x6064 / 0x607A in motor-encoder increments (the loop's),
                0x608F their resolution, 0x6091 the gear ratio, the load
                encoder in 0x60E4 sub 1 (0x60E6 / 0x60EB its resolution);
                the driver reads the load encoder (encoder=auto)
  odrive twin   turns of the motor (the loop's encoder), the estimates its
                encoder PLL's; an overspeed disarms the axis with
                VELOCITY_LIMIT_VIOLATION, as the firmware does
  model         the pseudo-Wiener bench plant, one encoder of
                --counts-per-rev increments (default {SIM_COUNTS_PER_REV}); torque
                mode too (the plant driven by torque x 1 rad/Nm)

The plant advances one sample per cycle. The CiA 402 drive runs a cycle per
SYNC, and the SYNC counter the driver sends tells it how many cycles passed
(slots the host skipped are cycles on the held target): it follows the
host's slots exactly, whatever the bus's timing. The ODrive axis, whose
protocol has no cycle number, runs on its own clock at --rate, as a real
axis does: sample it at the same rate (servoid identify --rate), or the plant
seen is another one (--rate 0: one sample per Set_Input_*). A twin's sample
is one period of servo time: the CiA 402 drive's from the SYNC period the
driver writes (0x1006), the ODrive's --rate.

Watchdogs: the CiA 402 drive watches the heartbeat the driver configures
(0x1016) and switches its power stage off when it stops; the ODrive axis runs
its axis watchdog when --watchdog S is given (as saved on a board with
odrivetool), fed by every frame, and --endpoints FILE writes its endpoint
table (flat_endpoints.json) for the driver's watchdog=/endpoints= options.
Each such event, and every power stage going off, is a line on stderr with
the monotonic time.

The first line on stdout is the URL; status lines go to stderr. The drive
runs until Ctrl-C (or SIGTERM).
"""

EPILOG = """\
examples:
  servoid emulate can                                # CiA 402 drive, node 1
  servoid emulate can --protocol odrive --node 3
  servoid emulate can --port 47000                   # a second, separate bus
  servoid emulate can --protocol odrive --rate 500   # an ODrive axis sampled at 500 Hz
  servoid emulate can --servo 'cia402?play_arcmin=4' # the CiA 402 twin with a worn gear
  servoid emulate can --servo model                  # the pseudo-Wiener plant (exact transport tests)
then, in another terminal, with the printed URL:
  servoid identify --driver 'can://udp_multicast/239.74.163.2?protocol=cia402&node=1&port=43113'
"""

#: Seconds between status lines on stderr.
STATUS_EVERY_S = 5.0


def register(p: argparse.ArgumentParser) -> None:
    p.epilog = EPILOG
    p.add_argument(
        "--protocol", choices=tuple(PROTOCOLS), default="cia402", help="what the drive speaks (default cia402)"
    )
    p.add_argument("--node", type=int, metavar="N",
                   help=f"node id (default {DEFAULT_NODES['cia402']} for cia402, {DEFAULT_NODES['odrive']} for odrive)")  # fmt: skip
    p.add_argument("--interface", default="udp_multicast",
                   help="python-can interface (default udp_multicast; socketcan where the kernel has CAN)")  # fmt: skip
    p.add_argument("--channel", default=None, help=f"channel: multicast group for udp_multicast (default {UDP_GROUP}), "
                                                   "can0 / vcan0 for socketcan")  # fmt: skip
    p.add_argument("--port", type=int, default=None, help=f"UDP port for udp_multicast (default {UDP_PORT})")
    p.add_argument("--bind", metavar="ADDRESS",
                   help="udp_multicast: IPv4 address of the interface to listen on (default 127.0.0.1: this host "
                        "only, no datagram from the network reaches the drive; 0.0.0.0: every interface)")  # fmt: skip
    p.add_argument("--servo", metavar="NAME[?K=V&...]",
                   help="the servo behind the drive: a twin preset with overrides, or model "
                        "(default: the protocol's twin, cia402 or odrive)")  # fmt: skip
    p.add_argument("--counts-per-rev", type=int, default=None, metavar="N",
                   help=f"cia402 with --servo model: encoder increments per revolution (default {SIM_COUNTS_PER_REV})")  # fmt: skip
    p.add_argument("--rate", type=float, default=DEFAULT_RATE_HZ, metavar="HZ",
                   help=f"odrive: the axis's own sample rate, Hz (default {DEFAULT_RATE_HZ:g}, that of servoid identify; "
                        "0: one sample per input); cia402 follows the SYNC counter")  # fmt: skip
    p.add_argument("--watchdog", type=float, metavar="S",
                   help="odrive: the axis watchdog timeout as saved on the board, s (default: off)")  # fmt: skip
    p.add_argument("--endpoints", type=Path, metavar="FILE",
                   help="odrive: write the simulated firmware's flat_endpoints.json here (for the driver's endpoints=)")  # fmt: skip
    p.add_argument("--force", action="store_true", help="replace --endpoints if it exists")
    p.add_argument("--quiet", action="store_true", help="no status lines on stderr (events are still shown)")


def _print_event(line: str) -> None:
    """A drive's own decision (watchdog, power stage off), with the monotonic time a watching process can compare."""
    print(f"{line} (monotonic {time.monotonic():.6f} s)", file=sys.stderr, flush=True)


def run(args: argparse.Namespace) -> int:
    from servoid.cli._emulate_bus import priority_line
    from servoid.drivers.can.simulated import simulated_drive
    from servoid.drivers.realtime import collector_off_heap, make_realtime
    from servoid.drivers.servos import parse_servo

    if args.interface == "virtual":
        raise ConfigError(
            "--interface virtual reaches only buses of the same process; use udp_multicast (the default) "
            "to reach the drive from another process"
        )
    port = args.port if args.port is not None or args.interface != "udp_multicast" else UDP_PORT
    bus = BusAddress(args.interface, args.channel or "", port=port, bind=args.bind)
    if not (args.rate >= 0 and args.rate < float("inf")):
        raise ConfigError(f"--rate (={args.rate:g}) must be >= 0 Hz (0: one sample per input)")
    servo = parse_servo(args.servo if args.servo is not None else args.protocol)
    if args.protocol == "cia402":
        if args.watchdog is not None or args.endpoints is not None:
            raise ConfigError(
                "--watchdog and --endpoints are the ODrive's; a CiA 402 drive's watchdog is set by its driver"
            )
        options: dict[str, object] = {"counts_per_rev": args.counts_per_rev}
    else:
        if args.counts_per_rev is not None:
            raise ConfigError("--counts-per-rev applies to --protocol cia402 with --servo model")
        options = {"period_s": 1.0 / args.rate if args.rate else None, "watchdog_s": args.watchdog}
        if args.endpoints is not None:
            from servoid.drivers.can.sim_odrive import SimOdriveAxis

            output_file(args.endpoints, option="--endpoints", force=args.force)
            args.endpoints.write_text(json.dumps(SimOdriveAxis.flat_endpoints(), indent=2) + "\n", encoding="utf-8")
    drive = simulated_drive(args.protocol, bus=bus, node=args.node, servo=servo, **options)
    drive.on_event = _print_event
    stop = threading.Event()

    def _terminate(signum: int, frame: FrameType | None) -> None:  # noqa: ARG001 - signal handler signature
        stop.set()

    previous = signal.signal(signal.SIGTERM, _terminate)
    granted = make_realtime()  # the drive's clock first, where permitted (servoid.drivers.realtime); before its threads
    try:
        with drive, collector_off_heap():  # a full collection would hold the drive's replies (drivers.realtime)
            print(drive.url(), flush=True)
            if not args.quiet:
                print(
                    f"simulated {args.protocol} drive on {bus.describe()}, servo {servo.describe()}; Ctrl-C to stop",
                    file=sys.stderr, flush=True,
                )  # fmt: skip
                print(priority_line(granted), file=sys.stderr, flush=True)
            last = ""
            while not stop.wait(STATUS_EVERY_S):
                line = drive.status()
                if not args.quiet and line != last:
                    print(line, file=sys.stderr, flush=True)
                    last = line
    except KeyboardInterrupt:
        pass
    finally:
        signal.signal(signal.SIGTERM, previous)
    return 0
