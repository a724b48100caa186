"""Resumable acquisition: a plan of poses -> a pre-allocated Zarr frame cube, one pose at a time.

For each pose of a :class:`sunlab.plans.Plan` the runner moves the stage (which waits for
motion done and settles), takes ``plan.shots`` frames, each with the encoder read-back and a
timestamp, and writes the pose into a Zarr store that was allocated up front in the frames/1
contract (:func:`sunlab.schema.frames_dataset` of lazy zeros): frames, ``alpha_read``,
``beta_read`` and ``time`` on (pose, shot), and a per-pose flag ``done``.

Crash safety rests on one ordering: a pose's frames and read-backs are written (and fsync'ed)
before its ``done`` flag, and every chunk file is replaced atomically by Zarr (write to a
temporary file, then rename). A run killed at any instant therefore leaves poses that are
either complete and flagged, or unflagged; restarting with ``resume=True`` continues at the first
unflagged pose and rewrites it whole. The store itself is created in a temporary directory and
renamed into place, so a half-created store is never mistaken for a run.

One session writes a run at a time: :func:`run_lock` takes ``OUT.lock`` (the process id, host
and start time of the session) before the stage moves; a second session on the same run is
refused, naming the holder, and a lock left by a session that died on this host is taken over
with a message. The store's metadata are sealed with a checksum (:mod:`sunlab.integrity`) when a
session ends and unsealed when the next one starts.

Run metadata live in the store's attributes: ``uid``, ``plan``, ``versions``, ``start``,
``stop``, ``exit_status`` (``running``, ``complete``, ``interrupted``, ``failed``), ``error``,
``stage``, ``camera`` and ``sessions`` (one entry per start or resume; a session that was killed
keeps ``running`` until the next resume marks it ``killed``).

Examples
--------
>>> import tempfile, os
>>> from sunlab import plans
>>> from sunlab.hardware import acquire, open_run, open_stage
>>> stage = open_stage("fake://?velocity=1e4", retry_delay_s=0.0, poll_s=0.001)
>>> class Ramp:  # a minimal camera: any object with grab, shape, dtype, bit_depth
...     shape, dtype, bit_depth = (4, 5), np.dtype(np.uint16), 10
...     def grab(self):
...         return np.arange(20, dtype=np.uint16).reshape(4, 5)
>>> path = os.path.join(tempfile.mkdtemp(), "run.zarr")
>>> result = acquire(plans.custom([0.0, 1.0], [0.0, 2.0], shots=2), stage, Ramp(), path,
...                  progress=False)
>>> result.exit_status, result.poses_done
('complete', 2)
>>> run = open_run(path)
>>> run.beta_read.values.tolist()
[[0.0, 0.0], [2.0, 2.0]]
>>> stage.close()
"""

from __future__ import annotations

import contextlib
import json
import os
import platform
import signal
import sys
import threading
import time
import uuid
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path

import numpy as np

from ..errors import ConfigurationError
from ..extras import installed_version
from ..options import show_progress
from .errors import BenchError, CameraError

__all__ = ["acquire", "open_run"]

#: Units of the ``time`` coordinate (CF): float seconds since the Unix epoch, UTC.
TIME_UNITS = "seconds since 1970-01-01T00:00:00+00:00"

_PER_POSE = ("frames", "alpha_read", "beta_read", "time")


@dataclass(frozen=True)
class RunResult:
    """What :func:`acquire` did.

    Attributes
    ----------
    path : str
        The Zarr store.
    uid : str
        Run identifier (kept across resumes).
    exit_status : str
        ``complete``, ``interrupted`` or ``failed``.
    poses_total, poses_done : int
        Poses in the plan, and poses flagged done in the store.
    poses_this_session : int
        Poses written by this call.
    error : str or None
        The fault that stopped a failed run.
    """

    path: str
    uid: str
    exit_status: str
    poses_total: int
    poses_done: int
    poses_this_session: int
    error: str | None = None


def _now() -> str:
    return datetime.now(UTC).isoformat(timespec="milliseconds")


