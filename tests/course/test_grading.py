"""The gradebook (sunlab.course.grading): totals per student, written answers apart, and the
CSV and JSON files written both or neither (grading itself runs kernels: tests/test_course.py)."""

import csv
import io
import json

import pytest

from sunlab.course.grading import COLUMNS, csv_text, totals, write_gradebook
from sunlab.errors import SunlabError

ROWS = [
    {"student": "ada", "notebook": "03.ipynb", "exercise": "03.1", "points": 2, "max_points": 2,
     "message": "passed"},
    {"student": "ada", "notebook": "03.ipynb", "exercise": "03.2", "points": 0, "max_points": 1,
     "message": "check altered: scored 0"},
    {"student": "ada", "notebook": "03.ipynb", "exercise": "03.3", "points": None,
     "max_points": 3, "message": "written answer: graded by hand"},
    {"student": "bo", "notebook": "03.ipynb", "exercise": "03.1", "points": 1, "max_points": 2,
     "message": "partly"},
]


def test_totals_keep_hand_graded_points_apart():
    assert totals(ROWS) == {
        "ada": {"points": 2, "max_points": 3, "written_max_points": 3},
        "bo": {"points": 1, "max_points": 2, "written_max_points": 0},
    }


def test_csv_has_the_columns_and_an_empty_cell_for_a_written_answer():
    rows = list(csv.DictReader(io.StringIO(csv_text(ROWS))))
    assert tuple(rows[0]) == COLUMNS and len(rows) == 4
    assert rows[0]["points"] == "2" and rows[2]["points"] == ""
    assert rows[1]["message"] == "check altered: scored 0"


def test_gradebook_files_are_written_together_and_kept_unless_overwrite(tmp_path):
    folder = tmp_path / "grades"
    paths = write_gradebook(ROWS, folder, seed=77)
    assert [p.name for p in paths] == ["gradebook.csv", "gradebook.json"]
    doc = json.loads(paths[1].read_text())
    assert doc["seed"] == 77 and doc["columns"] == list(COLUMNS)
    assert doc["totals"] == totals(ROWS) and doc["rows"][2]["points"] is None
    before = paths[0].read_text()
    with pytest.raises(SunlabError, match="--overwrite"):
        write_gradebook(ROWS[:1], folder, seed=1)
    assert paths[0].read_text() == before and json.loads(paths[1].read_text())["seed"] == 77
    write_gradebook(ROWS[:1], folder, seed=1, overwrite=True)
    assert json.loads(paths[1].read_text())["seed"] == 1
