"""ROS 2 bags (and ROS 1 ``.bag`` files): a measured joint position and a command, by topic, aligned in time.

Read with ``rosbags`` (``pip install 'servoid[ros]'``), a pure-Python reader
of both ROS 2 storage formats (SQLite ``.db3`` and MCAP) and of ROS 1 bags,
with the standard message definitions built in: no ROS installation needed.

Topics are named ``TOPIC[:SELECTOR]``. What the selector picks from each
message:

======================================  ===================================================
message                                 selector
======================================  ===================================================
``sensor_msgs/msg/JointState``          a joint's name (or its index): its ``position``;
                                        none needed when the message has one joint
``std_msgs/msg/Float64`` (any scalar    none: ``data``
``data``)
``std_msgs/msg/Float64MultiArray``      an index into ``data`` (none when it has one value),
(``forward_position_controller``)
any message                             a field path: ``reference.positions[0]``,
                                        ``point.x``
======================================  ===================================================

Alignment: the samples are the measurement's messages (``y``), stamped
with the time the bag recorded them (one clock for every topic, unlike
header stamps, which each publisher sets). Sample ``k`` takes as ``u(k)``
the command the servo holds over the interval that measurement ``k`` opens:
the last command recorded before measurement ``k + 1``. This is how
servoid's own recordings pair them (the command sent in a slot with the
position read in it), so that ``y(k)`` depends on ``u(k - 1)`` and earlier,
the model's delay ``d >= 1``. Measurements before the first command are
dropped, and a command topic much faster than the measurement is noted
(each sample takes the last command, no averaging).
"""

from __future__ import annotations

import contextlib
import os
import re
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from servoid.errors import DataError, MissingDependency
from servoid.readers._series import assemble
from servoid.recording import Recording

__all__ = ["read_rosbag", "bag_topics", "BAG_SUFFIXES"]

#: A ROS 2 bag is a folder (with ``metadata.yaml``) or one of these files; ``.bag`` is ROS 1.
BAG_SUFFIXES = (".db3", ".mcap", ".bag")

#: One step of a field path (a field or an index), and a whole path.
_STEP = re.compile(r"([A-Za-z_]\w*)|\[(-?\d+)\]")
_FIELD_PATH = re.compile(r"[A-Za-z_]\w*(?:\[-?\d+\]|\.[A-Za-z_]\w*)*")


def read_rosbag(path: str | os.PathLike[str], *, y: str, u: str) -> Recording:
    """Read a measured output and a command from two topics of a bag.

    Parameters
    ----------
    path : path-like
        A ROS 2 bag folder, a ``.db3`` or ``.mcap`` file, or a ROS 1 ``.bag``.
    y : str
        ``TOPIC[:SELECTOR]`` of the measurement, e.g. ``/joint_states:joint2``.
    u : str
        ``TOPIC[:SELECTOR]`` of the command, e.g. ``/cmd`` or
        ``/forward_position_controller/commands:1``.

    Returns
    -------
    Recording
        One sample per measurement message from the first command on; ``t``
        in seconds from the first kept sample (the bag's record time), the
        absolute start in ``metadata["start_time_ns"]``.

    Raises
    ------
    DataError
        Not a bag, a topic missing (the message lists the bag's topics and
        their types), a joint or field missing (listing those there), a
        message that cannot be decoded, no command before the last
        measurement.
    MissingDependency
        ``rosbags`` is not installed.
    """
    p = _bag_path(path)
    specs = {"y": _split(y), "u": _split(u)}
    times: dict[str, list[int]] = {"y": [], "u": []}
    values: dict[str, list[float]] = {"y": [], "u": []}
    with _open(p) as reader:
        roles = _connections(reader, p, specs)
        for connection, stamp, raw in reader.messages(connections=[c for cs in roles.values() for c in cs]):
            message = _decode(reader, raw, connection, p)
            for role, connections in roles.items():
                if connection in connections:
                    topic, selector = specs[role]
                    values[role].append(_pick(message, selector, f"{p}: {topic} ({connection.msgtype})"))
                    times[role].append(int(stamp))
    return _align(p, specs, times, values)


