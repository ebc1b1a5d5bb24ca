"""What both CAN protocols share: URLs and their errors, lazy imports, socketcan, another process."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap

import numpy as np
import pytest

from servoid.drivers import driver_from_url
from servoid.drivers.can._bus import NO_KERNEL_CAN, BusAddress, kernel_has_can
from servoid.drivers.can.cia402 import Cia402Driver
from servoid.drivers.can.odrive import OdriveDriver
from servoid.drivers.can.simulated import simulated_drive
from servoid.drivers.model_plant import MODEL_PLANT
from servoid.errors import ConfigError, DriverError, DriverTimeout
from servoid.ident.models.simulate import simulate
from servoid.recording import read_recording

from . import ctrl_c_reaches_it
from .can_helpers import (
    PATIENT_S,
    bench_input,
    buses_closed,  # noqa: F401 - autouse fixture
    free_udp_port,
    private_bus,
    recorded_run,
)


def test_urls_pick_the_protocol_and_carry_the_bus():
    d = driver_from_url("can://virtual/ch0?protocol=cia402&node=1&bitrate=1000000&timeout=0.02&min=-1&max=1")
    assert isinstance(d, Cia402Driver)
    assert (d.address.interface, d.address.channel, d.address.bitrate, d.node, d.mode) == (
        "virtual",
        "ch0",
        1000000,
        1,
        "position",
    )
    assert d.timeout == 0.02 and (d.limits.minimum, d.limits.maximum) == (-1.0, 1.0)
    o = driver_from_url("can://socketcan/can0?protocol=odrive&node=3&mode=torque")
    assert isinstance(o, OdriveDriver) and o.command_unit.unit == "Nm" and o.position_unit.unit == "rad"
    u = driver_from_url("can://udp_multicast/239.74.163.2?protocol=odrive&port=47001")
    assert (u.address.channel, u.address.port, u.node) == ("239.74.163.2", 47001, 0)
    assert driver_from_url("can://udp_multicast/?protocol=cia402").address.channel == "239.74.163.2"


@pytest.mark.parametrize(
    ("url", "message"),
    [
        ("can://virtual/ch0", r"add protocol=<cia402\|odrive>"),
        ("can://virtual/ch0?protocol=canopen", r"unknown CAN protocol 'canopen'; known: cia402, odrive"),
        ("can://virtual/ch0?protocol=cia402&mode=velocity", r"option mode='velocity' is invalid.*position"),
        ("can://virtual/ch0?protocol=cia402&node=128", r"node \(=128\) must be 1..127"),
        ("can://virtual/ch0?protocol=odrive&node=64", r"node \(=64\) must be 0..63"),
        (
            "can://virtual/ch0?protocol=cia402&port=47000",
            r"port \(=47000\) applies to the udp_multicast interface only",
        ),
        ("can://virtual/ch0?protocol=cia402&baud=1000000", r"unknown option\(s\) baud;.*bitrate"),
        ("can://virtual/?protocol=cia402", r"CAN channel is missing for interface 'virtual'"),
        ("can://virtual/ch0?protocol=cia402&counts_per_rev=0", r"option counts_per_rev='0' is invalid"),
        ("can://virtual/ch0?protocol=odrive&timeout=-1", r"option timeout='-1' is invalid"),
    ],
)
def test_bad_urls_say_what_is_wrong(url, message):
    with pytest.raises(ConfigError, match=message):
        driver_from_url(url)


def test_an_unknown_interface_is_named_when_opened():
    with pytest.raises(ConfigError, match=r"unknown CAN interface 'vcan'; python-can offers .*socketcan"):
        driver_from_url("can://vcan/can0?protocol=cia402").open()


def test_importing_the_driver_and_the_cli_loads_neither_python_can_nor_canopen():
    code = textwrap.dedent(
        """
        import sys
        import servoid.drivers.can, servoid.drivers.can.simulated, servoid.cli
        servoid.cli.build_parser()
        print(sorted(m for m in ("can", "canopen") if m in sys.modules))
        """
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


@pytest.mark.skipif(kernel_has_can(), reason="this kernel has CAN: the next test runs instead")
def test_socketcan_without_kernel_support_is_a_clear_driver_error():
    with pytest.raises(DriverError, match=f"cannot open CAN bus socketcan can0 \\({NO_KERNEL_CAN}\\)"):
        driver_from_url("can://socketcan/can0?protocol=cia402").open()


@pytest.mark.skipif(not kernel_has_can(), reason=NO_KERNEL_CAN)
@pytest.mark.parametrize("protocol", ["cia402", "odrive"])
def test_socketcan_vcan(protocol):
    if not os.path.exists("/sys/class/net/vcan0"):
        pytest.skip("no vcan0: sudo ip link add vcan0 type vcan && sudo ip link set up vcan0")
    u = bench_input(200, seed=21)
    with simulated_drive(protocol, bus=BusAddress("socketcan", "vcan0"), servo="model") as drive:
        with driver_from_url(drive.url()) as servo:
            servo.enable()
            y = np.array([servo.exchange(v).position for v in u])
    assert np.max(np.abs(y - simulate(MODEL_PLANT, u).y)) < 1e-4


@pytest.mark.timeout(60)
@pytest.mark.parametrize("protocol", ["cia402", "odrive"])
def test_the_emulator_in_another_process_over_udp_multicast(protocol):
    port = free_udp_port()
    # --rate 0: one sample per input, since the exchanges below come as fast as they can, not at a rate
    cmd = [sys.executable, "-m", "servoid", "emulate", "can", "--protocol", protocol, "--port", str(port), "--quiet",
           "--rate", "0", "--servo", "model"]  # fmt: skip
    proc = subprocess.Popen(
        cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, preexec_fn=ctrl_c_reaches_it
    )
    try:
        url = proc.stdout.readline().strip()
        assert url.startswith("can://udp_multicast/239.74.163.2?") and f"port={port}" in url, proc.stderr.read()
        u = bench_input(300, seed=22)
        with driver_from_url(f"{url}&timeout={PATIENT_S}") as servo:
            servo.enable()
            y = np.array([servo.exchange(v).position for v in u])
        assert np.max(np.abs(y - simulate(MODEL_PLANT, u).y)) < 1e-4
    finally:
        proc.send_signal(signal.SIGINT)
        assert proc.wait(timeout=10) == 0


def test_the_emulator_refuses_the_virtual_interface(capsys):
    from servoid.cli import main

    assert main(["emulate", "can", "--interface", "virtual"]) == 2
    assert "reaches only buses of the same process" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("protocol", "message"),
    [
        ("cia402", r"node 1 .*: no TPDO within 50 ms after SYNC"),
        ("odrive", r"ODrive node 0 .*: no encoder estimates within 50 ms"),
    ],
)
def test_a_drive_that_stops_answering_times_out_keeps_the_recording_and_ends_switched_off(
    protocol, message, tmp_path, caplog
):
    path = tmp_path / "run.csv"
    with simulated_drive(protocol, bus=private_bus(), servo="model") as drive:
        with driver_from_url(drive.url(timeout=0.05)) as servo:
            servo.enable()
            with pytest.raises(DriverTimeout, match=message) as info:
                recorded_run(servo, bench_input(60, seed=23), path, at=30, event=drive.mute)
            assert isinstance(info.value, TimeoutError)
        # the drive still listens: the torque-off command reached it, only its confirmation was lost
        assert not drive.power_on
    assert "could not switch the torque off" in caplog.text
    assert len(read_recording(path)) == 30


@pytest.mark.parametrize("protocol", ["cia402", "odrive"])
def test_a_reply_that_comes_after_the_timeout_is_not_taken_for_the_next_one(protocol):
    u = bench_input(40, seed=24)
    expected = simulate(MODEL_PLANT, u).y
    late = 22
    assert abs(expected[late + 1] - expected[late]) > 0.01  # a stale reply would show
    y = np.full(u.size, np.nan)
    with simulated_drive(protocol, bus=private_bus(), servo="model") as drive:
        with driver_from_url(drive.url(timeout=0.1)) as servo:
            servo.enable()
            for k, value in enumerate(u):
                if k == late:
                    drive.delay_next_reply(0.15)  # later than the timeout, sooner than two
                try:
                    y[k] = servo.exchange(value).position
                except DriverTimeout:
                    assert k == late
    # the drive applied the late sample all the same: every other sample is the plant's own, none shifted
    assert np.isnan(y[late]) and np.nanmax(np.abs(y - expected)) < 1e-4
