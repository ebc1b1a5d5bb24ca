"""How to read a recording whose names differ from servoid's: the column map, the time unit, the ROS topics.

One object for every format, so that the command line has one set of flags
(``--columns``, ``--time-column``, ``--time-unit``, ``--topics``) and each
reader takes what applies to it and refuses what does not.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Literal

from servoid.errors import ConfigError
from servoid.recording import TIME_UNITS

__all__ = ["ReadOptions", "parse_columns", "parse_topics", "COLUMN_ROLES", "TOPIC_ROLES"]

#: What a column map may name: the input, the output and the time.
COLUMN_ROLES = ("u", "y", "t")

#: What a topic map must name: the measured output and the command.
TOPIC_ROLES = ("y", "u")

#: How a time column is switched off on the command line.
NONE_WORD = "none"


@dataclass(frozen=True, kw_only=True)
class ReadOptions:
    """Names and units that tell a reader where the input, output and time are.

    Parameters
    ----------
    columns : mapping
        Role (``u``, ``y``, ``t``) to the name of a column (CSV), a variable
        (``.mat``) or a field (BAM log); roles not given keep the format's
        default (``u``, ``y``, and ``t`` when present). ``t`` may be
        ``"none"``: no time, the samples taken as equally spaced.
    time_unit : str, optional
        Unit of the time column or variable (``s``, ``ms``, ``us``, ``ns``);
        default seconds (or a CSV's ``# time_unit:`` line).
    topics : mapping
        ROS bags: role (``y``, ``u``) to ``TOPIC[:SELECTOR]`` (see
        :func:`servoid.readers.rosbag.read_rosbag`).
    """

    columns: Mapping[str, str] = field(default_factory=dict)
    time_unit: str | None = None
    topics: Mapping[str, str] = field(default_factory=dict)

    def __post_init__(self) -> None:
        for key in self.columns:
            if key not in COLUMN_ROLES:
                raise ConfigError(f"columns: unknown role {key!r}; give {', '.join(COLUMN_ROLES)}")
        for key in self.topics:
            if key not in TOPIC_ROLES:
                raise ConfigError(f"topics: unknown role {key!r}; give {', '.join(TOPIC_ROLES)}")
        if self.time_unit is not None and self.time_unit not in TIME_UNITS:
            raise ConfigError(f"time unit {self.time_unit!r} is not one of {', '.join(TIME_UNITS)}")
        object.__setattr__(self, "columns", dict(self.columns))
        object.__setattr__(self, "topics", dict(self.topics))

    def name(self, role: str, default: str) -> str:
        """The name given for ``role`` (``u`` or ``y``), else ``default``."""
        return self.columns.get(role, default)

    def time(self, default: str | None = None) -> str | None | Literal[False]:
        """The time column: its name, None (the format's default, when present) or False (none: :data:`~servoid.recording.NO_TIME`)."""
        given = self.columns.get("t")
        if given is None:
            return default
        if given.lower() == NONE_WORD:
            return False
        return given

    def refuse(self, what: str, *, columns: bool = False, topics: bool = False, time_unit: bool = False) -> None:
        """Raise :class:`ConfigError` for an option given that the format ``what`` does not take.

        Parameters
        ----------
        what : str
            The file and its format, for the message.
        columns, topics, time_unit : bool
            Which options the format refuses.
        """
        if columns and self.columns:
            raise ConfigError(f"{what} has no columns to map (--columns); it takes --topics")
        if topics and self.topics:
            raise ConfigError(f"{what} has no topics (--topics applies to ROS bags); map its columns with --columns")
        if time_unit and self.time_unit is not None:
            raise ConfigError(f"{what} stamps its own time; --time-unit applies to CSV and .mat files")


def _pairs(text: str, *, option: str, roles: tuple[str, ...], example: str) -> dict[str, str]:
    out: dict[str, str] = {}
    for item in (part.strip() for part in _top_level_split(text)):
        if not item:
            continue
        key, eq, value = item.partition("=")
        key, value = key.strip(), value.strip()
        if not eq or not value:
            raise ConfigError(f"{option}: {item!r} must be ROLE=NAME, e.g. {example}")
        if key not in roles:
            raise ConfigError(f"{option}: unknown role {key!r} in {item!r}; roles: {', '.join(roles)}")
        if key in out:
            raise ConfigError(f"{option}: {key!r} is given twice")
        out[key] = value
    if not out:
        raise ConfigError(f"{option} (={text!r}) names nothing; e.g. {example}")
    return out


def _top_level_split(text: str) -> list[str]:
    """``text`` split at the commas outside brackets, so that ``u=log(:,2)`` stays whole."""
    parts, depth, start = [], 0, 0
    for i, char in enumerate(text):
        if char in "([":
            depth += 1
        elif char in ")]":
            depth = max(depth - 1, 0)
        elif char == "," and depth == 0:
            parts.append(text[start:i])
            start = i + 1
    parts.append(text[start:])
    return parts


def parse_columns(text: str) -> dict[str, str]:
    """``u=goal,y=pos,t=time`` as a dict; ``t=none`` reads no time.

    Raises
    ------
    ConfigError
        An item that is not ``ROLE=NAME``, an unknown role, a role twice.
    """
    return _pairs(text, option="--columns", roles=COLUMN_ROLES, example="u=goal,y=pos,t=time")


def parse_topics(text: str) -> dict[str, str]:
    """``y=/joint_states:joint2,u=/cmd`` as a dict (role to ``TOPIC[:SELECTOR]``).

    Raises
    ------
    ConfigError
        An item that is not ``ROLE=TOPIC``, an unknown role, a role twice.
    """
    return _pairs(text, option="--topics", roles=TOPIC_ROLES, example="y=/joint_states:joint2,u=/cmd")
