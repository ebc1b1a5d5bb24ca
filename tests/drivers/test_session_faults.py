"""Faults of the CAN and Dynamixel servos during a sampling session: a clear error, the recording kept, torque off.

For each fault the issue names -- a Dynamixel that stops answering, its
hardware-error bit, CRC errors; a CiA 402 drive that drops out of Operation
Enabled or sends an EMCY; an ODrive axis error (and an ODrive that reboots)
-- :func:`servoid.session.run_session` runs with a recording, the fault is
injected into the emulated device before the exchange of sample
:data:`FAULT_AT`, and the test checks, from the outside:

* the error's type and message name the fault and the sample the run
  stopped at, and the file the samples are in;
* the recording on disk is intact and readable with
  :func:`servoid.recording.read_recording`: every sample before the fault,
  measured, and equal to the partial result the error carries;
* the torque is off afterwards, as the device itself says (the control
  table's Torque Enable, the drive's CiA 402 state, the axis state).
"""

from __future__ import annotations

import contextlib
import logging
from collections.abc import Callable, Iterator
from contextlib import AbstractContextManager
from dataclasses import dataclass
from typing import Any

import numpy as np
import pytest

from servoid.drivers import Driver, driver_from_url
from servoid.drivers.dynamixel.control_table import HardwareError
from servoid.drivers.model_plant import MODEL_AMPLITUDE
from servoid.errors import DeviceFault, DriverError, DriverTimeout
from servoid.recording import read_recording
from servoid.session import SessionConfig, run_session

from .can_helpers import (
    PATIENT_S,
    buses_closed,  # noqa: F401 - autouse fixture
    private_bus,
)

FAULT_AT = 40
RATE_HZ = 500.0


@contextlib.contextmanager
def dxl() -> Iterator[tuple[Driver, Any]]:
    from servoid.drivers.dynamixel.emulator import DynamixelEmulator

    with DynamixelEmulator(ids=[1], return_delay_us=0) as emu:
        with driver_from_url(emu.url(1, latency_ms=5)) as servo:  # 12 ms reply timeout: a silent servo is found soon
            yield servo, emu


@contextlib.contextmanager
def cia402() -> Iterator[tuple[Driver, Any]]:
    from servoid.drivers.can.sim_cia402 import SimCia402Drive

    with SimCia402Drive(node=1, bus=private_bus()) as drive:
        with driver_from_url(drive.url(timeout=PATIENT_S)) as servo:
            yield servo, drive


@contextlib.contextmanager
def odrive() -> Iterator[tuple[Driver, Any]]:
    from servoid.drivers.can.sim_odrive import SimOdriveAxis

    with SimOdriveAxis(node=3, bus=private_bus()) as axis:
        with driver_from_url(axis.url(timeout=PATIENT_S)) as servo:
            yield servo, axis


def dxl_torque_off(emu: Any) -> bool:
    return not emu.servo(1).torque


def drive_off(drive: Any) -> bool:
    return not drive.power_on


@dataclass(frozen=True)
class Fault:
    """One fault: how to set up the device, inject the fault, and what must come out."""

    name: str
    device: Callable[[], AbstractContextManager[tuple[Driver, Any]]]
    inject: Callable[[Any], None]
    error: type[DriverError]
    message: str
    torque_off: Callable[[Any], bool]
    stops_at_fault: bool = True  # False: the session goes on (timeouts) until it gives up


def _corrupt_every_reply(emu: Any) -> None:
    emu.faults(1).corrupt_replies = 10**6