def _versions() -> dict:
    import xarray
    import zarr

    from .. import __version__

    return {
        "sunlab": __version__,
        "python": platform.python_version(),
        "numpy": np.__version__,
        "xarray": xarray.__version__,
        "zarr": zarr.__version__,
        "pyserial": installed_version("pyserial"),
    }


def _plan_arrays(plan) -> tuple[np.ndarray, np.ndarray, int, str]:
    try:
        alpha = np.asarray(plan.alpha, dtype=float).ravel()
        beta = np.asarray(plan.beta, dtype=float).ravel()
        shots = int(plan.shots)
        name = str(getattr(plan, "name", ""))
    except (AttributeError, TypeError, ValueError) as err:
        raise ConfigurationError(
            f"plan: found {type(plan).__name__}, expected a sunlab.plans.Plan (alpha, beta in "
            "degrees, shots). Fix: build one with sunlab.plans.experiment/grid/custom"
        ) from err
    if alpha.shape != beta.shape or alpha.size == 0 or shots < 1:
        raise ConfigurationError(
            f"plan: found {alpha.size} alpha, {beta.size} beta, shots={shots}, expected equal "
            "non-empty angle lists and shots >= 1"
        )
    if not (np.all(np.isfinite(alpha)) and np.all(np.isfinite(beta))):
        raise ConfigurationError("plan: found non-finite angles, expected finite degrees")
    return alpha, beta, shots, name


def _motion(plan, n: int) -> dict:
    """How the stage moves through the plan: visit order, scan, approach, and the direction in
    which the inner axis reaches each pose (:meth:`sunlab.plans.Plan.beta_approach`)."""
    if not callable(getattr(plan, "visit_order", None)):
        return {"order": np.arange(n), "scan": "raster", "approach": "direct",
                "beta_approach": None}
    return {"order": np.asarray(plan.visit_order()), "scan": plan.scan,
            "approach": plan.approach, "beta_approach": plan.beta_approach()}


def _camera_spec(camera) -> tuple[tuple[int, int], np.dtype, int]:
    try:
        shape = tuple(int(n) for n in camera.shape)
        dtype = np.dtype(camera.dtype)
        bits = int(camera.bit_depth)
    except (AttributeError, TypeError, ValueError) as err:
        raise ConfigurationError(
            f"camera: found {type(camera).__name__}, expected a sunlab.hardware.Camera (grab(), "
            "shape, dtype, bit_depth)"
        ) from err
    if len(shape) != 2 or min(shape) < 1 or dtype not in (np.dtype(np.uint8), np.dtype(np.uint16)):
        raise ConfigurationError(
            f"camera: found shape {shape} dtype {dtype}, expected a 2-d (ny, nx) frame of uint8 "
            "or uint16"
        )
    return shape, dtype, bits


def _describe(obj) -> dict:
    describe = getattr(obj, "describe", None)
    info = describe() if callable(describe) else {"type": type(obj).__name__}
    return json.loads(json.dumps(info, default=str))


