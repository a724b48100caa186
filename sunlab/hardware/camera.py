"""The cameras sunlab ships, each a :class:`~sunlab.hardware.cameras.ControlledCamera` (the protocol
and how a lab's own camera is opened are :mod:`sunlab.hardware.cameras`):

- :class:`SimCamera` renders frames from the virtual bench (:func:`sunlab.sim.render_frame`) at
  the platform's true pose, deterministic in (seed, pose, shot); a region of interest and
  binning give small frames for quick runs.
- :class:`FolderCamera` serves real cameras whose software writes one image file per frame
  (TIFF or PNG): it waits for a new, complete file and reads it.

"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from ..errors import ConfigurationError
from .errors import CameraError, CameraTimeout

__all__ = ["SimCamera", "FolderCamera"]


def _roi(roi, ny: float = math.inf, nx: float = math.inf) -> tuple[int, int, int, int]:
    """``(y0, y1, x0, x1)`` as integers, checked to be half-open ranges within ``ny`` rows and
    ``nx`` columns (the sensor's, when known)."""
    y0, y1, x0, x1 = (int(v) for v in roi)
    if not (0 <= y0 < y1 <= ny and 0 <= x0 < x1 <= nx):
        raise ConfigurationError(f"roi: found {tuple(roi)}, expected (y0, y1, x0, x1) with "
                                 f"0 <= y0 < y1 <= {ny} and 0 <= x0 < x1 <= {nx}")
    return y0, y1, x0, x1


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
        :meth:`FakeESP.true_pose <sunlab.hardware.fake.FakeESP.true_pose>` of the controller that
        moves the platform. Without it the true pose comes from
        :func:`sunlab.sim.platform.platform_pose` at the read-back angles the runner hands to
        :meth:`set_index`.
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
    >>> # a 128 px ROI (rows 339-467, columns 668-796) round the zero-pose spot, binned 2 x 2
    >>> cam = SimCamera(Bench.paper_single_hole(), roi=(339, 467, 668, 796), binning=2)
    >>> cam.shape, cam.bit_depth
    ((64, 64), 12)
    >>> cam.set_index(0, 0, alpha=0.0, beta=0.0)
    >>> frame = cam.grab()
    >>> row, col = np.unravel_index(frame.argmax(), frame.shape)
    >>> frame.dtype, bool(20 <= row < 44 and 20 <= col < 44)
    (dtype('uint16'), True)
    """

    def __init__(self, bench=None, *, seed: int = 0,
                 truth: Callable[[int, int], tuple[float, float]] | None = None,
                 roi: Sequence[int] | None = None, binning: int = 1):
        from .. import sim

        self.bench = sim.Bench.paper_single_hole() if bench is None else bench
        self.seed, self.truth, self.binning = int(seed), truth, int(binning)
        if self.binning < 1:
            raise ConfigurationError(f"binning: found {binning!r}, expected a positive integer")
        self.set_roi(roi)
        base_bits = int(self.bench.detector.bit_depth)
        self.bit_depth = base_bits + math.ceil(2 * math.log2(self.binning))
        if self.bit_depth > 16:
            raise ConfigurationError(
                f"binning: {binning} x {binning} sums of {base_bits}-bit pixels need "
                f"{self.bit_depth} bits, expected <= 16 (uint16). Fix: bin less")
        self.dtype = np.dtype(np.uint16)
        self.exposure_s = None  # the virtual bench's exposure is its detector model's
        self.pose = self.shot = self._n_dark = 0
        self.alpha = self.beta = 0.0
        self.last_truth: tuple[float, float] | None = None

    def set_roi(self, roi: Sequence[int] | None) -> None:
        """Read rows ``y0:y1`` and columns ``x0:x1`` (half-open) of the detector; ``shape``
        follows (binned).

        Parameters
        ----------
        roi : (y0, y1, x0, x1) or None
            Region of interest in unbinned detector pixels, half-open (rows, then columns);
            None reads the whole detector. Both sides must be multiples of ``binning``.
        """
        ny, nx = (int(n) for n in self.bench.detector.shape)
        y0, y1, x0, x1 = _roi((0, ny, 0, nx) if roi is None else roi, ny, nx)
        b = self.binning
        if (y1 - y0) % b or (x1 - x0) % b:
            raise ConfigurationError(f"binning: found {b!r} for a {y1 - y0} x {x1 - x0} roi, "
                                     "expected a positive divisor of both sides")
        self.roi, self.shape = (y0, y1, x0, x1), ((y1 - y0) // b, (x1 - x0) // b)

    def set_exposure(self, seconds: float) -> None:
        """Refused: the virtual bench's signal and noise are set by its detector model.

        Parameters
        ----------
        seconds : float
            The exposure asked for, s (named in the error).
        """
        raise ConfigurationError(
            f"set_exposure({seconds!r}): the sim camera's exposure is its detector model's. Fix: "
            "change the bench's detector (sunlab.sim.Detector: qe, gain, dark signal) instead")

    def set_index(self, pose: int, shot: int, *, alpha: float | None = None,
                  beta: float | None = None) -> None:
        """Select the (pose, shot) of the next frame and the stage's read-back angles.

        Parameters
        ----------
        pose : int
            Pose index of the next frame.
        shot : int
            Shot index within the pose.
        alpha, beta : float, optional
            The stage's read-back angles, degrees (None keeps the previous value); the true
            pose is drawn round them when the camera has no ``truth``.
        """
        self.pose, self.shot = int(pose), int(shot)
        self.alpha = self.alpha if alpha is None else float(alpha)
        self.beta = self.beta if beta is None else float(beta)

    def true_pose(self) -> tuple[float, float]:
        """True platform angles of the next frame.

        Returns
        -------
        (float, float)
            (alpha, beta) true platform angles, degrees: ``truth(pose, shot)``, or else
            :func:`sunlab.sim.platform.platform_pose` round the read-back angles.
        """
        from ..sim.platform import platform_pose

        a, b = (self.truth(self.pose, self.shot) if self.truth is not None else
                platform_pose(self.bench, self.alpha, self.beta, seed=self.seed,
                              pose=self.pose, shot=self.shot))
        return float(a), float(b)

    def _render(self, alpha: float, beta: float, pose: int, shot: int) -> np.ndarray:
        """The bench's frame, cropped to the ROI and binned."""
        from ..sim import render_frame

        y0, y1, x0, x1 = self.roi
        frame = np.asarray(render_frame(self.bench, alpha, beta, seed=self.seed, pose=pose,
                                        shot=shot))[y0:y1, x0:x1]
        b = self.binning
        if b > 1:
            frame = frame.reshape(self.shape[0], b, self.shape[1], b).sum(axis=(1, 3),
                                                                         dtype=np.uint32)
        return frame.astype(self.dtype, copy=False)

    def grab(self) -> np.ndarray:
        """Render the frame of the current (pose, shot) at the true pose.

        Returns
        -------
        numpy.ndarray
            The frame, shape ``shape`` (ROI and binning applied), uint16, in DN; the true
            angles it was rendered at are kept in ``last_truth`` (degrees).
        """
        self.last_truth = self.true_pose()
        return self._render(*self.last_truth, self.pose, self.shot)

    def grab_dark(self) -> np.ndarray:
        """A dark frame: the detector with the sun far outside the field (its bias, dark
        signal, fixed pattern, hot pixels and noise), a new noise draw per call.

        Returns
        -------
        numpy.ndarray
            The frame, shape ``shape`` (ROI and binning applied), uint16, in DN.
        """
        self._n_dark += 1
        return self._render(80.0, 80.0, 10**6, self._n_dark)

    @property
    def attrs(self) -> dict:
        """Sensor attributes of the cube in this camera's pixels (ROI and binning applied)."""
        b, (y0, _, x0, _) = self.binning, self.roi
        x_design, y_design = self.bench.hole_design_px()
        return {
            "pixel_pitch_mm": float(self.bench.detector.pixel_pitch_mm) * b,
            "mask_distance_mm": float(self.bench.mask_distance_mm),
            # binned pixel j sums pixels b*j .. b*j + b-1, whose centre is b*j + (b-1)/2
            "x_cf_px": (float(np.mean(x_design)) - x0 - (b - 1) / 2) / b,
            "y_cf_px": (float(np.mean(y_design)) - y0 - (b - 1) / 2) / b,
            "bit_depth": self.bit_depth,
            "mask": str(self.bench.mask.name),
        }

    def describe(self) -> dict:
        """What the run metadata records about the camera.

        Returns
        -------
        dict
            JSON-ready description: the camera's class name and its settings.
        """
        return {"camera": "sunlab.hardware.SimCamera", "seed": self.seed, "roi": list(self.roi),
                "binning": self.binning, "shape": list(self.shape), "bit_depth": self.bit_depth,
                "truth": "stage controller" if self.truth is not None else "read-back angles"}


class _Unreadable(CameraError):
    """The decoder failed: a truncated file still being written, or a corrupt one."""


def _read_new_file(path: Path) -> np.ndarray:
    """Decode a TIFF (tifffile) or PNG (Pillow) file a camera just wrote, as a 2-d array.

    Not :func:`sunlab.io.read_image`, which reads finished raw frames: here a decoder failure
    is :class:`_Unreadable`, a file still being written that :meth:`FolderCamera.grab` polls
    again, and any integer type is returned for :meth:`FolderCamera._check` to fit.
    """
    suffix = path.suffix.lower()
    if suffix not in (".tif", ".tiff", ".png"):
        raise CameraError(f"camera: {path.name}: suffix {suffix!r}, expected .tif, .tiff, .png")
    try:
        if suffix == ".png":
            from PIL import Image

            with Image.open(path) as img:
                data = np.asarray(img)
        else:
            import tifffile

            data = tifffile.imread(path)
    except Exception as err:  # noqa: BLE001 - any decoder failure is an unreadable file
        raise _Unreadable(f"camera: cannot read {str(path)!r}: {err}") from err
    if data.ndim != 2:
        raise CameraError(
            f"camera: {path.name} holds an array of shape {data.shape}, expected one grey frame "
            "(ny, nx). Fix: save single-channel images, one frame per file")
    return data


class FolderCamera:
    """A real camera whose acquisition software writes one image file per frame.

    :meth:`grab` notes the files already in the folder, optionally fires ``trigger()`` (e.g. a
    software trigger of the camera SDK), then takes the **first file written after that
    moment**: the oldest new file, once its size has stopped changing for ``stable_s`` and it
    decodes completely. The runner calls :meth:`grab` only once the pose is reached and
    settled, so a frame written during the move is never taken, even from a camera that runs
    free and writes files all the time; such a camera may still have started exposing its first
    new file before the trigger: ``skip=1`` drops it and takes the next. Hidden files (a name
    starting with ``.``, as writers name a file in progress before renaming it) are ignored.

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
        Longest wait for a new complete file, s (:class:`CameraTimeout` after it).
    poll_s : float
        Folder polling interval, s.
    stable_s : float
        How long a file's size must stay unchanged before it is read, s.
    trigger : callable, optional
        Called at the start of each :meth:`grab`.
    skip : int
        New files dropped after the trigger before one is taken (a free-running camera: 1).
    dark_trigger : callable, optional
        Called by :meth:`grab_dark` instead of ``trigger``: block the light (close a shutter,
        switch the source off) and trigger a frame.
    exposure : callable, optional
        ``exposure(seconds)`` sets the camera's exposure (the SDK call); without it
        :meth:`set_exposure` says to set it in the camera software.

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

    def __init__(self, folder, *, shape: Sequence[int] = (1024, 1280), dtype=np.uint16,
                 bit_depth: int = 10, patterns: Sequence[str] = ("*.tif", "*.tiff", "*.png"),
                 timeout_s: float = 10.0, poll_s: float = 0.02, stable_s: float = 0.05,
                 trigger: Callable[[], object] | None = None, skip: int = 0,
                 dark_trigger: Callable[[], object] | None = None,
                 exposure: Callable[[float], object] | None = None):
        self.folder = Path(folder)
        if not self.folder.is_dir():
            raise ConfigurationError(
                f"camera folder: {str(self.folder)!r} is not a directory. Fix: create it or "
                "point the camera software and --camera folder:PATH at the same folder")
        self.dtype, self.bit_depth, self.patterns = np.dtype(dtype), int(bit_depth), tuple(patterns)
        self.timeout_s, self.poll_s = float(timeout_s), float(poll_s)
        self.stable_s = float(stable_s)
        self.trigger, self.skip, self.dark_trigger = trigger, int(skip), dark_trigger
        self.exposure, self.exposure_s = exposure, None
        self.set_roi((0, int(shape[0]), 0, int(shape[1])))
        self.last_file: Path | None = None

    def set_exposure(self, seconds: float) -> None:
        """Set the exposure through the ``exposure`` callable (the camera SDK's call).

        Parameters
        ----------
        seconds : float
            Exposure time, s; kept in ``exposure_s``.
        """
        if self.exposure is None:
            raise CameraError("camera: this folder camera has no exposure control. Fix: set the "
                              "exposure in the camera software, or pass "
                              "FolderCamera(exposure=sdk_call)")
        self.exposure(float(seconds))
        self.exposure_s = float(seconds)

    def set_roi(self, roi: Sequence[int]) -> None:
        """Expect frames of the ROI ``(y0, y1, x0, x1)`` (set the same ROI in the camera
        software: the files it writes are the ROI).

        Parameters
        ----------
        roi : (y0, y1, x0, x1)
            Half-open pixel ranges of the sensor (rows, then columns); ``shape`` becomes
            ``(y1 - y0, x1 - x0)``.
        """
        y0, y1, x0, x1 = _roi(roi)
        self.roi, self.shape = (y0, y1, x0, x1), (y1 - y0, x1 - x0)

    def grab(self) -> np.ndarray:
        """Wait for the next new complete image file and return its frame.

        Returns
        -------
        numpy.ndarray
            The frame, shape ``shape``, type ``dtype``, in DN; its file is kept in
            ``last_file``.
        """
        return self._next_file(self.trigger)

    def grab_dark(self) -> np.ndarray:
        """A dark frame: ``dark_trigger()`` blocks the light and triggers, then as :meth:`grab`.

        Returns
        -------
        numpy.ndarray
            The frame of the first new complete file, shape ``shape``, type ``dtype``, in DN.
        """
        if self.dark_trigger is None:
            raise CameraError(
                "camera: no dark_trigger. Fix: pass FolderCamera(dark_trigger=...) that closes "
                "the shutter (or switches the source off) and triggers a frame")
        return self._next_file(self.dark_trigger)

    def _listing(self) -> list[Path]:
        files = {p for pattern in self.patterns for p in self.folder.glob(pattern)
                 if p.is_file() and not p.name.startswith(".")}  # hidden: a write in progress
        return sorted(files, key=lambda p: (p.stat().st_mtime_ns, p.name))

    def _next_file(self, trigger) -> np.ndarray:
        """Fire ``trigger``, then read the first complete file written after it (``skip``
        dropped)."""
        seen = set(self._listing())  # whatever is there now was written before
        if trigger is not None:
            trigger()
        t_end = time.monotonic() + self.timeout_s
        sizes: dict[Path, tuple[int, float]] = {}
        last_error, to_skip = None, self.skip
        while True:
            now = time.monotonic()
            for path in [p for p in self._listing() if p not in seen][:1]:  # the oldest new one
                try:
                    size = path.stat().st_size
                except FileNotFoundError:
                    continue
                if sizes.get(path, (None,))[0] != size:  # new or still growing: time it anew
                    sizes[path] = (size, now)
                if size == 0 or now - sizes[path][1] < self.stable_s:
                    continue
                try:
                    data = _read_new_file(path)
                except _Unreadable as err:  # still being written: try again at the next poll
                    last_error, sizes[path] = err, (size, now)
                    continue
                seen.add(path)
                if to_skip:
                    to_skip -= 1
                    continue
                self.last_file = path
                return self._check(data, path)
            if now > t_end:
                detail = f"; last read error: {last_error}" if last_error else ""
                raise CameraTimeout(
                    f"camera: no new complete image ({', '.join(self.patterns)}) in "
                    f"{str(self.folder)!r} within {self.timeout_s:g} s{detail}. Fix: check that "
                    "the camera software saves into this folder and is triggered, or raise "
                    "timeout_s")
            time.sleep(self.poll_s)

    def _check(self, data: np.ndarray, path: Path) -> np.ndarray:
        if data.shape != self.shape:
            raise CameraError(f"camera: {path.name} is {data.shape}, expected {self.shape}. Fix: "
                              "set the camera's ROI or FolderCamera(shape=...)")
        info = np.iinfo(self.dtype)
        if data.dtype != self.dtype and not (
                np.issubdtype(data.dtype, np.integer)
                and info.min <= data.min(initial=0) and data.max(initial=0) <= info.max):
            raise CameraError(f"camera: {path.name} holds {data.dtype} values that do not fit "
                              f"{self.dtype}. Fix: save raw integer frames")
        return data.astype(self.dtype, copy=False)

    def describe(self) -> dict:
        """What the run metadata records about the camera.

        Returns
        -------
        dict
            JSON-ready description: the camera's class name and its settings.
        """
        return {"camera": "sunlab.hardware.FolderCamera", "folder": str(self.folder),
                "patterns": list(self.patterns), "shape": list(self.shape),
                "bit_depth": self.bit_depth}
