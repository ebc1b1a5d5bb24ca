"""Servo drives on a CAN bus: CANopen CiA 402 and ODrive CAN Simple, with simulated drives.

``can://<interface>/<channel>?protocol=cia402|odrive&node=N&...`` opens a
drive through python-can (:class:`CanDriver` dispatches on ``protocol=``).
:class:`~servoid.drivers.can.sim_cia402.SimCia402Drive` and
:class:`~servoid.drivers.can.sim_odrive.SimOdriveAxis` put the bench plant
behind each protocol, on python-can's ``virtual`` bus (one process) or
``udp_multicast`` (``servoid emulate can``, another process).

Importing this package imports neither python-can nor canopen: they are
loaded when a bus is opened.
"""

from servoid.drivers.can.driver import CanDriver

__all__ = ["CanDriver"]