def _create_store(path: Path, alpha, beta, shots, name, camera, stage, attrs,
                  motion=None) -> None:
    import dask.array as da
    import zarr

    from .. import schema

    (ny, nx), dtype, bits = _camera_spec(camera)
    n = alpha.size
    sensor = dict(getattr(camera, "attrs", None) or {})
    sensor.setdefault("bit_depth", bits)
    nan = da.full((n, shots), np.nan, chunks=(1, shots))
    coords = {
        "alpha_read": (("pose", "shot"), nan,
                       {"units": "deg", "long_name": "encoder read-back of the outer axis"}),
        "beta_read": (("pose", "shot"), nan,
                      {"units": "deg", "long_name": "encoder read-back of the inner axis"}),
        "time": (("pose", "shot"), da.full((n, shots), np.datetime64("NaT", "ns"),
                                           chunks=(1, shots)),
                 {"long_name": "start of the frame's capture, UTC"}),
        "done": ("pose", da.zeros(n, dtype=np.uint8, chunks=1),
                 {"flag_values": [0, 1], "flag_meanings": "pending done",
                  "long_name": "pose fully written"}),
    }
    if motion is not None and motion["beta_approach"] is not None:
        coords["beta_approach"] = ("pose", np.asarray(motion["beta_approach"], dtype=np.int8), {
            "long_name": "direction in which the inner axis reached the pose (+1 up, -1 down)"})
    zeros = da.zeros((n, shots, ny, nx), dtype=dtype, chunks=(1, 1, ny, nx))  # allocated lazily
    cube = schema.frames_dataset(zeros, alpha, beta, experiment=name, coords=coords, **sensor)
    from .. import atomic

    tmp = atomic.temporary_name(path)  # a later run removes it if this one is killed
    # time is stored as float seconds since the epoch (NaN until taken), decoded to datetime64
    encoding = {v: {"_FillValue": np.nan} for v in ("alpha_read", "beta_read")}
    encoding["time"] = {"units": TIME_UNITS, "calendar": "proleptic_gregorian",
                        "dtype": "float64", "_FillValue": np.nan}
    cube.to_zarr(tmp, compute=False, consolidated=False, encoding=encoding)
    group = zarr.open_group(tmp, mode="r+")
    group.attrs.update({
        "uid": uuid.uuid4().hex,
        "plan": {"name": name, "n_poses": int(n), "shots": int(shots)},
        "versions": _versions(),
        "stage": _describe(stage),
        "camera": _describe(camera),
        "start": None,
        "stop": None,
        "exit_status": "created",
        "error": None,
        "sessions": [],
        **({} if motion is None else {
            "scan_order": motion["scan"], "approach": motion["approach"],
            "visit_order": [int(i) for i in motion["order"]]}),
        **dict(attrs or {}),
    })
    os.replace(tmp, path)


def _check_store(group, alpha, beta, shots, camera) -> None:
    (ny, nx), dtype, _ = _camera_spec(camera)
    attrs = group.attrs
    names = set(group.array_keys())
    if (attrs.get("sunlab_schema") != "frames/1" or "uid" not in attrs
            or not names >= {"frames", "alpha", "beta", "alpha_read", "beta_read", "time", "done"}):
        raise ConfigurationError(
            f"out: {group.store} is not a sunlab acquisition store (no frames/1 schema, uid or "
            "done flags). Fix: choose a new path"
        )
    frames = group["frames"]
    found = (tuple(frames.shape), np.dtype(frames.dtype))
    expected = ((alpha.size, shots, ny, nx), dtype)
    if found != expected:
        raise ConfigurationError(
            f"out: store frames {found} do not match this plan and camera {expected}. Fix: "
            "resume with the plan and camera settings of the original run, or choose a new path"
        )
    if not (np.array_equal(group["alpha"][:], alpha) and np.array_equal(group["beta"][:], beta)):
        raise ConfigurationError(
            "out: the store's commanded angles differ from the plan's. Fix: resume with the "
            "original plan, or choose a new path"
        )


def _fsync_pose(root: Path, names, pose: int) -> None:
    """fsync the chunk files of one pose (zarr v3 'c/' keys) and their folders."""
    dirs = set()
    for name in names:
        base = root / name / "c" / str(pose)
        files = [base] if base.is_file() else sorted(p for p in base.rglob("*") if p.is_file())
        for file in files:
            fd = os.open(file, os.O_RDONLY)
            try:
                os.fsync(fd)
            finally:
                os.close(fd)
            dirs.add(file.parent)
    for folder in dirs:
        try:
            fd = os.open(folder, os.O_RDONLY)
        except OSError:
            continue
        try:
            os.fsync(fd)
        except OSError:
            pass
        finally:
            os.close(fd)


def _capture_pose(stage, camera, pose, alpha, beta, shots, shape, dtype, bits,
                  overshoot=0.0):
    """Move and capture one pose into memory; nothing is written here. With ``overshoot``
    the inner axis first goes that far below the target, then up to it (a unidirectional
    approach: the same gear flank at every pose)."""
    if overshoot:
        stage.move_to(alpha, beta - overshoot)
    stage.move_to(alpha, beta)
    frames = np.empty((shots, *shape), dtype=dtype)
    read = np.empty((2, shots))
    stamps = np.empty(shots)
    set_index = getattr(camera, "set_index", None)
    for shot in range(shots):
        read[:, shot] = stage.position()
        if callable(set_index):
            set_index(pose, shot, alpha=read[0, shot], beta=read[1, shot])
        stamps[shot] = time.time()
        frame = np.asarray(camera.grab())
        if frame.shape != shape or frame.dtype != dtype:
            raise CameraError(
                f"camera: pose {pose} shot {shot} gave a {frame.dtype} frame of shape "
                f"{frame.shape}, expected {dtype} {shape}. Fix: check the camera's ROI, binning "
                "and pixel format"
            )
        top = int(frame.max()) if frame.size else 0
        if top >= 2**bits:
            raise CameraError(
                f"camera: pose {pose} shot {shot} holds {top} DN, above the {bits}-bit range. "
                "Fix: set the camera's bit_depth to its ADC's"
            )
        frames[shot] = frame
    return frames, read, stamps


