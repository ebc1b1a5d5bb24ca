"""Feetech STS servos (STS3215: LeRobot's SO-100/SO-101 arms): the driver and an emulator the SDK talks to.

``feetech:///dev/ttyUSB0?id=1&baud=1000000`` opens :class:`FeetechDriver`;
:class:`~servoid.drivers.feetech.emulator.FeetechEmulator` serves emulated
servos on a pseudo-terminal (``servoid emulate feetech --ids 1,2,3``).
Modules: ``control_table`` (addresses, sign-magnitude encodings, units),
``protocol`` (the packet codec), ``emulated_servo`` (one servo's behaviour and
its twin), ``emulator`` (the bus on a pty), ``driver``.

The driver needs the SDK (``pip install 'servoid[feetech]'``); the codec and
the emulator do not (they are written from the protocol): importing this
package imports the driver, and so the SDK, on first use of ``FeetechDriver``.
"""

from servoid import lazy

__all__ = ["FeetechDriver"]

lazy.install(__name__, {"FeetechDriver": "servoid.drivers.feetech.driver"})
