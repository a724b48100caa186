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

One session writes a run at a time: :func:`run_lock` flocks ``OUT.lock`` (the process id, host
and start time of the session) before the stage moves; a second session on the same run is
refused, naming the holder, and the kernel releases the lock of a session that dies. The
store's metadata are sealed with a checksum (:mod:`sunlab.integrity`) when a session ends and
unsealed when the next one starts.

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
>>> open_run(path).beta_read.values.tolist()
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
from ..plans import Plan
from ._lock import RunLockedError, run_lock  # noqa: F401 - the CLI takes the lock from here
from ._plugins import call  # the CLI closes the stage through it too
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
        ``complete`` or ``interrupted`` (a failed run raises).
    poses_total, poses_done : int
        Poses in the plan, and poses flagged done in the store.
    poses_this_session : int
        Poses written by this call.
    """

    path: str
    uid: str
    exit_status: str
    poses_total: int
    poses_done: int
    poses_this_session: int


@dataclass(frozen=True)
class _Run:
    """What one call of :func:`acquire` takes: the plan, its visit order and overshoot, and the
    camera's frames."""

    plan: Plan
    order: np.ndarray
    overshoot: float
    shape: tuple[int, int]
    dtype: np.dtype
    bits: int


def _now() -> str:
    return datetime.now(UTC).isoformat(timespec="milliseconds")


def _checked(plan, camera, overshoot_deg) -> _Run:
    """The plan (checked when it was made) and the camera as :func:`acquire` uses them."""
    if not isinstance(plan, Plan):
        raise ConfigurationError(
            f"plan: found {type(plan).__name__}, expected a sunlab.plans.Plan (alpha, beta in "
            "degrees, shots). Fix: build one with sunlab.plans.experiment/grid/custom")
    overshoot = float(overshoot_deg) if plan.approach == "unidirectional" else 0.0
    if not (np.isfinite(overshoot) and overshoot >= 0):
        raise ConfigurationError(
            f"overshoot_deg: found {overshoot_deg!r}; expected a non-negative angle in deg "
            "(more than the inner axis's backlash). Fix: overshoot_deg=0.5.")
    try:
        shape = tuple(int(n) for n in camera.shape)
        dtype, bits = np.dtype(camera.dtype), int(camera.bit_depth)
    except (AttributeError, TypeError, ValueError) as err:
        raise ConfigurationError(
            f"camera: found {type(camera).__name__}, expected a sunlab.hardware.cameras.Camera "
            "(grab(), shape, dtype, bit_depth)") from err
    if len(shape) != 2 or min(shape) < 1 or dtype not in (np.uint8, np.uint16):
        raise ConfigurationError(f"camera: found shape {shape} dtype {dtype}, expected a 2-d "
                                 "(ny, nx) frame of uint8 or uint16")
    return _Run(plan, np.asarray(plan.visit_order()), overshoot, shape, dtype, bits)


def _describe(obj, role: str) -> dict:
    describe = getattr(obj, "describe", None)
    info = call(role, obj, "describe") if callable(describe) else {"type": type(obj).__name__}
    return json.loads(json.dumps(info, default=str))


def _create_store(path: Path, run: _Run, camera, stage) -> None:
    """Allocate the store of the whole run in a temporary sibling, then rename it into place."""
    import dask.array as da
    import xarray
    import zarr

    from .. import __version__, atomic, schema

    plan, (ny, nx) = run.plan, run.shape
    n, shots = len(plan), plan.shots
    coords = {f"{ax}_read": (("pose", "shot"), da.full((n, shots), np.nan, chunks=(1, shots)),
                             {"units": "deg", "long_name": f"encoder read-back of the {side} axis"})
              for ax, side in (("alpha", "outer"), ("beta", "inner"))}
    coords["time"] = (("pose", "shot"), da.full((n, shots), np.datetime64("NaT", "ns"),
                                                chunks=(1, shots)),
                      {"long_name": "start of the frame's capture, UTC"})
    coords["done"] = ("pose", da.zeros(n, dtype=np.uint8, chunks=1), {
        "flag_values": [0, 1], "flag_meanings": "pending done", "long_name": "pose fully written"})
    coords["beta_approach"] = ("pose", np.asarray(plan.beta_approach(), np.int8), {
        "long_name": "direction in which the inner axis reached the pose (+1 up, -1 down)"})
    zeros = da.zeros((n, shots, ny, nx), dtype=run.dtype, chunks=(1, 1, ny, nx))  # lazily
    cube = schema.frames_dataset(zeros, plan.alpha, plan.beta, experiment=plan.name,
                                 coords=coords, **{"bit_depth": run.bits,
                                                   **dict(getattr(camera, "attrs", None) or {})})
    # refused at once where the whole run cannot fit on the disk (issue 47, size before work);
    # allocated in a temporary sibling, renamed into place (removed if this run is killed)
    with atomic.atomic_output(path, kind="zarr", nbytes=zeros.nbytes) as tmp:
        # time is stored as float seconds since the epoch (NaN until taken), decoded to datetime64
        encoding = {v: {"_FillValue": np.nan} for v in ("alpha_read", "beta_read")}
        encoding["time"] = {"units": TIME_UNITS, "calendar": "proleptic_gregorian",
                            "dtype": "float64", "_FillValue": np.nan}
        cube.to_zarr(tmp, compute=False, consolidated=False, encoding=encoding)
        zarr.open_group(tmp, mode="r+").attrs.update({
            "uid": uuid.uuid4().hex, "plan": {"name": plan.name, "n_poses": n, "shots": shots},
            "versions": {"sunlab": __version__, "python": platform.python_version(),
                         "numpy": np.__version__, "xarray": xarray.__version__,
                         "zarr": zarr.__version__, "pyserial": installed_version("pyserial")},
            "stage": _describe(stage, "stage"), "camera": _describe(camera, "camera"),
            "start": None, "stop": None, "exit_status": "created", "error": None, "sessions": [],
            "scan_order": plan.scan, "approach": plan.approach,
            "visit_order": [int(i) for i in run.order],
        })