def acquire(plan, stage, camera, out, *, resume: bool = False, progress: bool = True,
            stop: threading.Event | None = None, fsync: bool = True, attrs: dict | None = None,
            handle_sigint: bool = True, overshoot_deg: float = 0.5) -> RunResult:
    """Run a plan on the bench into a resumable Zarr store.

    Parameters
    ----------
    plan : sunlab.plans.Plan
        Poses (alpha outer, beta inner, degrees) and shots per pose.
    stage : sunlab.hardware.Stage
        The platform; ``move_to`` must return once settled (e.g. :class:`~sunlab.hardware.ESP300`).
    camera : sunlab.hardware.Camera
        ``grab()``, ``shape``, ``dtype``, ``bit_depth``; optional ``set_index(pose, shot,
        alpha=, beta=)`` (called before each grab with the read-back angles) and ``attrs``
        (sensor attributes of the cube: ``pixel_pitch_mm``, ``mask_distance_mm``, ``x_cf_px``,
        ``y_cf_px``, ``mask``).
    out : str or path
        The Zarr store (a directory). Created if missing.
    resume : bool
        Continue an existing store of the same plan and camera at its first unfinished pose;
        without it an existing ``out`` is an error.
    progress : bool
        Show a tqdm progress bar (poses).
    stop : threading.Event, optional
        Set it to stop between poses (as Ctrl-C does).
    fsync : bool
        fsync each pose's chunk files before flagging it done (survives a power cut as well as
        a killed process).
    attrs : dict, optional
        Extra JSON-able attributes recorded when the store is created.
    handle_sigint : bool
        In the main thread, turn the first Ctrl-C into a stop between poses (a second one
        interrupts at once).
    overshoot_deg : float
        For a plan with ``approach="unidirectional"``: how far below each pose the inner axis
        goes before it returns upward to it, deg (more than the axis's backlash). The poses are
        visited in the plan's scan order (:meth:`sunlab.plans.Plan.visit_order`), and the
        store records the motion (``scan_order``, ``approach``, ``visit_order`` attributes and
        ``beta_approach`` on pose) for :mod:`sunlab.studies.platform_fault`. A resumed
        direct-approach run reaches its first pose from wherever the stage stood: use a
        unidirectional approach where the approach matters.

    Returns
    -------
    RunResult
        With ``exit_status`` ``complete`` or ``interrupted``.

    Raises
    ------
    ConfigurationError
        ``out`` exists without ``resume``, or does not match the plan and camera.
    BenchError
        A stage or camera fault that outlasted its retries; the store then records
        ``exit_status = 'failed'`` and the error, and the failed pose holds nothing.
    """
    alpha, beta, shots, name = _plan_arrays(plan)
    motion = _motion(plan, alpha.size)
    overshoot = _overshoot(overshoot_deg, motion)
    shape, dtype, bits = _camera_spec(camera)
    with run_lock(out):
        store = _open_store(Path(out), resume, alpha, beta, shots, name, camera, stage, attrs,
                            motion)
        return _run_poses(store, plan, stage, camera, motion, overshoot, stop, handle_sigint,
                          progress, fsync)


