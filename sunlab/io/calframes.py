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

A pixel clipped at full scale in the flats has no known response: its master flat is NaN and
its corrected value reads as saturated (see :func:`with_calibration_frames`).

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

__all__ = ["with_calibration_frames", "corrected_frames", "corrected_saturation"]

#: The master frames a cube may hold: kind -> variable name.
MASTER_NAMES = {"dark": "master_dark", "bias": "master_bias", "flat": "master_flat"}
#: Above this fraction of clipped pixels a master flat is refused rather than flagged.
_MAX_CLIPPED_FLAT = 0.01


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
    if not (source.is_dir() or source.is_file()):
        raise SchemaError("calibration frames", str(source), "an existing folder or TIFF stack",
                          "check the path (relative to the current directory unless absolute)")
    files = sorted(p for p in source.iterdir() if p.suffix.lower() in IMAGE_SUFFIXES) \
        if source.is_dir() else [source]
    if not files:
        raise SchemaError("calibration frames", f"{source} (no {', '.join(IMAGE_SUFFIXES)} "
                          "images)", "a folder of frames or a TIFF stack",
                          "point to the folder that holds the dark/flat/bias frames")
    frames = []
    for path in files:
        n_pages = _image_header(path, stack=True)[2]
        frames += [read_image(path, bit_depth=bit_depth, page=page, left_aligned=left_aligned)
                   for page in ([None] if n_pages == 1 else range(n_pages))]
    shapes = {f.shape for f in frames}
    if len(shapes) > 1:
        raise SchemaError(f"calibration frames {source}", f"frames of shapes {sorted(shapes)}",
                          "frames of one size", "remove the odd frames from the folder")
    return np.stack(frames)


def _as_stack(frames, what: str, bit_depth=None, left_aligned=False) -> tuple[np.ndarray, str]:
    """Frames (n, y, x) and a description of their source, from a path or an array."""
    if isinstance(frames, str | Path):
        return (read_stack(frames, bit_depth=bit_depth, left_aligned=left_aligned),
                str(Path(frames).resolve()))
    try:
        arr = np.asarray(frames)
    except ValueError as err:  # ragged nested lists
        raise SchemaError(what, f"not an array ({err})", "frames (n, y, x) or one (y, x)",
                          "stack frames of one size along a first axis") from err
    arr = arr[None] if arr.ndim == 2 else arr
    if arr.ndim != 3 or arr.shape[0] == 0:
        raise SchemaError(what, f"an array of shape {arr.shape}", "frames (n, y, x) or one (y, x)",
                          "stack the calibration frames along a first axis")
    if arr.dtype.kind not in "uif":
        raise SchemaError(what, f"an array of {arr.dtype}", "numbers (DN)",
                          "pass the frames as an integer or float array")
    bad = ~np.isfinite(arr) if arr.dtype.kind == "f" else np.zeros(0, bool)
    if bad.any():
        # a NaN or inf pixel propagates through the median into every corrected frame, and
        # then into every centroid window that holds it (all shots invalid, no reason given)
        n, y, x = np.argwhere(bad)[0]
        raise SchemaError(
            what, f"{int(bad.sum())} value(s) that are not finite (first {arr[n, y, x]} at "
                  f"frame {n}, row {y}, column {x})", "finite DN in every pixel",
            "replace the NaN/inf pixels (e.g. by the median of their neighbours) or take the "
            "frames again")
    return arr, "array"


