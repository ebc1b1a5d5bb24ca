"""CAN over UDP multicast: malformed datagrams skipped and counted, the bus on loopback unless told otherwise.

Before: one malformed datagram on the group ended every session over
``udp_multicast`` (python-can's ``recv`` raised) and killed the emulated
drive's receiver thread; the socket was bound to every interface, so a
datagram from the LAN reached it.
"""

from __future__ import annotations

import socket
import time

import msgpack
import numpy as np
import pytest

from servoid.drivers import driver_from_url
from servoid.drivers.can import odrive_protocol as proto
from servoid.drivers.can._bus import UDP_GROUP, BusAddress
from servoid.drivers.can.sim_odrive import SimOdriveAxis
from servoid.errors import ConfigError
from servoid.session import SessionConfig, run_session

from .can_helpers import PATIENT_S, bench_input, free_udp_port


def _send(payload: bytes, port: int, *, via: str = "127.0.0.1", to: str = UDP_GROUP) -> None:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_IF, socket.inet_aton(via))
        s.setsockopt(socket.IPPROTO_IP, socket.IP_MULTICAST_LOOP, 1)
        s.sendto(payload, (to, port))


def _estop(node: int) -> bytes:
    """A well-formed udp_multicast datagram carrying an ODrive Estop for ``node``."""
    frame = {"timestamp": 0.0, "arbitration_id": proto.arbitration_id(node, proto.ESTOP), "is_extended_id": False,
             "is_remote_frame": False, "is_error_frame": False, "channel": None, "dlc": 0, "data": b"",
             "is_fd": False, "bitrate_switch": False, "error_state_indicator": False}  # fmt: skip
    return msgpack.packb(frame, use_bin_type=True)


def test_malformed_datagrams_are_skipped_and_counted_and_the_session_and_the_drive_go_on():
    port = free_udp_port()
    bus = BusAddress("udp_multicast", UDP_GROUP, port=port)
    with SimOdriveAxis(node=3, bus=bus) as axis, driver_from_url(axis.url(timeout=PATIENT_S)) as servo:
        garbage = [b"\xff\x00not msgpack", msgpack.packb({"arbitration_id": "x"}), b"", msgpack.packb([1, 2, 3])]
        u = bench_input(300, seed=2)

        def spoil(sample):
            if sample.k % 60 == 30:
                for payload in garbage:
                    _send(payload, port)

        result = run_session(servo, u, SessionConfig(period_s=0.004), on_sample=spoil)
        time.sleep(0.05)
        # no sample lost to the garbage (a busy machine may skip slots: missed, never a timeout)
        assert result.counts["timeout"] == 0 and result.stopped is None and len(result) == 300
        assert result.counts["ok"] + result.counts["late"] > 100
        assert servo._bus.malformed >= len(garbage) and axis._bus.malformed >= len(garbage)
        assert axis.power_on is False and axis._thread.is_alive()  # the session switched it off; it still serves
        servo.enable()
        assert np.isfinite(servo.exchange(0.01).position) and axis.power_on


def test_the_bus_listens_on_loopback_only_unless_told():
    port = free_udp_port()
    bus = BusAddress("udp_multicast", UDP_GROUP, port=port)
    assert "on 127.0.0.1" in bus.describe() and "bind" not in bus.url("odrive", 3)
    lan = next((a for a in _local_addresses() if not a.startswith("127.")), None)
    if lan is None:
        pytest.skip("this machine has no network interface besides loopback")
    with SimOdriveAxis(node=3, bus=bus) as axis, driver_from_url(axis.url(timeout=PATIENT_S)) as servo:
        servo.enable()
        servo.exchange(0.01)
        # an Estop from the network: sent to the group out of the LAN card, and to the card's own address
        _send(_estop(3), port, via=lan)
        _send(_estop(3), port, via=lan, to=lan)
        time.sleep(0.1)
        assert axis.power_on and not axis.axis_error, "a datagram from the network reached the drive"
        _send(_estop(3), port)  # the same from this host, on loopback
        time.sleep(0.1)
        assert not axis.power_on and axis.axis_error


def test_bind_is_checked_and_carried_in_the_url():
    bus = BusAddress("udp_multicast", UDP_GROUP, port=47002, bind="0.0.0.0")
    assert "bind=0.0.0.0" in bus.url("cia402", 1)
    assert driver_from_url(bus.url("cia402", 1)).address.bind == "0.0.0.0"
    with pytest.raises(ConfigError, match=r"bind \(='eth0'\) must be the IPv4 address of a local interface"):
        BusAddress("udp_multicast", UDP_GROUP, bind="eth0")
    with pytest.raises(ConfigError, match="applies to the udp_multicast interface only"):
        BusAddress("virtual", "ch0", bind="127.0.0.1")


def _local_addresses() -> list[str]:
    found: set[str] = set()
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        try:
            s.connect(("192.0.2.254", 9))  # no packet is sent: the kernel only picks the route's source address
            found.add(s.getsockname()[0])
        except OSError:
            pass
    return sorted(found)
