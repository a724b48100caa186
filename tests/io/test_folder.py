"""A folder of images and its manifest (sunlab.io.folder): manifests that would name another
place, loop, or overflow are refused with their line (issue 37)."""

from __future__ import annotations

import hashlib
import os

import numpy as np
import pytest
from PIL import Image

from sunlab import cli, io
from sunlab.errors import SchemaError


@pytest.fixture
def folder(tmp_path):
    imgs = tmp_path / "imgs"
    imgs.mkdir()
    for k in range(2):
        Image.fromarray(np.full((8, 10), 100 + k, np.uint16)).save(imgs / f"f{k}.png")
    return imgs


def _manifest(folder, header="file,alpha,beta,shot", extra=("", "")):
    rows = [header] + [f"f{k}.png,{k},0,0{extra[k]}" for k in range(2)]
    (folder / "manifest.csv").write_text("\n".join(rows) + "\n")


def _tree(root):
    return {p: hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(root.rglob("*"))
            if p.is_file()}


@pytest.mark.parametrize("name", ["..", "../../x", "a/b", ".hidden", "__x", "zarr.json",
                                  "ZARR.JSON"])
def test_an_extra_column_that_names_a_path_is_refused(folder, tmp_path, capsys, name):
    _manifest(folder, f"file,alpha,beta,shot,{name}", (",1", ",2"))
    with pytest.raises(SchemaError, match="cannot name a variable"):
        io.open_frames(folder, bit_depth=10)
    before = _tree(tmp_path)
    status = cli.main(["import", str(folder), "--out", str(tmp_path / "cube.zarr"),
                       "--bit-depth", "10", "--no-progress"])
    err = capsys.readouterr().err.strip()
    assert status == 1 and len(err.splitlines()) == 1 and "rename the column" in err
    assert _tree(tmp_path) == before and not (tmp_path / "cube.zarr").exists()


def test_an_ordinary_extra_column_is_kept(folder):
    _manifest(folder, "file,alpha,beta,shot,exposure_ms", (",2.5", ",2.5"))
    cube = io.open_frames(folder, bit_depth=10)
    assert cube["exposure_ms"].values.tolist() == [[2.5], [2.5]]


def test_a_symlink_loop_in_a_manifest_is_named_by_its_line(folder):
    os.symlink("loop_b.png", folder / "loop_a.png")
    os.symlink("loop_a.png", folder / "loop_b.png")
    (folder / "manifest.csv").write_text("file,alpha,beta,shot\nf0.png,0,0,0\n"
                                         "loop_a.png,1,0,0\n")
    with pytest.raises(SchemaError, match=r"manifest manifest.csv line 3 column 'file'"):
        io.open_frames(folder, bit_depth=10)


def test_a_page_of_1e19_is_refused_naming_its_line(folder, capsys, tmp_path):
    (folder / "manifest.csv").write_text("file,alpha,beta,shot,page\nf0.png,0,0,0,0\n"
                                         "f1.png,1,0,0,1e19\n")
    with pytest.raises(SchemaError, match=r"line 3 column 'page': found '1e19'"):
        io.open_frames(folder, bit_depth=10)
    status = cli.main(["import", str(folder), "--out", str(tmp_path / "c.zarr"),
                       "--bit-depth", "10", "--no-progress"])
    err = capsys.readouterr().err
    assert status == 1 and "line 3" in err and "-9223372036854775808" not in err


def test_a_manifest_with_comma_decimals_is_refused(folder):
    (folder / "manifest.csv").write_text("file,alpha,beta,shot\nf0.png,0,5,0,0\n"
                                         "f1.png,1,5,0,0\n")
    with pytest.raises(SchemaError, match=r"line 2: found '5 fields'"):
        io.open_frames(folder, bit_depth=10)


def test_a_manifest_with_a_duplicated_column_is_refused(folder):
    _manifest(folder, "file,alpha,beta,shot,alpha", (",7", ",8"))
    with pytest.raises(SchemaError, match=r"column 'alpha' twice"):
        io.open_frames(folder, bit_depth=10)
