"""ROBOTIS Dynamixel servos (Protocol 2.0, X series): the driver and an emulator the SDK talks to.

``dxl:///dev/ttyUSB0?id=1&baud=1000000`` opens :class:`DynamixelDriver`;
:class:`~servoid.drivers.dynamixel.emulator.DynamixelEmulator` serves emulated
servos on a pseudo-terminal (``servoid emulate dxl --ids 1``). Modules:
``control_table`` (addresses and units), ``protocol`` (the packet codec),
``emulated_servo`` (one servo's behaviour and its plant), ``emulator`` (the
bus on a pty, in a thread or a child process), ``driver``.
"""

from servoid.drivers.dynamixel.driver import DynamixelDriver

__all__ = ["DynamixelDriver"]
