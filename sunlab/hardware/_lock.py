"""One session writes an acquisition run at a time: :func:`run_lock` and its lock file.

The lock is the file ``OUT.lock`` beside the store, created in one step (a hard link of a
complete temporary file, so a reader never sees it half-written) and holding the process id,
host and start time of the session. A second session on the same run is refused, naming the
holder; a lock left by a session that died on this host is taken over with a message.
"""

from __future__ import annotations

import contextlib
import json
import os
import socket
import sys
from datetime import UTC, datetime
from pathlib import Path

from ..errors import ConfigurationError


class RunLockedError(ConfigurationError):
    """Another session holds the acquisition run (its lock file names it)."""


#: Locks this process holds: lock path -> depth (the CLI takes it, then :func:`acquire`).
_HELD: dict[str, int] = {}


def _read_lock(lock: Path) -> dict:
    try:
        if lock.stat().st_size > 4096:  # not a lock sunlab wrote
            return {}
        info = json.loads(lock.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError, RecursionError):
        return {}
    return info if isinstance(info, dict) else {}


def _publish(lock: Path, me: dict) -> bool:
    """Create ``lock`` holding ``me``, complete, in one step; False if it exists."""
    from .. import atomic

    tmp, text = atomic.temporary_name(lock), json.dumps(me)
    tmp.write_text(text, encoding="utf-8")
    try:
        try:
            os.link(tmp, lock)  # fails if the lock exists; readers never see it half-written
        except FileExistsError:
            raise
        except OSError:  # a file system without hard links: created exclusively, then written
            with open(lock, "x", encoding="utf-8") as fh:
                fh.write(text)
        return True
    except FileExistsError:
        return False
    finally:
        tmp.unlink(missing_ok=True)


def _take_lock(lock: Path, out: Path) -> None:
    from .. import atomic

    me = {"pid": os.getpid(), "host": socket.gethostname(),
          "start": datetime.now(UTC).isoformat(timespec="milliseconds")}
    for _ in range(5):
        if _publish(lock, me):
            return
        if not lock.is_file() and (lock.exists() or lock.is_symlink()):
            kind = "a directory" if lock.is_dir() else "not a regular file"
            raise RunLockedError(
                f"out: {out}: the lock path {lock} is {kind}, not a lock file that sunlab "
                f"writes. Fix: remove or rename {lock} (no session of sunlab made it)")
        holder = _read_lock(lock)
        pid, host = holder.get("pid"), holder.get("host")
        if not holder:
            raise RunLockedError(
                f"out: {out}: the lock file {lock} holds no session (unreadable, empty or "
                f"not written by sunlab). Fix: if no acquisition runs into this store, delete "
                f"{lock}")
        if host == me["host"] and isinstance(pid, int) and not atomic.process_alive(pid):
            stale = lock.with_name(f"{lock.name}.stale-{os.getpid()}")
            try:
                os.replace(lock, stale)  # only one of two sessions taking over gets it
            except FileNotFoundError:
                continue
            stale.unlink(missing_ok=True)
            print(f"sunlab acquire: {out}: took over the lock of a session that is no longer "
                  f"running (pid {pid} on {host}, started {holder.get('start')})",
                  file=sys.stderr)
            continue
        raise RunLockedError(
            f"out: {out} is being written by another session (pid {pid} on {host}, started "
            f"{holder.get('start')}; lock file {lock}). Fix: wait for that session to finish or "
            f"stop it (Ctrl-C); if it is no longer running, delete {lock}")
    raise RunLockedError(f"out: {out}: could not take the lock {lock} (other sessions keep "
                         "taking it). Fix: run one session at a time")


@contextlib.contextmanager
def run_lock(out):
    """Hold the lock of the acquisition run ``out`` (one writing session at a time).

    The lock is the file ``OUT.lock`` beside the store, created in one step and holding the
    process id, host and start time of the session; it is removed when the block ends. A
    lock held by a live process (or by another host) raises :class:`RunLockedError`, naming
    it; a lock whose process no longer runs on this host is taken over with a message on
    stderr. The same process may nest the lock (the ``sunlab acquire`` command takes it before
    it opens the stage, :func:`acquire` again).

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
    if not _HELD.get(key):
        lock.parent.mkdir(parents=True, exist_ok=True)
        _take_lock(lock, out)
    _HELD[key] = _HELD.get(key, 0) + 1
    try:
        yield lock
    finally:
        _HELD[key] -= 1
        if not _HELD[key]:
            del _HELD[key]
            if _read_lock(lock).get("pid") == os.getpid():
                lock.unlink(missing_ok=True)