def bag_topics(path: str | os.PathLike[str]) -> dict[str, str]:
    """The topics of a bag and their message types (``{"/joint_states": "sensor_msgs/msg/JointState"}``)."""
    with _open(_bag_path(path)) as reader:
        return {c.topic: c.msgtype for c in reader.connections}


def _require() -> None:
    try:
        import rosbags.highlevel  # noqa: F401 - only whether it is there
    except ImportError:
        raise MissingDependency("reading ROS bags needs rosbags: pip install 'servoid[ros]'") from None


def _bag_path(path: str | os.PathLike[str]) -> Path:
    p = Path(path)
    if not p.exists():
        raise DataError(f"{p}: no such ROS bag (a bag folder, .db3, .mcap or .bag file)")
    return p


@contextlib.contextmanager
def _open(path: Path) -> Iterator[Any]:
    """``AnyReader`` over the bag; a bag it cannot open is a :class:`DataError` naming it."""
    _require()
    from rosbags.highlevel import AnyReader, AnyReaderError
    from rosbags.typesys import Stores, get_typestore

    # bags without message definitions (ROS 2 Humble's .db3) decode with the standard types
    reader = AnyReader([path], default_typestore=get_typestore(Stores.LATEST))
    try:
        reader.open()
    except (AnyReaderError, OSError, ValueError, KeyError) as exc:
        raise DataError(f"{path}: not a readable ROS bag ({exc})") from None
    try:
        yield reader
    finally:
        reader.close()


def _split(spec: str) -> tuple[str, str]:
    topic, _, selector = spec.partition(":")
    topic, selector = topic.strip(), selector.strip()
    if not topic:
        raise DataError(f"topic (={spec!r}) must look like TOPIC[:SELECTOR], e.g. /joint_states:joint2")
    return topic, selector


def _connections(reader: Any, p: Path, specs: dict[str, tuple[str, str]]) -> dict[str, list[Any]]:
    found = {}
    for role, (topic, _) in specs.items():
        connections = [c for c in reader.connections if c.topic == topic]
        if not connections:
            shown = ", ".join(f"{c.topic} ({c.msgtype})" for c in reader.connections) or "none"
            raise DataError(f"{p}: no topic {topic!r} (for {role}); the bag has {shown}")
        found[role] = connections
    return found


def _decode(reader: Any, raw: bytes, connection: Any, p: Path) -> Any:
    from rosbags.serde import SerdeError
    from rosbags.typesys import TypesysError

    try:
        return reader.deserialize(raw, connection.msgtype)
    except (SerdeError, TypesysError, KeyError, ValueError, IndexError) as exc:
        raise DataError(
            f"{p}: cannot decode {connection.msgtype} on {connection.topic} ({exc}); the bag holds no definition "
            f"of it and it is not a standard ROS 2 type"
        ) from None


def _pick(message: Any, selector: str, where: str) -> float:
    """The number ``selector`` names in ``message`` (see the module's table); ``where`` names the topic."""
    names: list[str] = getattr(message, "name", None) or []
    joint_state = isinstance(getattr(message, "name", None), list) and hasattr(message, "position")
    if joint_state and (not selector or selector in names or selector.lstrip("-").isdigit()):
        return _joint(message, names, selector, where)
    first = _STEP.match(selector)
    if selector and first is not None and first.group(1) and hasattr(message, first.group(1)):
        return _number(_path(message, selector, where), f"{where}, field {selector!r},")
    if joint_state:
        raise DataError(f"{where}: no joint or field {selector!r}; the joints are {', '.join(names) or 'none'}")
    if hasattr(message, "data"):
        data = message.data
        if np.ndim(data) == 0:
            if selector:
                raise DataError(f"{where} holds one value, 'data'; drop the selector {selector!r}")
            return _number(data, where)
        return _element(np.asarray(data), selector, f"{where} data")
    fields = ", ".join(getattr(message, "__dataclass_fields__", {})) or "none"
    raise DataError(f"{where}: name the field that holds the value (TOPIC:FIELD.SUBFIELD); fields: {fields}")


