"""Faults of a Dynamixel run: each gives a clear error, the recording is kept, the torque ends off.

The run is a plain loop that appends every measurement to a
:class:`~servoid.recording.RecordingWriter` as it arrives, as the sampling
session does; a fault is injected into the emulated servo after
:data:`FAULT_AT` samples.
"""

from __future__ import annotations

import logging

import numpy as np
import pytest

from servoid.drivers import driver_from_url
from servoid.drivers.dynamixel.control_table import HardwareError
from servoid.drivers.model_plant import MODEL_AMPLITUDE
from servoid.errors import DeviceFault, DriverTimeout, ProtocolError
from servoid.recording import RecordingWriter, read_recording

from .dxl_helpers import clock, emulator, url  # noqa: F401 - fixtures

FAULT_AT = 60


def run(emu, path, inject, samples=120):
    """Excite servo 1, recording each sample, with ``inject(emu)`` called before sample FAULT_AT."""
    u = np.random.default_rng(5).uniform(-MODEL_AMPLITUDE, MODEL_AMPLITUDE, samples)
    # the device clock, not the time of the samples (the emulator's tick does not move here): not a t column
    with RecordingWriter(path, ["device_time", "u", "y"], metadata={"unit": "rad"}) as rec:
        with driver_from_url(url(emu)) as servo:
            servo.enable()
            for k, u_k in enumerate(u):
                if k == FAULT_AT:
                    inject(emu)
                m = servo.exchange(u_k)
                rec.append(m.device_time, m.command, m.position)


def mute(emu):
    emu.faults(1).mute = True


def overload(emu):
    emu.servo(1).inject_hardware_error(HardwareError.OVERLOAD)


def corrupt_replies(emu):
    emu.faults(1).corrupt_replies = 1_000


def corrupt_requests(emu):
    # a burst: the sample's READ and the first torque-off attempt arrive corrupted
    emu.faults(1).corrupt_requests = 2


@pytest.mark.parametrize(
    "inject, error, message",
    [
        (mute, DriverTimeout, "servo 1 did not answer the READ of the present values within"),
        (overload, DeviceFault, "servo 1 reports a hardware error: overload .*torque off"),
        (corrupt_replies, ProtocolError, "answer of servo 1 to the READ of the present values was corrupted"),
        (corrupt_requests, ProtocolError, "servo 1 refused the READ of the present values: CRC error"),
    ],
    ids=["stops answering", "hardware error", "corrupted replies", "corrupted requests"],
)
def test_a_fault_is_named_the_recording_kept_and_the_torque_left_off(
    emulator,  # noqa: F811 - the fixture imported above
    tmp_path,
    inject,
    error,
    message,
    caplog,
):
    path = tmp_path / "run.csv"
    with caplog.at_level(logging.WARNING, logger="servoid.drivers"), pytest.raises(error, match=message):
        run(emulator, path, inject)
    kept = read_recording(path)
    assert len(kept) == FAULT_AT and np.all(np.isfinite(kept.y)) and kept.metadata["unit"] == "rad"
    # the torque-off write reached the servo even where its answer could not come back
    assert not emulator.servo(1).torque


def test_a_servo_gone_from_the_bus_still_closes_in_bounded_time(emulator, tmp_path, caplog):  # noqa: F811
    with caplog.at_level(logging.WARNING, logger="servoid.drivers"), pytest.raises(DriverTimeout):
        run(emulator, tmp_path / "run.csv", lambda emu: emu.unplug(1))
    assert len(read_recording(tmp_path / "run.csv")) == FAULT_AT
    assert "could not switch the torque off" in caplog.text  # said, not hidden, and not raised over the timeout


def test_one_corrupted_reply_costs_one_sample(emulator):  # noqa: F811
    with driver_from_url(url(emulator)) as servo:
        servo.enable()
        servo.exchange(0.1)
        emulator.faults(1).corrupt_replies = 1
        with pytest.raises(ProtocolError):
            servo.exchange(0.1)
        assert servo.exchange(0.1).position != 0.0 and servo.stats.errors == 1


def test_a_pending_hardware_error_is_refused_at_open_unless_rebooting(emulator):  # noqa: F811
    emulator.servo(1).inject_hardware_error(HardwareError.OVERHEATING | HardwareError.INPUT_VOLTAGE)
    with pytest.raises(DeviceFault, match="reports a hardware error \\(input voltage, overheating\\).*reboot=1"):
        driver_from_url(url(emulator)).open()
    with driver_from_url(url(emulator, reboot=1)) as servo:
        servo.enable()
        assert servo.exchange(0.0).position == 0.0
    assert emulator.servo(1).reboots == 1 and not emulator.servo(1).alert


def test_a_corrupted_answer_while_opening_is_tried_again(emulator):  # noqa: F811
    emulator.faults(1).corrupt_replies = 2  # the PING's answer, then the first READ's
    with driver_from_url(url(emulator)) as servo:
        servo.enable()
        assert servo.exchange(0.1).position == 0.0
        assert servo.stats.rejected == 2 and emulator.stats.received >= 2
