"""The paper's figures of calibration accuracy as functions returning matplotlib Figures.

- :func:`error_maps` — Fig. 10: maps of the local statistics over the field of view;
- :func:`error_histogram` — Fig. 11: histogram of an angle's error with a normal fit;
- :func:`error_rectangles` — Fig. 12: the [M - 3 sigma_M, M + 3 sigma_M] rectangles of the
  methods.

Figures are built with :class:`matplotlib.figure.Figure` (no pyplot state, no GUI): they display
as cell outputs in Jupyter and save with ``fig.savefig(path)``.

Examples
--------
>>> from sunlab import stats
>>> fig = error_rectangles(stats.paper_table4())
>>> len(fig.axes[0].patches)
4
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import xarray as xr
from matplotlib.figure import Figure
from matplotlib.patches import Rectangle

from ._errors import ConfigurationError
from .stats import ANGLES, rectangles, unstack_poses

__all__ = ["error_maps", "error_histogram", "error_rectangles"]

_LABELS = {"local_error": "local error", "max_error": "maximum error"}


def error_maps(local: xr.Dataset, *, variables=("local_error", "max_error"), angles=ANGLES,
               title: str | None = None, cmap: str = "viridis") -> Figure:
    """Fig. 10: maps of local statistics over the field of view.

    Parameters
    ----------
    local : xarray.Dataset
        Output of :func:`sunlab.stats.local_errors` with the pose angles ``alpha_cmd``,
        ``beta_cmd`` as coordinates; poses are unstacked to an (alpha, beta) grid.
    variables : sequence of str
        Rows of the figure (``local_error``, ``max_error``).
    angles : sequence of str
        Columns of the figure (``alpha``, ``beta``).
    title : str, optional
        Figure title.
    cmap : str
        Colour map.

    Returns
    -------
    matplotlib.figure.Figure
        One panel per (variable, angle), colour in deg, commanded alpha on x, beta on y.

    Examples
    --------
    >>> import numpy as np, xarray as xr
    >>> a, b = np.meshgrid([0.0, 1.0], [0.0, 1.0, 2.0], indexing="ij")
    >>> loc = xr.Dataset({v: (("angle", "pose"), np.ones((2, 6))) for v in
    ...                   ("local_error", "max_error")}, coords={"angle": ["alpha", "beta"],
    ...                   "alpha_cmd": ("pose", a.ravel()), "beta_cmd": ("pose", b.ravel())})
    >>> len(error_maps(loc).axes)  # 4 panels + 4 colour bars
    8
    """
    grid = unstack_poses(local[list(variables)])
    fig = Figure(figsize=(4.2 * len(angles), 3.4 * len(variables)), layout="constrained")
    axes = fig.subplots(len(variables), len(angles), squeeze=False)
    for i, var in enumerate(variables):
        for j, ang in enumerate(angles):
            ax = axes[i, j]
            da = grid[var].sel(angle=ang).transpose("beta", "alpha")
            mesh = ax.pcolormesh(da["alpha"].values, da["beta"].values,
                                 np.ma.masked_invalid(da.values), shading="nearest", cmap=cmap)
            fig.colorbar(mesh, ax=ax, label="deg")
            ax.set_title(f"{_LABELS.get(var, var)} of {ang}")
            ax.set_xlabel("alpha (deg)")
            ax.set_ylabel("beta (deg)")
            ax.set_aspect("equal")
    if title:
        fig.suptitle(title)
    return fig


def error_histogram(values, *, angle: str = "alpha", variable: str = "local_error",
                    bins="auto", title: str | None = None) -> Figure:
    """Fig. 11: histogram of an angle's error with the normal distribution of the same mean and
    standard deviation.

    Parameters
    ----------
    values : xarray.Dataset or array_like
        A :func:`sunlab.stats.local_errors` dataset (``variable`` of ``angle`` is taken), or the
        errors themselves (deg; e.g. signed per-shot errors from
        :func:`sunlab.stats.shot_errors`).
    angle : str
        Angle to show when ``values`` is a dataset.
    variable : str
        ``local_error`` (the paper) or ``max_error``.
    bins : int or str
        Histogram bins (numpy's rules).
    title : str, optional
        Axes title.

    Returns
    -------
    matplotlib.figure.Figure
        A density histogram and the normal curve N(mu, sigma) (sample standard deviation).

    Examples
    --------
    >>> fig = error_histogram(np.random.default_rng(0).normal(0.01, 0.005, 300))
    >>> len(fig.axes[0].lines), len(fig.axes[0].patches) > 5
    (1, True)
    """
    if isinstance(values, xr.Dataset):
        if variable not in values:
            raise ConfigurationError(f"variable: found {variable!r}, expected one of "
                                     f"{sorted(map(str, values.data_vars))}")
        v = values[variable].sel(angle=angle).values
        xlabel = f"{_LABELS.get(variable, variable)} of {angle} (deg)"
    else:
        v = np.asarray(values, dtype=float)
        xlabel = f"error of {angle} (deg)"
    v = v[np.isfinite(v)].ravel()
    if v.size < 2:
        raise ConfigurationError(f"values: found {v.size} finite errors, expected at least 2")
    mu, sigma = float(v.mean()), float(v.std(ddof=1))
    fig = Figure(figsize=(5.5, 3.8), layout="constrained")
    ax = fig.subplots()
    ax.hist(v, bins=bins, density=True, color="0.75", edgecolor="0.4", label=f"{v.size} values")
    if sigma > 0:
        x = np.linspace(min(v.min(), mu - 4 * sigma), max(v.max(), mu + 4 * sigma), 300)
        pdf = np.exp(-0.5 * ((x - mu) / sigma) ** 2) / (sigma * np.sqrt(2 * np.pi))
        ax.plot(x, pdf, color="C3", label=f"normal fit: mu = {mu:.4f}, sigma = {sigma:.4f}")
    ax.set_xlabel(xlabel)
    ax.set_ylabel("probability density (1/deg)")
    ax.legend(loc="upper right", fontsize="small")
    if title:
        ax.set_title(title)
    return fig


def error_rectangles(table: pd.DataFrame, *, title: str | None = None,
                     colors=None) -> Figure:
    """Fig. 12: one rectangle [M - 3 sigma_M, M + 3 sigma_M] (alpha x beta) per method.

    Parameters
    ----------
    table : pandas.DataFrame
        Global statistics (:func:`sunlab.stats.global_stats`, :func:`sunlab.stats.paper_table4`)
        or their :func:`sunlab.stats.rectangles`.
    title : str, optional
        Axes title.
    colors : sequence, optional
        One matplotlib colour per method.

    Returns
    -------
    matplotlib.figure.Figure
        One :class:`matplotlib.patches.Rectangle` per method (in table order), labelled with
        its area in deg^2; a smaller rectangle is a better method.

    Examples
    --------
    >>> from sunlab import stats
    >>> ax = error_rectangles(stats.paper_table4()).axes[0]
    >>> ax.patches[2].get_label().startswith("polynomial")
    True
    """
    rect = table if "area" in table.columns else rectangles(table)
    fig = Figure(figsize=(5.5, 5.0), layout="constrained")
    ax = fig.subplots()
    for k, (method, r) in enumerate(rect.iterrows()):
        color = colors[k] if colors is not None else f"C{k % 10}"
        ax.add_patch(Rectangle(
            (r["alpha_low"], r["beta_low"]), r["alpha_high"] - r["alpha_low"],
            r["beta_high"] - r["beta_low"], fill=False, edgecolor=color, linewidth=1.8,
            label=f"{method} (area {r['area']:.2e} deg$^2$)",
        ))
    lo = min(rect["alpha_low"].min(), rect["beta_low"].min())
    hi = max(rect["alpha_high"].max(), rect["beta_high"].max())
    pad = 0.05 * (hi - lo) if hi > lo else 1.0
    ax.set_xlim(rect["alpha_low"].min() - pad, rect["alpha_high"].max() + pad)
    ax.set_ylim(rect["beta_low"].min() - pad, rect["beta_high"].max() + pad)
    ax.axhline(0.0, color="0.8", linewidth=0.8)
    ax.axvline(0.0, color="0.8", linewidth=0.8)
    ax.set_xlabel("alpha error interval (deg)")
    ax.set_ylabel("beta error interval (deg)")
    ax.legend(loc="upper left", fontsize="small")
    if title:
        ax.set_title(title)
    return fig
