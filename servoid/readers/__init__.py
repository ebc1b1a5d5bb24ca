"""Reading the data people have: one entry point that picks the reader by the file, one module per format.

======================  ==========================  ===============================================
format                  module                      names the input, output and time by
======================  ==========================  ===============================================
CSV (``.csv``, .txt)    :mod:`servoid.recording`    columns (``u``, ``y``, ``t`` unless mapped)
MATLAB (``.mat``)       :mod:`.mat`                 variables (``u``, ``y``, ``t`` unless mapped)
ROS bag (folder,        :mod:`.rosbag`              topics (``y=/joint_states:joint2,u=/cmd``)
``.db3``, ``.mcap``,
``.bag``)
BAM log (``.json``)     :mod:`.bam`                 entry fields (``goal_position``, ``position``,
                                                    ``timestamp`` unless mapped)
pandas DataFrame        :mod:`.dataframe`           columns (Python only: :func:`from_dataframe`)
======================  ==========================  ===============================================

:func:`read` takes a path and :class:`ReadOptions` (the command line's
``--columns``, ``--time-column``, ``--time-unit`` and ``--topics``) and
returns a :class:`~servoid.recording.Recording`; an option a format does
not take is refused, not ignored. Every reader checks the same things with
the same messages (:mod:`._series`): a missing column, variable, field or
topic is named with a list of those there; values must be finite numbers
within :data:`servoid.limits.MAX_MAGNITUDE`; time must increase strictly. :mod:`.excitation_file` reads an excitation to
replay (``--excitation file:PATH[:COLUMN]``).
"""

from __future__ import annotations

import os
from pathlib import Path

from servoid.errors import DataError
from servoid.readers.bam import read_bam
from servoid.readers.dataframe import from_dataframe
from servoid.readers.mat import read_emps, read_mat
from servoid.readers.options import ReadOptions, parse_columns, parse_topics
from servoid.readers.rosbag import BAG_SUFFIXES, bag_topics, read_rosbag
from servoid.recording import Recording, read_recording

__all__ = [
    "read",
    "format_of",
    "FORMATS",
    "ReadOptions",
    "parse_columns",
    "parse_topics",
    "read_recording",
    "read_mat",
    "read_emps",
    "read_rosbag",
    "read_bam",
    "from_dataframe",
]

#: File suffix -> format.
FORMATS: dict[str, str] = {".csv": "csv", ".txt": "csv", ".mat": "mat", ".json": "bam"}
FORMATS.update({suffix: "rosbag" for suffix in BAG_SUFFIXES})


def format_of(path: str | os.PathLike[str]) -> str:
    """The format of a file by its suffix (a folder is a ROS 2 bag).

    Parameters
    ----------
    path : path-like
        The file or folder.

    Raises
    ------
    DataError
        A suffix servoid does not read (the message lists those it does).
    """
    p = Path(path)
    if p.is_dir():
        return "rosbag"
    try:
        return FORMATS[p.suffix.lower()]
    except KeyError:
        known = ", ".join(FORMATS)
        raise DataError(f"{p}: cannot tell the format from {p.suffix or 'no suffix'!r}; servoid reads {known} "
                        "and ROS 2 bag folders") from None  # fmt: skip


def read(path: str | os.PathLike[str], options: ReadOptions | None = None) -> Recording:
    """Read a recording in any format servoid knows, with the names and units ``options`` give.

    Parameters
    ----------
    path : path-like
        A CSV, ``.mat``, BAM ``.json`` file or a ROS bag.
    options : ReadOptions, optional
        Column, variable or field names, the time unit, the bag's topics.

    Raises
    ------
    DataError
        What the format's reader raises; a bag without topics named (the
        message lists its topics).
    ConfigError
        An option the format does not take.
    """
    opts = options if options is not None else ReadOptions()
    kind = format_of(path)
    what = f"{path} ({kind})"
    if kind == "csv":
        opts.refuse(what, topics=True)
        return read_recording(path, u_column=opts.name("u", "u"), y_column=opts.name("y", "y"),
                              time_column=opts.time(), time_unit=opts.time_unit)  # fmt: skip
    if kind == "mat":
        opts.refuse(what, topics=True)
        return read_mat(path, u=opts.name("u", "u"), y=opts.name("y", "y"), t=opts.time(), time_unit=opts.time_unit)
    if kind == "bam":
        opts.refuse(what, topics=True, time_unit=True)
        time = opts.time("timestamp")
        return read_bam(path, u=opts.name("u", "goal_position"), y=opts.name("y", "position"),
                        t=time if time is not None else "timestamp")  # fmt: skip
    opts.refuse(what, columns=True, time_unit=True)
    missing = [role for role in ("y", "u") if role not in opts.topics]
    if missing:
        shown = ", ".join(f"{topic} ({kind})" for topic, kind in bag_topics(path).items()) or "no topics"
        raise DataError(f"{path}: a ROS bag needs its topics named (--topics y=TOPIC[:JOINT],u=TOPIC); "
                        f"missing {', '.join(missing)}; the bag has {shown}")  # fmt: skip
    return read_rosbag(path, y=opts.topics["y"], u=opts.topics["u"])
