"""Which side of the play a driver's position readings are on: the one owner of the names.

A drive reports the position of one shaft. Most report the output's (a
Dynamixel's horn encoder, a CiA 402 drive's load encoder, the serial
firmware's); an ODrive's CAN estimates are its loop encoder's, the motor's
unless a load encoder was made the axis's position source, and a CiA 402
drive's position actual value (0x6064) is often the motor encoder's: the
CAN drivers take ``readings=`` in their URL. The play sits between motor and output, so a record read on the
motor cannot show it: identification then says the play is not identifiable
(:func:`servoid.ident.offline.intervals.verdict`).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from servoid.errors import ConfigError

__all__ = ["OUTPUT", "MOTOR", "SIDES", "METADATA_KEY", "check", "of"]

#: The readings are the output shaft's: the play lies between the command and them.
OUTPUT = "output"

#: The readings are the motor shaft's: the play lies beyond them, not in the record.
MOTOR = "motor"

#: Every side a reading may be on.
SIDES = (OUTPUT, MOTOR)

#: The key of the side in a driver's identity (``model.json``'s ``servo``) and a recording's metadata.
METADATA_KEY = "readings"


def check(name: str, side: str) -> str:
    """``side`` when it is one of :data:`SIDES`; otherwise a one-line :class:`ConfigError` naming ``name``."""
    if side not in SIDES:
        raise ConfigError(f"{name} (={side!r}) must be one of {', '.join(SIDES)}")
    return side


def of(metadata: Mapping[str, Any] | None) -> str:
    """The side named in a recording's metadata or a driver's identity; :data:`OUTPUT` when it names none."""
    side = (metadata or {}).get(METADATA_KEY, OUTPUT)
    return check(METADATA_KEY, str(side).strip())
