"""Servo drivers behind one interface (``servoid.drivers``).

The simulated servo and the serial, CAN and Dynamixel drivers, each with an
emulator so that every path can be tried without hardware. Vendor libraries
(pyserial, python-can, canopen, dynamixel-sdk) are imported only when their
driver is opened.
"""
