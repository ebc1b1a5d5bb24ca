"""Servo drivers behind one interface (``servoid.drivers``).

The simulated servo and the serial, CAN and Dynamixel drivers, each with an
emulator so that every path can be tried without hardware. Vendor libraries
(pyserial, python-can, canopen, dynamixel-sdk) are imported only when their
driver is opened. :mod:`servoid.drivers.base` states what a driver must and
may implement; :func:`driver_from_url` opens one from a URL.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from servoid import lazy

if TYPE_CHECKING:  # pragma: no cover
    from servoid.drivers.base import (
        Driver,
        DriverStats,
        DriverURL,
        Limits,
        Measurement,
        Option,
        Reading,
        UnitConversion,
    )
    from servoid.drivers.registry import driver_class, driver_from_url, parse_url, register, schemes

#: Each public name and the module that defines it, imported when the name is first used.
_EXPORTS: dict[str, str] = {
    "Driver": "servoid.drivers.base",
    "DriverStats": "servoid.drivers.base",
    "DriverURL": "servoid.drivers.base",
    "Limits": "servoid.drivers.base",
    "Measurement": "servoid.drivers.base",
    "Option": "servoid.drivers.base",
    "Reading": "servoid.drivers.base",
    "UnitConversion": "servoid.drivers.base",
    "driver_class": "servoid.drivers.registry",
    "driver_from_url": "servoid.drivers.registry",
    "parse_url": "servoid.drivers.registry",
    "register": "servoid.drivers.registry",
    "schemes": "servoid.drivers.registry",
}

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

lazy.install(__name__, _EXPORTS)
