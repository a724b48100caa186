"""Cameras: the protocol the runner uses, a simulated camera and a folder-watching camera.

A camera is anything with ``grab() -> ndarray`` (one frame, ``shape``, ``dtype``) and
``bit_depth``. Two optional members are used when present: ``set_index(pose, shot, alpha=,
beta=)``, called by the runner before each grab with the stage's read-back angles, and ``attrs``,
the sensor attributes of the frame cube (``pixel_pitch_mm``, ``mask_distance_mm``, ``x_cf_px``,
``y_cf_px``, ``mask``).

- :class:`SimCamera` renders frames from the virtual bench (:func:`sunlab.sim.render_frame`) at
  the platform's true pose, deterministic in (seed, pose, shot); a region of interest and
  binning give small frames for quick runs.
- :class:`FolderCamera` serves real cameras whose software writes one image file per frame
  (TIFF or PNG): it waits for a new, complete file and reads it.

Examples
--------
>>> import numpy as np
>>> class Dark:
...     shape, dtype, bit_depth = (2, 3), np.dtype(np.uint16), 10
...     def grab(self):
...         return np.zeros(self.shape, self.dtype)
>>> isinstance(Dark(), Camera)
True
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Protocol, runtime_checkable

import numpy as np

from ..errors import ConfigurationError
from .errors import CameraError, CameraTimeout

__all__ = ["Camera", "SimCamera", "FolderCamera"]


@runtime_checkable
class Camera(Protocol):
    """A frame source: ``grab()`` returns one ``(ny, nx)`` frame of ``dtype`` in DN."""

    shape: tuple[int, int]
    dtype: np.dtype
    bit_depth: int

    def grab(self) -> np.ndarray:
        """Take one frame, shape ``shape``, type ``dtype``, values below ``2**bit_depth``."""
        ...


def _bin(frame: np.ndarray, b: int) -> np.ndarray:
    ny, nx = frame.shape
    return frame.reshape(ny // b, b, nx // b, b).sum(axis=(1, 3), dtype=np.uint32)


class SimCamera:
    """A camera on the virtual bench: frames rendered at the platform's true pose.

    Parameters
    ----------
    bench : sunlab.sim.Bench, optional
        The virtual bench (default ``Bench.paper_single_hole()``).
    seed : int
        Seed of the frame noise and, without ``truth``, of the platform model.
    truth : callable, optional
        ``truth(pose, shot) -> (alpha_true, beta_true)`` in degrees, e.g.
        :meth:`FakeESP.true_pose <sunlab.hardware.FakeESP.true_pose>` of the controller that moves
        the platform. Without it the true pose comes from :func:`sunlab.sim.platform_pose` at
        the read-back angles the runner hands to :meth:`set_index`.
    roi : (y0, y1, x0, x1), optional
        Region of interest of the detector, half-open pixel ranges (rows, then columns).
    binning : int
        Sum ``binning x binning`` pixels (charge-binning model: the bit depth grows by
        ``2 log2(binning)``, the pixel pitch by ``binning``).

    Notes
    -----
    The frame of (pose, shot) is ``render_frame(bench, alpha_true, beta_true, seed, pose,
    shot)`` cropped and binned: the same pose and shot give the same frame in any run, which is
    what lets a resumed run equal an uninterrupted one.

    Examples
    --------
    >>> from sunlab.sim import Bench
    >>> # a 128 px ROI (rows 105-233, columns 904-1032) round the zero-pose spot, binned 2 x 2
    >>> cam = SimCamera(Bench.paper_single_hole(), roi=(105, 233, 904, 1032), binning=2)
    >>> cam.shape, cam.bit_depth
    ((64, 64), 12)
    >>> cam.set_index(0, 0, alpha=0.0, beta=0.0)
    >>> frame = cam.grab()
    >>> row, col = np.unravel_index(frame.argmax(), frame.shape)
    >>> frame.dtype, bool(20 <= row < 44 and 20 <= col < 44)
    (dtype('uint16'), True)
    """

    def __init__(
        self,
        bench=None,
        *,
        seed: int = 0,
        truth: Callable[[int, int], tuple[float, float]] | None = None,
        roi: Sequence[int] | None = None,
        binning: int = 1,
    ):
        from .. import sim

        self.bench = sim.Bench.paper_single_hole() if bench is None else bench
        self.seed = int(seed)
        self.truth = truth
        ny, nx = (int(n) for n in self.bench.detector.shape)
        y0, y1, x0, x1 = (0, ny, 0, nx) if roi is None else (int(v) for v in roi)
        if not (0 <= y0 < y1 <= ny and 0 <= x0 < x1 <= nx):
            raise ConfigurationError(
                f"roi: found {tuple(roi)}, expected (y0, y1, x0, x1) with 0 <= y0 < y1 <= {ny} "
                f"and 0 <= x0 < x1 <= {nx}"
            )
        b = int(binning)
        if b < 1 or (y1 - y0) % b or (x1 - x0) % b:
            raise ConfigurationError(
                f"binning: found {binning!r} for a {y1 - y0} x {x1 - x0} roi, expected a "
                "positive divisor of both sides"
            )
        base_bits = int(self.bench.detector.bit_depth)
        bits = base_bits + math.ceil(2 * math.log2(b))
        if bits > 16:
            raise ConfigurationError(
                f"binning: {b} x {b} sums of {base_bits}-bit pixels need {bits} bits, expected "
                "<= 16 (uint16). Fix: bin less"
            )
        self.roi = (y0, y1, x0, x1)
        self.binning = b
        self.shape = ((y1 - y0) // b, (x1 - x0) // b)
        self.dtype = np.dtype(np.uint16)
        self.bit_depth = bits
        self.pose, self.shot = 0, 0
        self.alpha, self.beta = 0.0, 0.0
        self.last_truth: tuple[float, float] | None = None

    def set_index(self, pose: int, shot: int, *, alpha: float | None = None,
                  beta: float | None = None) -> None:
        """Select the (pose, shot) of the next frame and the stage's read-back angles (deg)."""
        self.pose, self.shot = int(pose), int(shot)
        if alpha is not None:
            self.alpha = float(alpha)
        if beta is not None:
            self.beta = float(beta)

    def true_pose(self) -> tuple[float, float]:
        """True platform angles (alpha, beta) of the next frame, degrees."""
        if self.truth is not None:
            a, b = self.truth(self.pose, self.shot)
        else:
            from ..sim import platform_pose

            a, b = platform_pose(self.bench, self.alpha, self.beta, seed=self.seed,
                                 pose=self.pose, shot=self.shot)
        return float(a), float(b)

    def grab(self) -> np.ndarray:
        """Render the frame of the current (pose, shot) at the true pose."""
        from ..sim import render_frame

        a, b = self.true_pose()
        self.last_truth = (a, b)
        full = render_frame(self.bench, a, b, seed=self.seed, pose=self.pose, shot=self.shot)
        y0, y1, x0, x1 = self.roi
        frame = np.asarray(full)[y0:y1, x0:x1]
        if self.binning > 1:
            frame = _bin(frame, self.binning)
        return frame.astype(self.dtype, copy=False)

    @property
    def attrs(self) -> dict:
        """Sensor attributes of the cube in this camera's pixels (ROI and binning applied)."""
        det = self.bench.detector
        b = self.binning
        y0, _, x0, _ = self.roi
        x_design, y_design = self.bench.hole_design_px()
        x_cf, y_cf = float(np.mean(x_design)), float(np.mean(y_design))
        return {
            "pixel_pitch_mm": float(det.pixel_pitch_mm) * b,
            "mask_distance_mm": float(self.bench.mask_distance_mm),
            # binned pixel j sums pixels b*j .. b*j + b-1, whose centre is b*j + (b-1)/2
            "x_cf_px": (x_cf - x0 - (b - 1) / 2) / b,
            "y_cf_px": (y_cf - y0 - (b - 1) / 2) / b,
            "bit_depth": self.bit_depth,
            "mask": str(self.bench.mask.name),
        }

    def describe(self) -> dict:
        """What the run metadata records about the camera."""
        return {"camera": "sunlab.hardware.SimCamera", "seed": self.seed, "roi": list(self.roi),
                "binning": self.binning, "shape": list(self.shape), "bit_depth": self.bit_depth,
                "truth": "stage controller" if self.truth is not None else "read-back angles"}


