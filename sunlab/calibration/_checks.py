"""Checks shared by the calibration classes: of training data (:func:`_check_spots_move`) and
of a ``calibration/1`` document's parameters.

Each class checks its own parameters (``_check_parameters``) with these helpers before it
builds any array, so that a corrupt file is refused with a :class:`sunlab.SchemaError` naming
the field, and a corrupt size (an order of 20000) cannot allocate gigabytes first.
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import ConfigurationError, SchemaError
from ..schema import STATUS, USABLE_STATUS

__all__: list[str] = []


def _ok_mask(ds) -> np.ndarray:
    """The usable shots: a usable status (:data:`sunlab.schema.USABLE_STATUS`), finite x, y."""
    v = ds.variables
    usable = np.isin(np.asarray(v["status"].values), [STATUS[k] for k in USABLE_STATUS])
    return usable & np.isfinite(v["x"].values) & np.isfinite(v["y"].values)


def _check_spots_move(x: np.ndarray, y: np.ndarray, name: str) -> None:
    """Refuse training points whose spot (``x``, ``y``, px) never moves along an axis from pose
    to pose: no kind learns angles from a spot that stays put (a camera that kept one frame),
    and most would fit one anyway, with errors of degrees."""
    for c, v in (("x", x), ("y", y)):
        if not np.ptp(v) > 0:
            raise ConfigurationError(
                f"{name}: every usable shot has its spot at the same {c} ({v[0]:g} px) at "
                "every pose, nothing to calibrate. Fix: calibrate on poses that move the spot "
                "along both axes (a grid such as experiment I)")


def _bad(field: str, found, expected: str, fix: str = "the file is corrupt or edited by hand; "
         "re-fit the calibration with `sunlab calibrate`") -> SchemaError:
    return SchemaError(f"parameters.{field}", found, expected, fix)


def _finite(v) -> bool:
    """A JSON number that is finite as a double (an integer of 400 digits is not: ``float()``
    of it overflows)."""
    if isinstance(v, bool) or not isinstance(v, int | float):
        return False
    try:
        return math.isfinite(float(v))
    except OverflowError:
        return False


def _numbers(value, field: str, length: int | None = None, *, positive: bool = False) -> list:
    """A flat list of finite numbers (checked without building an array)."""
    if not isinstance(value, list):
        raise _bad(field, type(value).__name__, "a list of numbers")
    if length is not None and len(value) != length:
        raise _bad(field, f"{len(value)} values", f"{length} values")
    for i, v in enumerate(value):
        if not _finite(v) or (positive and not v > 0):
            raise _bad(f"{field}[{i}]", v, "a finite positive number" if positive
                       else "a finite number")
    return value


def _number(value, field: str, *, positive: bool = False) -> float:
    """One finite number."""
    if not _finite(value) or (positive and not value > 0):
        raise _bad(field, value, "a finite positive number" if positive else "a finite number")
    return value


def _count(value, field: str, low: int = 0, high: int | None = None) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < low or (
            high is not None and value > high):
        raise _bad(field, value, f"an integer >= {low}" if high is None
                   else f"an integer from {low} to {high}")
    return value


def _scaling_ok(p: dict) -> None:
    scaling = p.get("scaling")
    if not isinstance(scaling, dict):
        raise _bad("scaling", type(scaling).__name__, "an object {'x': [lo, hi], 'y': [lo, hi]}")
    for axis in ("x", "y"):
        lo, hi = _numbers(scaling.get(axis), f"scaling.{axis}", 2)
        if not hi > lo:
            raise _bad(f"scaling.{axis}", [lo, hi], "[lo, hi] with hi > lo (a range of "
                       "centroids, px)", "a zero or negative range divides by zero in predict; "
                       "re-fit the calibration on poses that move the spot along both axes")


def _coefficients_ok(p: dict, counts: dict) -> None:
    coef = p.get("coefficients")
    if not isinstance(coef, dict):
        raise _bad("coefficients", type(coef).__name__, "an object {'alpha': [...], 'beta': [...]}")
    for angle, n in counts.items():
        _numbers(coef.get(angle), f"coefficients.{angle}", n)