def _open_store(path: Path, resume: bool, run: _Run, camera, stage):
    """Create the store (allocated up front), or reopen it to resume; check it fits the run."""
    import zarr

    from .. import atomic

    atomic.remove_stale(path)
    if path.exists() and not resume:
        raise ConfigurationError(f"out: {str(path)!r} exists. Fix: pass resume=True (--resume) "
                                 "to continue that run, or choose a new path")
    if not path.exists():
        path.parent.mkdir(parents=True, exist_ok=True)
        _create_store(path, run, camera, stage)
    for leftover in path.rglob("*.partial"):  # temporary chunk files of a killed writer
        leftover.unlink(missing_ok=True)
    with zarr.config.set({"array.write_empty_chunks": True}):  # a dark frame is a chunk too
        group = zarr.open_group(path, mode="r+")
        arrays = {name: group[name] for name in group.array_keys()}
    if (group.attrs.get("sunlab_schema") != "frames/1" or "uid" not in group.attrs
            or not set(arrays) >= {"frames", "alpha", "beta", *_PER_POSE, "done"}):
        raise ConfigurationError(
            f"out: {group.store} is not a sunlab acquisition store (no frames/1 schema, uid or "
            "done flags). Fix: choose a new path")
    found = (tuple(arrays["frames"].shape), np.dtype(arrays["frames"].dtype))
    expected = ((len(run.plan), run.plan.shots, *run.shape), run.dtype)
    if found != expected:
        raise ConfigurationError(
            f"out: store frames {found} do not match this plan and camera {expected}. Fix: "
            "resume with the plan and camera settings of the original run, or choose a new path")
    if not (np.array_equal(arrays["alpha"][:], run.plan.alpha)
            and np.array_equal(arrays["beta"][:], run.plan.beta)):
        raise ConfigurationError("out: the store's commanded angles differ from the plan's. Fix: "
                                 "resume with the original plan, or choose a new path")
    return group, arrays


def _fsync(root: Path, names, pose: int) -> None:
    """fsync the chunk files of one pose (zarr v3 ``c/`` keys) and their folders."""
    for name in names:
        base = root / name / "c" / str(pose)
        files = [base] if base.is_file() else sorted(p for p in base.rglob("*") if p.is_file())
        for path in [*files, *{f.parent for f in files}]:
            fd = os.open(path, os.O_RDONLY)
            try:
                os.fsync(fd)
            except OSError:  # a folder cannot be fsync'ed on every file system
                if path.is_file():
                    raise
            finally:
                os.close(fd)


def _capture_pose(stage, camera, pose: int, run: _Run):
    """Move and capture one pose into memory; nothing is written here. With an overshoot the
    inner axis first goes that far below the target, then up to it (a unidirectional
    approach: the same gear flank at every pose)."""
    alpha, beta, shots = run.plan.alpha[pose], run.plan.beta[pose], run.plan.shots
    if run.overshoot:
        call("stage", stage, "move_to", alpha, beta - run.overshoot)
    call("stage", stage, "move_to", alpha, beta)
    frames = np.empty((shots, *run.shape), dtype=run.dtype)
    read, stamps = np.empty((2, shots)), np.empty(shots)
    for shot in range(shots):
        read[:, shot] = call("stage", stage, "position")
        if callable(getattr(camera, "set_index", None)):
            call("camera", camera, "set_index", pose, shot, alpha=read[0, shot],
                 beta=read[1, shot])
        stamps[shot] = time.time()
        frame = np.asarray(call("camera", camera, "grab"))
        if frame.shape != run.shape or frame.dtype != run.dtype:
            raise CameraError(
                f"camera: pose {pose} shot {shot} gave a {frame.dtype} frame of shape "
                f"{frame.shape}, expected {run.dtype} {run.shape}. Fix: check the camera's ROI, "
                "binning and pixel format")
        if frame.size and int(frame.max()) >= 2**run.bits:
            raise CameraError(
                f"camera: pose {pose} shot {shot} holds {int(frame.max())} DN, above the "
                f"{run.bits}-bit range. Fix: set the camera's bit_depth to its ADC's")
        frames[shot] = frame
    return frames, read, stamps


