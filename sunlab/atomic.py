"""Atomic outputs: write a temporary sibling, then rename it into place.

Every file or store sunlab writes goes through this module, so that an output is either the old
one or the new one, never a half-written mix, and an existing output is replaced only when the
caller says so (``overwrite=True`` / ``--overwrite``):

* :func:`check_target` checks an output path *before* any work is done (the folder exists and
  is writable; an existing output needs ``overwrite``);
* :func:`atomic_output` yields a temporary sibling path to write (a file or a directory, e.g. a
  Zarr store) and moves it into place when the block ends without error. A file replaces the old
  one with :func:`os.replace`; a directory is swapped by renaming the old one aside, renaming the
  new one in and only then deleting the old one, so the old output survives any failure;
* :func:`write_text` and :func:`write_bytes` do both for small files (JSON, CSV).

Examples
--------
>>> import pathlib, tempfile
>>> from sunlab import atomic
>>> path = pathlib.Path(tempfile.mkdtemp()) / "table.csv"
>>> _ = atomic.write_text(path, "a,b\\n1,2\\n")
>>> with atomic.atomic_output(path, overwrite=True) as tmp:
...     _ = tmp.write_text("a,b\\n3,4\\n")
>>> path.read_text()
'a,b\\n3,4\\n'
>>> try:
...     atomic.write_text(path, "x")
... except FileExistsError as err:
...     print(type(err).__name__)
OutputExistsError
"""

from __future__ import annotations

import contextlib
import os
import shutil
import uuid
from pathlib import Path

from .errors import SunlabError

__all__ = ["OutputExistsError", "check_target", "atomic_output", "write_text", "write_bytes"]


class OutputExistsError(SunlabError, FileExistsError):
    """An output exists and the caller did not ask to replace it."""


def _is_zarr_store(path: Path) -> bool:
    return (path / "zarr.json").exists() or (path / ".zgroup").exists() or (
        path / ".zarray").exists()


def check_target(path, *, overwrite: bool = False, kind: str = "file", flag: str = "overwrite=True"
                 ) -> Path:
    """Check that ``path`` can be written, before any work is done; return it as a Path.

    Parameters
    ----------
    path : str or path-like
        The output.
    overwrite : bool
        Whether an existing output may be replaced.
    kind : {"file", "zarr"}
        ``"zarr"``: the output is a Zarr directory store; an existing directory is replaced only
        if it is a Zarr store (sunlab never deletes any other folder).
    flag : str
        How the user asks to overwrite, for the message (``"--overwrite"`` on the command line).

    Raises
    ------
    OutputExistsError
        ``path`` exists and ``overwrite`` is False.
    SunlabError
        The parent folder is missing or not writable, or ``path`` is a folder that must not be
        replaced.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> folder = pathlib.Path(tempfile.mkdtemp())
    >>> check_target(folder / "c.json").name
    'c.json'
    >>> try:
    ...     check_target(folder / "nodir" / "c.json")
    ... except SunlabError as err:
    ...     print("does not exist" in str(err))
    True
    """
    path = Path(path)
    parent = path.parent if str(path.parent) else Path(".")
    if not parent.is_dir():
        raise SunlabError(
            f"{path}: the folder does not exist ({parent}). Fix: create it first "
            f"(mkdir -p {parent}) or choose another output path"
        )
    if not os.access(parent, os.W_OK | os.X_OK):
        raise SunlabError(
            f"{path}: the folder {parent} is not writable. Fix: choose an output path in a "
            "folder you can write to, or change the folder's permissions"
        )
    if path.exists() or path.is_symlink():
        if not overwrite:
            raise OutputExistsError(
                f"{path}: already exists. Fix: pass {flag} to replace it, or choose a new path"
            )
        if path.is_dir() and not (kind == "zarr" and _is_zarr_store(path)):
            what = "not a Zarr store" if kind == "zarr" else "a directory"
            raise SunlabError(
                f"{path}: is a directory, {what}; sunlab will not delete it. Fix: choose "
                "another path"
            )
    return path


def _remove(path: Path) -> None:
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path, ignore_errors=True)
    else:
        with contextlib.suppress(FileNotFoundError):
            path.unlink()


def _swap(tmp: Path, path: Path) -> None:
    """Move ``tmp`` to ``path``; an existing ``path`` survives any failure of the move."""
    if tmp.is_dir() and (path.exists() or path.is_symlink()):
        aside = path.with_name(f".{path.name}.old-{uuid.uuid4().hex[:8]}")
        os.replace(path, aside)
        try:
            os.replace(tmp, path)
        except BaseException:
            os.replace(aside, path)
            raise
        _remove(aside)
    else:
        os.replace(tmp, path)


@contextlib.contextmanager
def atomic_output(path, *, overwrite: bool = False, kind: str = "file",
                  flag: str = "overwrite=True"):
    """Yield a temporary sibling of ``path`` to write; move it into place on success.

    The temporary name is hidden (``.NAME.tmp-XXXXXXXX``) and in the same folder, so the final
    rename is atomic. On any error (or Ctrl-C) the temporary output is removed and an existing
    output at ``path`` is left as it was.

    Parameters
    ----------
    path : str or path-like
        The final output (a file, or a directory such as a Zarr store).
    overwrite, kind, flag
        As in :func:`check_target`, which runs first.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "store"
    >>> with atomic_output(path, kind="zarr") as tmp:
    ...     tmp.mkdir()
    ...     _ = (tmp / "zarr.json").write_text("{}")
    >>> sorted(p.name for p in path.iterdir())
    ['zarr.json']
    """
    path = check_target(path, overwrite=overwrite, kind=kind, flag=flag)
    tmp = path.with_name(f".{path.name}.tmp-{uuid.uuid4().hex[:8]}")
    try:
        yield tmp
        if not (tmp.exists() or tmp.is_symlink()):
            raise SunlabError(f"{path}: nothing was written. Fix: this is a bug in the writer")
        # Checked again: another process may have created the output meanwhile.
        if (path.exists() or path.is_symlink()) and not overwrite:
            raise OutputExistsError(
                f"{path}: was created while sunlab was writing it. Fix: pass {flag} to replace "
                "it, or choose a new path"
            )
        _swap(tmp, path)
    finally:
        if tmp.exists() or tmp.is_symlink():
            _remove(tmp)


def write_bytes(path, data: bytes, *, overwrite: bool = False, flag: str = "overwrite=True"
                ) -> Path:
    """Write ``data`` to ``path`` atomically (temporary sibling, fsync, rename); return the path.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "x.bin"
    >>> write_bytes(path, b"abc").read_bytes()
    b'abc'
    """
    with atomic_output(path, overwrite=overwrite, flag=flag) as tmp:
        with open(tmp, "xb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
    return Path(path)


def write_text(path, text: str, *, overwrite: bool = False, flag: str = "overwrite=True",
               encoding: str = "utf-8") -> Path:
    """Write ``text`` to ``path`` atomically; return the path. See :func:`write_bytes`.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "x.json"
    >>> write_text(path, "{}").read_text()
    '{}'
    """
    return write_bytes(path, text.encode(encoding), overwrite=overwrite, flag=flag)
