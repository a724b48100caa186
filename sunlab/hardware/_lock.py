"""One session writes an acquisition run at a time: :func:`run_lock` and its lock file.

The lock is an exclusive :func:`fcntl.flock` on the file ``OUT.lock`` beside the store, which
holds the process id, host and start time of the session. The kernel releases it when the
holder ends, however it ends (a killed session leaves no lock to clear); a second session on
the same run is refused, naming the holder.
"""

from __future__ import annotations

import contextlib
import fcntl
import json
import os
import socket
from datetime import UTC, datetime
from pathlib import Path

from ..errors import ConfigurationError


class RunLockedError(ConfigurationError):
    """Another session holds the acquisition run (its lock file names it)."""


#: Locks this process holds: lock path -> [open lock file, depth] (the CLI takes it, then
#: :func:`acquire`).
_HELD: dict[str, list] = {}


def _take_lock(lock: Path, out: Path):
    """The lock file, open and flocked by this process, holding this session's id."""
    while True:
        try:
            fh = open(lock, "a+", encoding="utf-8")  # noqa: SIM115 - held until run_lock ends
        except OSError as err:
            raise RunLockedError(
                f"out: {out}: the lock path {lock} is not a lock file that sunlab writes "
                f"({err.strerror}). Fix: remove or rename {lock}") from None
        try:
            fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            fh.seek(0)
            try:
                holder = json.loads(fh.read(4096))
                who = f"pid {holder['pid']} on {holder['host']}, started {holder['start']}"
            except (ValueError, TypeError, KeyError):  # the holder is still writing it
                who = "holder unknown"
            fh.close()
            raise RunLockedError(
                f"out: {out} is being written by another session ({who}; lock file {lock}). "
                "Fix: wait for that session to finish or stop it (Ctrl-C)") from None
        # a holder that ended between our open and flock removed the file we hold: retry
        with contextlib.suppress(FileNotFoundError):
            if os.stat(lock).st_ino == os.fstat(fh.fileno()).st_ino:
                fh.truncate(0)
                json.dump({"pid": os.getpid(), "host": socket.gethostname(),
                           "start": datetime.now(UTC).isoformat(timespec="milliseconds")}, fh)
                fh.flush()
                return fh
        fh.close()


@contextlib.contextmanager
def run_lock(out):
    """Hold the lock of the acquisition run ``out`` (one writing session at a time).

    The lock is a :func:`fcntl.flock` on the file ``OUT.lock`` beside the store, which holds
    the process id, host and start time of the session; the file is removed when the block
    ends, and the kernel releases the lock of a session that dies. A lock held by another
    session raises :class:`RunLockedError`, naming it. The same process may nest the lock (the
    ``sunlab acquire`` command takes it before it opens the stage, :func:`acquire` again).

    Parameters
    ----------
    out : str or path
        The run's store (e.g. ``run.zarr``); its lock is ``OUT.lock`` beside it.

    Yields
    ------
    pathlib.Path
        The lock file, held until the ``with`` block ends.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> out = pathlib.Path(tempfile.mkdtemp()) / "run.zarr"
    >>> with run_lock(out) as lock:
    ...     print(lock.name, lock.exists())
    run.zarr.lock True
    >>> lock.exists()
    False
    """
    out = Path(out)
    lock = out.with_name(out.name + ".lock")
    key = str(lock.resolve())
    if key not in _HELD:
        lock.parent.mkdir(parents=True, exist_ok=True)
        _HELD[key] = [_take_lock(lock, out), 0]
    _HELD[key][1] += 1
    try:
        yield lock
    finally:
        _HELD[key][1] -= 1
        if not _HELD[key][1]:
            fh = _HELD.pop(key)[0]
            lock.unlink(missing_ok=True)  # before the lock is released: see _take_lock
            fh.close()
