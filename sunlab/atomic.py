"""Atomic outputs: write a temporary sibling, then :func:`os.replace` it into place.

Every file or store sunlab writes goes through this module, so that an output is either the old
one or the new one, never a half-written mix, and an existing output is replaced only when the
caller says so (``overwrite=True`` / ``--overwrite``):

* :func:`check_target` checks an output path *before* any work is done (the folder exists and
  is writable; an existing output needs ``overwrite``; a named pipe, a socket or a device is
  never replaced; a folder is replaced only when it is a Zarr store);
* :func:`atomic_output` yields a temporary sibling path to write (a file or a directory, e.g. a
  Zarr store) and moves it into place when the block ends without error. A file replaces the old
  one (or a symbolic link, never followed) with :func:`os.replace`; a directory is swapped by
  renaming the old one aside, the new one in, and only then deleting the old one;
* :func:`atomic_files` does the same for several files of one folder (``export``'s header and
  source, ``evaluate``'s tables and figures): all the old files or all the new ones;
* :func:`write_text` does both for a small file (JSON, CSV), flushed to disk first.

Temporary names are short whatever the output's name (``.sl-PID-XXXXXXXX.tmp``, at most 24
bytes, so that any legal name can be written; an old output is set aside, under its own name, in
a folder ``.sl-PID-XXXXXXXX.old``) and carry the writer's process id: a later write in the same
folder removes the leftovers of a writer that was killed (its process is gone), and puts back an
old output that such a writer had set aside but not yet replaced. The moves into place run
with SIGINT, SIGTERM and SIGHUP held back (Ctrl-C cannot split them). A full disk or a
file-size limit is named with the output; an output far larger than its disk's free space is
refused before any work (:func:`check_target`'s ``nbytes``).

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
import errno
import os
import re
import shutil
import signal
import stat
import threading
import uuid
from pathlib import Path

from .errors import SunlabError

__all__ = []

_DISK_FULL = {errno.ENOSPC, errno.EFBIG, getattr(errno, "EDQUOT", errno.ENOSPC)}
_SPECIAL = ((stat.S_ISFIFO, "a named pipe (FIFO)"), (stat.S_ISSOCK, "a socket"),
            (stat.S_ISCHR, "a character device"), (stat.S_ISBLK, "a block device"))
#: Name of the staging folder that :func:`atomic_files` makes inside an existing folder.
_STAGING = "sunlab-output"
#: A temporary name of :func:`temporary_name`: the writer's process id, and what it holds.
_TEMPORARY = re.compile(r"\.sl-(\d+)-[0-9a-f]{8}\.(tmp|old)")
#: The most the writers' compression shrinks a frame cube: Zarr (Zstandard) wrote 4.9 MB for
#: the 23.6 MB of ``sunlab simulate --experiment I --subset 8 --shots 1`` (4.8 x; NetCDF 4.3 x).
COMPRESSION = 5


class OutputExistsError(SunlabError, FileExistsError):
    """An output exists and the caller did not ask to replace it."""


def _exists(path: Path) -> bool:
    return path.exists() or path.is_symlink()


def _exists_error(path, flag: str, meanwhile: bool = False, what: str = "path"):
    said = "was created while sunlab was writing it" if meanwhile else "already exists"
    return OutputExistsError(f"{path}: {said}. Fix: pass {flag} to replace it, or choose a new "
                             f"{what}")


def temporary_name(path, what: str = "tmp") -> Path:
    """A hidden sibling of ``path`` for this process: ``.sl-PID-XXXXXXXX.<what>``.

    Parameters
    ----------
    path : str or path-like
        The output.
    what : str
        ``"tmp"`` (an output being written) or ``"old"`` (an output set aside).

    Returns
    -------
    pathlib.Path
        In ``path``'s folder, naming this process's id (for :func:`remove_stale`) and 8
        random hexadecimal digits; at most 24 bytes (a Linux process id, up to
        2**22 = 4194304 by pid_max, has at most 7 digits).

    Examples
    --------
    >>> import os
    >>> temporary_name("/data/" + "c" * 255).name.startswith(f".sl-{os.getpid()}-")
    True
    """
    return Path(path).with_name(f".sl-{os.getpid()}-{uuid.uuid4().hex[:8]}.{what}")


def remove_stale(path) -> list[Path]:
    """Clear what killed writers left beside ``path``; return what was cleared.

    Temporary outputs (``.sl-PID-*.tmp``) of a process that no longer runs are removed; the
    old outputs it had set aside (in ``.sl-PID-*.old``) are put back where missing, and
    removed otherwise. Leftovers of running processes are not touched.

    Parameters
    ----------
    path : str or path-like
        The output whose folder is searched.

    Returns
    -------
    list of pathlib.Path
        The leftovers removed or put back, in name order.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> folder = pathlib.Path(tempfile.mkdtemp())
    >>> _ = (folder / ".sl-999999999-0123abcd.tmp").write_text("half")
    >>> [p.name for p in remove_stale(folder / "c.json")]
    ['.sl-999999999-0123abcd.tmp']
    """
    cleared = []
    with contextlib.suppress(OSError):
        for stale in sorted(Path(path).parent.iterdir()):
            match = _TEMPORARY.fullmatch(stale.name)
            if match is None:
                continue
            try:
                os.kill(int(match.group(1)), 0)  # this process, or another user's, runs
                continue
            except ProcessLookupError:  # the writer is gone
                pass
            except PermissionError:  # another user's process
                continue
            cleared.append(stale)
            for old in stale.iterdir() if match.group(2) == "old" else ():
                if not _exists(stale.parent / old.name):
                    with contextlib.suppress(OSError):
                        os.replace(old, stale.parent / old.name)
            _remove(stale)
    return cleared


def check_target(path, *, overwrite: bool = False, kind: str = "file",
                 flag: str = "overwrite=True", nbytes: int = 0) -> Path:
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
    nbytes : int
        The output's size uncompressed, bytes, when known before the work: refused when even
        :data:`COMPRESSION` times smaller it exceeds the free space of the folder's disk.

    Returns
    -------
    pathlib.Path
        ``path``, with the leftovers of a killed writer of it cleared (:func:`remove_stale`).

    Raises
    ------
    OutputExistsError
        ``path`` exists and ``overwrite`` is False.
    SunlabError
        The parent folder is missing or not writable, or ``path`` is a folder that must not be
        replaced, or a named pipe, a socket or a device, or its name is too long, or ``nbytes``
        cannot fit on the disk.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> folder = pathlib.Path(tempfile.mkdtemp())
    >>> check_target(folder / "c.json").name
    'c.json'
    """
    path = Path(path)
    parent = path.parent
    if not parent.is_dir():
        raise SunlabError(f"{path}: the folder does not exist ({parent}). Fix: create it first "
                          f"(mkdir -p {parent}) or choose another output path")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise SunlabError(f"{path}: the folder {parent} is not writable. Fix: choose an output "
                          "path in a folder you can write to, or change the folder's permissions")
    remove_stale(path)
    try:
        mode = os.stat(path).st_mode
    except OSError as err:  # missing, or a dangling link: nothing a write reaches
        if err.errno == errno.ENAMETOOLONG:
            raise SunlabError(f"{path}: the name is longer than the file system allows ("
                              f"{len(os.fsencode(path.name))} bytes). Fix: choose a shorter "
                              "name") from None
        mode = 0
    for test, name in _SPECIAL:
        if test(mode):
            raise SunlabError(f"{path}: is {name}, not a regular file; sunlab never replaces "
                              "one (a reader may hold it open). Fix: choose a path for a new file")
    zarr = kind == "zarr" and any(_exists(path / n) for n in ("zarr.json", ".zgroup", ".zarray"))
    if path.is_dir() and not path.is_symlink() and not zarr:
        what = "a Zarr store" if kind == "zarr" else "a file"
        raise SunlabError(f"{path}: is a directory, not {what}; sunlab will not delete it. Fix: "
                          "choose another path")
    if _exists(path) and not overwrite:
        raise _exists_error(path, flag)
    free = shutil.disk_usage(parent).free if nbytes else 0
    if nbytes / COMPRESSION > free:
        raise SunlabError(
            f"{path}: would be about {nbytes / 1e9:,.1f} GB uncompressed (at least "
            f"{nbytes / COMPRESSION / 1e9:,.1f} GB written) but its disk has "
            f"{free / 1e9:,.1f} GB free; nothing was done. Fix: ask for fewer poses or shots, "
            "or write to a larger disk")
    return path


