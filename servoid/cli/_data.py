"""The options that say how to read a recording (``--columns``, ``--time-column``, ``--time-unit``, ``--topics``), one set for every command that reads one."""

from __future__ import annotations

import argparse
import textwrap
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # pragma: no cover
    from pathlib import Path

    from servoid.readers import ReadOptions
    from servoid.recording import Recording

__all__ = ["add_options", "options", "read", "formats_help", "FORMATS_HELP", "EXAMPLES"]

#: What a recording may be, for a command's description.
FORMATS_HELP = (
    "a CSV file (a header row; columns u, y and optionally t, in seconds; lines starting with '#' are "
    "metadata such as '# unit: rad'), a MATLAB .mat file (variables u, y, t), a ROS 2 bag (a folder, "
    ".db3 or .mcap; ROS 1 .bag too) with --topics, or a BAM servo log (.json); other names with --columns"
)


def formats_help(first: str, indent: int, last: str = "") -> str:
    """:data:`FORMATS_HELP` between ``first`` and ``last``, wrapped to 79 columns, the lines after the first indented."""
    return textwrap.fill(first + FORMATS_HELP + last, width=79, subsequent_indent=" " * indent)


#: Examples of the reading options, for a command's epilog (the command's name is put in).
EXAMPLES = """\
  servoid {cmd} --data log.csv --columns u=goal,y=pos,t=time_ms --time-unit ms
  servoid {cmd} --data log.csv --time-column none           (rows as equally spaced samples)
  servoid {cmd} --data run.mat --columns "u=qg,y=qm,t=t"      (MATLAB variables; also log(:,2), s.field)
  servoid {cmd} --data bag/ --topics y=/joint_states:wrist,u=/forward_position_controller/commands:1"""


def add_options(parser: argparse.ArgumentParser) -> None:
    """Add the reading options as a group of ``parser``."""
    group = parser.add_argument_group("reading the recording (docs/data.md)")
    group.add_argument("--columns", metavar="u=NAME,y=NAME[,t=NAME]",
                       help="the columns (CSV), variables (.mat) or fields (BAM) holding the input, the output "
                            "and the time, when not named u, y, t; t=none reads no time")  # fmt: skip
    group.add_argument("--time-column", metavar="NAME|none",
                       help="the time column alone (same as --columns t=NAME); 'none': no time, the rows are "
                            "equally spaced samples (default: t when there is one)")  # fmt: skip
    group.add_argument("--time-unit", choices=("s", "ms", "us", "ns"),
                       help="unit of the time column (default s, or the CSV's '# time_unit:' line)")  # fmt: skip
    group.add_argument("--topics", metavar="y=TOPIC[:JOINT],u=TOPIC[:SEL]",
                       help="ROS bags: the measured joint position and the command, e.g. "
                            "y=/joint_states:wrist,u=/cmd (SEL: a joint, an index, or a field path)")  # fmt: skip


def options(args: argparse.Namespace) -> ReadOptions:
    """The reading options in ``args`` (``servoid batch`` ships them to its workers).

    Raises
    ------
    ConfigError
        Options that do not parse or disagree.
    """
    from servoid.errors import ConfigError
    from servoid.readers import ReadOptions, parse_columns, parse_topics

    columns = parse_columns(args.columns) if args.columns is not None else {}
    if args.time_column is not None:
        if "t" in columns and columns["t"] != args.time_column:
            raise ConfigError(f"--time-column {args.time_column!r} and --columns t={columns['t']!r} disagree; give one")
        columns["t"] = args.time_column
    topics = parse_topics(args.topics) if args.topics is not None else {}
    return ReadOptions(columns=columns, time_unit=args.time_unit, topics=topics)


def read(path: Path, args: argparse.Namespace) -> Recording:
    """Read the recording at ``path`` as the options in ``args`` say; warn of what the reader noted.

    Raises
    ------
    ConfigError
        Options that do not parse, disagree or do not apply to the format.
    DataError
        What the reader raises.
    """
    from servoid.cli import _term
    from servoid.readers import read as read_any

    rec = read_any(path, options(args))
    for note in rec.notes:
        _term.warn(f"{path}: {note}")
    return rec
