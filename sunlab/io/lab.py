"""A lab's own recording as a cube in one call: frames, ``sensor.json``, calibration frames.

:func:`import_folder` is what ``sunlab import`` runs: the folder's frames and manifest
(:func:`~sunlab.io.from_image_folder`), the sensor constants of its ``sensor.json``
(:func:`~sunlab.io.read_sensor_json`) unless given, and the master dark, bias and flat
(:func:`~sunlab.io.with_calibration_frames`).

Examples
--------
>>> from sunlab import io
>>> cube = import_folder(io.example_folder("train"))
>>> cube.attrs["bit_depth"], cube.attrs["mask_distance_mm"], cube.attrs["left_aligned"]
(10, 17.0, False)
"""

from __future__ import annotations

from pathlib import Path

from .calframes import with_calibration_frames
from .folder import from_image_folder
from .sensor import find_sensor_json, read_sensor_json

__all__ = ["import_folder"]

_GIVEN = ("pixel_pitch_mm", "mask_distance_mm", "x_cf_px", "y_cf_px", "bit_depth",
          "left_aligned", "mask", "experiment")


def import_folder(folder, manifest=None, *, dark=None, flat=None, bias=None, lazy: bool = True,
                  **sensor):
    """A frame cube from a lab's folder of frames, its ``sensor.json`` and calibration frames.

    Parameters
    ----------
    folder : str or path-like
        Frames and ``manifest.csv`` (see :func:`~sunlab.io.from_image_folder`).
    manifest : str or path-like, optional
        Another manifest; its folder's ``sensor.json`` is read first.
    dark, flat, bias : str, path-like or array_like, optional
        Calibration frames (folders of images, TIFF stacks, or arrays); their masters are stored
        with the cube (:func:`~sunlab.io.with_calibration_frames`).
    lazy : bool
        Read each frame when it is computed.
    **sensor
        Sensor constants that override ``sensor.json``: ``pixel_pitch_mm``,
        ``mask_distance_mm``, ``x_cf_px``, ``y_cf_px``, ``bit_depth``, ``left_aligned``, ``mask``,
        ``experiment`` (None = not given). The pitch and the mask distance are never guessed:
        absent, they stay absent, and only the methods that need them ask.

    Returns
    -------
    xarray.Dataset
        A ``frames/1`` cube, with ``attrs['sensor_json']`` naming the file read.
    """
    folder = Path(folder)
    unknown = sorted(set(sensor) - set(_GIVEN))
    if unknown:
        raise TypeError(f"import_folder() got unexpected keyword(s) {unknown}")
    path = find_sensor_json(folder, manifest)
    doc = read_sensor_json(path) if path is not None else {}
    values = {k: sensor[k] if sensor.get(k) is not None else doc.get(k) for k in _GIVEN}
    attrs = dict(doc.get("attrs") or {})
    if path is not None:
        attrs["sensor_json"] = str(path.resolve())
    kw = {k: values[k] for k in ("x_cf_px", "y_cf_px", "mask") if values[k] is not None}
    cube = from_image_folder(
        folder, manifest, bit_depth=values["bit_depth"],
        left_aligned=bool(values["left_aligned"]), lazy=lazy,
        pixel_pitch_mm=values["pixel_pitch_mm"], mask_distance_mm=values["mask_distance_mm"],
        experiment=values["experiment"] or folder.resolve().name, attrs=attrs, **kw,
    )
    return with_calibration_frames(cube, dark=dark, flat=flat, bias=bias)
