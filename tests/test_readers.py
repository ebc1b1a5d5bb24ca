"""Every reader on small files (shipped under tests/data/ by tests/data/make_data.py, or written here), and its errors.

The shipped files hold one record of the XM430 twin in three layouts; each
reader must give back the same samples. The bad files each break one rule,
and the message must name the value, the column, variable or topic, and what
is there instead.
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

from servoid.errors import ConfigError, DataError, MissingDependency
from servoid.readers import ReadOptions, from_dataframe, read, read_bam, read_mat, read_rosbag
from servoid.readers.excitation_file import read_excitation
from servoid.readers.mat import mat_variables
from servoid.readers.options import parse_columns, parse_topics
from servoid.recording import NO_TIME, read_recording, write_recording

DATA = Path(__file__).resolve().parent / "data"
EMPS = Path(__file__).resolve().parents[2] / "shared" / "data" / "emps" / "DATA_EMPS.mat"
BAG_TOPICS = {"y": "/joint_states:wrist", "u": "/forward_position_controller/commands:1"}


def _make_data():
    spec = importlib.util.spec_from_file_location("make_data", DATA / "make_data.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


make_data = _make_data()


@pytest.fixture(scope="module")
def reference():
    """The shipped record as the CSV holds it (u, y to 10 digits, t in seconds)."""
    return read(DATA / "xm430.csv", ReadOptions(columns={"u": "goal", "y": "pos", "t": "time_ms"}, time_unit="ms"))


# -- CSV --------------------------------------------------------------------------------------------------


def test_csv_column_map_and_time_unit(reference):
    assert len(reference) == make_data.SAMPLES and reference.sample_period == pytest.approx(make_data.PERIOD_S)
    assert reference.metadata["unit"] == "rad" and reference.notes == ()
    # the same file read as seconds: the reader says the period looks wrong instead of a 10 s sample period silently
    as_seconds = read_recording(DATA / "xm430.csv", u_column="goal", y_column="pos", time_column="time_ms")
    assert as_seconds.sample_period == pytest.approx(10.0)
    assert "if time_ms is not in seconds" in as_seconds.notes[0]


def test_csv_time_unit_from_metadata_and_no_time(tmp_path):
    p = tmp_path / "r.csv"
    p.write_text("# time_unit: us\nt,u,y\n0,1,2\n500,3,4\n1000,5,6\n")
    assert read_recording(p).sample_period == pytest.approx(5e-4)
    p.write_text("t,u,y\n0,1,2\n0,3,4\n")
    rec = read_recording(p, time_column=NO_TIME)
    assert rec.t is None and rec.u.tolist() == [1, 3]


def _bad(tmp_path, text):
    p = tmp_path / "bad.csv"
    p.write_text(text)
    return p


@pytest.mark.parametrize(
    "text, kwargs, fragment",
    [
        ("t,u,y\n0.3,1,2\n0.2,3,4\n0.1,5,6\n", {}, "line 3: t (=0.2 s) is earlier than the one before (0.3 s)"),
        ("t,u,y\n1,1,2\n1,3,4\n1,5,6\n", {}, "line 3: t (=1.0 s) repeats the one before"),
        ("t,u,y\n0,1,2\n2,3,4\n1,5,6\n3,1,1\n", {}, "line 4: t (=1.0 s) is earlier"),
        ("t,u,y,u\n0,1,2,3\n1,3,4,5\n", {}, "column 'u' appears 2 times in the header (columns 2, 4)"),
        ("a,b\n1,2\n", {"u_column": "goal"}, "missing column(s) 'goal', 'y'; the header has 'a', 'b'"),
        ("time,u,y\n0,1,2\n", {"time_column": "stamp"}, "missing column(s) 'stamp'"),
        ("u,y\n1,2\n" + "3," + "9" * 140_000 + "\n", {}, "line 3: field larger than field limit (131072)"),
        ("u,y\n1,2\n3,-1e300\n", {}, "y[1] (=-1e+300) lies beyond +/-1e+100"),
        ("u,pos\n1,2\n3,1e300\n", {"y_column": "pos"}, "pos[1] (=1e+300) lies beyond +/-1e+100"),
    ],
)
def test_csv_refuses_with_one_line_naming_the_problem(tmp_path, text, kwargs, fragment):
    with pytest.raises(DataError) as info:
        read_recording(_bad(tmp_path, text), **kwargs)
    message = str(info.value)
    assert fragment in message and "\n" not in message


def test_csv_duplicate_columns_it_does_not_read_are_fine_and_gaps_are_noted(tmp_path):
    p = _bad(tmp_path, "t,u,y,x,x\n0,1,2,0,0\n1,3,4,0,0\n2,5,6,0,0\n10,7,8,0,0\n11,9,9,0,0\n")
    rec = read_recording(p)
    assert rec.u.tolist() == [1, 3, 5, 7, 9]
    assert "1 gap(s) in time longer than 2 sample periods" in rec.notes[0] and "line 5" in rec.notes[0]


def test_unknown_time_unit(tmp_path):
    with pytest.raises(ConfigError, match="time unit 'min' is not one of s, ms, us, ns"):
        read_recording(_bad(tmp_path, "t,u,y\n0,1,2\n"), time_unit="min")


# -- MATLAB -----------------------------------------------------------------------------------------------


def test_mat_reads_vectors_matrix_columns_and_lists_variables(reference):
    rec = read_mat(DATA / "xm430.mat", u="goal", y="pos")
    assert np.allclose(rec.u, reference.u, atol=1e-9) and np.allclose(rec.y, reference.y, atol=1e-9)
    assert rec.sample_period == pytest.approx(make_data.PERIOD_S)
    cols = read_mat(DATA / "xm430.mat", u="log(:,2)", y="log(:, 3)", t="log(:,1)")
    assert np.array_equal(cols.u, rec.u) and np.array_equal(cols.t, rec.t)
    assert mat_variables(DATA / "xm430.mat")["log"] == f"{make_data.SAMPLES}x3"
    with pytest.raises(
        DataError, match=r"no variable 'u'; the file has t \(1500x1\), goal \(1500x1\), pos \(1500x1\), log \(1500x3\)"
    ):
        read_mat(DATA / "xm430.mat")
    with pytest.raises(DataError, match="'log' of .* is a 1500x3 matrix; expected a vector"):
        read_mat(DATA / "xm430.mat", u="log", y="pos")
    with pytest.raises(DataError, match=r"'log\(:,4\)' is outside 'log', a 1500x3 matrix \(indices start at 1\)"):
        read_mat(DATA / "xm430.mat", u="log(:,4)", y="pos")


def test_mat_v73_is_read_with_h5py(tmp_path, reference):
    pytest.importorskip("h5py")
    p = make_data.write_mat73(tmp_path / "v73.mat", {"t": reference.t, "cmd": reference.u, "pos": reference.y})
    rec = read_mat(p, u="cmd", y="pos")
    assert np.array_equal(rec.u, reference.u) and np.array_equal(rec.t, reference.t)
    with pytest.raises(DataError, match=r"no variable 'u'; the file has cmd \(1500x1\), pos \(1500x1\), t"):
        read_mat(p)


def test_mat_v73_without_h5py_names_the_extra(tmp_path, reference, monkeypatch):
    pytest.importorskip("h5py")
    p = make_data.write_mat73(tmp_path / "v73.mat", {"u": reference.u, "y": reference.y})
    monkeypatch.setitem(sys.modules, "h5py", None)  # import h5py now raises ImportError
    with pytest.raises(MissingDependency, match=r"v7.3 \(HDF5\) file, which needs h5py: pip install 'servoid\[mat\]'"):
        read_mat(p)


def test_mat_not_a_mat_file(tmp_path):
    p = tmp_path / "x.mat"
    p.write_text("hello")
    with pytest.raises(DataError, match="not a MATLAB .mat file"):
        read_mat(p)


@pytest.mark.skipif(not EMPS.exists(), reason=f"EMPS data not found at {EMPS}")
def test_mat_reads_the_emps_benchmark():
    rec = read(EMPS, ReadOptions(columns={"u": "qg", "y": "qm", "t": "t"}))
    assert len(rec) == 24841 and rec.sample_period == pytest.approx(1e-3, rel=1e-3)


# -- ROS bags ---------------------------------------------------------------------------------------------


def test_bag_reads_a_joint_and_an_array_command(reference):
    pytest.importorskip("rosbags")
    rec = read(DATA / "xm430_bag", ReadOptions(topics=BAG_TOPICS))
    # each measurement takes the command of its own cycle (sent 0.5 ms after it): the CSV's pairing
    assert np.allclose(rec.u, reference.u, atol=1e-9) and np.allclose(rec.y, reference.y, atol=1e-9)
    assert rec.sample_period == pytest.approx(make_data.PERIOD_S) and rec.notes == ()
    field = read_rosbag(DATA / "xm430_bag", y="/joint_states:position[1]", u=BAG_TOPICS["u"])
    assert np.array_equal(field.y, rec.y)


def _bag(tmp_path, y_ns, u_events, *, storage="sqlite3", command_type="std_msgs/msg/Float64", joints=("j1",)):
    positions = [[0.001 * k] * len(joints) for k in range(len(y_ns))]
    return make_data.write_bag(tmp_path / "bag", y_ns, positions, joints, u_events, command_topic="/cmd",
                               command_type=command_type, storage=storage)  # fmt: skip


def test_bag_alignment_holds_the_last_command_before_the_next_measurement(tmp_path):
    pytest.importorskip("rosbags")
    ms = 1_000_000
    y_ns = [10 * ms * k for k in range(6)]  # measurements every 10 ms from 0
    # the first command arrives after the second measurement; then three commands in one interval
    u_events = [(15 * ms, [1.0]), (31 * ms, [2.0]), (33 * ms, [3.0]), (38 * ms, [4.0])]
    rec = read_rosbag(_bag(tmp_path, y_ns, u_events), y="/joint_states", u="/cmd")
    assert rec.u.tolist() == [1.0, 1.0, 4.0, 4.0, 4.0]  # samples 1..5: the interval each one opens
    assert rec.y.tolist() == pytest.approx([0.001, 0.002, 0.003, 0.004, 0.005])
    assert rec.t.tolist() == pytest.approx([0.0, 0.01, 0.02, 0.03, 0.04])
    assert "dropped 1 measurement(s) on /joint_states made before the first command on /cmd" in rec.notes


@pytest.mark.parametrize(
    "y, u, fragment",
    [
        ("/js", "/cmd", "no topic '/js' (for y); the bag has /joint_states (sensor_msgs/msg/JointState), /cmd"),
        ("/joint_states", "/cmd", "has joints j1, j2: name one, e.g. TOPIC:j1"),
        ("/joint_states:j9", "/cmd", "no joint or field 'j9'; the joints are j1, j2"),
        ("/joint_states:position[7]", "/cmd", "index 7 in 'position[7]' is outside its 2 values"),
        ("/joint_states:j1", "/cmd:2", "holds one value, 'data'; drop the selector '2'"),
        ("/joint_states:header", "/cmd", "field 'header', is a"),
    ],
)
def test_bag_names_the_missing_topic_joint_or_field(tmp_path, y, u, fragment):
    pytest.importorskip("rosbags")
    bag = _bag(tmp_path, [0, 10_000_000], [(1, [0.5])], joints=("j1", "j2"), storage="mcap")
    with pytest.raises(DataError) as info:
        read_rosbag(bag, y=y, u=u)
    assert fragment in str(info.value) and "\n" not in str(info.value)


def test_bag_without_topics_lists_them_and_refuses_csv_options(tmp_path):
    pytest.importorskip("rosbags")
    bag = _bag(tmp_path, [0, 10_000_000], [(1, [0.5])])
    with pytest.raises(DataError, match=r"needs its topics named .* missing y, u; the bag has /joint_states"):
        read(bag)
    with pytest.raises(ConfigError, match="has no columns to map"):
        read(bag, ReadOptions(columns={"u": "x"}, topics={"y": "/joint_states", "u": "/cmd"}))
    with pytest.raises(ConfigError, match="--topics applies to ROS bags"):
        read(DATA / "xm430.csv", ReadOptions(topics={"y": "/a"}))


# -- DataFrames, BAM logs, the entry point ------------------------------------------------------------------


def test_dataframe_columns_and_time_index(reference):
    pd = pytest.importorskip("pandas")
    index = pd.to_datetime("2024-05-01T12:00:00") + pd.to_timedelta(reference.t, unit="s")
    frame = pd.DataFrame({"goal": reference.u, "pos": reference.y}, index=index)
    rec = from_dataframe(frame, u="goal", y="pos", t="index", metadata={"unit": "rad"})
    assert np.array_equal(rec.u, reference.u) and rec.sample_period == pytest.approx(make_data.PERIOD_S)
    assert rec.metadata["unit"] == "rad"
    with pytest.raises(DataError, match="the DataFrame has no column 'u'; its columns: goal, pos"):
        from_dataframe(frame)
    twice = pd.DataFrame([[1.0, 2.0, 3.0]], columns=["u", "y", "u"])
    with pytest.raises(DataError, match="the DataFrame has 2 columns named 'u'"):
        from_dataframe(twice)


def test_bam_names_the_missing_field(tmp_path):
    p = tmp_path / "x.json"
    p.write_text('{"entries": [{"timestamp": 0, "position": 1.0}]}')
    with pytest.raises(DataError, match="entry 0 has no field 'goal_position'; it has timestamp, position"):
        read_bam(p)
    with pytest.raises(DataError, match="not a MATLAB"):
        read_mat(p)


@pytest.mark.parametrize(
    "value, fragment",
    [
        ("true", "sample 1 (=True) is not a number"),
        ("1" + "0" * 400, "sample 1 (an integer of about 401 digits) lies beyond +/-1e+100"),
        ("1e300", "position[1] (=1e+300) lies beyond +/-1e+100"),
        ('"x"', "sample 1 (='x') is not a number"),
        ("[1, 2]", "sample 1 (=[1, 2]) is not a number"),
    ],
)
def test_bam_refuses_values_that_are_no_numbers_or_beyond_the_limit(tmp_path, value, fragment):
    p = tmp_path / "x.json"
    entries = [f'{{"timestamp": {k}, "goal_position": 0.5, "position": {value if k == 1 else 0.25}}}' for k in range(3)]
    p.write_text('{"entries": [' + ", ".join(entries) + "]}")
    with pytest.raises(DataError) as info:
        read_bam(p)
    assert fragment in str(info.value) and "\n" not in str(info.value)


def test_mat_refuses_complex_variables_and_values_beyond_the_limit(tmp_path):
    scipy_io = pytest.importorskip("scipy.io")
    p = tmp_path / "x.mat"
    scipy_io.savemat(p, {"u": np.array([1 + 2j, 0j, 1j]), "y": np.ones(3), "big": np.array([0.0, -1e300, 1.0])})
    with pytest.raises(DataError, match="variable 'u' of .* holds complex numbers; expected real ones"):
        read_mat(p)
    with pytest.raises(DataError, match=r"big\[1\] \(=-1e\+300\) lies beyond \+/-1e\+100"):
        read_mat(p, u="big")


def test_dataframe_refuses_true_false_columns():
    pd = pytest.importorskip("pandas")
    frame = pd.DataFrame({"u": [True, False, True], "y": [0.1, 0.2, 0.3]})
    with pytest.raises(DataError, match="column 'u' holds true/false values; expected numbers"):
        from_dataframe(frame)


def test_read_picks_by_suffix_and_refuses_unknown(tmp_path):
    with pytest.raises(DataError, match=r"cannot tell the format from '.xlsx'; servoid reads .csv, .txt, .mat"):
        read(tmp_path / "x.xlsx")


def test_option_strings_parse_and_refuse():
    assert parse_columns("u=goal, y=pos,t=none") == {"u": "goal", "y": "pos", "t": "none"}
    assert parse_columns("u=log(:,2),y=log(:, 3)") == {"u": "log(:,2)", "y": "log(:, 3)"}
    assert parse_topics("y=/joint_states:j2,u=/cmd") == {"y": "/joint_states:j2", "u": "/cmd"}
    for text, fragment in [("u=a,u=b", "'u' is given twice"), ("x=a", "unknown role 'x'"), ("u", "must be ROLE=NAME")]:
        with pytest.raises(ConfigError, match=fragment):
            parse_columns(text)


# -- replaying an excitation, recording operations --------------------------------------------------------


def test_excitation_file_reads_a_column_or_variable_and_checks_limits(tmp_path, reference):
    p = write_recording(tmp_path / "exc.csv", {"t": reference.t, "u": reference.u, "cmd": 2 * reference.u})
    assert np.array_equal(read_excitation(f"file:{p}").u, reference.u)
    named = read_excitation(f"file:{p}:cmd")
    assert np.array_equal(named.u, 2 * reference.u) and named.first(10).size == 10
    assert np.array_equal(
        read_excitation(f"file:{DATA / 'xm430.mat'}:goal").u, read_mat(DATA / "xm430.mat", u="goal", y="pos").u
    )
    with pytest.raises(DataError, match=r"missing column\(s\) 'x'; the header has 't', 'u', 'cmd'"):
        read_excitation(f"file:{p}:x")
    with pytest.raises(ConfigError, match=r"--samples \(=2000\) must lie in \[1, 1500\]"):
        named.first(2000)
    with pytest.raises(ConfigError, match=r"u\[\d+\] \(=-?0.1\d* rad\) lies outside the servo's limits \[-0.1, 0.1\]"):
        named.check_within(-0.1, 0.1, unit="rad")
    with pytest.raises(ConfigError, match=r"steps by .* over the servo's max_step 0.01"):
        read_excitation(f"file:{p}").check_within(-1, 1, 0.01)


def test_recording_split_decimate_and_csv_roundtrip(tmp_path, reference):
    first, second = reference.split(0.6)
    assert len(first) == 900 and len(second) == 600 and second.t[0] == reference.t[900]
    thin = reference.decimated(10)
    assert len(thin) == 150 and thin.sample_period == pytest.approx(0.1) and thin.metadata["decimated_by"] == "10"
    back = read_recording(thin.to_csv(tmp_path / "thin.csv"))
    assert np.array_equal(back.u, thin.u) and np.array_equal(back.t, thin.t)