class _Unreadable(CameraError):
    """The decoder failed: a truncated file still being written, or a corrupt one."""


def _read_new_file(path) -> np.ndarray:
    """Decode a TIFF (tifffile) or PNG (Pillow) file a camera just wrote, as a 2-d array.

    Not :func:`sunlab.io.read_image`, which reads finished raw frames (uint8/uint16 only, a
    :class:`~sunlab.SchemaError` naming the fix): here a decoder failure is
    :class:`_Unreadable`, which :meth:`FolderCamera.grab` takes for a file still being written
    and polls again, and any integer type is returned for :meth:`FolderCamera._check` to fit.

    Raises
    ------
    CameraError
        Unknown suffix, or not a single 2-d frame; :class:`_Unreadable` for a truncated or
        unreadable file.

    Examples
    --------
    >>> import tempfile, os, tifffile
    >>> path = os.path.join(tempfile.mkdtemp(), "f.tif")
    >>> tifffile.imwrite(path, np.full((2, 3), 7, np.uint16))
    >>> _read_new_file(path).tolist()
    [[7, 7, 7], [7, 7, 7]]
    """
    path = Path(path)
    suffix = path.suffix.lower()
    try:
        if suffix in (".tif", ".tiff"):
            import tifffile

            data = tifffile.imread(path)
        elif suffix == ".png":
            from PIL import Image

            with Image.open(path) as img:
                img.load()
                data = np.asarray(img)
        else:
            raise CameraError(f"camera: {path.name}: suffix {suffix!r}, expected .tif, .tiff, .png")
    except CameraError:
        raise
    except Exception as err:  # noqa: BLE001 - any decoder failure is an unreadable file
        raise _Unreadable(f"camera: cannot read {str(path)!r}: {err}") from err
    data = np.asarray(data)
    if data.ndim != 2:
        raise CameraError(
            f"camera: {path.name} holds an array of shape {data.shape}, expected one grey frame "
            "(ny, nx). Fix: save single-channel images, one frame per file"
        )
    return data


