"""Write the small recordings the reader tests and the docs use, from a physical servo twin (run to regenerate).

Run: ``.venv/bin/python tests/data/make_data.py`` (needs the ``ros`` and
``mat`` extras: ``pip install -e '.[test]'`` has them). Seeded, so a rerun
writes the same numbers.

The servo is the XM430 twin (:mod:`servoid.drivers.twin`: motor, friction
that sticks, gear play 0.25 deg, 4096-count encoder, the drive's loops),
driven by a uniform set point of +-0.1 rad at 100 Hz for 15 s and sampled as
a host samples it. The same record in three layouts a bench produces:

``xm430.csv``
    A logger's CSV: ``time_ms,goal,pos,current`` (time in milliseconds), so
    reading it needs ``--columns u=goal,y=pos,t=time_ms --time-unit ms``.
``xm430.mat``
    A MATLAB v5 file: vectors ``t`` [s], ``goal``, ``pos`` [rad], and a
    matrix ``log`` with the columns ``[t goal pos]``.
``xm430_bag/``
    A ROS 2 bag (MCAP storage): ``/joint_states`` (``sensor_msgs/msg/JointState``,
    joints ``base`` and ``wrist``; the servo is ``wrist``) and
    ``/forward_position_controller/commands`` (``std_msgs/msg/Float64MultiArray``,
    one value per joint), each command published 0.5 ms after the
    measurement of its cycle, as ros2_control's read-update-write loop does.

The functions that write each layout are used by ``tests/test_readers.py``
for its own small files (bad ones too).
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
SAMPLES = 1500
PERIOD_S = 0.01
AMPLITUDE_RAD = 0.1
SEED = 3
#: how long after its cycle's measurement a command is recorded
COMMAND_LAG_NS = 500_000
#: the bag's record time of the first sample (an arbitrary wall-clock start)
START_NS = 1_700_000_000_000_000_000


def twin_record(samples: int = SAMPLES, seed: int = SEED) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Time [s], set point and measured position [rad] of the XM430 twin."""
    from servoid.drivers.twin import Twin, preset

    twin = Twin(preset("xm430"), seed=seed)
    twin.enable()
    u = np.random.default_rng(seed).uniform(-AMPLITUDE_RAD, AMPLITUDE_RAD, samples)
    rec = twin.sample(u, PERIOD_S)
    return rec.t_s - rec.t_s[0], rec.u, rec.y


def write_csv(
    path: Path, t: np.ndarray, u: np.ndarray, y: np.ndarray, *, header: str = "time_ms,goal,pos,current"
) -> Path:
    """A logger's CSV: time in ms, set point, position, and a column servoid does not read."""
    current = np.round(40.0 * (u - y), 3)
    with open(path, "w", encoding="utf-8") as fh:
        fh.write("# unit: rad\n# input_unit: rad\n# source: XM430 twin, uniform +-0.1 rad at 100 Hz\n")
        fh.write(header + "\n")
        for row in zip(t * 1e3, u, y, current):
            fh.write(",".join(f"{v:.10g}" for v in row) + "\n")
    return path


def write_mat(path: Path, variables: dict[str, np.ndarray]) -> Path:
    """A MATLAB v5 file with these variables (vectors are saved as columns, as MATLAB does)."""
    from scipy.io import savemat

    savemat(path, {k: (v[:, None] if v.ndim == 1 else v) for k, v in variables.items()}, do_compression=True)
    return path


def write_mat73(path: Path, variables: dict[str, np.ndarray]) -> Path:
    """A MATLAB v7.3 file: HDF5 behind MATLAB's 512-byte header, arrays stored transposed as MATLAB does."""
    import h5py

    with h5py.File(path, "w", userblock_size=512) as fh:
        for name, value in variables.items():
            arr = value[:, None] if value.ndim == 1 else value
            fh.create_dataset(name, data=np.ascontiguousarray(arr.T))
            fh[name].attrs["MATLAB_class"] = np.bytes_(b"double")
    header = b"MATLAB 7.3 MAT-file, Platform: GLNXA64, Created on: servoid test data HDF5 schema 1.00 ."
    with open(path, "r+b") as fh:
        fh.write(header.ljust(116, b" ") + b"\x00" * 8 + b"\x00\x02IM")
    return path


