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
>>> table, _, loc = evaluate({"demo": est}, return_errors=True)
>>> np.round(loc["demo"].local_error.sel(angle="alpha").values, 6).tolist()
[0.1, 0.1]
>>> table.loc[("alpha", "M"), "demo"].round(6)
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

__all__ = ["evaluate"]

ANGLES = ("alpha", "beta")
#: Row labels of the global statistics, in the paper's order (Table 4).
STATS = ("mu", "sigma", "M", "sigma_M")

_REFERENCE = ("docs/paper.md sec. 5, Tables 4 and 5 (the 2005 preprint on the Naples APS sun "
              "sensor: "
              "laboratory tests and calibration)")


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
    if reference is None:
        missing = [f"{a}_cmd" for a in ANGLES if f"{a}_cmd" not in estimate.variables]
        if missing:
            raise SchemaError(
                "estimate", f"no coordinates {missing}", "commanded angles alpha_cmd, beta_cmd",
                "predict from a centroid table with alpha/beta coordinates, or pass reference=",
            )
        reference = {a: estimate[f"{a}_cmd"] for a in ANGLES}
    elif isinstance(reference, (xr.Dataset, Mapping)):
        try:
            reference = {a: reference[a] for a in ANGLES}
        except KeyError as err:
            raise SchemaError("reference", f"keys {list(reference.keys())}",
                              "a mapping with 'alpha' and 'beta' (deg)",
                              "e.g. {'alpha': cube.true_alpha, 'beta': cube.true_beta}") from err
    else:
        raise SchemaError("reference", type(reference).__name__,
                          "None (commanded angles) or a mapping with 'alpha' and 'beta'")
    out = {}
    for a in ANGLES:
        e = estimate[a] - reference[a]
        if absolute:
            e = abs(e)
        if "status" in estimate.variables:
            usable = [STATUS[k] for k in USABLE_STATUS]
            e = e.where(estimate["status"].isin(usable))
        out[a] = e.assign_attrs(units="deg", long_name=f"{'absolute ' if absolute else ''}"
                                                       f"error of {a}")
    return xr.Dataset(out, attrs=dict(estimate.attrs))


def _local_errors(estimate: xr.Dataset, reference=None) -> xr.Dataset:
    """``local_error`` (mean over the shots of the absolute error) and ``max_error`` per pose
    and angle (deg, NaN for a pose without a usable shot), and ``n_shots``."""
    err = shot_errors(estimate, reference)
    dim = "shot"  # the shots of a pose are averaged
    if dim not in err.dims:
        raise SchemaError("estimate.dims", tuple(err.dims), f"a {dim!r} dimension to reduce")
    e = xr.concat([err[a] for a in ANGLES], dim=pd.Index(list(ANGLES), name="angle"))
    n = e.notnull().sum(dim)
    return xr.Dataset(
        {"local_error": (e.fillna(0.0).sum(dim) / n.where(n > 0)).assign_attrs(
            units="deg", long_name="local error (mean over shots of |measured - estimated|)"),
         "max_error": e.fillna(-np.inf).max(dim).where(n > 0).assign_attrs(
             units="deg", long_name="maximum error over shots"),
         "n_shots": n.assign_attrs(long_name="usable shots")},
        attrs={k: v for k, v in estimate.attrs.items() if isinstance(v, str)})


def _global_stats(local: Mapping, ddof: int = 1) -> pd.DataFrame:
    """mu, sigma (of the local errors over the poses), M, sigma_M (of the maximum errors) per
    angle: index ``(angle, stat)``, one column per entry of ``local``."""
    cols = {}
    for name, ds in local.items():
        col = {}
        for a in ANGLES:
            for stat, var in (("mu", "local_error"), ("sigma", "local_error"),
                              ("M", "max_error"), ("sigma_M", "max_error")):
                v = np.asarray(ds[var].sel(angle=a).values, dtype=float).ravel()
                v = v[np.isfinite(v)]
                sigma = stat.startswith("sigma")
                col[(a, stat)] = (np.nan if v.size <= (ddof if sigma else 0)
                                  else float(v.std(ddof=ddof) if sigma else v.mean()))
        cols[str(name)] = col
    return pd.DataFrame(cols, index=pd.MultiIndex.from_product([ANGLES, STATS],
                                                               names=["angle", "stat"]))