def acquire(plan, stage, camera, out, *, resume: bool = False, progress: bool = True,
            stop: threading.Event | None = None, fsync: bool = True, handle_sigint: bool = True,
            overshoot_deg: float = 0.5) -> RunResult:
    """Run a plan on the bench into a resumable Zarr store.

    Parameters
    ----------
    plan : sunlab.plans.Plan
        Poses (alpha outer, beta inner, degrees) and shots per pose.
    stage : sunlab.hardware.stage.Stage
        The platform; ``move_to`` must return once settled (e.g. :class:`~sunlab.hardware.ESP300`).
    camera : sunlab.hardware.cameras.Camera
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
    handle_sigint : bool
        In the main thread, turn the first Ctrl-C into a stop between poses (a second one
        interrupts at once).
    overshoot_deg : float
        For a plan with ``approach="unidirectional"``: how far below each pose the inner axis
        goes before it returns upward to it, deg (more than the axis's backlash). The poses are
        visited in the plan's scan order (:meth:`sunlab.plans.Plan.visit_order`), and the
        store records the motion (``scan_order``, ``approach``, ``visit_order`` attributes and
        ``beta_approach`` on pose) for :mod:`sunlab.reproduce.fault`. A resumed
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
    run, path = _checked(plan, camera, overshoot_deg), Path(out)
    with run_lock(path):
        group, arrays = _open_store(path, resume, run, camera, stage)
        return _run_poses(path, group, arrays, run, stage, camera, stop or threading.Event(),
                          handle_sigint, progress, fsync)


def _run_poses(path: Path, group, arrays: dict, run: _Run, stage, camera, stop, handle_sigint,
               progress, fsync) -> RunResult:
    """The poses of :func:`acquire` not yet done, in visit order, one session: each pose's
    data are written (and fsync'ed) before its done flag."""
    from tqdm.auto import tqdm

    done = np.asarray(arrays["done"][:], dtype=bool)
    with _session(path, group) as session, _sigint_stops(stop, handle_sigint), tqdm(
            total=done.size, initial=int(done.sum()), unit="pose",
            disable=not show_progress(progress), desc=f"acquire {run.plan.name}".strip()) as bar:
        for pose in run.order[~done[run.order]]:
            if stop.is_set():
                break
            frames, read, stamps = _capture_pose(stage, camera, int(pose), run)
            for name, values in zip(_PER_POSE, (frames, *read, stamps), strict=True):
                arrays[name][pose] = values
            if fsync:
                _fsync(path, _PER_POSE, pose)
            arrays["done"][pose] = 1
            if fsync:
                _fsync(path, ("done",), pose)
            done[pose] = True
            session["poses"] += 1
            bar.update(1)
        session["exit_status"] = "complete" if done.all() else "interrupted"
    return RunResult(str(path), str(group.attrs["uid"]), session["exit_status"], done.size,
                     int(done.sum()), session["poses"])


@contextlib.contextmanager
def _session(path: Path, group):
    """Record a running session in the store; on exit, its end (status, error, poses)."""
    from .. import integrity

    integrity.unseal_zarr(path, group)  # the metadata change while the session runs
    sessions = [dict(s, exit_status="killed") if s.get("exit_status") == "running" else s
                for s in group.attrs.get("sessions", [])]
    session = {"start": _now(), "stop": None, "exit_status": "running", "poses": 0}
    group.attrs.update({"start": group.attrs.get("start") or session["start"],
                        "exit_status": "running", "sessions": [*sessions, session]})
    error = None
    try:
        yield session
    except KeyboardInterrupt:
        session["exit_status"] = "interrupted"
        raise
    except BaseException as err:
        session["exit_status"] = "failed"
        error = str(err) if isinstance(err, BenchError) else f"{type(err).__name__}: {err}"
        raise
    finally:
        session["stop"] = _now()
        group.attrs.update({"stop": session["stop"], "exit_status": session["exit_status"],
                            "error": error, "sessions": [*sessions, session]})
        integrity.seal_zarr(path, group)


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