class FolderCamera:
    """A real camera whose acquisition software writes one image file per frame.

    :meth:`grab` optionally fires ``trigger()`` (e.g. a software trigger of the camera SDK),
    then waits for a file that was not in the folder before, whose size has stopped changing
    for ``stable_s`` and which decodes completely, and returns it.

    Parameters
    ----------
    folder : str or path
        The folder the camera writes into (files present at start are ignored).
    shape : (int, int)
        Frame shape (ny, nx); default the Ibis4's (1024, 1280).
    dtype : numpy dtype
        Frame type (uint8 or uint16).
    bit_depth : int
        ADC bit depth.
    patterns : sequence of str
        Glob patterns of image files.
    timeout_s : float
        Longest wait for a new complete file, s.
    poll_s : float
        Folder polling interval, s.
    stable_s : float
        How long a file's size must stay unchanged before it is read, s.
    trigger : callable, optional
        Called at the start of each :meth:`grab`.

    Examples
    --------
    >>> import tempfile, tifffile
    >>> folder = tempfile.mkdtemp()
    >>> cam = FolderCamera(folder, shape=(2, 3), stable_s=0.0, timeout_s=2.0,
    ...                    trigger=lambda: tifffile.imwrite(f"{folder}/a.tif",
    ...                                                     np.ones((2, 3), np.uint16)))
    >>> cam.grab().sum()
    np.uint64(6)
    """

    def __init__(
        self,
        folder,
        *,
        shape: Sequence[int] = (1024, 1280),
        dtype=np.uint16,
        bit_depth: int = 10,
        patterns: Sequence[str] = ("*.tif", "*.tiff", "*.png"),
        timeout_s: float = 10.0,
        poll_s: float = 0.02,
        stable_s: float = 0.05,
        trigger: Callable[[], object] | None = None,
    ):
        self.folder = Path(folder)
        if not self.folder.is_dir():
            raise ConfigurationError(
                f"camera folder: {str(self.folder)!r} is not a directory. Fix: create it or "
                "point the camera software and --camera folder:PATH at the same folder"
            )
        self.shape = tuple(int(n) for n in shape)
        self.dtype = np.dtype(dtype)
        self.bit_depth = int(bit_depth)
        self.patterns = tuple(patterns)
        self.timeout_s = float(timeout_s)
        self.poll_s = float(poll_s)
        self.stable_s = float(stable_s)
        self.trigger = trigger
        self._seen = set(self._listing())
        self.last_file: Path | None = None

    def _listing(self) -> list[Path]:
        files = {p for pattern in self.patterns for p in self.folder.glob(pattern) if p.is_file()}
        return sorted(files, key=lambda p: (p.stat().st_mtime_ns, p.name))

    def grab(self) -> np.ndarray:
        """Wait for the next new complete image file and return its frame.

        Raises
        ------
        CameraTimeout
            No new complete file within ``timeout_s``.
        CameraError
            The file holds a frame of another shape or a type that does not fit ``dtype``.
        """
        if self.trigger is not None:
            self.trigger()
        t_end = time.monotonic() + self.timeout_s
        sizes: dict[Path, tuple[int, float]] = {}
        last_error: _Unreadable | None = None
        while True:
            now = time.monotonic()
            for path in (p for p in self._listing() if p not in self._seen):
                try:
                    size = path.stat().st_size
                except FileNotFoundError:
                    continue
                seen = sizes.get(path)
                if seen is None or seen[0] != size or size == 0:
                    sizes[path] = (size, now)
                    if self.stable_s > 0 or size == 0:
                        continue
                elif now - seen[1] < self.stable_s:
                    continue
                try:
                    data = _read_new_file(path)
                except _Unreadable as err:  # still being written: try again at the next poll
                    last_error = err
                    sizes[path] = (size, now)
                    continue
                self._seen.add(path)
                self.last_file = path
                return self._check(data, path)
            if now > t_end:
                detail = f"; last read error: {last_error}" if last_error else ""
                raise CameraTimeout(
                    f"camera: no new complete image ({', '.join(self.patterns)}) in "
                    f"{str(self.folder)!r} within {self.timeout_s:g} s{detail}. Fix: check that "
                    "the camera software saves into this folder and is triggered, or raise "
                    "timeout_s"
                )
            time.sleep(self.poll_s)

    def _check(self, data: np.ndarray, path: Path) -> np.ndarray:
        if data.shape != self.shape:
            raise CameraError(
                f"camera: {path.name} is {data.shape}, expected {self.shape}. Fix: set the "
                "camera's ROI or FolderCamera(shape=...)"
            )
        if data.dtype != self.dtype:
            if not np.issubdtype(data.dtype, np.integer) or (
                data.size and (data.min() < 0 or data.max() > np.iinfo(self.dtype).max)
            ):
                raise CameraError(
                    f"camera: {path.name} holds {data.dtype} values that do not fit "
                    f"{self.dtype}. Fix: save raw integer frames"
                )
            data = data.astype(self.dtype)
        return data

    def describe(self) -> dict:
        """What the run metadata records about the camera."""
        return {"camera": "sunlab.hardware.FolderCamera", "folder": str(self.folder),
                "patterns": list(self.patterns), "shape": list(self.shape),
                "bit_depth": self.bit_depth}
