"""Foreign CSV tables (sunlab.io.csvtable): a table another tool wrote is read exactly or
refused naming its line, never read with shifted columns (issue 37)."""

from __future__ import annotations

import numpy as np
import pytest

from sunlab import cli, io
from sunlab.errors import SchemaError

GRID = [(a, b) for a in (-8.0, -4.0, 0.0, 4.0, 8.0) for b in (-8.0, -4.0, 0.0, 4.0, 8.0)]


def _rows(sep=",", dec=".", trailing=""):
    lines = []
    for a, b in GRID:
        x, y = f"{640 + 36.5 * a:.2f}", f"{512 + 36.25 * b:.2f}"
        lines.append(sep.join(v.replace(".", dec) for v in (f"{a:g}", f"{b:g}", x, y))
                     + trailing)
    return lines


def _write(path, header, lines):
    path.write_text("\n".join([header, *lines]) + "\n")
    return path


def test_trailing_commas_read_the_same_table(tmp_path):
    clean = io.open_centroids(_write(tmp_path / "a.csv", "alpha,beta,x,y", _rows()))
    trailing = io.open_centroids(_write(tmp_path / "b.csv", "alpha,beta,x,y,",
                                        _rows(trailing=",")))
    np.testing.assert_array_equal(trailing["x"].values, clean["x"].values)
    np.testing.assert_array_equal(trailing["alpha"].values, clean["alpha"].values)


def test_comma_decimals_are_refused_naming_the_line(tmp_path):
    path = _write(tmp_path / "t.csv", "alpha,beta,x,y", _rows(dec=","))
    with pytest.raises(SchemaError, match=r"t.csv line 2: found '.* fields', expected the "
                                          r"header's 4 .*write decimals with '.'"):
        io.open_centroids(path)


def test_a_semicolon_table_is_refused_with_the_fix(tmp_path):
    path = _write(tmp_path / "t.csv", "alpha;beta;x;y", _rows(sep=";", dec=","))
    with pytest.raises(SchemaError, match=r"line 1: found \"fields separated by ';'\""):
        io.open_centroids(path)


def test_a_duplicated_column_is_refused(tmp_path):
    path = _write(tmp_path / "t.csv", "alpha,beta,x,x", _rows())
    with pytest.raises(SchemaError, match=r"column 'x' twice \(columns 3 and 4\)"):
        io.open_centroids(path)


def test_a_column_name_with_an_escape_sequence_is_refused_escaped(tmp_path, capsys):
    path = _write(tmp_path / "t.csv", "alpha,beta,x,y,\x1b[2Jnote", _rows(trailing=",1"))
    status = cli.main(["calibrate", str(path), "--out", str(tmp_path / "cal.json")])
    err = capsys.readouterr().err
    assert status == 1 and "\x1b" not in err and "\\x1b[2Jnote" in err


def test_a_commanded_angle_of_a_million_degrees_is_refused_naming_its_line(tmp_path, capsys):
    lines = _rows()
    lines[7] = "1e6," + lines[7].split(",", 1)[1]
    path = _write(tmp_path / "t.csv", "# from the bench log\nalpha,beta,x,y", lines)
    with pytest.raises(SchemaError, match=r"t.csv line 10 column 'alpha': found '1e6', "
                                          r"expected a commanded angle within \(-90, 90\)"):
        io.open_centroids(path)
    status = cli.main(["calibrate", str(path), "--out", str(tmp_path / "cal.json")])
    err = capsys.readouterr().err.strip()
    assert status == 1 and len(err.splitlines()) == 1 and "line 10" in err
    assert not (tmp_path / "cal.json").exists()


@pytest.mark.parametrize("header, lines", [
    ("alpha,beta,x,y", lambda rows: [r.replace(".", ",") for r in rows]),
    ("alpha,beta,x,x", lambda rows: rows),
])
def test_calibrate_refuses_a_misread_table_in_one_line(tmp_path, capsys, header, lines):
    path = _write(tmp_path / "t.csv", header, lines(_rows()))
    status = cli.main(["calibrate", str(path), "--out", str(tmp_path / "cal.json")])
    err = capsys.readouterr().err.strip()
    assert status == 1 and len(err.splitlines()) == 1 and "Fix:" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["t.csv"]


def test_a_repeated_pose_and_shot_is_refused_naming_both_lines(tmp_path):
    path = _write(tmp_path / "t.csv", "alpha,beta,x,y,shot",
                  ["0,0,640,512,0", "0,0,641,512,1", "0,0,642,512,1"])
    with pytest.raises(SchemaError, match=r"t.csv line 4: found 'alpha=0, beta=0, shot=1 again "
                                          r"\(first on line 3\)'") as err:
        io.open_centroids(path)
    assert "remove the duplicate row" in err.value.fix


def test_a_status_column_reads_names_and_codes_and_refuses_others_naming_the_line(tmp_path):
    rows = ["0,0,640,512,ok", "1,0,,,no_spot", "2,0,700,512,2"]
    cen = io.open_centroids(_write(tmp_path / "s.csv", "alpha,beta,x,y,status", rows))
    assert cen.status.values.ravel().tolist() == [0, 1, 2]  # ok, no_spot, saturated
    path = _write(tmp_path / "t.csv", "alpha,beta,x,y,status", [*rows[:2], "2,0,700,512,lost"])
    with pytest.raises(SchemaError, match=r"t.csv line 4 column 'status': found 'lost'") as err:
        io.open_centroids(path)
    assert "no_spot" in err.value.expected and err.value.fix
