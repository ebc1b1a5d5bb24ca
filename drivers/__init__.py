"""Servo drivers behind one interface (``servoid.drivers``).

The simulated servo and the serial, CAN and Dynamixel drivers, each with an
emulator so that every path can be tried without hardware. Vendor libraries
(pyserial, python-can, canopen, dynamixel-sdk) are imported only when their
driver is opened. :mod:`servoid.drivers.base` states what a driver must and
may implement; :func:`driver_from_url` opens one from a URL.
"""

from servoid.drivers.base import Driver, DriverStats, DriverURL, Limits, Measurement, Option, Reading, UnitConversion
from servoid.drivers.registry import driver_class, driver_from_url, parse_url, register, schemes

__all__ = [
    "Driver",
    "DriverStats",
    "DriverURL",
    "Limits",
    "Measurement",
    "Option",
    "Reading",
    "UnitConversion",
    "driver_class",
    "driver_from_url",
    "parse_url",
    "register",
    "schemes",
]
