"""Nothing lost, nothing silent: a table of bad inputs (issue 14).

Each row is one bad input: a damaged store, a wrong argument, a calibration file edited by hand,
an output that already exists, a folder that cannot be written, a stage whose error reply is
lost. Every row asserts

* the error (or flag) expected, with a message that names the thing at fault;
* on the command line (``sunlab.cli.main`` in-process): a non-zero exit, no traceback, one
  ``error:`` line;
* that every file present before the row ran is still there, byte for byte (hash before and
  after), and that a failed write leaves no temporary file behind;
* no silent wrong result: corrupt data fail to read rather than read back wrong.

Rows marked ``OK`` are the positive controls of the same paths (an old store without checksums
still opens, ``--overwrite`` does replace).
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import tracemalloc
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from sunlab import calibration, cli, integrity, io, schema, sim
from sunlab.errors import SchemaError, SunlabError

NY, NX = 24, 32


# ------------------------------------------------------------------------------------------
# Assets: written once, copied into each row's folder
# ------------------------------------------------------------------------------------------
def _frames(seed: int = 0, peak: int = 1000) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return rng.integers(0, peak, (2, 2, NY, NX)).astype(np.uint16)


@pytest.fixture(scope="module")
def assets(tmp_path_factory):
    root = tmp_path_factory.mktemp("assets")
    cube = schema.frames_dataset(_frames(), alpha=[0.0, 1.0], beta=[0.0, 0.0])
    io.save_frames(cube, root / "cube.zarr")
    io.save_frames(cube, root / "cube.nc")
    a, b = np.meshgrid(np.arange(-8.0, 9.0, 4), np.arange(-8.0, 9.0, 4), indexing="ij")
    cen = sim.synthetic_centroids(a.ravel(), b.ravel(), shots=2)
    io.save_centroids(cen, root / "cen.zarr")
    io.save_centroids(cen, root / "cen.nc")
    cal = calibration.Polynomial(order=2).fit(cen)
    (root / "cal.json").write_text(json.dumps(cal.to_dict()))
    trig = calibration.Trigonometric(order=1).fit(cen)
    (root / "trig.json").write_text(json.dumps(trig.to_dict()))
    interp = calibration.Interpolation("linear").fit(cen)
    (root / "interp.json").write_text(json.dumps(interp.to_dict()))
    ideal = calibration.IdealModel().fit(cen)
    (root / "ideal.json").write_text(json.dumps(ideal.to_dict()))
    opt = calibration.OptimisedModel().fit(cen)
    (root / "opt.json").write_text(json.dumps(opt.to_dict()))
    from PIL import Image

    imgs = root / "imgs"
    imgs.mkdir()
    rows = ["file,alpha,beta,shot"]
    for k in range(2):
        Image.fromarray(np.full((NY, NX), 100 * k + 7, np.uint16)).save(imgs / f"f{k}.png")
        rows.append(f"f{k}.png,{k},0,0")
    (imgs / "manifest.csv").write_text("\n".join(rows) + "\n")
    return {"root": root, "cube": cube, "cen": cen, "cal": cal}


@dataclass
class Ctx:
    tmp: Path
    assets: dict
    mp: pytest.MonkeyPatch
    capsys: Any
    state: dict = field(default_factory=dict)

    def copy(self, name: str, to: str | None = None) -> Path:
        src, dst = self.assets["root"] / name, self.tmp / (to or name)
        (shutil.copytree if src.is_dir() else shutil.copy)(src, dst)
        return dst

    def cli(self, *argv) -> tuple[int, str]:
        """Run ``sunlab ARGV`` in-process; return (exit status, stderr)."""
        self.capsys.readouterr()
        try:
            rc = cli.main([str(a) for a in argv])
        except SystemExit as exc:  # argparse
            rc = exc.code
        except BaseException as exc:  # noqa: BLE001 - a traceback is what the rows look for
            pytest.fail(f"sunlab {' '.join(map(str, argv))}: traceback {exc!r}")
        err = self.capsys.readouterr().err
        return rc, err


def _hashes(root: Path) -> dict[str, str]:
    return {
        str(p.relative_to(root)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(root.rglob("*")) if p.is_file()
    }


def _no_work(*args, **kwargs):
    raise AssertionError("the work started before the output path was checked")


def _flip(path: Path, n: int = 64, at: int = 16) -> None:
    data = bytearray(path.read_bytes())
    for i in range(at, min(at + n, len(data))):
        data[i] ^= 0xFF
    path.write_bytes(bytes(data))


def _read_only(ctx: Ctx, folder: Path) -> None:
    """Make ``folder`` read-only for sunlab (tests may run as root, which chmod cannot stop)."""
    real = os.access
    folder = str(folder)
    ctx.mp.setattr(os, "access", lambda p, m, **k: False if str(p) == folder and m & os.W_OK
                   else real(p, m, **k))
    os.chmod(folder, 0o555)


def _failing_replace(ctx: Ctx) -> None:
    """os.replace raises PermissionError (the final rename of an atomic write fails)."""

    def replace(src, dst, *a, **k):
        raise PermissionError(13, "Permission denied", str(dst))

    ctx.mp.setattr(os, "replace", replace)


def _lazy_failing_cube(ctx: Ctx, fail_pose: int = 1):
    """A lazy frame cube whose second pose fails to compute (a write that dies midway)."""
    import dask.array as da

    def block(b, block_info=None):
        if block_info[0]["chunk-location"][0] == fail_pose:
            raise RuntimeError("camera link lost while rendering")
        return b

    frames = da.from_array(_frames(1), chunks=(1, 1, NY, NX)).map_blocks(block, dtype=np.uint16)
    return schema.frames_dataset(frames, alpha=[0.0, 1.0], beta=[0.0, 0.0])


def _edit_json(path: Path, edit: Callable[[dict], None]) -> Path:
    doc = json.loads(path.read_text())
    edit(doc)
    path.write_text(json.dumps(doc))
    return path


def _cal_edit(ctx: Ctx, edit: Callable[[dict], None], name: str = "cal.json") -> Path:
    return _edit_json(ctx.copy(name), edit)


def _set(*keys_value):
    """An edit that sets doc[k1][k2]... = value."""
    *keys, value = keys_value

    def edit(doc):
        d = doc
        for k in keys[:-1]:
            d = d[k]
        d[keys[-1]] = value

    return edit


# ------------------------------------------------------------------------------------------
# The rows
# ------------------------------------------------------------------------------------------
@dataclass
class Row:
    """One bad input.

    ``setup(ctx)`` makes the inputs (copied assets, monkeypatches); the files present after it
    are hashed. ``act(ctx)`` runs it: an API row raises ``exc`` matching ``match``; a CLI row
    (``cli=True``) returns ``ctx.cli(...)``, which must exit non-zero with one ``error:`` line
    matching ``match`` and no traceback; an ``ok`` row must succeed (``act`` asserts the result).
    ``changes``: files the row may change (an ``ok`` row's output).
    """

    id: str
    setup: Callable[[Ctx], Any]
    act: Callable[[Ctx], Any]
    match: str = ""
    exc: type = SunlabError
    cli: bool = False
    ok: bool = False
    code: int | None = None
    changes: tuple = ()


def nothing(ctx):
    return None


ROWS: list[Row] = []


def row(*args, **kwargs):
    ROWS.append(Row(*args, **kwargs))


# --- outputs that exist: replaced only with overwrite, and only after a complete write -------
row("save_frames zarr exists", lambda c: c.copy("cube.zarr"),
    lambda c: io.save_frames(c.assets["cube"], c.tmp / "cube.zarr"),
    r"cube.zarr: already exists.*overwrite=True")
row("save_frames nc exists", lambda c: c.copy("cube.nc"),
    lambda c: io.save_frames(c.assets["cube"], c.tmp / "cube.nc"),
    r"cube.nc: already exists.*overwrite=True")
row("save_centroids zarr exists", lambda c: c.copy("cen.zarr"),
    lambda c: io.save_centroids(c.assets["cen"], c.tmp / "cen.zarr"),
    r"cen.zarr: already exists")
row("save_centroids nc exists", lambda c: c.copy("cen.nc"),
    lambda c: io.save_centroids(c.assets["cen"], c.tmp / "cen.nc"),
    r"cen.nc: already exists")
row("Calibration.save exists", lambda c: c.copy("cal.json"),
    lambda c: c.assets["cal"].save(c.tmp / "cal.json"),
    r"cal.json: already exists.*overwrite=True")
row("save_frames zarr fails midway, overwrite", lambda c: c.copy("cube.zarr"),
    lambda c: io.save_frames(_lazy_failing_cube(c), c.tmp / "cube.zarr", overwrite=True),
    "camera link lost", exc=RuntimeError)
row("save_frames nc fails midway, overwrite", lambda c: c.copy("cube.nc"),
    lambda c: io.save_frames(_lazy_failing_cube(c), c.tmp / "cube.nc", overwrite=True),
    "camera link lost", exc=RuntimeError)
row("save_frames zarr fails midway, new path", nothing,
    lambda c: io.save_frames(_lazy_failing_cube(c, 0), c.tmp / "new.zarr"),
    "camera link lost", exc=RuntimeError)
row("save_frames over a plain folder", lambda c: (c.tmp / "notes").mkdir()
    or (c.tmp / "notes" / "keep.txt").write_text("x"),
    lambda c: io.save_frames(c.assets["cube"], c.tmp / "notes", overwrite=True),
    r"notes: is a directory, not a Zarr store; sunlab will not delete it")
row("save_centroids nc over a folder", lambda c: c.copy("cube.zarr", "t.nc"),
    lambda c: io.save_centroids(c.assets["cen"], c.tmp / "t.nc", overwrite=True),
    r"t.nc: is a directory.*will not delete")
row("save_frames missing folder (checked before the work)", nothing,
    lambda c: io.save_frames(_lazy_failing_cube(c, 0), c.tmp / "nodir" / "c.zarr"),
    r"nodir/c.zarr: the folder does not exist")
row("save_centroids missing folder", nothing,
    lambda c: io.save_centroids(c.assets["cen"], c.tmp / "nodir" / "c.nc"),
    r"nodir/c.nc: the folder does not exist")
row("Calibration.save missing folder", nothing,
    lambda c: c.assets["cal"].save(c.tmp / "nodir" / "c.json"),
    r"nodir/c.json: the folder does not exist")
row("save_frames read-only folder", lambda c: _read_only(c, c.tmp),
    lambda c: io.save_frames(c.assets["cube"], c.tmp / "c.zarr"), r"is not writable")
row("Calibration.save read-only folder", lambda c: _read_only(c, c.tmp),
    lambda c: c.assets["cal"].save(c.tmp / "c.json"), r"c.json: the folder .* not writable")
row("save_frames zarr final rename fails, overwrite",
    lambda c: (c.copy("cube.zarr"), _failing_replace(c)),
    lambda c: io.save_frames(c.assets["cube"], c.tmp / "cube.zarr", overwrite=True),
    "Permission denied", exc=PermissionError)
row("save_centroids nc final rename fails, overwrite",
    lambda c: (c.copy("cen.nc"), _failing_replace(c)),
    lambda c: io.save_centroids(c.assets["cen"], c.tmp / "cen.nc", overwrite=True),
    "Permission denied", exc=PermissionError)
row("Calibration.save final rename fails, overwrite",
    lambda c: (c.copy("cal.json"), _failing_replace(c)),
    lambda c: c.assets["cal"].save(c.tmp / "cal.json", overwrite=True),
    "Permission denied", exc=PermissionError)
row("save_frames lazy DN above bit depth, overwrite", lambda c: c.copy("cube.zarr"),
    lambda c: io.save_frames(
        schema.frames_dataset(__import__("dask.array").array.from_array(
            _frames(peak=4000), chunks=(1, 1, NY, NX)), alpha=[0.0, 1.0], beta=[0.0, 0.0]),
        c.tmp / "cube.zarr", overwrite=True),
    r"cube.zarr \(being written\) frames chunk \(pose \d, shot \d, .*DN up to 39\d\d.*bit_depth",
    exc=SchemaError)


def _overwrite_replaces(c):
    io.save_frames(c.assets["cube"].assign(frames=c.assets["cube"].frames // 2),
                   c.tmp / "cube.zarr", overwrite=True)
    back = io.open_frames(c.tmp / "cube.zarr")
    np.testing.assert_array_equal(back.frames.values, c.assets["cube"].frames.values // 2)
    assert sorted(p.name for p in c.tmp.iterdir()) == ["cube.zarr"]  # nothing left aside


row("OK save_frames overwrite=True replaces", lambda c: c.copy("cube.zarr"),
    _overwrite_replaces, ok=True, changes=("cube.zarr",))


def _cal_overwrite(c):
    c.assets["cal"].save(c.tmp / "cal.json", overwrite=True)
    assert calibration.load(c.tmp / "cal.json").label == "polynomial(2)"


row("OK Calibration.save overwrite=True replaces", lambda c: c.copy("cal.json"),
    _cal_overwrite, ok=True, changes=("cal.json",))

# --- command line: outputs checked before the work ------------------------------------------
row("CLI centroid --out exists",
    lambda c: (c.copy("cube.zarr"), c.copy("cen.zarr", "out.zarr"),
               c.mp.setattr("sunlab.centroid.locate", _no_work)),
    lambda c: c.cli("centroid", c.tmp / "cube.zarr", "--out", c.tmp / "out.zarr"),
    r"out.zarr: already exists. Fix: pass --overwrite", cli=True)
row("CLI centroid --out missing folder",
    lambda c: (c.copy("cube.zarr"), c.mp.setattr("sunlab.centroid.locate", _no_work)),
    lambda c: c.cli("centroid", c.tmp / "cube.zarr", "--out", c.tmp / "nodir" / "o.nc"),
    r"nodir/o.nc: the folder does not exist", cli=True)
row("CLI centroid --out read-only folder",
    lambda c: (c.copy("cube.zarr"), (c.tmp / "ro").mkdir(), _read_only(c, c.tmp / "ro"),
               c.mp.setattr("sunlab.centroid.locate", _no_work)),
    lambda c: c.cli("centroid", c.tmp / "cube.zarr", "--out", c.tmp / "ro" / "o.zarr"),
    r"ro/o.zarr: the folder .*ro is not writable", cli=True)
row("CLI centroid --overwrite over a plain folder",
    lambda c: (c.copy("cube.zarr"), (c.tmp / "o").mkdir(), (c.tmp / "o" / "k.txt").write_text(
        "keep"), c.mp.setattr("sunlab.centroid.locate", _no_work)),
    lambda c: c.cli("centroid", c.tmp / "cube.zarr", "--out", c.tmp / "o", "--overwrite"),
    r"o: is a directory, not a Zarr store; sunlab will not delete it", cli=True)
row("CLI calibrate --out missing folder (before the fit)",
    lambda c: (c.copy("cen.zarr"), c.mp.setattr("sunlab.calibration.Polynomial.fit", _no_work)),
    lambda c: c.cli("calibrate", c.tmp / "cen.zarr", "--order", "2", "--out",
                    c.tmp / "nodir" / "c.json"),
    r"nodir/c.json: the folder does not exist", cli=True)
row("CLI calibrate --out exists",
    lambda c: (c.copy("cen.zarr"), c.copy("cal.json"),
               c.mp.setattr("sunlab.calibration.Polynomial.fit", _no_work)),
    lambda c: c.cli("calibrate", c.tmp / "cen.zarr", "--order", "2", "--out",
                    c.tmp / "cal.json"),
    r"cal.json: already exists. Fix: pass --overwrite", cli=True)
row("CLI calibrate --out read-only folder",
    lambda c: (c.copy("cen.zarr"), (c.tmp / "ro").mkdir(), _read_only(c, c.tmp / "ro"),
               c.mp.setattr("sunlab.calibration.Polynomial.fit", _no_work)),
    lambda c: c.cli("calibrate", c.tmp / "cen.zarr", "--order", "2", "--out",
                    c.tmp / "ro" / "c.json"),
    r"not writable", cli=True)
row("CLI calibrate final rename fails",
    lambda c: (c.copy("cen.zarr"), c.copy("cal.json"), _failing_replace(c)),
    lambda c: c.cli("calibrate", c.tmp / "cen.zarr", "--order", "2", "--out",
                    c.tmp / "cal.json", "--overwrite"),
    r"cal.json: Permission denied. Fix: check the permissions", cli=True)
row("CLI simulate --out exists",
    lambda c: (c.copy("cube.zarr"), c.mp.setattr("sunlab.sim.simulate", _no_work)),
    lambda c: c.cli("simulate", "--out", c.tmp / "cube.zarr", "--no-progress"),
    r"cube.zarr: already exists. Fix: pass --overwrite", cli=True)
row("CLI simulate --out missing folder",
    lambda c: c.mp.setattr("sunlab.sim.simulate", _no_work),
    lambda c: c.cli("simulate", "--out", c.tmp / "a" / "b.nc", "--no-progress"),
    r"a/b.nc: the folder does not exist", cli=True)
row("CLI acquire --out read-only folder",
    lambda c: ((c.tmp / "ro").mkdir(), _read_only(c, c.tmp / "ro"),
               c.mp.setattr("sunlab.hardware.open_stage", _no_work)),
    lambda c: c.cli("acquire", "--stage", "fake://", "--camera", "sim", "--plan", "I",
                    "--out", c.tmp / "ro" / "run.zarr", "--no-progress"),
    r"run.zarr: the folder .* not writable", cli=True)
row("CLI acquire --out missing folder",
    lambda c: c.mp.setattr("sunlab.hardware.open_stage", _no_work),
    lambda c: c.cli("acquire", "--stage", "fake://", "--camera", "sim", "--plan", "I",
                    "--out", c.tmp / "x" / "run.zarr", "--no-progress"),
    r"x/run.zarr: the folder does not exist", cli=True)


def _cli_calibrate_overwrite(c):
    rc, err = c.cli("calibrate", c.tmp / "cen.zarr", "--order", "1", "--out",
                    c.tmp / "cal.json", "--overwrite")
    assert rc == 0, err
    assert calibration.load(c.tmp / "cal.json").label == "polynomial(1)"


row("OK CLI calibrate --overwrite replaces", lambda c: (c.copy("cen.zarr"), c.copy("cal.json")),
    _cli_calibrate_overwrite, ok=True, changes=("cal.json",))

# --- command-line arguments ---------------------------------------------------------------
for argv, match in [
    (("centroid", "c.zarr", "--out", "o.zarr", "--workers", "-3"),
     r"--workers: found -3, expected an integer >= 1"),
    (("centroid", "c.zarr", "--out", "o.zarr", "--workers", "0"), r"--workers: found 0"),
    (("centroid", "c.zarr", "--out", "o.zarr", "--workers", "many"), r"--workers: found 'many'"),
    (("simulate", "--out", "o.zarr", "--workers", "-3"), r"--workers: found -3"),
    (("simulate", "--out", "o.zarr", "--shots", "0"), r"--shots: found 0"),
    (("simulate", "--out", "o.zarr", "--subset", "-2"), r"--subset: found -2"),
    (("calibrate", "t.zarr", "--out", "c.json", "--hidden", "0"), r"--hidden: found 0"),
    (("calibrate", "t.zarr", "--out", "c.json", "--max-iter", "-1"), r"--max-iter: found -1"),
    (("acquire", "--stage", "fake://", "--camera", "sim", "--plan", "I", "--out", "r.zarr",
      "--settle", "-1"), r"--settle: found '-1'"),
    (("acquire", "--stage", "fake://", "--camera", "sim", "--plan", "I", "--out", "r.zarr",
      "--timeout", "nan"), r"--timeout: found 'nan'"),
    (("acquire", "--stage", "fake://", "--camera", "sim", "--plan", "I", "--out", "r.zarr",
      "--shots", "-8"), r"--shots: found -8"),
    (("acquire", "--stage", "fake://", "--camera", "sim", "--plan", "I", "--out", "r.zarr",
      "--binning", "0"), r"--binning: found 0"),
    (("centroid", "c.zarr", "--out", "o.zarr", "--method", "magic"),
     r"--method: invalid choice: 'magic'"),
    (("reproduce", "--table", "7"), r"--table: invalid choice: '7'"),
]:
    row(f"CLI args {' '.join(argv[:1] + argv[-2:])}", nothing,
        lambda c, argv=argv: c.cli(*argv), match, cli=True, code=2)

row("CLI calibrate --order abc",
    lambda c: c.copy("cen.zarr"),
    lambda c: c.cli("calibrate", c.tmp / "cen.zarr", "--order", "abc", "--out",
                    c.tmp / "c.json"),
    r"--order: found 'abc', expected an integer or 'auto'", cli=True)
row("CLI calibrate --order auto without --validation",
    lambda c: c.copy("cen.zarr"),
    lambda c: c.cli("calibrate", c.tmp / "cen.zarr", "--order", "auto", "--out",
                    c.tmp / "c.json"),
    r"--order: found 'auto' without --validation", cli=True)
row("CLI acquire --plan missing file", nothing,
    lambda c: c.cli("acquire", "--stage", "fake://", "--camera", "sim", "--plan",
                    c.tmp / "plan.csv", "--out", c.tmp / "r.zarr", "--no-progress"),
    r"--plan: found .*plan.csv', expected I, II, III or an existing CSV file", cli=True)
row("CLI acquire --plan CSV without beta", lambda c: (c.tmp / "p.csv").write_text("alpha\n1\n"),
    lambda c: c.cli("acquire", "--stage", "fake://", "--camera", "sim", "--plan",
                    c.tmp / "p.csv", "--out", c.tmp / "r.zarr", "--no-progress"),
    r"p.csv: columns \['alpha'\], missing \['beta'\]", cli=True)

# --- command line: input paths --------------------------------------------------------------
row("CLI info missing path", nothing, lambda c: c.cli("info", c.tmp / "nope.zarr"),
    r"nope.zarr: no such file or directory", cli=True)
row("CLI centroid missing cube", nothing,
    lambda c: c.cli("centroid", c.tmp / "nope.zarr", "--out", c.tmp / "o.zarr"),
    r"nope.zarr: no such file or directory", cli=True)
row("CLI calibrate missing table", nothing,
    lambda c: c.cli("calibrate", c.tmp / "nope.nc", "--out", c.tmp / "c.json"),
    r"nope.nc: no such file or directory", cli=True)
row("CLI calibrate missing --validation", lambda c: c.copy("cen.zarr"),
    lambda c: c.cli("calibrate", c.tmp / "cen.zarr", "--validation", c.tmp / "v.nc", "--out",
                    c.tmp / "c.json"),
    r"v.nc: no such file or directory", cli=True)
row("CLI info text file", lambda c: (c.tmp / "notes.txt").write_text("hello"),
    lambda c: c.cli("info", c.tmp / "notes.txt"),
    r"notes.txt: neither a Zarr store .* nor a NetCDF4/HDF5 file", cli=True)
row("CLI info empty file", lambda c: (c.tmp / "e.nc").write_bytes(b""),
    lambda c: c.cli("info", c.tmp / "e.nc"), r"e.nc: (neither a Zarr store|found 'invalid JSON)",
    cli=True)
row("CLI info NetCDF3 file", lambda c: (c.tmp / "old.nc").write_bytes(b"CDF\x01" + bytes(60)),
    lambda c: c.cli("info", c.tmp / "old.nc"), r"old.nc: a NetCDF3 \(classic\) file", cli=True)
row("CLI info plain folder", lambda c: (c.tmp / "d").mkdir(),
    lambda c: c.cli("info", c.tmp / "d"), r"d: not a Zarr store \(no zarr.json", cli=True)
row("CLI centroid on a centroid table", lambda c: c.copy("cen.zarr"),
    lambda c: c.cli("centroid", c.tmp / "cen.zarr", "--out", c.tmp / "o.zarr"),
    r"attrs\['sunlab_schema'\]: found 'centroids/1', expected 'frames/1'", cli=True)
row("CLI calibrate on a frame cube", lambda c: c.copy("cube.zarr"),
    lambda c: c.cli("calibrate", c.tmp / "cube.zarr", "--order", "2", "--out",
                    c.tmp / "c.json"),
    r"train.*(frames|sunlab_schema|centroids)", cli=True)
row("CLI calibrate unreadable table (permission)",
    lambda c: (c.copy("cen.nc"), c.mp.setattr(
        "sunlab.io.read._open_raw", lambda *a, **k: (_ for _ in ()).throw(
            PermissionError(13, "Permission denied", str(c.tmp / "cen.nc"))))),
    lambda c: c.cli("calibrate", c.tmp / "cen.nc", "--out", c.tmp / "c.json"),
    r"cen.nc: Permission denied. Fix: check the permissions", cli=True)


# --- corrupt stores: detected on read, naming the store and the chunk -----------------------
def _chunk(c, store="cube.zarr", key="frames/c/1/0/0/0"):
    return c.tmp / store / key


def _read_all(path):
    with io.open_frames(path) as ds:
        return {k: np.asarray(v.values) for k, v in ds.variables.items()}


row("zarr frames chunk 64 bytes flipped", lambda c: (c.copy("cube.zarr"), _flip(_chunk(c))),
    lambda c: _read_all(c.tmp / "cube.zarr"),
    r"cube.zarr/frames/c/1/0/0/0: chunk \(pose 1, shot 0, y 0, x 0\) of variable 'frames'.*"
    "checksum")
row("zarr frames chunk one bit flipped",
    lambda c: (c.copy("cube.zarr"), _flip(_chunk(c, key="frames/c/0/1/0/0"), n=1, at=40)),
    lambda c: _read_all(c.tmp / "cube.zarr"), r"frames/c/0/1/0/0: chunk \(pose 0, shot 1")
row("zarr frames chunk truncated",
    lambda c: (c.copy("cube.zarr"), _chunk(c).write_bytes(_chunk(c).read_bytes()[:50])),
    lambda c: _read_all(c.tmp / "cube.zarr"), r"frames/c/1/0/0/0: chunk \(pose 1, shot 0")
row("zarr frames chunk garbled",
    lambda c: (c.copy("cube.zarr"), _chunk(c).write_bytes(
        np.random.default_rng(3).bytes(len(_chunk(c).read_bytes())))),
    lambda c: _read_all(c.tmp / "cube.zarr"), r"frames/c/1/0/0/0: chunk \(pose 1, shot 0")
row("zarr frames chunk emptied",
    lambda c: (c.copy("cube.zarr"), _chunk(c).write_bytes(b"")),
    lambda c: _read_all(c.tmp / "cube.zarr"), r"frames/c/1/0/0/0: chunk \(pose 1, shot 0")
row("zarr frames chunk deleted",
    lambda c: (c.copy("cube.zarr"), _chunk(c).unlink()),
    lambda c: io.open_frames(c.tmp / "cube.zarr"),
    r"frames chunks: found '1 of 4 chunk files missing.*frames/c/1/0/0/0", exc=SchemaError)
row("zarr centroid chunk flipped",
    lambda c: (c.copy("cen.zarr"), _flip(_chunk(c, "cen.zarr", "x/c/0/0"), n=8, at=4)),
    lambda c: io.open_centroids(c.tmp / "cen.zarr"),
    r"cen.zarr/x/c/0/0: chunk \(pose 0, shot 0\) of variable 'x'")
row("zarr coordinate chunk flipped",
    lambda c: (c.copy("cube.zarr"), _flip(_chunk(c, key="alpha/c/0"), n=4, at=2)),
    lambda c: _read_all(c.tmp / "cube.zarr"), r"cube.zarr")
row("zarr metadata corrupt",
    lambda c: (c.copy("cube.zarr"), _chunk(c, key="frames/zarr.json").write_text("{not json")),
    lambda c: io.open_frames(c.tmp / "cube.zarr"),
    r"frames/zarr.json: corrupt Zarr metadata")
row("CLI centroid on a flipped chunk",
    lambda c: (c.copy("cube.zarr"), _flip(_chunk(c))),
    lambda c: c.cli("centroid", c.tmp / "cube.zarr", "--out", c.tmp / "o.zarr",
                    "--no-progress", "--scheduler", "synchronous"),
    r"frames/c/1/0/0/0: chunk \(pose 1, shot 0, y 0, x 0\).*checksum", cli=True)
row("CLI info on a store without metadata",
    lambda c: (c.copy("cube.zarr"), _chunk(c, key="zarr.json").unlink()),
    lambda c: c.cli("info", c.tmp / "cube.zarr"), r"cube.zarr: not a Zarr store", cli=True)
row("netcdf truncated", lambda c: c.copy("cube.nc").write_bytes(
    (c.assets["root"] / "cube.nc").read_bytes()[:3000]),
    lambda c: _read_all(c.tmp / "cube.nc"), r"cube.nc: cannot be read as NetCDF4.*truncated")


def _nc_damaged(c):
    path = c.copy("cube.nc")
    size = path.stat().st_size
    _flip(path, n=64, at=int(size * 0.7))


def _nc_read_or_same(c):
    """Damaged bytes in a NetCDF file: an error naming the file, or the same values."""
    try:
        back = _read_all(c.tmp / "cube.nc")
    except SunlabError as err:
        assert "cube.nc" in str(err)
        return
    np.testing.assert_array_equal(back["frames"], c.assets["cube"].frames.values)


row("OK netcdf data bytes flipped: error or same values", _nc_damaged, _nc_read_or_same, ok=True)


def _old_store(c):
    """A store written without checksums (sunlab before issue 14) still opens, exactly."""
    c.assets["cube"].to_zarr(c.tmp / "old.zarr", zarr_format=3, consolidated=False)


def _old_store_opens(c):
    back = io.open_frames(c.tmp / "old.zarr")
    np.testing.assert_array_equal(back.frames.values, c.assets["cube"].frames.values)
    meta = json.loads((c.tmp / "old.zarr" / "frames" / "zarr.json").read_text())
    assert "crc32c" not in json.dumps(meta["codecs"])


row("OK store without checksums still opens", _old_store, _old_store_opens, ok=True)


def _new_store_has_checksums(c):
    for var in ("frames", "alpha", "pose"):
        meta = json.loads((c.tmp / "cube.zarr" / var / "zarr.json").read_text())
        assert meta["codecs"][-1]["name"] == "crc32c", (var, meta["codecs"])


row("OK every array of a new store has a crc32c codec", lambda c: c.copy("cube.zarr"),
    _new_store_has_checksums, ok=True)


# --- image folders: errors name the file -----------------------------------------------------
def _truncate(path: Path, keep: float = 0.6) -> None:
    data = path.read_bytes()
    path.write_bytes(data[: int(len(data) * keep)])


row("image folder truncated PNG (lazy, at compute)",
    lambda c: (c.copy("imgs"), _truncate(c.tmp / "imgs" / "f1.png")),
    lambda c: io.open_frames(c.tmp / "imgs", bit_depth=10).frames.values,
    r"image .*imgs/f1.png: found 'unreadable pixel data", exc=SchemaError)
row("image folder truncated PNG (eager)",
    lambda c: (c.copy("imgs"), _truncate(c.tmp / "imgs" / "f1.png")),
    lambda c: io.open_frames(c.tmp / "imgs", bit_depth=10, lazy=False),
    r"image .*f1.png", exc=SchemaError)
row("image folder PNG header garbled",
    lambda c: (c.copy("imgs"), (c.tmp / "imgs" / "f0.png").write_bytes(b"\x89PNG garbage")),
    lambda c: io.open_frames(c.tmp / "imgs", bit_depth=10),
    r"image f0.png: found .unreadable", exc=SchemaError)
row("image folder DN above bit depth",
    lambda c: c.copy("imgs"),
    lambda c: io.open_frames(c.tmp / "imgs", bit_depth=6).frames.values,
    r"image .*f1.png: found 'maximum 107 DN', expected < 2\*\*6", exc=SchemaError)
row("read_image truncated TIFF",
    lambda c: (__import__("tifffile").imwrite(c.tmp / "t.tif", np.ones((NY, NX), np.uint16)),
               _truncate(c.tmp / "t.tif", 0.5)),
    lambda c: io.read_image(c.tmp / "t.tif"), r"image .*t.tif", exc=SchemaError)

# --- calibration files: checked before any allocation -----------------------------------------


def _load_small(path: Path):
    """Load, asserting that no more than 50 MB are allocated on the way."""
    tracemalloc.start()
    try:
        calibration.load(path)
    finally:
        peak = tracemalloc.get_traced_memory()[1]
        tracemalloc.stop()
        assert peak < 50e6, f"{peak / 1e6:.0f} MB allocated before the error"


def _load(c, name="cal.json"):
    return calibration.load(c.tmp / name)


for rid, name, edit, match in [
    ("order [20000, 20000]", "cal.json", _set("parameters", "order", [20000, 20000]),
     r"parameters.coefficients.alpha: found '6 values', expected 200030001 values"),
    ("order 10**9", "cal.json", _set("parameters", "order", 10**9),
     r"parameters.coefficients.alpha: .*expected 5000000.*values"),
    ("order -1", "cal.json", _set("parameters", "order", [-1, 2]),
     r"parameters.order: found -1, expected an integer >= 0"),
    ("order as text", "cal.json", _set("parameters", "order", ["2", "2"]),
     r"parameters.order: found '2', expected an integer"),
    ("order of three", "cal.json", _set("parameters", "order", [2, 2, 2]),
     r"parameters.order: found \[2, 2, 2\]"),
    ("scaling x [5, 5]", "cal.json", _set("parameters", "scaling", "x", [5, 5]),
     r"parameters.scaling.x: found \[5, 5\], expected \[lo, hi\] with hi > lo"),
    ("scaling y reversed", "cal.json", _set("parameters", "scaling", "y", [900.0, 100.0]),
     r"parameters.scaling.y: found \[900.0, 100.0\]"),
    ("scaling x one number", "cal.json", _set("parameters", "scaling", "x", [5]),
     r"parameters.scaling.x: found '1 values', expected 2 values"),
    ("scaling missing", "cal.json", _set("parameters", "scaling", None),
     r"parameters.scaling: found 'NoneType'"),
    ("coefficient null", "cal.json", lambda d: d["parameters"]["coefficients"]["alpha"]
     .__setitem__(3, None), r"parameters.coefficients.alpha\[3\]: found None"),
    ("coefficient text", "cal.json", lambda d: d["parameters"]["coefficients"]["beta"]
     .__setitem__(0, "1.5"), r"parameters.coefficients.beta\[0\]: found '1.5'"),
    ("coefficient list short", "cal.json", lambda d: d["parameters"]["coefficients"]["beta"]
     .pop(), r"parameters.coefficients.beta: found '5 values', expected 6 values"),
    ("coefficients missing", "cal.json", lambda d: d["parameters"].pop("coefficients"),
     r"parameters.coefficients"),
    ("trig order 10**6", "trig.json", _set("parameters", "order", 10**6),
     r"parameters.coefficients.alpha: .*expected 4000004000001 values"),
    ("trig period 0", "trig.json", _set("parameters", "period", 0),
     r"parameters.period: found 0, expected a finite positive number"),
    ("trig scaling [3, 3]", "trig.json", _set("parameters", "scaling", "x", [3, 3]),
     r"parameters.scaling.x: found \[3, 3\]"),
    ("interp nodes unequal", "interp.json", lambda d: d["parameters"]["nodes"]["beta"].pop(),
     r"parameters.nodes.beta: found '24 values', expected 25 values"),
    ("interp node null", "interp.json", lambda d: d["parameters"]["nodes"]["x"].__setitem__(
        2, None), r"parameters.nodes.x\[2\]: found None"),
    ("interp two nodes", "interp.json", lambda d: d["parameters"]["nodes"].update(
        {k: v[:2] for k, v in d["parameters"]["nodes"].items()}),
     r"parameters.nodes.x: found '2 nodes', expected at least 3"),
    ("ideal pixel pitch 0", "ideal.json", _set("parameters", "pixel_pitch_mm", 0),
     r"parameters.pixel_pitch_mm: found 0, expected a finite positive number"),
    ("ideal x_cf null", "ideal.json", _set("parameters", "x_cf_px", None),
     r"parameters.x_cf_px: found None"),
    ("optimised delta_f null", "opt.json", _set("parameters", "delta_f_mm", None),
     r"parameters.delta_f_mm: found None"),
    ("optimised mask distance negative", "opt.json", _set("parameters", "mask_distance_mm", -5),
     r"parameters.mask_distance_mm: found -5"),
    ("kind unknown", "cal.json", _set("kind", "spline"), r"kind: found 'spline'"),
    ("schema version", "cal.json", _set("sunlab_schema", "calibration/9"),
     r"sunlab_schema: found 'calibration/9'"),
    ("domain reversed", "cal.json", _set("domain", "alpha", [10.0, -10.0]),
     r"domain.alpha: found \[10.0, -10.0\]"),
    ("parameters missing", "cal.json", lambda d: d.pop("parameters"), r"parameters"),
]:
    row(f"calibration {rid}", lambda c, name=name, edit=edit: _cal_edit(c, edit, name),
        lambda c, name=name: _load_small(c.tmp / name), match, exc=SchemaError)


def _text_edit(c, old, new):
    path = c.copy("cal.json")
    text = path.read_text()
    assert old in text
    path.write_text(text.replace(old, new, 1))


_FIRST = '"coefficients": {"alpha": ['
for rid, new, match in [
    ("NaN literal", _FIRST + "NaN, ", r"coefficients.alpha\[0\]: found nan, expected a finite"),
    ("Infinity literal", _FIRST + "Infinity, ",
     r"coefficients.alpha\[0\]: found inf, expected a finite"),
    ("1e999", _FIRST + "1e999, ", r"coefficients.alpha\[0\]: found inf"),
    ("5000-digit integer", _FIRST + "9" * 5000 + ", ", r"cal.json: found 'invalid JSON"),
]:
    row(f"calibration {rid}", lambda c, new=new: _text_edit(c, _FIRST, new), _load, match,
        exc=SchemaError)

row("calibration truncated", lambda c: c.copy("cal.json").write_text(
    (c.assets["root"] / "cal.json").read_text()[:200]), _load,
    r"cal.json: found 'invalid JSON", exc=SchemaError)
row("calibration not UTF-8", lambda c: (c.tmp / "cal.json").write_bytes(b"\xff\xfe{\x00"),
    _load, r"cal.json: found .not UTF-8 text", exc=SchemaError)
row("calibration path is a folder", lambda c: (c.tmp / "cal.json").mkdir(), _load,
    r"path: found '.*cal.json \(IsADirectoryError", exc=SchemaError)
row("calibration path missing", nothing, _load,
    r"path: found '.*cal.json', expected an existing calibration", exc=SchemaError)
row("calibration file of 65 MB", lambda c: os.truncate(
    c.copy("cal.json"), calibration.artifact.MAX_FILE_BYTES + 1), _load,
    r"cal.json: found '67108865 bytes', expected a calibration JSON file of at most",
    exc=SchemaError)
row("calibration a list", lambda c: (c.tmp / "cal.json").write_text("[1, 2]"), _load,
    r"calibration document: found 'list'", exc=SchemaError)


# --- validation: the contract's index and DN rules --------------------------------------------
def _cube_with(**coords):
    return schema.validate_frames(
        schema.frames_dataset(_frames(), alpha=[0.0, 1.0], beta=[0.0, 0.0]).assign_coords(
            **coords))


row("frames pose [1, 0]", nothing, lambda c: _cube_with(pose=[1, 0]),
    r"coords\['pose'\]: found \[1, 0\], expected the integers 0 .. 1", exc=SchemaError)
row("frames shot [1, 2]", nothing, lambda c: _cube_with(shot=[1, 2]),
    r"coords\['shot'\]: found \[1, 2\]", exc=SchemaError)
row("frames shot float", nothing, lambda c: _cube_with(shot=[0.0, 1.0]),
    r"coords\['shot'\]: found \[0.0, 1.0\]", exc=SchemaError)
row("centroids pose [2, 0, 2]", nothing,
    lambda c: schema.validate_centroids(schema.centroids_dataset(
        np.ones((3, 2)), np.ones((3, 2))).assign_coords(pose=[2, 0, 2])),
    r"coords\['pose'\]: found \[2, 0, 2\], expected the integers 0 .. 2", exc=SchemaError)
row("save_centroids pose [2, 0, 2] writes nothing", nothing,
    lambda c: io.save_centroids(schema.centroids_dataset(
        np.ones((3, 2)), np.ones((3, 2))).assign_coords(pose=[2, 0, 2]), c.tmp / "c.zarr"),
    r"coords\['pose'\]: found \[2, 0, 2\]", exc=SchemaError)
row("centroids shot [0, 0]", nothing,
    lambda c: schema.validate_centroids(schema.centroids_dataset(
        np.ones((3, 2)), np.ones((3, 2))).assign_coords(shot=[0, 0])),
    r"coords\['shot'\]: found \[0, 0\]", exc=SchemaError)
row("frames bit_depth 10 with DN 3935", nothing,
    lambda c: schema.frames_dataset(np.full((1, 1, 4, 4), 3935, np.uint16), alpha=[0.0],
                                    beta=[0.0], bit_depth=10),
    r"frames: found 'DN up to 3935 \(16 pixels >= 1024\)', expected DN < 2\*\*10",
    exc=SchemaError)
row("frames bit_depth 0", nothing,
    lambda c: schema.frames_dataset(np.zeros((1, 1, 4, 4), np.uint8), alpha=[0.0],
                                    beta=[0.0], bit_depth=0),
    r"attrs\['bit_depth'\]", exc=SchemaError)


def _lying_store(c):
    """A store of 12-bit frames whose attrs claim 10 bits (edited metadata, and no checksum:
    as another tool would write it; with sunlab's checksum the edit is refused at once, see
    tests/test_faults.py)."""
    cube = schema.frames_dataset(_frames(peak=3936), alpha=[0.0, 1.0], beta=[0.0, 0.0],
                                 bit_depth=12)
    io.save_frames(cube, c.tmp / "lie.zarr")
    integrity.unseal_zarr(c.tmp / "lie.zarr")
    _edit_json(c.tmp / "lie.zarr" / "zarr.json", _set("attributes", "bit_depth", 10))


row("store DN above its bit_depth (read)", _lying_store,
    lambda c: _read_all(c.tmp / "lie.zarr"),
    r"lie.zarr frames chunk \(pose \d, shot \d, y 0, x 0\): found 'DN up to 393\d'",
    exc=SchemaError)
row("CLI centroid on a store DN above its bit_depth", _lying_store,
    lambda c: c.cli("centroid", c.tmp / "lie.zarr", "--out", c.tmp / "o.zarr",
                    "--no-progress", "--scheduler", "synchronous"),
    r"lie.zarr frames chunk \(pose \d, shot \d, y 0, x 0\): found 'DN up to", cli=True)


# --- --debug shows the trace -------------------------------------------------------------------
def _debug_raises(c):
    with pytest.raises(SunlabError, match="nope.zarr: no such file"):
        cli.main(["--debug", "info", str(c.tmp / "nope.zarr")])
    with pytest.raises(SunlabError, match="nope.zarr: no such file"):
        cli.main(["info", str(c.tmp / "nope.zarr"), "--debug"])


row("OK --debug re-raises with the traceback", nothing, _debug_raises, ok=True)


def _internal_error(c):
    c.mp.setattr("sunlab.io.summary", lambda ds: 1 / 0)
    rc, err = c.cli("info", c.tmp / "cube.zarr")
    assert rc == 3 and "Traceback" not in err
    assert "internal error: ZeroDivisionError" in err and "--debug" in err


row("OK an internal error is one line too (exit 3)", lambda c: c.copy("cube.zarr"),
    _internal_error, ok=True)


# --- the ESP300 driver: a lost error reply is never a success -----------------------------------
def _esp_lost(kind: str, after: int, error: bool):
    def act(c):
        from sunlab.hardware import ESP300
        from sunlab.hardware.fake import FakeESP

        fake = FakeESP(velocity_deg_s=float("inf"))
        try:
            stage = ESP300(fake.serve_pty(), timeout=0.08, retries=3, retry_delay_s=0.01,
                           poll_s=0.001)
            try:
                if error:
                    fake.inject("error", "1PA", code=104)
                fake.inject(kind, "TB?", after=after)
                stage.move_to(1.0, 2.0)
            finally:
                stage.close()
        finally:
            fake.close()

    return act


for kind in ("timeout", "garble"):
    for after, error in ((0, False), (0, True), (1, False)):
        row(f"ESP300 TB? reply {kind} after {after}{' with error 104' if error else ''}",
            nothing, _esp_lost(kind, after, error), r"TB\?.*may have been lost|lost")


# ------------------------------------------------------------------------------------------
# The runner
# ------------------------------------------------------------------------------------------
def test_the_table_has_at_least_90_rows():
    assert len(ROWS) >= 90
    assert len({r.id for r in ROWS}) == len(ROWS)


@pytest.mark.parametrize("r", ROWS, ids=[r.id for r in ROWS])
def test_bad_input(r: Row, assets, tmp_path, monkeypatch, capsys):
    ctx = Ctx(tmp_path, assets, monkeypatch, capsys)
    r.setup(ctx)
    before = _hashes(tmp_path)
    try:
        if r.ok:
            r.act(ctx)
        elif r.cli:
            rc, err = r.act(ctx)
            assert rc != 0, f"exit status 0; stderr {err!r}"
            if r.code is not None:
                assert rc == r.code, err
            assert "Traceback" not in err, err
            lines = [line for line in err.splitlines() if "error:" in line]
            assert len(lines) == 1, err
            assert __import__("re").search(r.match, lines[0]), (r.match, lines[0])
        else:
            with pytest.raises(r.exc, match=r.match):
                r.act(ctx)
    finally:
        os.chmod(tmp_path, 0o755)
        for p in tmp_path.rglob("*"):
            if p.is_dir():
                os.chmod(p, 0o755)
    monkeypatch.undo()
    after = _hashes(tmp_path)
    kept = {k: v for k, v in before.items() if not k.startswith(r.changes or ("\0",))}
    lost = {k for k in kept if after.get(k) != kept[k]}
    assert not lost, f"existing data changed or lost: {sorted(lost)[:5]}"
    if not r.ok:
        new = sorted(set(after) - set(before))
        assert not new, f"a failed run left files behind: {new[:5]}"
