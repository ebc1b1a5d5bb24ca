"""Reading the files servoid is given: each failure a one-line error naming the file."""

import pytest

from servoid.errors import DataError
from servoid.files import existing_file, read_json, read_text


def test_each_failure_names_the_file_and_the_problem(tmp_path):
    with pytest.raises(DataError, match=r"nope\.json: no such model file"):
        existing_file(tmp_path / "nope.json", what="model file")
    with pytest.raises(DataError, match="is a directory, expected a CSV file"):
        read_text(tmp_path, what="CSV file")
    (tmp_path / "latin1.csv").write_bytes("u,y\n1,\xe9\n".encode("latin-1"))
    with pytest.raises(DataError, match="latin1.csv: cannot read as UTF-8 text"):
        read_text(tmp_path / "latin1.csv")
    (tmp_path / "bad.json").write_text("{not json")
    with pytest.raises(DataError, match="bad.json: not a JSON file"):
        read_json(tmp_path / "bad.json")
    (tmp_path / "ok.json").write_text('{"a": [1, 2]}')
    assert read_json(tmp_path / "ok.json") == {"a": [1, 2]}
