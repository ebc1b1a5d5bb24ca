"""Replaying an excitation from a file: ``--excitation file:PATH[:COLUMN]``, checked like every other excitation.

The file is a CSV in the recording format (the column ``u`` unless named;
``servoid excite`` writes one) or a ``.mat`` file (the variable ``u`` unless
named). Its values are the commands, sent as they are: not added to a
driver's centre, as a generated signal is, because a replayed input is the
input of some earlier run, already where it was meant to be.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from servoid.errors import ConfigError
from servoid.readers._series import series
from servoid.recording import check_magnitudes, read_column

__all__ = ["PREFIX", "ExcitationFile", "is_file_spec", "read_excitation"]

#: What marks an excitation spec as a file to replay.
PREFIX = "file:"


@dataclass(frozen=True)
class ExcitationFile:
    """A replayed excitation.

    Attributes
    ----------
    u : ndarray
        The commands, in file order.
    path : str
        The file.
    column : str
        The column or variable read.
    """

    u: np.ndarray
    path: str
    column: str

    @property
    def describe(self) -> str:
        """``file:PATH:COLUMN``, for the recording's metadata and the messages."""
        return f"{PREFIX}{self.path}:{self.column}"

    def first(self, samples: int | None) -> np.ndarray:
        """The first ``samples`` commands (all when None).

        Parameters
        ----------
        samples : int, optional
            How many; more than the file holds is an error.
        """
        if samples is None:
            return self.u
        if not 1 <= samples <= self.u.size:
            raise ConfigError(
                f"--samples (={samples}) must lie in [1, {self.u.size}]: {self.describe} holds {self.u.size}"
            )
        return self.u[:samples]

    def check_within(self, low: float, high: float, max_step: float = math.inf, *, unit: str = "") -> None:
        """Refuse a replay that would leave ``[low, high]`` or step by more than ``max_step``, before anything is sent.

        Parameters
        ----------
        low, high : float
            The command range (a driver's limits).
        max_step : float
            The largest change from one sample to the next.
        unit : str
            Unit of the commands, for the message.
        """
        outside = np.flatnonzero((self.u < low) | (self.u > high))
        if outside.size:
            k = int(outside[0])
            raise ConfigError(
                f"{self.describe}: u[{k}] (={self.u[k]:g} {unit}) lies outside the servo's limits [{low:g}, {high:g}]"
                f"{'' if outside.size == 1 else f' ({outside.size} samples do)'}; nothing was sent"
            )
        if self.u.size > 1 and math.isfinite(max_step):
            steps = np.abs(np.diff(self.u))
            big = np.flatnonzero(steps > max_step)
            if big.size:
                k = int(big[0]) + 1
                raise ConfigError(
                    f"{self.describe}: u[{k}] steps by {steps[k - 1]:g} {unit}, over the servo's max_step "
                    f"{max_step:g}; nothing was sent"
                )


def is_file_spec(spec: str | None) -> bool:
    """Whether an ``--excitation`` value names a file to replay."""
    return spec is not None and spec.startswith(PREFIX)


def read_excitation(spec: str) -> ExcitationFile:
    """Read ``file:PATH[:COLUMN]`` (a CSV column, default ``u``, or a ``.mat`` variable).

    Parameters
    ----------
    spec : str
        The ``--excitation`` value.

    Raises
    ------
    DataError
        The file or column missing (the message lists those there), values
        not finite numbers or beyond :data:`~servoid.limits.MAX_MAGNITUDE`, none at all.
    ConfigError
        Not a ``file:`` spec.
    """
    if not is_file_spec(spec):
        raise ConfigError(f"excitation (={spec!r}) must look like {PREFIX}PATH[:COLUMN]")
    rest = spec[len(PREFIX) :]
    path, column = rest, "u"
    if not Path(rest).is_file() and ":" in rest:
        path, _, column = rest.rpartition(":")
    if not path:
        raise ConfigError(f"excitation (={spec!r}) names no file; give {PREFIX}PATH[:COLUMN]")
    if Path(path).suffix.lower() == ".mat":
        from servoid.readers.mat import read_mat_variable

        values = read_mat_variable(path, column)
    else:
        values, _ = read_column(path, column)
    u = series(values, what=f"excitation {PREFIX}{path}:{column}")
    check_magnitudes({column: u}, where=f"excitation {PREFIX}{path}")
    return ExcitationFile(u=u, path=path, column=column)