FAULTS = [
    Fault("dxl stops answering", dxl, lambda emu: setattr(emu.faults(1), "mute", True), DriverTimeout,
          r"stopped answering: no usable reply for .* servo 1 did not answer the READ of the present values",
          dxl_torque_off, stops_at_fault=False),
    Fault("dxl hardware error", dxl, lambda emu: emu.servo(1).inject_hardware_error(HardwareError.OVERLOAD),
          DeviceFault, r"servo 1 reports a hardware error: overload .*switched its torque off", dxl_torque_off),
    Fault("dxl CRC errors", dxl, _corrupt_every_reply, DriverTimeout,
          r"stopped answering: .*the answer of servo 1 to the READ of the present values was corrupted \(bad CRC",
          dxl_torque_off, stops_at_fault=False),
    Fault("cia402 drops out of Operation Enabled", cia402, lambda drive: drive.drop_out(), DeviceFault,
          r"node 1 on virtual test-\w+ left Operation Enabled: statusword 0x[0-9A-F]{4} = SWITCH ON DISABLED",
          drive_off),
    Fault("cia402 EMCY", cia402, lambda drive: drive.inject_fault(code=0x4310), DeviceFault,
          r"node 1 on virtual test-\w+ reported EMCY 0x4310 \(temperature\).*state FAULT", drive_off),
    Fault("odrive axis error", odrive, lambda axis: axis.inject_axis_error(0x1000), DeviceFault,
          r"ODrive node 3 .* reported axis error 0x00001000 \(CURRENT_LIMIT_VIOLATION\), axis state IDLE", drive_off),
    Fault("odrive reboots", odrive, lambda axis: axis.inject_reboot(), DeviceFault,
          r"ODrive node 3 .* left closed-loop control: axis state IDLE", drive_off),
]  # fmt: skip


def inject_before_exchange(n: int, inject: Callable[[], None]) -> Callable[[float], float]:
    """A command filter that injects the fault before the ``n``-th exchange (counted from 0)."""
    calls = iter(range(10**9))

    def command(reference: float) -> float:
        if next(calls) == n:
            inject()
        return reference

    return command


@pytest.mark.parametrize("fault", FAULTS, ids=lambda f: f.name)
def test_a_fault_stops_the_session_with_a_clear_error_the_recording_kept_and_torque_off(fault, tmp_path, caplog):
    path = tmp_path / "recording.csv"
    u = np.random.default_rng(7).uniform(-MODEL_AMPLITUDE, MODEL_AMPLITUDE, 400)
    with caplog.at_level(logging.WARNING), fault.device() as (servo, device):
        with pytest.raises(fault.error, match=fault.message) as info:
            run_session(servo, u, SessionConfig(period_s=1 / RATE_HZ, give_up_after_s=0.1), recording=path,
                        command_filter=inject_before_exchange(FAULT_AT, lambda: fault.inject(device)))  # fmt: skip
        assert fault.torque_off(device), "the device still has its torque on"
    partial = info.value.partial
    # which sample, which fault, where the samples are
    assert f"(stopped at sample {len(partial)}; the {len(partial)} samples so far are in {path})" in str(info.value)
    exchanged = partial.status != "missed"
    before_fault = np.flatnonzero(exchanged)[:FAULT_AT]
    if fault.stops_at_fault:
        assert exchanged.sum() == FAULT_AT  # the faulty exchange raised: it is not a sample
    else:
        assert np.all(partial.status[np.flatnonzero(exchanged)[FAULT_AT:]] == "timeout")
    # the recording: intact, readable, what the session measured before the fault
    rec = read_recording(path)
    assert len(rec) == len(partial) and rec.metadata["unit"] == "rad"
    np.testing.assert_array_equal(rec.y, partial.y)
    np.testing.assert_array_equal(rec.status, partial.status)
    assert np.all(np.isfinite(rec.y[before_fault])) and set(rec.status[before_fault]) <= {"ok", "late"}


def test_one_crc_error_costs_one_sample_and_the_session_goes_on(tmp_path):
    u = np.random.default_rng(8).uniform(-MODEL_AMPLITUDE, MODEL_AMPLITUDE, 200)
    with dxl() as (servo, emu):
        inject = inject_before_exchange(FAULT_AT, lambda: setattr(emu.faults(1), "corrupt_replies", 1))
        result = run_session(servo, u, SessionConfig(period_s=1 / RATE_HZ), recording=tmp_path / "r.csv",
                             command_filter=inject)  # fmt: skip
        assert servo.stats.rejected == 1
    assert result.counts["timeout"] == 1 and len(result) == 200
    assert len(read_recording(tmp_path / "r.csv")) == 200
    # the samples after it are measured again (on time or late: the 2 cores may be busy with other work)
    assert np.sum(np.isin(result.status[FAULT_AT + 1 :], ["ok", "late"])) >= 20
