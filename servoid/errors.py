"""The one exception root of servoid, and its branches.

Every error servoid raises on purpose is a :class:`ServoidError`. Each subclass
also inherits the builtin it resembles, so ``except TimeoutError`` catches a
:class:`DriverTimeout` and ``except ValueError`` catches a :class:`ConfigError`.
Errors from vendor libraries (pyserial, python-can, the Dynamixel SDK, NumPy)
are wrapped with ``raise ... from`` so the cause stays visible.

This module is a leaf: it imports nothing from servoid, so the pillars
(``servoid.ident``, ``servoid.excitation``, ``servoid.drivers``) may import it
without depending on the app layer.

The command line maps every :class:`ServoidError` to a one-line message and
exit status 2; anything else is a bug and keeps its traceback.
"""

from __future__ import annotations

__all__ = [
    "ServoidError",
    "ConfigError",
    "DataError",
    "ModelError",
    "EstimatorError",
    "EstimatorDiverged",
    "DriverError",
    "DriverTimeout",
    "ProtocolError",
    "CommandUnconfirmed",
    "DeviceFault",
    "DeviceRestarted",
    "PositionOutOfRange",
    "MissingDependency",
]


class ServoidError(Exception):
    """Root of every error servoid raises on purpose."""


class ConfigError(ServoidError, ValueError):
    """An argument, option or specification has a value servoid cannot use."""


class DataError(ServoidError, ValueError):
    """A recording or data file is missing, malformed or unusable for the task."""


class ModelError(ServoidError, ValueError):
    """Model parameters violate the model's assumptions (stability, c1 > 0, ...)."""


class EstimatorError(ServoidError, RuntimeError):
    """The estimator cannot produce a trustworthy result."""


class EstimatorDiverged(EstimatorError, ArithmeticError):
    """The estimate or its covariance became non-finite.

    Parameters
    ----------
    message : str
        What happened.
    sample : int
        Index (0-based) of the sample at which the divergence was detected.
    """

    def __init__(self, message: str, *, sample: int) -> None:
        super().__init__(message)
        self.sample = sample


class DriverError(ServoidError, OSError):
    """A driver could not talk to its servo."""


class DriverTimeout(DriverError, TimeoutError):
    """The servo did not answer in time."""


class ProtocolError(DriverError):
    """A reply was corrupted or did not follow the protocol (bad CRC, length, sequence)."""


class CommandUnconfirmed(ProtocolError):
    """The servo's read-back of a command differs from what was sent: the command was lost or corrupted on its way."""


class DeviceFault(DriverError):
    """The servo reported a fault (hardware-error bit, CiA 402 fault, axis error)."""


class DeviceRestarted(DriverError):
    """The servo restarted during a run (its clock or sequence went back to zero)."""


class PositionOutOfRange(DeviceFault):
    """The measured position left the allowed range by more than the guard: the run was stopped, torque off."""


class MissingDependency(ServoidError, ImportError):
    """An optional library needed for the requested feature is not installed."""