def write_bag(
    path: Path,
    y_stamps_ns: Sequence[int],
    positions: Sequence[Sequence[float]],
    joints: Sequence[str],
    commands: Sequence[tuple[int, Sequence[float]]],
    *,
    command_topic: str = "/forward_position_controller/commands",
    command_type: str = "std_msgs/msg/Float64MultiArray",
    storage: str = "mcap",
) -> Path:
    """A ROS 2 bag with ``/joint_states`` and a command topic, written by rosbags' own writer.

    ``commands`` are ``(stamp_ns, values)``; a ``std_msgs/msg/Float64`` command takes the first value.
    """
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.rosbag2.enums import CompressionFormat, CompressionMode
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    js_type = store.types["sensor_msgs/msg/JointState"]
    header_type = store.types["std_msgs/msg/Header"]
    time_type = store.types["builtin_interfaces/msg/Time"]
    plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
    empty = np.zeros(0)
    writer = Writer(path, version=8, storage_plugin=plugin)
    if storage == "mcap":  # zstd chunks, as ros2 bag record writes MCAP by default
        writer.set_compression(CompressionMode.STORAGE, CompressionFormat.ZSTD)
    with writer:
        joint_states = writer.add_connection("/joint_states", js_type.__msgtype__, typestore=store)
        command = writer.add_connection(command_topic, command_type, typestore=store)
        events = [(int(s), 0, i) for i, s in enumerate(y_stamps_ns)] + [
            (int(s), 1, i) for i, (s, _) in enumerate(commands)
        ]
        for stamp, kind, i in sorted(events):
            if kind == 0:
                stamp_msg = time_type(sec=stamp // 1_000_000_000, nanosec=stamp % 1_000_000_000)
                msg = js_type(header=header_type(stamp=stamp_msg, frame_id=""), name=list(joints),
                              position=np.asarray(positions[i], dtype=np.float64), velocity=empty, effort=empty)  # fmt: skip
                writer.write(joint_states, stamp, store.serialize_cdr(msg, js_type.__msgtype__))
            else:
                writer.write(
                    command, stamp, store.serialize_cdr(_command(store, command_type, commands[i][1]), command_type)
                )
    return path


def _command(store, msgtype: str, values: Sequence[float]):
    kind = store.types[msgtype]
    if msgtype == "std_msgs/msg/Float64":
        return kind(data=float(values[0]))
    layout = store.types["std_msgs/msg/MultiArrayLayout"](dim=[], data_offset=0)
    return kind(layout=layout, data=np.asarray(values, dtype=np.float64))


def main() -> None:
    t, u, y = twin_record()
    write_csv(HERE / "xm430.csv", t, u, y)
    write_mat(HERE / "xm430.mat", {"t": t, "goal": u, "pos": y, "log": np.column_stack([t, u, y])})
    bag = HERE / "xm430_bag"
    if bag.exists():
        for f in bag.iterdir():
            f.unlink()
        bag.rmdir()
    stamps = START_NS + np.round(t * 1e9).astype(np.int64)
    base = np.zeros_like(y)
    write_bag(bag, stamps, np.column_stack([base, y]), ["base", "wrist"],
              [(s + COMMAND_LAG_NS, (0.0, v)) for s, v in zip(stamps, u)])  # fmt: skip
    for f in sorted([*HERE.glob("xm430*"), *bag.iterdir()]):
        if f.is_file():
            print(f"{f.relative_to(HERE.parent.parent)}  {os.path.getsize(f)} bytes")


if __name__ == "__main__":
    main()