def _remove(path: Path) -> None:
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path, ignore_errors=True)
    else:
        with contextlib.suppress(FileNotFoundError):
            path.unlink()


@contextlib.contextmanager
def signals_held():
    """Hold SIGINT, SIGTERM and SIGHUP back while the block runs (delivered when it ends): for
    a few renames, or writes on another thread that would recreate a removed temporary. The
    Python handlers are swapped (a thread's signal mask would not do: the kernel hands the signal
    to another thread, and Python runs the handler in the main thread all the same)."""
    if threading.current_thread() is not threading.main_thread():  # no handlers to set there
        yield
        return
    got: list[int] = []
    held = {signal.SIGINT, signal.SIGTERM, getattr(signal, "SIGHUP", signal.SIGTERM)}
    # None: a handler set outside Python, left alone
    previous = {sig: h for sig in held if (h := signal.getsignal(sig)) is not None}
    for sig in previous:
        signal.signal(sig, lambda signum, frame: got.append(signum))
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
        if got:  # delivered now, to the handler the caller had
            signal.raise_signal(got[0])


def _named(err: OSError, tmp: Path, path: Path) -> BaseException:
    """An OS error of a write into ``tmp``, naming the output ``path`` the user asked for: a
    full disk or an error without a file name becomes a SunlabError (the system's own words: a
    library's text may name the temporary file), one naming ``tmp`` names ``path`` instead."""
    if err.filename is not None and err.errno not in _DISK_FULL:
        if str(tmp) in str(err.filename):
            err.filename = str(path)
        return err
    what = (os.strerror(err.errno) if isinstance(err.errno, int)
            else err.strerror or str(err) or type(err).__name__)
    if err.errno in _DISK_FULL:
        return SunlabError(
            f"{path}: {what} while writing it (errno {errno.errorcode.get(err.errno, '?')}); "
            "nothing was changed there. Fix: free disk space (or raise the file-size or quota "
            "limit), or write to another disk")
    return SunlabError(f"{path}: {what} while writing it; nothing was changed there. Fix: check "
                       "the folder, its free space and its permissions")


