"""A human-readable summary of a frame cube or a centroid table (``sunlab info``)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import xarray as xr

from ..errors import SchemaError
from ..schema import CENTROIDS_SCHEMA, FRAMES_SCHEMA, STATUS
from .chunks import _chunk_report

__all__ = ["summary"]


def _nbytes(n: float) -> str:
    for unit in ("B", "kB", "MB", "GB", "TB"):
        if n < 1000 or unit == "TB":
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.1f} {unit}"
        n /= 1000
    return f"{n:.1f} TB"  # pragma: no cover


def _range(values, unit: str) -> str:
    values = np.asarray(values, dtype=float)
    finite = values[np.isfinite(values)]
    if finite.size == 0:
        return "no finite values"
    n_unique = np.unique(finite).size
    return f"{finite.min():g} .. {finite.max():g} {unit} ({n_unique} distinct)"


def _coord_lines(ds: xr.Dataset, skip) -> list[str]:
    lines = []
    for name in ds.coords:
        if name in skip:
            continue
        var = ds.coords[name]
        lines.append(f"  {name}: dims {tuple(map(str, var.dims))}, {var.dtype}")
    return lines


def summary(ds) -> str:
    """A human-readable summary of a frame cube or a centroid table.

    Frame cubes: contract, dims, pose grid ranges, shots, dtype and bit depth, chunking, size,
    sensor attributes and extra coordinates. Centroid tables: dims, method, status counts and
    the centroid ranges. A Zarr store opened with ``check_chunks=False`` that lacks chunk files
    (an acquisition in progress, an interrupted copy) gets an ``INCOMPLETE`` line per array.
    Only coordinates are read; the frames stay lazy.

    Parameters
    ----------
    ds : xarray.Dataset or path-like
        A frame cube (``frames/1``) or a centroid table (``centroids/1``), or a store or file
        holding one (opened lazily, whichever contract it names, with missing chunks allowed:
        ``sunlab info``).

    Returns
    -------
    str
        Several lines, the first naming the kind and the contract; as ``sunlab info`` prints.

    Raises
    ------
    SchemaError
        ``attrs['sunlab_schema']`` names neither contract.

    Examples
    --------
    >>> import numpy as np
    >>> from sunlab import schema
    >>> cen = schema.centroids_dataset([[1.0, np.nan], [3.0, 4.0]], [[2.0, np.nan], [5.0, 6.0]])
    >>> print(summary(cen).splitlines()[0])
    sunlab centroid table (centroids/1)
    >>> "no_spot 1 (25.0 %)" in summary(cen)
    True
    """
    if not isinstance(ds, xr.Dataset):
        from .read import _open_any

        ds = _open_any(ds)
    contract = ds.attrs.get("sunlab_schema")
    source = ds.encoding.get("source")
    storage = _storage_lines(ds, source)
    if contract not in (FRAMES_SCHEMA, CENTROIDS_SCHEMA):
        raise SchemaError(
            "attrs['sunlab_schema']", contract, f"{FRAMES_SCHEMA!r} or {CENTROIDS_SCHEMA!r}",
            "open the file with sunlab.io.open_frames or sunlab.io.open_centroids",
        )
    kind = "frame cube" if contract == FRAMES_SCHEMA else "centroid table"
    lines = [f"sunlab {kind} ({contract})"]
    if source:
        lines.append(f"  source: {source}")
    lines.extend(storage)
    lines.append("  dims: " + ", ".join(f"{k}={v}" for k, v in ds.sizes.items()))
    lines.extend(_frames_lines(ds) if contract == FRAMES_SCHEMA else _centroids_lines(ds))
    return "\n".join(lines)


def _storage_lines(ds: xr.Dataset, source) -> list[str]:
    """An ``INCOMPLETE`` line per array of a Zarr store with missing chunk files."""
    storage = []
    if ds.encoding.get("sunlab_format") == "zarr" and source:
        for name, (n_missing, total, examples) in _chunk_report(Path(source)).items():
            storage.append(
                f"  INCOMPLETE: {name}: {n_missing} of {total} chunk files missing (they read "
                f"as 0 or NaN){', e.g. ' + examples[0] if examples else ''}"
            )
    return storage


def _frames_lines(ds: xr.Dataset) -> list[str]:
    """Frames, pose grid, sensor and extra coordinates of a frame cube."""
    frames = ds["frames"]
    lines = []
    chunks = getattr(frames.data, "chunksize", None)
    lines.append(
        f"  frames: {frames.dtype} DN, {ds.attrs.get('bit_depth')}-bit ADC, "
        f"{_nbytes(frames.nbytes)}"
        + (f", chunks {tuple(int(c) for c in chunks)} (lazy)" if chunks else " (in memory)")
    )
    n_pose = ds.sizes["pose"]
    lines.append(f"  poses: {n_pose}, shots per pose: {ds.sizes['shot']}")
    if n_pose:
        lines.append(f"  alpha: {_range(ds['alpha'].values, 'deg')}")
        lines.append(f"  beta:  {_range(ds['beta'].values, 'deg')}")
    a = ds.attrs
    said = {k: f"{a[k]} mm" if k in a else "not given" for k in ("pixel_pitch_mm",
                                                                  "mask_distance_mm")}
    lines.append(
        f"  sensor: pixel pitch {said['pixel_pitch_mm']}, mask distance F "
        f"{said['mask_distance_mm']}, x_cf {a.get('x_cf_px')} px, "
        f"y_cf {a.get('y_cf_px')} px" + (", left-aligned on read" if a.get("left_aligned")
                                         else "")
    )
    lines.append(f"  mask: {a.get('mask')!r}, experiment: {a.get('experiment')!r}")
    for kind, prov in (a.get("calibration_frames") or {}).items():
        lines.append(f"  master {kind}: {prov.get('combine')} of {prov.get('n_frames')} "
                     f"frames from {prov.get('source')} (applied before centroiding)")
    extra = _coord_lines(ds, skip=("pose", "shot", "alpha", "beta"))
    if extra:
        lines.append("  coordinates:")
        lines.extend("  " + line for line in extra)
    others = [n for n in ds.data_vars if n != "frames"]
    if others:
        lines.append(f"  other variables: {', '.join(map(str, others))}")
    return lines


def _centroids_lines(ds: xr.Dataset) -> list[str]:
    """Method, status counts and centroid ranges of a centroid table."""
    lines = [f"  method: {ds.attrs.get('method') or '(not recorded)'}"]
    status = np.asarray(ds["status"].values).ravel()
    total = status.size
    counts = [
        f"{name} {int(np.sum(status == code))} ({100 * np.mean(status == code):.1f} %)"
        for name, code in STATUS.items()
        if np.any(status == code)
    ]
    lines.append(f"  status ({total} spots): " + (", ".join(counts) or "none"))
    lines.append(f"  x: {_range(ds['x'].values, 'px')}")
    lines.append(f"  y: {_range(ds['y'].values, 'px')}")
    if "alpha" in ds.coords and ds.sizes["pose"]:
        lines.append(f"  alpha: {_range(ds['alpha'].values, 'deg')}")
        lines.append(f"  beta:  {_range(ds['beta'].values, 'deg')}")
    others = [
        n for n in ds.data_vars
        if n not in ("x", "y", "flux", "status", "x0", "x1", "y0", "y1")
    ]
    if others:
        lines.append(f"  other variables: {', '.join(map(str, others))}")
    return lines