def evaluate(calibration, table: xr.Dataset | None = None, *, reference=None, ddof: int = 1,
             return_errors: bool = False):
    """The paper's global statistics (Table 4's columns): the one way to score a calibration.

    Each calibration estimates the angles of every centroid of ``table`` (or the estimate is
    given); each shot's estimate is compared with the reference (the commanded angles): per pose
    the local error (mean over the usable shots of the absolute error) and the maximum error,
    then over the poses mu, sigma (mean and standard deviation of the local errors), M and
    sigma_M (of the maximum errors), per angle (docs/paper.md sec. 5). Poses without a usable
    shot are left out.

    Parameters
    ----------
    calibration : Calibration, xarray.Dataset or mapping
        A fitted (or loaded) calibration, an estimate (its ``predict``'s output: ``alpha``,
        ``beta`` in deg, ``status``, the commanded ``alpha_cmd``, ``beta_cmd``), or a mapping
        of column name to either (one column each).
    table : xarray.Dataset, optional
        ``centroids/1`` test table on (pose, shot) with the commanded angles ``alpha``, ``beta``
        (deg) as coordinates (experiment III), which the calibrations predict.
    reference : mapping, optional
        The measured angles ``{"alpha": ..., "beta": ...}`` (deg, broadcasting against the
        estimate), e.g. the simulated truth; default the commanded angles.
    ddof : int
        Delta degrees of freedom of sigma and sigma_M (1: the sample standard deviation; the
        paper does not say which it used, 0.14 % apart for 361 poses).
    return_errors : bool
        Also return the estimate(s) and the per-pose errors: ``local_error``, ``max_error``
        (deg) and ``n_shots`` on ``(angle, pose)`` (what Figs. 10 and 11 draw).

    Returns
    -------
    pandas.DataFrame
        Index ``(angle, stat)`` as :func:`paper_table4`; one column per calibration (its label,
        or the mapping's key); degrees. With ``return_errors``: ``(table, estimate, local)``,
        the last two dicts by column for a mapping.

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
    single = isinstance(calibration, xr.Dataset) or not isinstance(calibration, Mapping)
    items = {None: calibration} if single else dict(calibration)
    if not items:
        raise ConfigurationError("calibration: found an empty mapping, expected calibrations or "
                                 "estimates by column name")
    est, local = {}, {}
    for key, obj in items.items():
        e = obj if isinstance(obj, xr.Dataset) else obj.predict(table)
        name = key if key is not None else (getattr(obj, "label", None) or e.attrs.get("label")
                                            or e.attrs.get("calibration") or "method")
        for a in ANGLES:
            if a not in e.variables:
                raise SchemaError(f"{name}.{a}", "missing", "estimated angles alpha, beta (deg)",
                                  "pass a calibration or its predict() output")
        est[str(name)], local[str(name)] = e, _local_errors(e, reference)
    frame = _global_stats(local, ddof)
    if not return_errors:
        return frame
    return (frame, *(next(iter(d.values())) for d in (est, local))) if single else \
        (frame, est, local)


def error_summary(est: xr.Dataset) -> dict:
    """One estimate's column of :func:`evaluate` as a dict per angle, with the RMS and the
    number of poses: what the multi-hole strategies report per hole.

    A hole never seen (no usable estimate) gives NaN statistics with ``n_poses = 0``.

    Parameters
    ----------
    est : xarray.Dataset
        Estimates ``alpha``, ``beta`` on (pose, shot) with the commanded angles ``alpha_cmd``,
        ``beta_cmd`` as coordinates, or signed errors (no ``*_cmd``).

    Returns
    -------
    dict
        Per angle a dict of ``mu``, ``sigma``, ``M``, ``sigma_M`` and ``rms`` (deg, float) and
        ``n_poses`` (int).

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
    table, _, loc = evaluate({"m": est[["alpha", "beta"]]}, reference=ref, return_errors=True)
    err = shot_errors(est[["alpha", "beta"]], ref)
    out = {}
    for name in ANGLES:
        e = np.asarray(err[name].values, dtype=float)
        e = e[np.isfinite(e)]
        n_poses = int(np.isfinite(loc["m"]["local_error"].sel(angle=name).values).sum())
        out[name] = {k: float(table.loc[(name, k), "m"]) if n_poses else math.nan for k in STATS}
        out[name]["rms"] = float(np.sqrt(np.mean(e**2))) if e.size else math.nan
        out[name]["n_poses"] = n_poses
    return out


def rectangles(table: pd.DataFrame) -> pd.DataFrame:
    """The error rectangles of Fig. 12: ``[M - 3 sigma_M, M + 3 sigma_M]`` per angle and method.

    Parameters
    ----------
    table : pandas.DataFrame
        Output of :func:`evaluate` (or :func:`paper_table4`).

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
    M, s = table.xs("M", level="stat"), table.xs("sigma_M", level="stat")  # angle x method
    out = pd.DataFrame({f"{a}_{side}": M.loc[a] + k * 3 * s.loc[a] for a in ANGLES
                        for side, k in (("low", -1), ("high", 1))}).rename_axis("method")
    out["area"] = ((out["alpha_high"] - out["alpha_low"])
                   * (out["beta_high"] - out["beta_low"]))
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
    ``(angle, stat)`` as :func:`evaluate`. Source: docs/paper.md sec. 5, Table 4.

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
        Tables with the index of :func:`evaluate` and one column per method (deg).
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
    out = pd.concat({(c, n): t[c] for c in common for n, t in zip(names, (ours, paper),
                                                                   strict=True)}, axis=1)
    return out.rename_axis(columns=["method", "source"])