def _joint(message: Any, names: list[str], selector: str, where: str) -> float:
    position = np.asarray(message.position, dtype=np.float64)
    if position.size != len(names):
        raise DataError(f"{where}: {len(names)} joints but {position.size} positions in a message")
    if not selector:
        if len(names) != 1:
            raise DataError(f"{where} has joints {', '.join(names)}: name one, e.g. TOPIC:{names[0]}")
        return float(position[0])
    if selector in names:
        return float(position[names.index(selector)])
    return _element(position, selector, f"{where} position")


def _element(values: np.ndarray, selector: str, where: str) -> float:
    if not selector:
        if values.size != 1:
            raise DataError(f"{where} holds {values.size} values: give an index, e.g. TOPIC:0")
        return _number(values[0], where)
    i = int(selector)
    if not -values.size <= i < values.size:
        raise DataError(f"{where}: index {i} is outside its {values.size} values")
    return _number(values[i], f"{where}[{i}]")


def _path(message: Any, selector: str, where: str) -> Any:
    if not _FIELD_PATH.fullmatch(selector):
        raise DataError(f"{where}: cannot read the field path {selector!r} (fields and [index], e.g. a.b[0])")
    value = message
    for attr, index in _STEP.findall(selector):
        if attr:
            if not hasattr(value, attr):
                fields = ", ".join(getattr(value, "__dataclass_fields__", {})) or "none"
                raise DataError(f"{where}: no field {attr!r} in {selector!r}; there: {fields}")
            value = getattr(value, attr)
            continue
        i = int(index)
        if not -len(value) <= i < len(value):
            raise DataError(f"{where}: index {i} in {selector!r} is outside its {len(value)} values")
        value = value[i]
    return value


def _number(value: Any, where: str) -> float:
    try:
        out = float(value)
    except (TypeError, ValueError):
        raise DataError(f"{where} is a {type(value).__name__}, not a number; name a numeric field") from None
    return out


def _align(
    p: Path, specs: dict[str, tuple[str, str]], times: dict[str, list[int]], values: dict[str, list[float]]
) -> Recording:
    ty, tu = np.asarray(times["y"], dtype=np.int64), np.asarray(times["u"], dtype=np.int64)
    label = {role: ":".join(part for part in spec if part) for role, spec in specs.items()}
    if ty.size == 0:
        raise DataError(f"{p}: no message on {label['y']}")
    if tu.size == 0:
        raise DataError(f"{p}: no message on {label['u']}")
    # u(k): the command the servo holds over the interval that measurement k opens, the last one recorded
    # before measurement k+1 (the last sample's interval closes a median period later)
    period = int(np.median(np.diff(ty))) if ty.size > 1 else 0
    closes = np.append(ty[1:], ty[-1] + period)
    held = np.searchsorted(tu, closes, side="left") - 1
    keep = held >= 0
    if not keep.any():
        raise DataError(f"{p}: no command on {label['u']} comes before the last message on {label['y']}")
    notes = []
    dropped = int((~keep).sum())
    if dropped:
        notes.append(f"dropped {dropped} measurement(s) on {label['y']} made before the first command on {label['u']}")
    if tu.size > 1.5 * ty.size:
        notes.append(
            f"{label['u']} has {tu.size / ty.size:.1f} commands per measurement: each sample takes the last one "
            "before the next measurement (no averaging)"
        )
    y = np.asarray(values["y"])[keep]
    u = np.asarray(values["u"])[held[keep]]
    stamps = ty[keep]
    t = (stamps - stamps[0]) * 1e-9
    meta = {"source": f"ROS bag {p.name}", "u": label["u"], "y": label["y"], "start_time_ns": str(int(stamps[0]))}
    names = {"u": label["u"], "y": label["y"], "t": f"{label['y']} record time"}
    return assemble({"u": u, "y": y, "t": t}, names=names, where=str(p), time_unit="s", metadata=meta,
                    path=str(p), notes=tuple(notes))  # fmt: skip
