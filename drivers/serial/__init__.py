"""The serial bench servo: protocol, pyserial driver, reference firmware in C and its emulator.

``firmware/`` holds the reference firmware (portable C99, no dynamic memory,
a HAL of a few functions in ``firmware/hal.h``) and ``firmware/host/`` its
host build: the HAL over a pseudo-terminal and a simulated motor + gear with
backlash. :mod:`servoid.drivers.serial.build` compiles it with the system's C
compiler at first use; :mod:`servoid.drivers.serial.emulator` runs it.
The protocol is documented in ``docs/serial-protocol.md``.

Importing this package imports pyserial (the registry does so only when a
``serial://`` URL is opened).
"""

from servoid.drivers.serial.driver import SerialDriver

__all__ = ["SerialDriver"]
