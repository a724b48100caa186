"""The paper's figures of the 100-hole mask (Figs. 13-15) and the map of a defect metric.

- :func:`fig13_frame` — Fig. 13: a frame of the mask, its centroids and bad holes marked;
- :func:`fig14_bad_holes` — Fig. 14: close-ups of bad holes' spots beside a good one;
- :func:`fig15_rectangles` — Fig. 15: the [M - 3 sigma_M, M + 3 sigma_M] rectangles of one hole
  and of the 100-hole strategies;
- :func:`plot_metric_map` — the mask's holes coloured by a defect metric.

They draw through pyplot (a notebook cell ending in ``;`` still shows them inline).

Examples
--------
>>> fig = fig13_frame(np.zeros((64, 80)))
>>> fig.axes[0].get_title()
'100-hole mask: one frame (Fig. 13)'
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import xarray as xr

from ..errors import ConfigurationError
from .accuracy import draw_rectangles

__all__ = ["fig13_frame", "fig14_bad_holes", "fig15_rectangles", "plot_metric_map"]


def fig13_frame(frame, cen_frame=None, *, ax=None, bad=None):
    """Fig. 13: a frame of the 100-hole mask, with the centroids and bad holes marked.

    Parameters
    ----------
    frame : array_like, shape (ny, nx)
        One detector frame, DN.
    cen_frame : xarray.Dataset, optional
        The frame's centroids on ``hole`` (``cen.isel(pose=p, shot=s)``).
    ax : matplotlib Axes, optional
    bad : array_like of bool, optional
        Bad holes, circled in red.

    Returns
    -------
    matplotlib.figure.Figure

    Examples
    --------
    >>> fig = fig13_frame(np.zeros((64, 80)))
    >>> fig.axes[0].get_xlabel()
    'x (column), px'
    """
    import matplotlib.pyplot as plt

    fig = ax.figure if ax is not None else plt.figure(figsize=(7, 5.6))
    ax = ax or fig.add_subplot()
    im = ax.imshow(np.asarray(frame), cmap="gray", origin="upper", interpolation="nearest")
    fig.colorbar(im, ax=ax, label="DN", shrink=0.8)
    if cen_frame is not None:
        ax.plot(cen_frame["x"].values, cen_frame["y"].values, "+", color="tab:orange", ms=5,
                label="centroids")
        if bad is not None:
            b = np.asarray(bad, bool)
            ax.plot(cen_frame["x"].values[b], cen_frame["y"].values[b], "o", mfc="none",
                    color="red", ms=14, label="rejected holes")
        ax.legend(loc="lower right", fontsize=8)
    ax.set_xlabel("x (column), px")
    ax.set_ylabel("y (row), px")
    ax.set_title("100-hole mask: one frame (Fig. 13)")
    return fig


def fig14_bad_holes(frame, cen_frame, holes, *, reference=None, half: int = 30, metrics=None):
    """Fig. 14: stamps of bad holes' spots beside a good one.

    Parameters
    ----------
    frame : array_like, shape (ny, nx)
    cen_frame : xarray.Dataset
        Centroids of that frame on ``hole``.
    holes : sequence of int
        The bad holes to show.
    reference : int, optional
        A good hole shown first.
    half : int
        Stamp half-size, px.
    metrics : xarray.Dataset, optional
        Defect metrics, printed under each stamp.

    Returns
    -------
    matplotlib.figure.Figure

    Examples
    --------
    >>> from sunlab.sim import synthetic_centroids
    >>> cen = synthetic_centroids([0.0], [0.0], shots=1, layout="grid").isel(pose=0, shot=0)
    >>> fig = fig14_bad_holes(np.zeros((1024, 1280)), cen, [3, 4], reference=0)
    >>> len(fig.axes)
    3
    """
    import matplotlib.pyplot as plt

    from ..multihole.holes import cutout

    show = ([reference] if reference is not None else []) + [int(h) for h in holes]
    if not show:
        raise ConfigurationError("holes: no hole to show; pass at least one hole index")
    fig, axes = plt.subplots(1, len(show), figsize=(2.6 * len(show), 3.4), squeeze=False,
                             layout="constrained")
    frame = np.asarray(frame)
    stamps = {}
    for h in show:
        x, y = float(cen_frame["x"].values[h]), float(cen_frame["y"].values[h])
        if np.isfinite(x):
            stamps[h] = (*cutout(frame, x, y, half), x, y)
    # one colour scale for every panel, so that a flux deficit shows; its top is a high
    # percentile, not the maximum, so that a hot pixel does not darken the spots
    top = max((np.percentile(st, 99.5) for st, *_ in stamps.values()), default=1.0)
    bottom = min((np.percentile(st, 1.0) for st, *_ in stamps.values()), default=0.0)
    for ax, h in zip(axes[0], show, strict=True):
        if h in stamps:
            st, (x0, y0), x, y = stamps[h]
            ax.imshow(st, cmap="magma", origin="upper", vmin=bottom, vmax=top,
                      extent=(x0 - 0.5, x0 + st.shape[1] - 0.5, y0 + st.shape[0] - 0.5, y0 - 0.5))
            ax.plot(x, y, "+", color="cyan")
        else:
            ax.text(0.5, 0.5, "no spot", ha="center", transform=ax.transAxes)
        title = f"hole {h}" + (" (good)" if h == reference else "")
        if metrics is not None:
            m = metrics.sel(hole=h) if "hole" in metrics.dims else metrics
            bits = [f"{k.replace('_', ' ')} {float(m[k]):.2g}" for k in
                    ("flux_deficit", "ellipticity", "asymmetry", "edge_roughness") if k in m]
            title += "".join(("\n" if n % 2 == 0 else ", ") + b for n, b in enumerate(bits))
        ax.set_title(title, fontsize=8)
        ax.set_xticks([])
        ax.set_yticks([])
    fig.suptitle("Spots of bad holes (Fig. 14)", fontsize=10)  # constrained layout: no overlap
    return fig


def fig15_rectangles(table: Mapping[str, Mapping], *, ax=None):
    """Fig. 15: the paper's rectangles [M - 3 sigma_M, M + 3 sigma_M] in alpha and beta.

    Parameters
    ----------
    table : mapping
        ``{label: {"alpha": {"M": .., "sigma_M": ..}, "beta": {...}}}`` in deg, e.g. the
        ``stats`` of :func:`sunlab.multihole.gain_study` or the columns of
        :func:`sunlab.reproduce.reproduce_table5`.

    Returns
    -------
    matplotlib.figure.Figure

    Examples
    --------
    >>> t = {"1 hole": {"alpha": {"M": 0.0099, "sigma_M": 0.0054},
    ...                 "beta": {"M": 0.0178, "sigma_M": 0.0080}}}
    >>> len(fig15_rectangles(t).axes[0].patches)
    1
    """
    import matplotlib.pyplot as plt

    fig = ax.figure if ax is not None else plt.figure(figsize=(6, 5.8), layout="constrained")
    ax = ax or fig.add_subplot()
    boxes = [(label, s["alpha"]["M"] - 3 * s["alpha"]["sigma_M"],
              s["alpha"]["M"] + 3 * s["alpha"]["sigma_M"],
              s["beta"]["M"] - 3 * s["beta"]["sigma_M"], s["beta"]["M"] + 3 * s["beta"]["sigma_M"])
             for label, s in table.items()]
    # numbered rectangles, a shared tag where they coincide, the legend below the axes
    draw_rectangles(ax, boxes)
    ax.set_xlabel(r"$\alpha$ error, deg: $M \pm 3\sigma_M$")
    ax.set_ylabel(r"$\beta$ error, deg: $M \pm 3\sigma_M$")
    ax.set_title("One hole vs 100 holes (Fig. 15)")
    return fig


def plot_metric_map(metrics: xr.Dataset, name: str, *, bad=None, ax=None):
    """The mask's holes as a map coloured by one defect metric; rejected holes crossed.

    Parameters
    ----------
    metrics : xarray.Dataset
        Defect metrics on ``hole`` (:func:`sunlab.multihole.defect_metrics`); the holes'
        grid places come from ``hole_i``, ``hole_j`` (a square row-major grid without them).
    name : str
        The metric to colour by (a variable of ``metrics``); the colour scale spans its 2nd to
        98th percentile over the holes (:func:`sunlab.multihole.defects.metric_scale`).
    bad : array_like of bool, optional
        One per hole: True draws a red cross on the hole (e.g.
        :func:`sunlab.multihole.reject_bad_holes`).
    ax : matplotlib.axes.Axes, optional
        Where to draw; default a new 4.8 x 4 inch figure.

    Returns
    -------
    matplotlib.figure.Figure
        The figure holding the map (``ax``'s when given), titled ``name``, with a colour bar in
        the metric's units.

    Examples
    --------
    >>> from sunlab.multihole import defect_metrics
    >>> from sunlab.sim import synthetic_centroids
    >>> cen = synthetic_centroids([0.0, 1.0], [0.0, 1.0], shots=1, layout="grid",
    ...                           defects={7: {"flux": 0.4}})
    >>> fig = plot_metric_map(defect_metrics(cen), "flux_deficit")
    >>> fig.axes[0].get_title()
    'flux_deficit'
    """
    import matplotlib.pyplot as plt

    from ..multihole.defects import metric_scale
    from ..multihole.holes import hole_grid

    if name not in metrics:
        raise ConfigurationError(f"name: metric {name!r} not in {list(metrics.data_vars)}")
    i, j, nr, nc = hole_grid(metrics)
    grid = np.full((nr, nc), np.nan)
    grid[i, j] = metrics[name].values
    fig = ax.figure if ax is not None else plt.figure(figsize=(4.8, 4))
    ax = ax or fig.add_subplot()
    lo, hi = metric_scale(metrics[name].values)
    im = ax.imshow(grid, cmap="viridis", origin="upper", vmin=lo, vmax=hi)
    fig.colorbar(im, ax=ax, label=metrics[name].attrs.get("units", ""), extend="both")
    if bad is not None:
        b = np.asarray(bad, bool)
        ax.plot(j[b], i[b], "x", color="red", ms=12, mew=2)
    ax.set_xlabel("hole column j")
    ax.set_ylabel("hole row i")
    ax.set_title(name)
    return fig
