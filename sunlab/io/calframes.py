"""Calibration frames: master dark, bias and flat, stored with a cube and applied lazily.

An uncorrected APS frame is not the light alone: every pixel adds its own dark offset (a ramp
of hundreds of DN across an Ibis4 frame is common), and the optics and the pixels respond
unevenly (vignetting of a few percent, a flat-field pattern). A lab measures both with
calibration frames, and this module turns them into masters and applies them:

* master **bias** and master **dark**: the pixel-wise median of their frames (the median rejects
  a cosmic ray or a flicker in one frame);
* master **flat**: the pixel-wise median of the flats after subtracting the dark (the bias when no
  dark is given), normalised to a median of 1;
* the corrected frame, :func:`corrected_frames`, of the raw frame ``R``:

  .. math:: C = \\frac{R - D}{F}

  with ``D`` the master dark (the master bias when no dark is given) and ``F`` the master flat
  (1 when none). A dark taken at the exposure of the frames holds the bias, so the bias is only
  subtracted on its own when there is no dark.

:func:`with_calibration_frames` stores the masters in the cube (variables ``master_dark``,
``master_bias``, ``master_flat`` on (y, x), float32) with their provenance in
``attrs['calibration_frames']`` (source, number of frames, how they were combined), so a saved
cube carries what it needs. :func:`sunlab.centroid.locate` applies the correction by itself,
lazily, in the task that centroids each frame, whenever a cube holds masters; the raw frames
stay the raw DN of the contract ``frames/1``.

Saturation survives the correction: a raw pixel at full scale (``2**bit_depth - 1``) becomes
exactly :func:`corrected_saturation`, a level above any corrected value of an unsaturated pixel,
and the estimators are given that level, so they flag (or repair, for an isolated hot pixel)
what the ADC clipped.

Examples
--------
>>> import numpy as np
>>> from sunlab import schema
>>> raw = np.full((1, 1, 8, 8), 300, np.uint16)
>>> cube = schema.frames_dataset(raw, alpha=[0.0], beta=[0.0])
>>> cube = with_calibration_frames(cube, dark=np.full((3, 8, 8), 100, np.uint16),
...                                flat=np.full((2, 8, 8), 500, np.uint16))
>>> float(corrected_frames(cube)[0, 0, 0, 0])
200.0
>>> cube.attrs["calibration_frames"]["dark"]["n_frames"]
3
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import SchemaError
from .images import IMAGE_SUFFIXES, _image_header, read_image

__all__ = [
    "MASTER_NAMES",
    "read_stack",
    "master_frame",
    "master_flat",
    "with_calibration_frames",
    "corrected_frames",
    "corrected_saturation",
    "has_calibration_frames",
]

#: The master frames a cube may hold: kind -> variable name.
MASTER_NAMES = {"dark": "master_dark", "bias": "master_bias", "flat": "master_flat"}


def read_stack(source, *, bit_depth: int | None = None, left_aligned: bool = False):
    """The frames of a folder of images (every PNG/TIFF in it, by name), of a multi-page TIFF,
    or of one image, as an array (n, y, x) of DN.

    Parameters
    ----------
    source : str or path-like
        A folder (its ``manifest.csv``, if any, is not needed: every image is one frame), a TIFF
        stack, or one image file.
    bit_depth, left_aligned
        As for :func:`~sunlab.io.read_image`.

    Returns
    -------
    numpy.ndarray, shape (n, y, x)
    """
    source = Path(source)
    if source.is_dir():
        files = sorted(p for p in source.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES)
        if not files:
            raise SchemaError(
                "calibration frames", f"{source} (no {', '.join(IMAGE_SUFFIXES)} images)",
                "a folder of frames or a TIFF stack",
                "point to the folder that holds the dark/flat/bias frames",
            )
    elif source.is_file():
        files = [source]
    else:
        raise SchemaError("calibration frames", str(source), "an existing folder or TIFF stack",
                          "check the path (relative to the current directory unless absolute)")
    frames = []
    for path in files:
        _, _, n_pages = _image_header(path, stack=True)
        pages = [None] if n_pages == 1 else range(n_pages)
        frames.extend(read_image(path, bit_depth=bit_depth, page=page, left_aligned=left_aligned)
                      for page in pages)
    shapes = {f.shape for f in frames}
    if len(shapes) > 1:
        raise SchemaError(f"calibration frames {source}", f"frames of shapes {sorted(shapes)}",
                          "frames of one size", "remove the odd frames from the folder")
    return np.stack(frames)


def _as_stack(frames, what: str, bit_depth, left_aligned) -> tuple[np.ndarray, str]:
    """Frames (n, y, x) and a description of their source, from a path or an array."""
    if isinstance(frames, str | Path):
        return read_stack(frames, bit_depth=bit_depth, left_aligned=left_aligned), str(
            Path(frames).resolve())
    arr = np.asarray(frames)
    if arr.ndim == 2:
        arr = arr[None]
    if arr.ndim != 3 or arr.shape[0] == 0:
        raise SchemaError(what, f"an array of shape {arr.shape}", "frames (n, y, x) or one (y, x)",
                          "stack the calibration frames along a first axis")
    return arr, "array"


def master_frame(frames, *, bit_depth: int | None = None, left_aligned: bool = False):
    """Master dark or bias: the pixel-wise median of the frames, DN (float32, (y, x)).

    Parameters
    ----------
    frames : path or array_like
        A folder of frames, a TIFF stack, or an array (n, y, x).
    bit_depth, left_aligned
        As for :func:`~sunlab.io.read_image`, when ``frames`` is a path.

    Examples
    --------
    >>> master_frame([[[1, 5]], [[3, 5]], [[100, 6]]]).tolist()
    [[3.0, 5.0]]
    """
    stack, _ = _as_stack(frames, "dark", bit_depth, left_aligned)
    return np.median(stack, axis=0).astype(np.float32)


def master_flat(frames, offset=None, *, bit_depth: int | None = None, left_aligned: bool = False):
    """Master flat: the pixel-wise median of ``flats - offset``, normalised to a median of 1.

    Parameters
    ----------
    frames : path or array_like
        The flat frames (a uniformly lit sensor): a folder, a TIFF stack or an array (n, y, x).
    offset : array_like (y, x), optional
        The master dark (or bias) of the flats, DN; default none.

    Returns
    -------
    numpy.ndarray of float32, shape (y, x)
        The relative response of each pixel (1 = the median pixel).

    Raises
    ------
    SchemaError
        When a pixel's response is not positive (a dead pixel, or a flat darker than the dark).

    Examples
    --------
    >>> master_flat([[[110, 120, 130]]], offset=[[10, 10, 10]]).astype(float).round(3).tolist()
    [[0.909, 1.0, 1.091]]
    """
    stack, _ = _as_stack(frames, "flat", bit_depth, left_aligned)
    flat = np.median(stack.astype(np.float64) - (0.0 if offset is None else
                                                 np.asarray(offset, np.float64)), axis=0)
    level = float(np.median(flat))
    bad = ~(flat > 0.05 * level) if level > 0 else np.ones(flat.shape, bool)
    if bad.any():
        y, x = np.argwhere(bad)[0]
        raise SchemaError(
            "flat", f"{int(bad.sum())} pixel(s) with a response <= 5 % of the median "
                    f"(first at row {y}, column {x}: {flat[y, x]:.1f} DN over the dark)",
            "flats well above the dark everywhere",
            "expose the flats longer (a few thousand DN), check that dark and flats come from "
            "the same camera settings, or mask dead pixels before the flat",
        )
    return (flat / level).astype(np.float32)


def with_calibration_frames(
    cube, *, dark=None, flat=None, bias=None, left_aligned: bool | None = None,
):
    """The cube with master frames stored in it, ready for :func:`corrected_frames`.

    Parameters
    ----------
    cube : xarray.Dataset
        A frame cube (contract ``frames/1``).
    dark, flat, bias : path or array_like, optional
        Calibration frames: a folder of images, a TIFF stack, or an array (n, y, x) (or a
        master (y, x)). The dark (or, without one, the bias) is subtracted from the flats before
        they are combined.
    left_aligned : bool, optional
        The calibration files are left-aligned; default: as the cube
        (``attrs['left_aligned']``). Files are read at the cube's ``bit_depth``.

    Returns
    -------
    xarray.Dataset
        The cube with ``master_dark``, ``master_bias``, ``master_flat`` as given, and
        ``attrs['calibration_frames']``: per master, its source, number of frames and combination.

    Raises
    ------
    SchemaError
        A master of another frame size than the cube's, a path that is not frames, a flat with
        dead pixels.
    """
    if dark is None and flat is None and bias is None:
        return cube
    bits = int(cube.attrs["bit_depth"])
    left = bool(cube.attrs.get("left_aligned", False)) if left_aligned is None else left_aligned
    shape = (cube.sizes["y"], cube.sizes["x"])
    masters, prov = {}, dict(cube.attrs.get("calibration_frames") or {})
    for kind, given in (("bias", bias), ("dark", dark)):
        if given is not None:
            stack, src = _as_stack(given, kind, bits, left)
            masters[kind] = np.median(stack, axis=0).astype(np.float32)
            prov[kind] = {"source": src, "n_frames": int(stack.shape[0]), "combine": "median"}
    if flat is not None:
        stack, src = _as_stack(flat, "flat", bits, left)
        offset = masters.get("dark", masters.get("bias"))
        masters["flat"] = master_flat(stack, offset)
        prov["flat"] = {"source": src, "n_frames": int(stack.shape[0]),
                        "combine": "median of (flat - " + ("dark" if "dark" in masters else
                                                            "bias" if "bias" in masters else
                                                            "nothing") + "), normalised to 1"}
    for kind, master in masters.items():
        if master.shape != shape:
            raise SchemaError(
                f"master {kind}", f"frames of shape {master.shape}", f"the cube's {shape}",
                f"take the {kind} frames with the camera's settings (size, ROI, binning) of "
                "the cube",
            )
    units = {"dark": "DN", "bias": "DN", "flat": "1"}
    out = cube.assign({MASTER_NAMES[k]: (("y", "x"), m, {"units": units[k]})
                       for k, m in masters.items()})
    out.attrs["calibration_frames"] = prov
    return out


def has_calibration_frames(cube) -> bool:
    """Whether a cube holds any master frame (:data:`MASTER_NAMES`)."""
    return any(name in cube.variables for name in MASTER_NAMES.values())


def corrected_saturation(cube) -> float:
    """The level a raw pixel at full scale takes in :func:`corrected_frames`, DN.

    ``2 * full / min(flat)``: above ``(full - D) / F`` for every unsaturated pixel, so the
    estimators, given this level as ``saturation``, see exactly the pixels the ADC clipped.
    """
    full = float(2 ** int(cube.attrs["bit_depth"]) - 1)
    if MASTER_NAMES["flat"] in cube.variables:
        return 2.0 * full / float(cube[MASTER_NAMES["flat"]].min())
    return 2.0 * full


def _offset_and_flat(cube):
    """The offset (dark, else bias, else 0) and the flat (else 1) of a cube, NumPy float32."""
    names = MASTER_NAMES
    offset = (cube[names["dark"]] if names["dark"] in cube.variables else
              cube[names["bias"]] if names["bias"] in cube.variables else None)
    flat = cube[names["flat"]] if names["flat"] in cube.variables else None
    return (None if offset is None else np.asarray(offset.values, np.float32),
            None if flat is None else np.asarray(flat.values, np.float32))


def _correct_block(block, offset, flat, full, level):
    """``(R - offset) / flat`` of a block of raw frames (..., y, x), float32; raw pixels at or
    above ``full`` become ``level``."""
    raw = np.asarray(block)
    out = raw.astype(np.float32)
    if offset is not None:
        out -= offset
    if flat is not None:
        out /= flat
    out[raw >= full] = level
    return out


def corrected_frames(cube):
    """The cube's frames corrected by its masters, lazily: ``(R - D) / F``, float32 DN.

    Parameters
    ----------
    cube : xarray.Dataset
        A frame cube, with masters from :func:`with_calibration_frames` (without any, the raw
        frames as float32).

    Returns
    -------
    xarray.DataArray
        (pose, shot, y, x), Dask-backed when the frames are (one task per frame chunk, fused
        with the read). Raw pixels at full scale read :func:`corrected_saturation`.
    """
    import dask.array as da

    frames = cube["frames"]
    offset, flat = _offset_and_flat(cube)
    full = float(2 ** int(cube.attrs["bit_depth"]) - 1)
    level = corrected_saturation(cube)
    if isinstance(frames.data, da.Array):
        if any(len(c) > 1 for c in frames.data.chunks[-2:]):  # masters apply to whole frames
            frames = frames.chunk({"y": -1, "x": -1})
        data = da.map_blocks(_correct_block, frames.data, offset=offset, flat=flat, full=full,
                             level=level, dtype=np.float32)
    else:
        data = _correct_block(frames.values, offset, flat, full, level)
    return frames.copy(data=data).assign_attrs(units="DN", long_name="corrected frames")