def master_flat(frames, offset=None, *, bit_depth: int | None = None, left_aligned: bool = False):
    """Master flat: the pixel-wise median of ``flats - offset``, normalised to a median of 1.

    Parameters
    ----------
    frames : path or array_like
        The flat frames (a uniformly lit sensor): a folder, a TIFF stack or an array (n, y, x).
    offset : array_like (y, x), optional
        The master dark (or bias) of the flats, DN; default none.
    bit_depth, left_aligned
        As for :func:`~sunlab.io.read_image`, when ``frames`` is a path.

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
    stack = _as_stack(frames, "flat", bit_depth, left_aligned)[0].astype(np.float64)
    if offset is not None:
        offset = _as_stack(offset, "flat offset (dark or bias)")[0][0]
        if offset.shape != stack.shape[1:]:
            raise SchemaError(
                "flat offset (dark or bias)", f"a master of shape {offset.shape}",
                f"the flats' frame shape {stack.shape[1:]}",
                "take the dark (or bias) with the camera's settings of the flats")
        stack -= offset
    flat = np.median(stack, axis=0)
    level = float(np.median(flat))
    bad = ~(flat > 0.05 * level) if level > 0 else np.ones(flat.shape, bool)
    if bad.any():
        y, x = np.argwhere(bad)[0]
        raise SchemaError(
            "flat", f"{int(bad.sum())} pixel(s) with a response <= 5 % of the median "
                    f"(first at row {y}, column {x}: {flat[y, x]:.1f} DN over the dark)",
            "flats well above the dark everywhere",
            "expose the flats longer (a few thousand DN), check that dark and flats come from "
            "the same camera settings, or mask dead pixels before the flat")
    return (flat / level).astype(np.float32)


def with_calibration_frames(cube, *, dark=None, flat=None, bias=None,
                            left_aligned: bool | None = None):
    """The cube with master frames stored in it, ready for :func:`corrected_frames`.

    Parameters
    ----------
    cube : xarray.Dataset
        A frame cube (contract ``frames/1``).
    dark, flat, bias : path or array_like, optional
        Calibration frames: a folder of images, a TIFF stack, or an array (n, y, x) (or a
        master (y, x)). Master dark and bias: the pixel-wise median. The dark (or, without
        one, the bias) is subtracted from the flats before they are combined
        (:func:`master_flat`).
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
        Frames of another size or (8- vs 16-bit) pixel type than the cube's, values that are
        not finite, a path that is not frames, a flat with dead pixels, flats clipped at full
        scale in more than 1 % of the pixels.

    Notes
    -----
    A pixel that reached full scale in any flat frame has an unknown response: its master flat
    is NaN, :func:`corrected_frames` reads it as saturated (the estimators flag the spot, or
    repair an isolated pixel: status ``repaired``), and the provenance of the flat counts them
    (``clipped_pixels``, ``first_clipped`` [row, column]).
    """
    if dark is None and flat is None and bias is None:
        return cube
    bits = int(cube.attrs["bit_depth"])
    left = bool(cube.attrs.get("left_aligned", False)) if left_aligned is None else left_aligned
    masters, prov = {}, dict(cube.attrs.get("calibration_frames") or {})
    for kind, given in (("bias", bias), ("dark", dark), ("flat", flat)):
        if given is None:
            continue
        stack, src = _checked_stack(cube, given, kind, bits, left)
        prov[kind] = {"source": src, "n_frames": int(stack.shape[0]), "combine": "median"}
        if kind != "flat":
            masters[kind] = np.median(stack, axis=0).astype(np.float32)
            continue
        under = "dark" if "dark" in masters else "bias" if "bias" in masters else None
        masters["flat"] = master_flat(stack, masters.get(under))
        prov["flat"]["combine"] = f"median of (flat - {under or 'nothing'}), normalised to 1"
        # a pixel at full scale in a flat has an unknown response (the ADC cut it): NaN, read
        # as saturated by corrected_frames; a flat mostly clipped is refused
        clipped = (stack >= 2**bits - 1).any(axis=0)
        prov["flat"]["clipped_pixels"] = n = int(clipped.sum())
        if n:
            y, x = np.argwhere(clipped)[0]
            if n > _MAX_CLIPPED_FLAT * clipped.size:
                raise SchemaError(f"flat frames {src}", f"{n} of {clipped.size} pixels at full "
                                  f"scale ({2**bits - 1} DN; first at row {y}, column {x})",
                                  "flats below full scale",
                                  "expose the flats shorter (about half of full scale)")
            masters["flat"][clipped] = np.nan
            prov["flat"]["first_clipped"] = [int(y), int(x)]
    units = {"dark": "DN", "bias": "DN", "flat": "1"}
    out = cube.assign({MASTER_NAMES[k]: (("y", "x"), m, {"units": units[k]})
                       for k, m in masters.items()})
    out.attrs["calibration_frames"] = prov
    return out


def _checked_stack(cube, given, kind: str, bits: int, left: bool):
    """The frames of one kind of calibration frames, checked against the cube before they are
    combined: the frame size, and for integer frames the pixel type (8-bit darks read as the
    DN of 10-bit frames would be subtracted at a quarter of their level)."""
    stack, src = _as_stack(given, kind, bits, left)
    shape, own = (cube.sizes["y"], cube.sizes["x"]), np.dtype(cube["frames"].dtype)
    settings = f"take the {kind} frames with the camera's settings"
    if stack.shape[1:] != shape:
        raise SchemaError(f"{kind} frames {src}", f"frames of shape {stack.shape[1:]}",
                          f"the cube's {shape}", f"{settings} (size, ROI, binning) of the cube")
    types = (np.dtype(np.uint8), np.dtype(np.uint16))
    if stack.dtype in types and own in types and stack.dtype != own:
        raise SchemaError(f"{kind} frames {src}", f"pixel type {stack.dtype}",
                          f"{own} like the cube's frames ({bits}-bit DN)",
                          f"{settings} (bit depth, pixel format) of the frames, or convert them "
                          "to the frames' DN scale before the import")
    return stack, src


def has_calibration_frames(cube) -> bool:
    """Whether a cube holds any master frame (:data:`MASTER_NAMES`).

    Parameters
    ----------
    cube : xarray.Dataset
        A frame cube (contract ``frames/1``).

    Returns
    -------
    bool
        True when it has a ``master_dark``, ``master_bias`` or ``master_flat`` variable.
    """
    return any(name in cube.variables for name in MASTER_NAMES.values())


def corrected_saturation(cube) -> float:
    """The level a raw pixel at full scale takes in :func:`corrected_frames`, DN.

    ``2 * full / min(flat)``: above ``(full - D) / F`` for every unsaturated pixel, so the
    estimators, given this level as ``saturation``, see exactly the pixels the ADC clipped.

    Parameters
    ----------
    cube : xarray.Dataset
        A frame cube with attribute ``bit_depth`` and, optionally, masters from
        :func:`with_calibration_frames`.

    Returns
    -------
    float
        ``2 (2**bit_depth - 1) / min(F)`` DN, F the master flat (the smallest finite value);
        ``2 (2**bit_depth - 1)`` without a flat.
    """
    full = float(2 ** int(cube.attrs["bit_depth"]) - 1)
    if MASTER_NAMES["flat"] in cube.variables:  # NaN: a pixel clipped in the flats
        return 2.0 * full / float(np.nanmin(cube[MASTER_NAMES["flat"]].values))
    return 2.0 * full


def _correct_block(block, offset, flat, full, level):
    """``(R - offset) / flat`` of a block of raw frames (..., y, x), float32; raw pixels at or
    above ``full``, and pixels clipped in the flats (NaN), become ``level``."""
    raw = np.asarray(block)
    out = raw.astype(np.float32)
    if offset is not None:
        out -= offset
    if flat is not None:
        out /= flat
        out[..., ~np.isfinite(flat)] = level
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
    master = {k: np.asarray(cube[v].values, np.float32) for k, v in MASTER_NAMES.items()
              if v in cube.variables}
    kw = {"offset": master.get("dark", master.get("bias")), "flat": master.get("flat"),
          "full": float(2 ** int(cube.attrs["bit_depth"]) - 1),
          "level": corrected_saturation(cube)}
    if isinstance(frames.data, da.Array):
        if any(len(c) > 1 for c in frames.data.chunks[-2:]):  # masters apply to whole frames
            frames = frames.chunk({"y": -1, "x": -1})
        data = da.map_blocks(_correct_block, frames.data, dtype=np.float32, **kw)
    else:
        data = _correct_block(frames.values, **kw)
    return frames.copy(data=data).assign_attrs(units="DN", long_name="corrected frames")