def _run_poses(store, plan, stage, camera, motion, overshoot, stop, handle_sigint, progress,
               fsync) -> RunResult:
    """The poses of :func:`acquire` not yet done, in visit order, one session."""
    from tqdm.auto import tqdm

    alpha, beta, shots, name = _plan_arrays(plan)
    shape, dtype, bits = _camera_spec(camera)
    stop = stop if stop is not None else threading.Event()
    with _session(store) as run, _sigint_stops(stop, handle_sigint), contextlib.closing(tqdm(
            total=alpha.size, initial=int(store.done.sum()), unit="pose",
            disable=not show_progress(progress), desc=f"acquire {name}".strip())) as bar:
        for pose in motion["order"][~store.done[motion["order"]]]:
            if stop.is_set():
                break
            frames, read, stamps = _capture_pose(
                stage, camera, int(pose), alpha[pose], beta[pose], shots, shape, dtype, bits,
                overshoot,
            )
            store.write_pose(int(pose), frames, read, stamps, fsync)
            run.written += 1
            bar.update(1)
        run.status = "complete" if store.done.all() else "interrupted"
    return RunResult(str(store.path), str(store.group.attrs["uid"]), run.status,
                     int(alpha.size), int(store.done.sum()), run.written, run.error)


class RunLockedError(ConfigurationError):
    """Another session holds the acquisition run (its lock file names it)."""


#: Locks this process holds: lock path -> depth (the CLI takes it, then :func:`acquire`).
_HELD: dict[str, int] = {}


def _lock_path(out) -> Path:
    out = Path(out)
    return out.with_name(out.name + ".lock")


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

    tmp = atomic.temporary_name(lock)
    tmp.write_text(json.dumps(me), encoding="utf-8")
    try:
        os.link(tmp, lock)  # fails if the lock exists; readers never see it half-written
        return True
    except FileExistsError:
        return False
    except OSError:  # a file system without hard links
        try:
            fd = os.open(lock, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o644)
        except FileExistsError:
            return False
        with os.fdopen(fd, "w", encoding="utf-8") as fh:
            fh.write(json.dumps(me))
        return True
    finally:
        tmp.unlink(missing_ok=True)


def _take_lock(lock: Path, out: Path) -> None:
    import socket

    from .. import atomic

    me = {"pid": os.getpid(), "host": socket.gethostname(), "start": _now()}
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
                "not written by sunlab). Fix: if no acquisition runs into this store, delete "
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
            f"stop it (Ctrl-C); if it is no longer running, delete {lock}"
        )
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

    Raises
    ------
    RunLockedError
        Another live process (or another host) holds the lock.

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
    lock = _lock_path(out)
    key = str(lock.resolve())
    if _HELD.get(key):
        _HELD[key] += 1
        try:
            yield lock
        finally:
            _HELD[key] -= 1
        return
    if not lock.parent.is_dir():
        lock.parent.mkdir(parents=True, exist_ok=True)
    _take_lock(lock, Path(out))
    _HELD[key] = 1
    try:
        yield lock
    finally:
        del _HELD[key]
        if _read_lock(lock).get("pid") == os.getpid():
            lock.unlink(missing_ok=True)


def _overshoot(overshoot_deg, motion: dict) -> float:
    """How far below each pose the inner axis goes first: 0 unless the approach is one-way."""
    overshoot = float(overshoot_deg) if motion["approach"] == "unidirectional" else 0.0
    if not (np.isfinite(overshoot) and overshoot >= 0):
        raise ConfigurationError(
            f"overshoot_deg: found {overshoot_deg!r}; expected a non-negative angle in deg "
            "(more than the inner axis's backlash). Fix: overshoot_deg=0.5."
        )
    return overshoot


@dataclass
class _Store:
    """An open acquisition store: its arrays and which poses are flagged done."""

    path: Path
    group: object
    arrays: dict
    done: np.ndarray

    def write_pose(self, pose: int, frames, read, stamps, fsync: bool) -> None:
        """Write one pose's frames, read-backs and times, then (only then) its done flag."""
        self.arrays["frames"][pose] = frames
        self.arrays["alpha_read"][pose] = read[0]
        self.arrays["beta_read"][pose] = read[1]
        self.arrays["time"][pose] = stamps
        if fsync:
            _fsync_pose(self.path, _PER_POSE, pose)
        self.arrays["done"][pose] = 1
        if fsync:
            _fsync_pose(self.path, ("done",), pose)
        self.done[pose] = True


