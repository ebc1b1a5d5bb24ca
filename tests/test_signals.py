"""SIGTERM and SIGHUP stop a command as Ctrl-C does, and no signal cuts a driver's torque-off short.

A host killed with SIGTERM (``kill``, systemd, docker) or SIGHUP (a closed
terminal) used to leave Dynamixel, CiA 402 and ODrive servos enabled. The
end-to-end runs against every emulator are in ``tests/drivers/test_watchdogs.py``.
"""

from __future__ import annotations

import os
import signal

import pytest

from servoid.cli import _stop_signals_as_interrupt
from servoid.drivers.sim import SimDriver


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGHUP])
def test_a_stop_signal_is_a_keyboard_interrupt_inside_a_command_and_nothing_after(sig):
    before = signal.getsignal(sig)
    with pytest.raises(KeyboardInterrupt, match=sig.name), _stop_signals_as_interrupt():
        os.kill(os.getpid(), sig)
        for _ in range(1000):
            pass
    assert signal.getsignal(sig) is before


class _SlowOff(SimDriver):
    """The simulated servo, whose torque-off request is interrupted by a second Ctrl-C half-way."""

    def _set_torque(self, enabled: bool) -> None:
        if not enabled:
            os.kill(os.getpid(), signal.SIGINT)  # the user presses Ctrl-C again while the torque goes off
            for _ in range(10_000):  # Python would run the handler at any of these bytecodes
                pass
            self.off_completed = True
        super()._set_torque(enabled)


def test_a_second_ctrl_c_waits_until_the_torque_is_off():
    servo = _SlowOff()
    servo.open()
    servo.enable()
    with pytest.raises(KeyboardInterrupt):
        servo.close()
    assert servo.off_completed and not servo.torque_enabled and not servo.is_open
