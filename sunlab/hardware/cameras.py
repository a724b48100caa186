"""Cameras: the protocol the runner uses, and which camera ``sunlab acquire --camera SPEC``
opens (built-ins, entry points, or a class).

A camera is anything with ``grab() -> ndarray`` (one frame, ``shape``, ``dtype``) and
``bit_depth``. Two optional members are used when present: ``set_index(pose, shot, alpha=,
beta=)``, called by the runner before each grab with the stage's read-back angles, and ``attrs``,
the sensor attributes of the frame cube (``pixel_pitch_mm``, ``mask_distance_mm``, ``x_cf_px``,
``y_cf_px``, ``mask``). A camera that a lab controls from sunlab also offers
:class:`ControlledCamera`: ``exposure_s`` and ``set_exposure(seconds)``, ``roi`` and
``set_roi((y0, y1, x0, x1))``, and ``grab_dark()`` (a frame with the light blocked), which
:func:`capture_darks` stacks into the dark frames of :func:`sunlab.io.with_calibration_frames`.

A lab's own camera is one class with the :class:`~sunlab.hardware.cameras.Camera` members (``grab``,
``shape``, ``dtype``, ``bit_depth``; optionally exposure, ROI and dark frames,
:class:`~sunlab.hardware.cameras.ControlledCamera`). sunlab finds it without being edited, in one of
two ways:

* by its import path: ``--camera mypkg.cameras:MyCamera`` imports ``mypkg.cameras`` and takes
  ``MyCamera``;
* by a name the lab's package registers in the entry point group ``sunlab.cameras``
  (``pyproject.toml``: ``[project.entry-points."sunlab.cameras"] mycam =
  "mypkg.cameras:MyCamera"``), then ``--camera mycam``.

The class is called with the options given as ``--camera-option KEY=VALUE`` (values read as
JSON when they parse, else as text), e.g. ``--camera-option serial=\\"21345\\"
--camera-option exposure_s=0.002``. The built-ins are ``sim`` (:class:`SimCamera`, the
virtual bench) and ``folder:PATH`` (:class:`FolderCamera`).

Examples
--------
>>> class Dark:
...     shape, dtype, bit_depth = (2, 3), np.dtype(np.uint16), 10
...     def grab(self):
...         return np.zeros(self.shape, self.dtype)
>>> isinstance(Dark(), Camera)
True
>>> camera_class("sunlab.hardware:FolderCamera").__name__
'FolderCamera'
>>> sorted(available_cameras())[:2]
['folder', 'sim']
"""

from __future__ import annotations

from collections.abc import Sequence
from importlib.metadata import EntryPoint
from typing import Protocol, runtime_checkable

import numpy as np

from .. import integrity
from ..errors import ConfigurationError
from ..extras import entry_points, load_plugin, open_device
from ._plugins import call
from .errors import CameraError

__all__ = ["open_camera"]

@runtime_checkable
class Camera(Protocol):
    """A frame source: ``grab()`` returns one ``(ny, nx)`` frame of ``dtype`` in DN."""

    shape: tuple[int, int]
    dtype: np.dtype
    bit_depth: int

    def grab(self) -> np.ndarray:
        """Take one frame.

        Returns
        -------
        numpy.ndarray
            One frame, shape ``shape`` (ny, nx), type ``dtype``, in DN (values below
            ``2**bit_depth``).
        """
        ...


@runtime_checkable
class ControlledCamera(Camera, Protocol):
    """A :class:`Camera` whose exposure, region of interest and dark frames sunlab can set."""

    exposure_s: float | None
    roi: tuple[int, int, int, int]

    def set_exposure(self, seconds: float) -> None:
        """Set the exposure (integration) time.

        Parameters
        ----------
        seconds : float
            Exposure time, s.
        """
        ...

    def set_roi(self, roi: Sequence[int]) -> None:
        """Read only rows ``y0:y1`` and columns ``x0:x1`` of the sensor; ``shape`` follows.

        Parameters
        ----------
        roi : (y0, y1, x0, x1)
            Region of interest, half-open pixel ranges of the full sensor (rows, then columns).
        """
        ...

    def grab_dark(self) -> np.ndarray:
        """Take one frame with the light blocked (shutter closed, source off), as ``grab``.

        Returns
        -------
        numpy.ndarray
            One dark frame, shape ``shape`` (ny, nx), type ``dtype``, in DN.
        """
        ...


def capture_darks(camera, n: int = 16) -> np.ndarray:
    """``n`` dark frames of a camera, stacked (n, ny, nx): the ``dark`` of
    :func:`sunlab.io.with_calibration_frames` (whose median is the master dark).

    Parameters
    ----------
    camera : object
        A camera with ``grab_dark()`` (a :class:`ControlledCamera`).
    n : int
        Number of dark frames to take.

    Returns
    -------
    numpy.ndarray
        The dark frames, shape (n, ny, nx), the camera's frame type, in DN.

    Examples
    --------
    >>> from sunlab.hardware import SimCamera
    >>> darks = capture_darks(SimCamera(roi=(100, 132, 900, 964)), 3)
    >>> darks.shape, bool(darks.mean() < 100)
    ((3, 32, 64), True)
    """
    if not callable(getattr(camera, "grab_dark", None)):
        raise CameraError(
            f"camera: {type(camera).__name__} cannot take dark frames (no grab_dark). Fix: "
            "give the camera a grab_dark() (close the shutter or switch the source off, then "
            "grab), or take the dark frames by hand into a folder for sunlab import --dark")
    return np.stack([np.asarray(call("camera", camera, "grab_dark")) for _ in range(int(n))])