def _open_store(path: Path, resume: bool, alpha, beta, shots, name, camera, stage, attrs,
                motion) -> _Store:
    """Create the store (allocated up front), or reopen it to resume; check it fits the run."""
    import zarr

    from .. import atomic

    atomic.remove_stale(path)
    if path.exists() and not resume:
        raise ConfigurationError(
            f"out: {str(path)!r} exists. Fix: pass resume=True (--resume) to continue that run, "
            "or choose a new path"
        )
    if not path.exists():
        path.parent.mkdir(parents=True, exist_ok=True)
        _create_store(path, alpha, beta, shots, name, camera, stage, attrs, motion)
    for leftover in path.rglob("*.partial"):  # temporary chunk files of a killed writer
        leftover.unlink(missing_ok=True)
    with zarr.config.set({"array.write_empty_chunks": True}):  # a dark frame is a chunk too
        group = zarr.open_group(path, mode="r+")
        _check_store(group, alpha, beta, shots, camera)
        arrays = {k: group[k] for k in ("frames", "alpha_read", "beta_read", "time", "done")}
    return _Store(path, group, arrays, np.asarray(arrays["done"][:], dtype=bool))


@dataclass
class _Session:
    """This call's entry in the store's ``sessions`` and how it ends."""

    status: str = "complete"
    error: str | None = None
    written: int = 0


@contextlib.contextmanager
def _session(store: _Store):
    """Record a running session in the store; on exit, its end (status, error, poses)."""
    from .. import integrity

    group = store.group
    integrity.unseal_zarr(store.path, group)  # the metadata change while the session runs
    sessions = [dict(s, exit_status="killed") if s.get("exit_status") == "running" else s
                for s in group.attrs.get("sessions", [])]
    session = {"start": _now(), "stop": None, "exit_status": "running", "poses": 0}
    group.attrs.update({
        "start": group.attrs.get("start") or session["start"],
        "exit_status": "running",
        "sessions": [*sessions, session],
    })
    run = _Session()
    try:
        yield run
    except KeyboardInterrupt:
        run.status = "interrupted"
        raise
    except BenchError as err:
        run.status, run.error = "failed", str(err)
        raise
    except BaseException as err:
        run.status, run.error = "failed", f"{type(err).__name__}: {err}"
        raise
    finally:
        session.update(stop=_now(), exit_status=run.status, poses=run.written)
        group.attrs.update({
            "stop": session["stop"],
            "exit_status": run.status,
            "error": run.error,
            "sessions": [*sessions, session],
        })
        integrity.seal_zarr(store.path, group)


@contextlib.contextmanager
def _sigint_stops(stop: threading.Event, enabled: bool):
    """In the main thread, the first Ctrl-C sets ``stop`` (a second one interrupts at once)."""
    previous = None
    if enabled and threading.current_thread() is threading.main_thread():
        def on_sigint(signum, frame):
            if stop.is_set():
                raise KeyboardInterrupt
            stop.set()
            print("sunlab acquire: stopping after this pose (Ctrl-C again to abort)",
                  file=sys.stderr)

        previous = signal.signal(signal.SIGINT, on_sigint)
    try:
        yield
    finally:
        if previous is not None:
            signal.signal(signal.SIGINT, previous)


def open_run(path, *, chunks=None):
    """Open an acquisition store as a frame cube (lazy, Dask-backed, one frame per chunk).

    Parameters
    ----------
    path : str or path
        The Zarr store written by :func:`acquire`.
    chunks : dict, optional
        Dask chunks as :func:`xarray.open_zarr`; default: the store's (one frame per chunk).

    Returns
    -------
    xarray.Dataset
        Contract frames/1, with ``alpha_read``, ``beta_read``, ``time`` (datetime64, NaT for
        frames not yet taken) and ``done`` coordinates, and the run metadata in ``attrs``.
    """
    import xarray as xr

    from .. import integrity, schema

    path = Path(path)
    if not path.exists():
        raise ConfigurationError(f"path: {str(path)!r} does not exist, expected a run store")
    integrity.verify_zarr(path)  # sealed when its last session ended
    ds = xr.open_zarr(path, consolidated=False, chunks={} if chunks is None else chunks)
    return schema.validate_frames(ds)