@contextlib.contextmanager
def atomic_output(path, *, overwrite: bool = False, kind: str = "file",
                  flag: str = "overwrite=True", nbytes: int = 0):
    """Yield a temporary sibling of ``path`` to write; move it into place on success.

    The temporary name is hidden (``.sl-PID-XXXXXXXX.tmp``) and in the same folder, so the final
    rename is atomic. On any error (or Ctrl-C) the temporary output is removed and an existing
    output at ``path`` is left as it was.

    Parameters
    ----------
    path : str or path-like
        The final output (a file, or a directory such as a Zarr store).
    overwrite, kind, flag, nbytes
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
    path = check_target(path, overwrite=overwrite, kind=kind, flag=flag, nbytes=nbytes)
    tmp = temporary_name(path)
    try:
        try:
            yield tmp
        except OSError as err:
            raise _named(err, tmp, path) from err.__cause__
        if not _exists(tmp):
            raise SunlabError(f"{path}: nothing was written. Fix: this is a bug in the writer")
        if _exists(path) and not overwrite:  # another process may have created it meanwhile
            raise _exists_error(path, flag, meanwhile=True)
        with signals_held():
            if tmp.is_dir() and _exists(path):  # the old output survives a failed move
                (aside := temporary_name(path, "old")).mkdir()
                os.replace(path, aside / path.name)
                try:
                    os.replace(tmp, path)
                except BaseException:
                    os.replace(aside / path.name, path)
                    aside.rmdir()
                    raise
                _remove(aside)
            else:
                os.replace(tmp, path)
    finally:
        if _exists(tmp):
            _remove(tmp)


def check_folder(folder, names, *, overwrite: bool = False, flag: str = "overwrite=True"
                 ) -> Path:
    """The checks of :func:`atomic_files` (same parameters), to run before any work (nothing
    is created): the folder can be made or is a folder, and no file of ``names`` exists unless
    ``overwrite``; return ``folder`` as a Path.

    Raises
    ------
    OutputExistsError
        A listed file exists and ``overwrite`` is False.
    SunlabError
        ``folder`` exists and is not a folder, or its parent is missing or not writable.
    """
    folder = Path(folder)
    if folder.is_dir():
        remove_stale(folder / _STAGING)
        for name in names:
            check_target(folder / name, overwrite=overwrite, flag=flag)
    elif _exists(folder):
        raise SunlabError(f"{folder}: exists and is not a folder. Fix: choose another output "
                          "folder")
    else:  # the parent must exist and be writable; leftovers of a killed writer go
        check_target(folder, flag=flag)
    return folder


@contextlib.contextmanager
def atomic_files(folder, names=(), *, overwrite: bool = False, flag: str = "overwrite=True"):
    """Yield a temporary folder to write the files ``names`` in (without ``names``: any files,
    sub-folders too, not checked beforehand); move them into ``folder`` together when the block
    ends without error.

    Everything is checked before the block runs (:func:`check_folder`), and ``folder`` is not
    created until the files are complete: a missing ``folder`` is the temporary folder renamed
    (one atomic step); in an existing one the old files are set aside, the new ones moved in,
    and the old ones deleted, with SIGINT and SIGTERM held back, and the moves undone if one
    fails. On any error before that nothing in ``folder`` changes. Files of ``folder`` that are
    not written are left alone.

    Parameters
    ----------
    folder : str or path-like
        The output folder (created if missing).
    names : iterable of str, optional
        The files that may be written (checked for existence first); the block may leave some
        out.
    overwrite : bool
        Whether existing files of ``names`` may be replaced.
    flag : str
        How the user asks to overwrite, for the messages.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> out = pathlib.Path(tempfile.mkdtemp()) / "onboard"
    >>> with atomic_files(out, ["a.h", "a.c"]) as tmp:
    ...     _ = (tmp / "a.h").write_text("int f(void);")
    ...     _ = (tmp / "a.c").write_text("int f(void) { return 0; }")
    >>> sorted(p.name for p in out.iterdir())
    ['a.c', 'a.h']
    """
    names = list(names)
    folder = check_folder(folder, names, overwrite=overwrite, flag=flag)
    # beside a missing folder (renamed into place), inside an existing one (the same disk)
    staging = temporary_name(folder / _STAGING if folder.is_dir() else folder)
    try:
        try:
            staging.mkdir()
            yield staging
        except OSError as err:
            raise _named(err, staging, folder) from err.__cause__
        unknown = sorted(p.name for p in staging.iterdir() if names and p.name not in names)
        if unknown:
            raise SunlabError(f"{folder}: unexpected outputs {unknown}. Fix: this is a bug in "
                              "the writer")
        with signals_held():
            if not folder.exists():
                os.rename(staging, folder)
            else:
                _move_in(staging, folder, overwrite, flag)
    finally:
        if staging.exists():
            _remove(staging)


def _move_in(staging: Path, folder: Path, overwrite: bool, flag: str) -> None:
    """Move every file of ``staging`` (at any depth; sub-folders made as needed) into
    ``folder``, setting aside the files it replaces; on a failure, undo the moves made."""
    aside = staging / ".old"
    aside.mkdir()
    done: list[tuple[Path, Path | None]] = []
    try:
        for new in sorted(p for p in staging.rglob("*") if p.is_file() and aside not in p.parents):
            rel = new.relative_to(staging)
            target, old = folder / rel, None
            target.parent.mkdir(exist_ok=True)
            if _exists(target):
                if not overwrite:
                    raise _exists_error(target, flag, meanwhile=True, what="folder")
                (old := aside / rel).parent.mkdir(parents=True, exist_ok=True)
                os.replace(target, old)
            done.append((target, old))
            os.replace(new, target)
    except BaseException:
        for target, old in reversed(done):
            with contextlib.suppress(OSError):
                os.replace(old, target) if old is not None else target.unlink()
        raise


def write_text(path, text: str | bytes, *, overwrite: bool = False,
               flag: str = "overwrite=True") -> Path:
    """Write ``text`` (UTF-8; or bytes) to ``path`` atomically (temporary sibling, fsync,
    rename); return the path.

    Parameters
    ----------
    path : str or path-like
        The output file.
    text : str or bytes
        Its content.
    overwrite, flag
        As in :func:`check_target`.

    Returns
    -------
    pathlib.Path
        ``path``.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "x.json"
    >>> write_text(path, "{}").read_text()
    '{}'
    """
    with atomic_output(path, overwrite=overwrite, flag=flag) as tmp, open(tmp, "xb") as fh:
        fh.write(text.encode("utf-8") if isinstance(text, str) else text)
        fh.flush()
        os.fsync(fh.fileno())
    return Path(path)