#: The entry point group a lab's package registers its cameras in.
ENTRY_POINT_GROUP = "sunlab.cameras"

#: The cameras sunlab brings (name -> class); ``folder`` is opened as ``folder:PATH``.
_BUILTIN = {"sim": "sunlab.hardware:SimCamera", "folder": "sunlab.hardware:FolderCamera"}

_FIX = ("check that the camera is connected and powered, its driver installed and its options "
        "(--camera-option); run with --debug for the plug-in's traceback")


def available_cameras() -> dict:
    """Camera names ``--camera`` accepts: the built-ins and every registered entry point.

    Returns
    -------
    dict of str to str
        Name -> where it comes from (``module:Class``, or the entry point's value); each
        loads with :func:`camera_class`. A registered name never shadows a built-in.
    """
    found = {name: ep.value for name, ep in entry_points(ENTRY_POINT_GROUP).items()}
    return {**found, **_BUILTIN}


def camera_class(spec: str):
    """The camera class of ``spec``: ``module:Class``, or a name registered in the entry point
    group ``sunlab.cameras``.

    Parameters
    ----------
    spec : str
        ``sim``, ``folder`` (the built-ins), ``module:Class`` (``Class`` may be dotted) or a
        name registered in :data:`ENTRY_POINT_GROUP`.

    Returns
    -------
    object
        The class (any attribute the spec names; :func:`open_camera` checks it is callable).

    Raises
    ------
    ConfigurationError
        An unknown name, a module that does not import or raises on import, or a missing
        attribute, naming the spec and the fix.

    Examples
    --------
    >>> camera_class("sim").__name__
    'SimCamera'
    """
    what = f"--camera {spec}"
    spec = _BUILTIN.get(spec, spec)
    eps = {} if ":" in spec else entry_points(ENTRY_POINT_GROUP)
    if ":" not in spec and spec not in eps:
        raise ConfigurationError(
            f"--camera: found {spec!r}, expected 'sim', 'folder:PATH', 'module:Class' or a "
            f"registered camera ({sorted(eps) or 'none registered'}). Fix: give the class "
            f"as mypkg.module:MyCamera, or register it in the entry point group "
            f"{ENTRY_POINT_GROUP!r} of your package (docs/hardware.md)")
    form = EntryPoint.pattern.match(spec) if ":" in spec else None
    if ":" in spec and (form is None or not form.group("attr")):
        raise ConfigurationError(f"--camera: found {spec!r}, expected module:Class (Python "
                                 "names). Fix: e.g. mypkg.cameras:MyCamera")
    ep = eps.get(spec) or EntryPoint(spec, spec, ENTRY_POINT_GROUP)  # module:Class, loaded alike
    return load_plugin(ep, what, _FIX)


def parse_camera_options(pairs) -> dict:
    """``KEY=VALUE`` strings as keyword arguments (values as JSON when they parse, else text).

    Parameters
    ----------
    pairs : iterable of str or None
        The ``--camera-option`` values, each ``KEY=VALUE`` with ``KEY`` a Python name.

    Returns
    -------
    dict
        Keyword arguments for the camera class, in the order given (a repeated key keeps its
        last value).

    Examples
    --------
    >>> parse_camera_options(["exposure_s=0.002", "serial=21A", "roi=[0, 64, 0, 64]"])
    {'exposure_s': 0.002, 'serial': '21A', 'roi': [0, 64, 0, 64]}
    """
    out = {}
    for pair in pairs or ():
        key, sep, value = str(pair).partition("=")
        if not sep or not key.strip().isidentifier():
            raise ConfigurationError(
                f"--camera-option: found {pair!r}, expected KEY=VALUE with KEY a Python name")
        out[key.strip()] = integrity.loads(value, f"--camera-option {key.strip()}", or_text=True)
    return out


def open_camera(spec: str, **options):
    """A camera object from ``spec`` (see the module): the class called with ``options``,
    checked against the :class:`~sunlab.hardware.cameras.Camera` protocol.

    Parameters
    ----------
    spec : str
        The camera, as :func:`camera_class` reads it.
    **options
        Keyword arguments of the camera class (``--camera-option KEY=VALUE``, read by
        :func:`parse_camera_options`).

    Returns
    -------
    Camera
        The open camera.

    Raises
    ------
    ConfigurationError
        The spec does not name a camera class, the class refuses the options, or the object
        lacks ``grab``, ``shape``, ``dtype`` or ``bit_depth``.
    """
    cls = camera_class(spec)
    if not callable(cls):
        raise ConfigurationError(f"--camera {spec}: found a {type(cls).__name__}, expected a "
                                 "camera class. Fix: give module:Class of the class itself")
    return open_device(cls, Camera, ("grab", "shape", "dtype", "bit_depth"), f"--camera {spec}",
                       _FIX, **options)
