"""The ``calibration/1`` artifact read back (sunlab.calibration.artifact): a file whose checksum
matches but whose numbers no double can hold is refused with one line, by the library and by
every command that reads it (issue 37)."""

from __future__ import annotations

import json

import pytest

from sunlab import calibration, cli, integrity, sim
from sunlab.errors import SchemaError, SunlabError

HUGE = 10**399  # 400 digits: valid JSON (Python reads up to 4,300 digits), no double


@pytest.fixture(scope="module")
def cal():
    cen = sim.synthetic_centroids([0.0, 1, 2, 0, 1, 2, 0, 1, 2], [0.0, 0, 0, 1, 1, 1, 2, 2, 2])
    return calibration.Polynomial(order=1).fit(cen)


def _sealed_with_huge_coefficient(cal, path):
    doc = cal.to_dict()
    doc["parameters"]["coefficients"]["alpha"][1] = HUGE
    path.write_text(json.dumps(integrity.seal_document(doc)))
    return path


def test_from_dict_refuses_an_integer_no_double_can_hold(cal):
    doc = cal.to_dict()
    doc["parameters"]["coefficients"]["alpha"][1] = HUGE
    with pytest.raises(SchemaError, match=r"parameters.coefficients.alpha\[1\].*a finite number"):
        calibration.artifact.from_dict(doc)


def test_load_refuses_a_sealed_file_with_a_400_digit_coefficient(cal, tmp_path):
    path = _sealed_with_huge_coefficient(cal, tmp_path / "cal.json")
    with pytest.raises(SunlabError, match=r"parameters.coefficients.alpha\[1\]: found an "
                                          r"integer of 400 digits"):
        calibration.load(path)


@pytest.mark.parametrize("argv", [["export", "{cal}", "--out", "{tmp}/onboard"],
                                  ["evaluate", "{cal}", "{tmp}/test.csv"],
                                  ["info", "{cal}"]])
def test_every_command_refuses_it_in_one_line_with_status_1(cal, tmp_path, capsys, argv):
    path = _sealed_with_huge_coefficient(cal, tmp_path / "cal.json")
    (tmp_path / "test.csv").write_text("alpha,beta,x,y\n0,0,1,2\n")
    status = cli.main([a.format(cal=path, tmp=tmp_path) for a in argv])
    err = capsys.readouterr().err.strip()
    assert status == 1, err
    assert len(err.splitlines()) == 1 and "integer of 400 digits" in err
    assert not (tmp_path / "onboard").exists()
