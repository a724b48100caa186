"""Error statistics of a calibration on a test experiment (docs/paper.md sec. 5), and the
paper's tables.

Protocol of the paper, per pose of the test experiment III and per angle:

- per shot, the error :math:`e^k = |\\text{measured} - \\text{estimated}|` (measured = the
  platform's commanded angle, or any reference such as simulated truth);
- the **local error** :math:`\\bar e` = mean of :math:`e^k` over the shots of the pose, and the
  **maximum error** :math:`e_{max}` = their maximum.

Over the field of view, per angle: :math:`\\mu` = mean of the local errors, :math:`\\sigma` =
their standard deviation, :math:`M` = mean of the maximum errors, :math:`\\sigma_M` = their
standard deviation. Every realisation is taken to lie in :math:`[M - 3\\sigma_M, M + 3\\sigma_M]`;
methods are compared by the rectangle these intervals span for alpha and beta, of area
:math:`36\\,\\sigma_{M,\\alpha}\\sigma_{M,\\beta}` (Fig. 12): smaller is better.

Only shots of status ``ok`` with finite estimates count; a pose with none is NaN and is left
out of the global statistics. Standard deviations use ``ddof=1`` (sample standard deviation over
the poses) unless told otherwise; the paper does not say which it used (the difference is
0.14 % for 361 poses).

Examples
--------
>>> import numpy as np, xarray as xr
>>> est = xr.Dataset({"alpha": (("pose", "shot"), [[1.0, 1.2], [2.0, 2.0]]),
...                   "beta": (("pose", "shot"), [[0.0, 0.0], [0.5, 0.3]])},
...                  coords={"alpha_cmd": ("pose", [1.0, 2.1]), "beta_cmd": ("pose", [0.0, 0.4])})
>>> loc = local_errors(est)
>>> np.round(loc.local_error.sel(angle="alpha").values, 6).tolist()
[0.1, 0.1]
>>> global_stats({"demo": loc}).loc[("alpha", "M"), "demo"].round(6)
np.float64(0.15)
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np
import pandas as pd
import xarray as xr

from .errors import ConfigurationError, SchemaError
from .schema import STATUS, USABLE_STATUS

__all__ = [
    "shot_errors",
    "local_errors",
    "global_stats",
    "evaluate",
    "error_summary",
    "rectangles",
    "paper_table4",
    "paper_table5",
]

ANGLES = ("alpha", "beta")
#: Row labels of the global statistics, in the paper's order (Table 4).
STATS = ("mu", "sigma", "M", "sigma_M")

_REFERENCE = ("docs/paper.md sec. 5, Tables 4 and 5 (the 2005 preprint on the Naples APS sun "
              "sensor: "
              "laboratory tests and calibration)")


def _reference_arrays(estimate: xr.Dataset, reference) -> dict:
    if reference is None:
        missing = [f"{a}_cmd" for a in ANGLES if f"{a}_cmd" not in estimate.variables]
        if missing:
            raise SchemaError(
                "estimate", f"no coordinates {missing}", "commanded angles alpha_cmd, beta_cmd",
                "predict from a centroid table with alpha/beta coordinates, or pass reference=",
            )
        return {a: estimate[f"{a}_cmd"] for a in ANGLES}
    if isinstance(reference, (xr.Dataset, Mapping)):
        try:
            return {a: reference[a] for a in ANGLES}
        except KeyError as err:
            raise SchemaError("reference", f"keys {list(reference.keys())}",
                              "a mapping with 'alpha' and 'beta' (deg)",
                              "e.g. {'alpha': cube.true_alpha, 'beta': cube.true_beta}") from err
    raise SchemaError("reference", type(reference).__name__,
                      "None (commanded angles) or a mapping with 'alpha' and 'beta'")


def shot_errors(estimate: xr.Dataset, reference=None, *, absolute: bool = True) -> xr.Dataset:
    """Per-shot error of the estimated angles, degrees.

    Parameters
    ----------
    estimate : xarray.Dataset
        Output of :meth:`sunlab.calibration.Calibration.predict`: ``alpha``, ``beta`` (deg), and
        optionally ``status`` and the commanded angles ``alpha_cmd``, ``beta_cmd``.
    reference : mapping, optional
        The measured angles ``{"alpha": ..., "beta": ...}`` (DataArrays broadcasting against the
        estimate, deg). Default: the commanded angles ``alpha_cmd``, ``beta_cmd``.
    absolute : bool
        ``|reference - estimate|`` (the paper) or the signed ``estimate - reference``.

    Returns
    -------
    xarray.Dataset
        ``alpha``, ``beta`` errors (deg) on the estimate's dims; NaN where the status is not
        usable (``ok`` or ``repaired``).

    Examples
    --------
    >>> est = xr.Dataset({"alpha": ("shot", [1.0, 3.0]), "beta": ("shot", [0.0, 1.0])})
    >>> shot_errors(est, {"alpha": xr.DataArray(2.0), "beta": xr.DataArray(0.0)},
    ...             absolute=False).alpha.values.tolist()
    [-1.0, 1.0]
    """
    ref = _reference_arrays(estimate, reference)
    out = {}
    for a in ANGLES:
        e = estimate[a] - ref[a]
        if absolute:
            e = abs(e)
        if "status" in estimate.variables:
            usable = [STATUS[k] for k in USABLE_STATUS]
            e = e.where(estimate["status"].isin(usable))
        out[a] = e.assign_attrs(units="deg", long_name=f"{'absolute ' if absolute else ''}"
                                                       f"error of {a}")
    return xr.Dataset(out, attrs=dict(estimate.attrs))


def local_errors(estimate: xr.Dataset, reference=None, *, dim: str = "shot") -> xr.Dataset:
    """Local (mean over shots) and maximum (max over shots) absolute error per pose.

    Parameters
    ----------
    estimate : xarray.Dataset
        Output of :meth:`sunlab.calibration.Calibration.predict`.
    reference : mapping, optional
        See :func:`shot_errors`; default the commanded angles.
    dim : str
        The dimension to reduce (the shots).

    Returns
    -------
    xarray.Dataset
        ``local_error`` and ``max_error`` (deg) on ``(angle, pose)`` (plus any other dims),
        ``n_shots`` (usable shots per pose), coordinate ``angle`` = ``["alpha", "beta"]`` and the
        pose coordinates of the estimate (e.g. ``alpha_cmd``, ``beta_cmd``). NaN for a pose
        without a usable shot.

    Examples
    --------
    >>> est = xr.Dataset({"alpha": (("pose", "shot"), [[0.1, -0.3]]),
    ...                   "beta": (("pose", "shot"), [[0.2, np.nan]])},
    ...                  coords={"alpha_cmd": ("pose", [0.0]), "beta_cmd": ("pose", [0.0])})
    >>> loc = local_errors(est)
    >>> loc.local_error.values.round(6).tolist(), loc.max_error.values.round(6).tolist()
    ([[0.2], [0.2]], [[0.3], [0.2]])
    """
    err = shot_errors(estimate, reference)
    if dim not in err.dims:
        raise SchemaError("estimate.dims", tuple(err.dims), f"a {dim!r} dimension to reduce")
    e = xr.concat([err[a] for a in ANGLES], dim=pd.Index(list(ANGLES), name="angle"))
    valid = e.notnull()
    n = valid.sum(dim)
    local = e.fillna(0.0).sum(dim) / n.where(n > 0)
    maximum = e.fillna(-np.inf).max(dim).where(n > 0)
    ds = xr.Dataset(
        {
            "local_error": local.assign_attrs(units="deg", long_name="local error (mean over "
                                              "shots of |measured - estimated|)"),
            "max_error": maximum.assign_attrs(units="deg", long_name="maximum error over shots"),
            "n_shots": n.assign_attrs(long_name="usable shots"),
        },
        attrs={k: v for k, v in estimate.attrs.items() if isinstance(v, str)},
    )
    return ds


def _column(local: xr.Dataset, ddof: int) -> dict:
    out = {}
    for a in ANGLES:
        for stat, var in (("mu", "local_error"), ("sigma", "local_error"),
                          ("M", "max_error"), ("sigma_M", "max_error")):
            v = np.asarray(local[var].sel(angle=a).values, dtype=float).ravel()
            v = v[np.isfinite(v)]
            if v.size <= (ddof if stat.startswith("sigma") else 0):
                out[(a, stat)] = np.nan
            elif stat in ("mu", "M"):
                out[(a, stat)] = float(v.mean())
            else:
                out[(a, stat)] = float(v.std(ddof=ddof))
    return out


def global_stats(local, *, ddof: int = 1) -> pd.DataFrame:
    """Global statistics mu, sigma, M, sigma_M per angle, laid out like the paper's Table 4.

    Parameters
    ----------
    local : xarray.Dataset or mapping of str to xarray.Dataset
        Output of :func:`local_errors`, or several keyed by method name (the columns).
    ddof : int
        Delta degrees of freedom of the standard deviations (1: sample standard deviation).

    Returns
    -------
    pandas.DataFrame
        Index ``(angle, stat)`` with angle in ``("alpha", "beta")`` and stat in
        ``("mu", "sigma", "M", "sigma_M")``; one column per method; degrees.

    Examples
    --------
    >>> loc = xr.Dataset({"local_error": (("angle", "pose"), [[1.0, 3.0], [2.0, 2.0]]),
    ...                   "max_error": (("angle", "pose"), [[2.0, 4.0], [3.0, 5.0]])},
    ...                  coords={"angle": ["alpha", "beta"]})
    >>> global_stats({"m": loc})["m"].round(4).tolist()
    [2.0, 1.4142, 3.0, 1.4142, 2.0, 0.0, 4.0, 1.4142]
    """
    if isinstance(local, xr.Dataset):
        local = {str(local.attrs.get("label") or local.attrs.get("calibration") or "method"):
                 local}
    if not isinstance(local, Mapping) or not local:
        raise ConfigurationError(
            f"local: found {type(local).__name__}, expected a local_errors() dataset or a "
            "non-empty mapping of method name to such datasets"
        )
    cols = {}
    for name, ds in local.items():
        for var in ("local_error", "max_error"):
            if var not in ds.variables or "angle" not in ds[var].dims:
                raise SchemaError(f"{name}.{var}", "missing", "output of sunlab.stats."
                                  "local_errors", "call local_errors(estimate) first")
        cols[str(name)] = _column(ds, ddof)
    index = pd.MultiIndex.from_product([ANGLES, STATS], names=["angle", "stat"])
    return pd.DataFrame(cols, index=index)


def evaluate(calibration, table: xr.Dataset, *, ddof: int = 1, return_errors: bool = False):
    """The paper's global statistics of a calibration on a test table (Table 4's column).

    The calibration estimates the angles of every centroid of ``table``; each is compared with
    the table's commanded angles: per pose the local error (mean over the ok shots) and the
    maximum error (:func:`local_errors`, eq. (6)), then mu, sigma, M, sigma_M per angle
    (:func:`global_stats`).

    Parameters
    ----------
    calibration : sunlab.calibration.Calibration
        A fitted (or loaded) calibration.
    table : xarray.Dataset
        ``centroids/1`` test table on (pose, shot) with the commanded angles ``alpha``,
        ``beta`` (deg) as coordinates (experiment III in the paper).
    ddof : int
        Delta degrees of freedom of the standard deviations.
    return_errors : bool
        Also return the estimate (``calibration.predict(table)``) and the per-pose errors.

    Returns
    -------
    pandas.DataFrame
        Index ``(angle, stat)`` as :func:`paper_table4`; one column, the calibration's label;
        degrees. With ``return_errors``: ``(table, estimate, local)``.

    Examples
    --------
    >>> from sunlab import sim
    >>> from sunlab.calibration import Polynomial
    >>> a, b = np.meshgrid(np.arange(-4.0, 5.0), np.arange(-4.0, 5.0), indexing="ij")
    >>> train = sim.synthetic_centroids(a.ravel(), b.ravel(), shots=2, noise_px=0.02, seed=1)
    >>> test = sim.synthetic_centroids(a.ravel(), b.ravel(), shots=2, noise_px=0.02, seed=2)
    >>> res = evaluate(Polynomial(order=3).fit(train), test)
    >>> res.index.equals(paper_table4().index), list(res.columns)
    (True, ['polynomial(3)'])
    >>> bool(res.loc[("alpha", "mu")].iloc[0] < 0.01)
    True
    """
    estimate = calibration.predict(table)
    local = local_errors(estimate)
    frame = global_stats({calibration.label: local}, ddof=ddof)
    return (frame, estimate, local) if return_errors else frame


def error_summary(est: xr.Dataset) -> dict:
    """The paper's global statistics of one estimate as a dict per angle, plus the RMS.

    Local error = mean over the shots of ``|error|``, maximum error = max over the shots; mu and
    sigma are the mean and (sample) standard deviation of the local errors over the poses, M and
    sigma_M those of the maximum errors (docs/paper.md sec. 5), computed by :func:`global_stats`
    (the table of several estimates side by side; this is one estimate's column as a dict).
    ``rms`` is the root mean square of the per-shot errors and ``n_poses`` the number of poses
    with at least one usable estimate. A hole never seen (no usable estimate: off the detector
    over the whole plan, or left without a calibration) gives NaN statistics with
    ``n_poses = 0``, not a warning.

    Parameters
    ----------
    est : xarray.Dataset
        Estimates ``alpha``, ``beta`` on (pose, shot) with the commanded angles ``alpha_cmd``,
        ``beta_cmd`` as coordinates (the strategies' output), or signed errors (no ``*_cmd``).

    Returns
    -------
    dict
        Per angle (``"alpha"``, ``"beta"``) a dict of ``mu``, ``sigma``, ``M``, ``sigma_M`` and
        ``rms`` (deg, float) and ``n_poses`` (int).

    Examples
    --------
    >>> e = xr.Dataset({"alpha": (("pose", "shot"), [[0.1, -0.3], [0.2, 0.2]]),
    ...                 "beta": (("pose", "shot"), [[0.0, 0.0], [0.0, 0.0]])})
    >>> s = error_summary(e)
    >>> round(s["alpha"]["mu"], 6), round(s["alpha"]["M"], 6), s["alpha"]["n_poses"]
    (0.2, 0.25, 2)
    >>> error_summary(e * np.nan)["beta"]["n_poses"]                   # a hole never seen
    0
    """
    ref = None
    if "alpha_cmd" not in est.variables or "beta_cmd" not in est.variables:
        ref = {"alpha": xr.DataArray(0.0), "beta": xr.DataArray(0.0)}
    loc = local_errors(est[["alpha", "beta"]], ref)
    table = global_stats({"m": loc})["m"]
    err = shot_errors(est[["alpha", "beta"]], ref)
    out = {}
    for name in ("alpha", "beta"):
        e = np.asarray(err[name].values, dtype=float)
        e = e[np.isfinite(e)]
        n_poses = int(np.isfinite(loc["local_error"].sel(angle=name).values).sum())
        out[name] = {k: float(table.loc[(name, k)]) if n_poses else math.nan
                     for k in STATS}
        out[name]["rms"] = float(np.sqrt(np.mean(e**2))) if e.size else math.nan
        out[name]["n_poses"] = n_poses
    return out


def rectangles(table: pd.DataFrame) -> pd.DataFrame:
    """The error rectangles of Fig. 12: ``[M - 3 sigma_M, M + 3 sigma_M]`` per angle and method.

    Parameters
    ----------
    table : pandas.DataFrame
        Output of :func:`global_stats` (or :func:`paper_table4`).

    Returns
    -------
    pandas.DataFrame
        One row per method: ``alpha_low``, ``alpha_high``, ``beta_low``, ``beta_high`` (deg)
        and ``area`` = :math:`36\\,\\sigma_{M,\\alpha}\\sigma_{M,\\beta}` (deg^2).

    Examples
    --------
    >>> r = rectangles(paper_table4())
    >>> r.loc["polynomial", "alpha_high"].round(4), r["area"].idxmin()
    (np.float64(0.0261), 'NN strategy 4')
    """
    rows = {}
    for method in table.columns:
        col = table[method]
        row = {}
        for a in ANGLES:
            m, s = col[(a, "M")], col[(a, "sigma_M")]
            row[f"{a}_low"], row[f"{a}_high"] = m - 3 * s, m + 3 * s
        row["area"] = ((row["alpha_high"] - row["alpha_low"])
                       * (row["beta_high"] - row["beta_low"]))
        rows[method] = row
    out = pd.DataFrame.from_dict(rows, orient="index")
    out.index.name = "method"
    return out


def unstack_poses(obj, alpha: str = "alpha_cmd", beta: str = "beta_cmd"):
    """Reshape a flat ``pose`` dimension to an (alpha, beta) grid for maps (Fig. 10).

    Parameters
    ----------
    obj : xarray.Dataset or xarray.DataArray
        Anything on ``pose`` with the pose's angles as coordinates.
    alpha, beta : str
        Names of the angle coordinates on ``pose`` (``alpha_cmd``/``beta_cmd`` after a
        prediction, ``alpha``/``beta`` on a centroid table).

    Returns
    -------
    Same type, with ``pose`` replaced by the dims ``alpha`` and ``beta`` (sorted); poses missing
    from a full grid are NaN.

    Examples
    --------
    >>> da = xr.DataArray([1.0, 2.0, 3.0], dims="pose",
    ...                   coords={"alpha_cmd": ("pose", [0.0, 0.0, 1.0]),
    ...                           "beta_cmd": ("pose", [0.0, 1.0, 0.0])})
    >>> unstack_poses(da).values.tolist()
    [[1.0, 2.0], [3.0, nan]]
    """
    for c in (alpha, beta):
        if c not in obj.coords:
            raise SchemaError(f"coords[{c!r}]", "missing", "the pose angles as coordinates",
                              "pass alpha=/beta= naming the pose-angle coordinates")
    obj = obj.drop_vars([c for c in obj.coords if c == "pose"])
    obj = obj.rename({alpha: "alpha", beta: "beta"}) if (alpha, beta) != ("alpha", "beta") \
        else obj
    obj = obj.set_index(pose=["alpha", "beta"]).unstack("pose")
    return obj.sortby("alpha").sortby("beta")


def _table(data: dict, columns: list[str], source: str) -> pd.DataFrame:
    index = pd.MultiIndex.from_product([ANGLES, STATS], names=["angle", "stat"])
    df = pd.DataFrame(data, index=index, columns=columns)
    df.attrs["source"] = source
    df.attrs["units"] = "deg"
    return df


#: The paper's Table 4 column of each calibration kind it reports (:func:`paper_table4`).
PAPER_COLUMNS = {"polynomial": "polynomial", "interpolation-linear": "linear interp.",
                 "interpolation-cubic": "cubic interp.", "neural": "NN strategy 4"}


def paper_table4() -> pd.DataFrame:
    """The paper's Table 4: global statistics on experiment III, one hole, deg.

    Columns ``linear interp.``, ``cubic interp.``, ``polynomial``, ``NN strategy 4``; index
    ``(angle, stat)`` as :func:`global_stats`. Source: docs/paper.md sec. 5, Table 4.

    Returns
    -------
    pandas.DataFrame
        8 rows (alpha and beta by mu, sigma, M, sigma_M) by 4 methods, deg; ``attrs`` name the
        ``source`` and the ``units``.

    Examples
    --------
    >>> paper_table4().loc[("beta", "mu"), "NN strategy 4"]
    np.float64(0.0108)
    """
    data = {
        "linear interp.": [0.0100, 0.0060, 0.0110, 0.0061, 0.0233, 0.0112, 0.0242, 0.0112],
        "cubic interp.": [0.0115, 0.0100, 0.0125, 0.0101, 0.0236, 0.0152, 0.0245, 0.0152],
        "polynomial": [0.0089, 0.0053, 0.0099, 0.0054, 0.0169, 0.0080, 0.0178, 0.0080],
        "NN strategy 4": [0.0143, 0.0049, 0.0154, 0.0050, 0.0108, 0.0084, 0.0118, 0.0084],
    }
    return _table(data, list(data), _REFERENCE + ", Table 4")


def paper_table5() -> pd.DataFrame:
    """The paper's Table 5: polynomial calibration, 100 holes vs one hole, deg.

    Columns ``100 holes: geometric centre``, ``100 holes: averaging``, ``1 hole``. Source:
    docs/paper.md sec. 6, Table 5.

    Returns
    -------
    pandas.DataFrame
        8 rows (alpha and beta by mu, sigma, M, sigma_M) by 3 columns, deg; ``attrs`` name the
        ``source`` and the ``units``.

    Examples
    --------
    >>> paper_table5().loc[("alpha", "mu")].tolist()
    [0.0041, 0.0045, 0.0089]
    """
    data = {
        "100 holes: geometric centre": [0.0041, 0.0028, 0.0054, 0.0033,
                                        0.0313, 0.0212, 0.0330, 0.0214],
        "100 holes: averaging": [0.0045, 0.0029, 0.0059, 0.0033,
                                 0.0404, 0.0246, 0.0423, 0.0247],
        "1 hole": [0.0089, 0.0053, 0.0099, 0.0054, 0.0169, 0.0080, 0.0178, 0.0080],
    }
    return _table(data, list(data), _REFERENCE + ", Table 5")


def side_by_side(ours: pd.DataFrame, paper: pd.DataFrame,
                 names: tuple[str, str] = ("sunlab", "paper")) -> pd.DataFrame:
    """Put our table beside the paper's: columns ``(method, source)`` for the common methods.

    Parameters
    ----------
    ours, paper : pandas.DataFrame
        Tables with the index of :func:`global_stats` and one column per method (deg).
    names : (str, str)
        The ``source`` labels of ``ours`` and ``paper``.

    Returns
    -------
    pandas.DataFrame
        The methods of ``ours`` that ``paper`` has too, in ``ours``' order, each as two columns
        ``(method, names[0])``, ``(method, names[1])``; the index aligned as pandas does.

    Raises
    ------
    ConfigurationError
        The tables share no method.

    Examples
    --------
    >>> t = side_by_side(paper_table4()[["polynomial"]], paper_table4())
    >>> list(t.columns)
    [('polynomial', 'sunlab'), ('polynomial', 'paper')]
    """
    common = [c for c in ours.columns if c in paper.columns]
    if not common:
        raise ConfigurationError(
            f"columns: ours {list(ours.columns)} and the paper's {list(paper.columns)} share no "
            "method. Fix: rename our columns to the paper's labels"
        )
    parts = {(c, names[0]): ours[c] for c in common}
    out = pd.DataFrame({k: v for c in common for k, v in
                        (((c, names[0]), parts[(c, names[0])]), ((c, names[1]), paper[c]))})
    out.columns = pd.MultiIndex.from_tuples(out.columns, names=["method", "source"])
    return out
