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
    k = 0
    while n >= 1000 and k < 4:
        n, k = n / 1000, k + 1
    return f"{n:.0f} B" if k == 0 else f"{n:.1f} {('kB', 'MB', 'GB', 'TB')[k - 1]}"


def _range(values, unit: str) -> str:
    finite = np.asarray(values, dtype=float)
    finite = finite[np.isfinite(finite)]
    if finite.size == 0:
        return "no finite values"
    return f"{finite.min():g} .. {finite.max():g} {unit} ({np.unique(finite).size} distinct)"


def _angles(ds: xr.Dataset) -> list[str]:
    return [f"  alpha: {_range(ds['alpha'].values, 'deg')}",
            f"  beta:  {_range(ds['beta'].values, 'deg')}"]


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
    contract, source = ds.attrs.get("sunlab_schema"), ds.encoding.get("source")
    if contract not in (FRAMES_SCHEMA, CENTROIDS_SCHEMA):
        raise SchemaError(
            "attrs['sunlab_schema']", contract, f"{FRAMES_SCHEMA!r} or {CENTROIDS_SCHEMA!r}",
            "open the file with sunlab.io.open_frames or sunlab.io.open_centroids")
    frames = contract == FRAMES_SCHEMA
    lines = [f"sunlab {'frame cube' if frames else 'centroid table'} ({contract})"]
    lines += [f"  source: {source}"] if source else []
    if ds.encoding.get("sunlab_format") == "zarr" and source:
        for name, (n_missing, total, examples) in _chunk_report(Path(source)).items():
            lines.append(
                f"  INCOMPLETE: {name}: {n_missing} of {total} chunk files missing (they read "
                f"as 0 or NaN){', e.g. ' + examples[0] if examples else ''}")
    lines.append("  dims: " + ", ".join(f"{k}={v}" for k, v in ds.sizes.items()))
    lines.extend(_frames_lines(ds) if frames else _centroids_lines(ds))
    return "\n".join(lines)


def _frames_lines(ds: xr.Dataset) -> list[str]:
    """Frames, pose grid, sensor and extra coordinates of a frame cube."""
    frames, a = ds["frames"], ds.attrs
    chunks = getattr(frames.data, "chunksize", None)
    lines = [
        f"  frames: {frames.dtype} DN, {a.get('bit_depth')}-bit ADC, {_nbytes(frames.nbytes)}"
        + (f", chunks {tuple(int(c) for c in chunks)} (lazy)" if chunks else " (in memory)"),
        f"  poses: {ds.sizes['pose']}, shots per pose: {ds.sizes['shot']}",
        *(_angles(ds) if ds.sizes["pose"] else [])]
    said = {k: f"{a[k]} mm" if k in a else "not given"
            for k in ("pixel_pitch_mm", "mask_distance_mm")}
    lines.append(
        f"  sensor: pixel pitch {said['pixel_pitch_mm']}, mask distance F "
        f"{said['mask_distance_mm']}, x_cf {a.get('x_cf_px')} px, y_cf {a.get('y_cf_px')} px"
        + (", left-aligned on read" if a.get("left_aligned") else ""))
    lines.append(f"  mask: {a.get('mask')!r}, experiment: {a.get('experiment')!r}")
    for kind, prov in (a.get("calibration_frames") or {}).items():
        lines.append(f"  master {kind}: {prov.get('combine')} of {prov.get('n_frames')} "
                     f"frames from {prov.get('source')} (applied before centroiding)")
    extra = [f"    {n}: dims {tuple(map(str, v.dims))}, {v.dtype}" for n, v in ds.coords.items()
             if n not in ("pose", "shot", "alpha", "beta")]
    lines += ["  coordinates:", *extra] if extra else []
    return lines + _others(ds, ("frames",))


def _others(ds: xr.Dataset, known) -> list[str]:
    others = [str(n) for n in ds.data_vars if n not in known]
    return [f"  other variables: {', '.join(others)}"] if others else []


def _centroids_lines(ds: xr.Dataset) -> list[str]:
    """Method, status counts and centroid ranges of a centroid table."""
    status = np.asarray(ds["status"].values).ravel()
    counts = [f"{name} {int(np.sum(status == code))} ({100 * np.mean(status == code):.1f} %)"
              for name, code in STATUS.items() if np.any(status == code)]
    lines = [f"  method: {ds.attrs.get('method') or '(not recorded)'}",
             f"  status ({status.size} spots): " + (", ".join(counts) or "none"),
             f"  x: {_range(ds['x'].values, 'px')}", f"  y: {_range(ds['y'].values, 'px')}"]
    lines += _angles(ds) if "alpha" in ds.coords and ds.sizes["pose"] else []
    return lines + _others(ds, ("x", "y", "flux", "status", "x0", "x1", "y0", "y1"))
