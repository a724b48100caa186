"""The paper's figures of calibration accuracy (Figs. 10-12) as functions returning Figures.

- :func:`error_maps` — Fig. 10: maps of the local statistics over the field of view;
- :func:`error_histogram` — Fig. 11: histogram of an angle's error with a normal fit;
- :func:`error_rectangles` — Fig. 12: the [M - 3 sigma_M, M + 3 sigma_M] rectangles of the
  methods.

Figures are built without pyplot (no global figure state, no GUI window, nothing to close in a
loop) as :class:`ShownFigure`, a :class:`matplotlib.figure.Figure` that also knows how to show
itself: returned as the last expression of a Jupyter cell (or passed to ``display``) it appears
as a PNG in any kernel, even one where pyplot never drew, which a bare ``Figure`` does not (it
prints ``<Figure size ...>`` there). In scripts it saves with ``fig.savefig(path)`` as usual.

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

from ..errors import ConfigurationError
from ..stats import ANGLES, rectangles, unstack_poses

__all__ = ["error_maps", "error_histogram", "error_rectangles"]

_LABELS = {"local_error": "local error", "max_error": "maximum error"}


class ShownFigure(Figure):
    """A :class:`matplotlib.figure.Figure` that displays as a PNG in Jupyter without pyplot.

    IPython shows a figure as an image only when pyplot's inline backend has registered its
    formatter, which happens once pyplot has drawn something in the kernel; this class adds
    ``_repr_png_`` so the figure shows in a fresh kernel too. Where the inline formatter is
    registered it takes precedence, so the figure is shown once, never twice.

    Examples
    --------
    >>> fig = ShownFigure(figsize=(2, 1.5))
    >>> _ = fig.subplots().plot([0, 1], [0, 1])
    >>> fig._repr_png_()[:8] == b"\\x89PNG\\r\\n\\x1a\\n"
    True
    """

    def _repr_png_(self) -> bytes:
        import io

        buf = io.BytesIO()
        self.savefig(buf, format="png", dpi=self.dpi, bbox_inches="tight",
                     facecolor="white")
        return buf.getvalue()


def new_figure(**kwargs) -> Figure:
    """A new :class:`~sunlab.plots.accuracy.ShownFigure` (keywords as a Figure's).

    The one place where sunlab's figure functions make a figure: no pyplot state, no GUI, shown
    as a PNG when a notebook cell returns it.

    Parameters
    ----------
    **kwargs
        Passed to :class:`matplotlib.figure.Figure` (``figsize`` in inches, ``layout``, ...).

    Returns
    -------
    ShownFigure
        An empty figure, not registered with pyplot.

    Examples
    --------
    >>> fig = new_figure(figsize=(3, 2), layout="constrained")
    >>> isinstance(fig, Figure), fig.get_size_inches().tolist()
    (True, [3.0, 2.0])
    """
    return ShownFigure(**kwargs)


def error_maps(local: xr.Dataset, *, variables=("local_error", "max_error"), angles=ANGLES,
               title: str | None = None, cmap: str = "viridis") -> Figure:
    """Fig. 10: maps of local statistics over the field of view.

    Parameters
    ----------
    local : xarray.Dataset
        The per-pose errors of :func:`sunlab.stats.evaluate` (``return_errors``) with the pose
        angles ``alpha_cmd``, ``beta_cmd`` as coordinates; poses are unstacked to an (alpha,
        beta) grid.
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
    fig = new_figure(figsize=(4.2 * len(angles), 3.4 * len(variables)), layout="constrained")
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
                    bins="auto", title: str | None = None, ax=None) -> Figure:
    """Fig. 11: histogram of an angle's error with the normal distribution of the same mean and
    standard deviation.

    Parameters
    ----------
    values : xarray.Dataset or array_like
        The per-pose errors of :func:`sunlab.stats.evaluate` (``return_errors``; ``variable``
        of ``angle`` is taken), or the errors themselves (deg; e.g. signed per-shot errors from
        :func:`sunlab.stats.shot_errors`).
    angle : str
        Angle to show when ``values`` is a dataset.
    variable : str
        ``local_error`` (the paper) or ``max_error``.
    bins : int or str
        Histogram bins (numpy's rules).
    title : str, optional
        Axes title.
    ax : matplotlib.axes.Axes, optional
        Draw into this axes (one panel of a larger figure) instead of a new figure.

    Returns
    -------
    matplotlib.figure.Figure
        A density histogram and the normal curve N(mu, sigma) (sample standard deviation);
        with ``ax``, the figure that holds it.

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
    ax = ax or new_figure(figsize=(5.5, 3.8), layout="constrained").subplots()
    ax.hist(v, bins=bins, density=True, color="0.75", edgecolor="0.4", label=f"{v.size} values")
    if sigma > 0:
        x = np.linspace(min(v.min(), mu - 4 * sigma), max(v.max(), mu + 4 * sigma), 300)
        pdf = np.exp(-0.5 * ((x - mu) / sigma) ** 2) / (sigma * np.sqrt(2 * np.pi))
        ax.plot(x, pdf, color="C3", label=f"normal fit: mu = {mu:.4f}, sigma = {sigma:.4f}")
    ax.set_xlabel(xlabel)
    ax.set_ylabel("probability density (1/deg)")
    ax.set_ylim(0.0, 1.3 * ax.get_ylim()[1])  # headroom: the legend sits above the bars
    ax.legend(loc="upper right", fontsize="small")
    if title:
        ax.set_title(title)
    return ax.figure


def error_rectangles(table: pd.DataFrame, *, title: str | None = None,
                     colors=None) -> Figure:
    """Fig. 12: one rectangle [M - 3 sigma_M, M + 3 sigma_M] (alpha x beta) per method.

    Parameters
    ----------
    table : pandas.DataFrame
        Global statistics (:func:`sunlab.stats.evaluate`, :func:`sunlab.stats.paper_table4`)
        or their :func:`sunlab.stats.rectangles`.
    title : str, optional
        Axes title.
    colors : sequence, optional
        One matplotlib colour per method.

    Returns
    -------
    matplotlib.figure.Figure
        One :class:`matplotlib.patches.Rectangle` per method (in table order), labelled
        ``"k: method (area ...)"`` with its number k (also written at its corner) and its area
        in deg^2; a smaller rectangle is a better method. The legend sits below the axes;
        coinciding rectangles share a tag (:func:`draw_rectangles`).

    Examples
    --------
    >>> from sunlab import stats
    >>> ax = error_rectangles(stats.paper_table4()).axes[0]
    >>> ax.patches[2].get_label().startswith("3: polynomial")
    True
    """
    rect = table if "area" in table.columns else rectangles(table)
    fig = new_figure(figsize=(5.5, 5.6), layout="constrained")
    ax = fig.subplots()
    boxes = [(str(method), r["alpha_low"], r["alpha_high"], r["beta_low"], r["beta_high"])
             for method, r in rect.iterrows()]
    draw_rectangles(ax, boxes, colors=colors)
    ax.set_xlabel("alpha error interval (deg)")
    ax.set_ylabel("beta error interval (deg)")
    if title:
        ax.set_title(title)
    return ax.figure


def draw_rectangles(ax, boxes, *, colors=None, tol: float = 0.02, legend: bool = True) -> list:
    """Draw error rectangles (Figs. 12 and 15) so that every one stays readable.

    Each rectangle gets a number, written at its upper right corner and in front of its legend
    entry. Rectangles that coincide (every side within ``tol`` of the axis span) share one tag,
    ``"1 = 2 = 3"``, and get different line styles, so a reader sees that they overlap rather
    than that some are missing. The legend goes below the axes, never over a rectangle.

    Parameters
    ----------
    ax : matplotlib.axes.Axes
    boxes : sequence of (str, float, float, float, float)
        ``(label, alpha_low, alpha_high, beta_low, beta_high)`` per rectangle, deg.
    colors : sequence, optional
        One matplotlib colour per rectangle (default the colour cycle).
    tol : float
        Relative tolerance (fraction of the axis span) under which two rectangles coincide.
    legend : bool
        Draw the legend (below the axes).

    Returns
    -------
    list of list of int
        The groups of coinciding rectangles (indices into ``boxes``), one list per tag.

    Examples
    --------
    >>> fig = new_figure()
    >>> ax = fig.subplots()
    >>> draw_rectangles(ax, [("a", 0, 1, 0, 2), ("b", 0, 1.001, 0, 2), ("c", 2, 3, 1, 4)])
    [[0, 1], [2]]
    >>> [t.get_text() for t in ax.texts]
    ['1 = 2', '3']
    """
    from matplotlib.ticker import MaxNLocator

    boxes = [(str(b[0]), *map(float, b[1:])) for b in boxes]
    if not boxes:
        raise ConfigurationError("boxes: no rectangle to draw; pass at least one")
    sides = np.array([b[1:] for b in boxes])
    (lo_a, lo_b), (hi_a, hi_b) = sides[:, [0, 2]].min(axis=0), sides[:, [1, 3]].max(axis=0)
    span_a, span_b = float(hi_a - lo_a) or 1.0, float(hi_b - lo_b) or 1.0
    groups = _coinciding(boxes, span_a, span_b, tol)
    styles = ["-", "--", ":", "-."]
    rank = {k: n for g in groups for n, k in enumerate(g)}  # place within its group
    for k, (label, a0, a1, b0, b1) in enumerate(boxes):  # patches in the order of `boxes`
        color = colors[k] if colors is not None else f"C{k % 10}"
        area = (a1 - a0) * (b1 - b0)
        ax.add_patch(Rectangle(
            (a0, b0), a1 - a0, b1 - b0, fill=False, edgecolor=color,
            linewidth=2.2 if rank[k] == 0 else 1.6, linestyle=styles[rank[k] % len(styles)],
            label=f"{k + 1}: {label} (area {area:.2e} deg$^2$)",
        ))
    pad_a, pad_b = 0.08 * span_a, 0.08 * span_b
    xlim = (lo_a - pad_a, hi_a + 2 * pad_a)
    ylim = (lo_b - pad_b, hi_b + 2 * pad_b)
    _write_tags(ax, boxes, groups, colors, xlim, ylim)
    ax.set_xlim(*xlim)
    ax.set_ylim(*ylim)
    ax.axhline(0.0, color="0.85", linewidth=0.8, zorder=0)
    ax.axvline(0.0, color="0.85", linewidth=0.8, zorder=0)
    ax.xaxis.set_major_locator(MaxNLocator(nbins=5))
    ax.yaxis.set_major_locator(MaxNLocator(nbins=6))
    if legend:
        ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.13), fontsize=8, frameon=False)
    return groups


def _coinciding(boxes, span_a: float, span_b: float, tol: float) -> list[list[int]]:
    """Groups of rectangles whose sides all agree within ``tol`` of the axis spans."""
    groups: list[list[int]] = []

    def distance(b, r):  # largest side difference, in fractions of the axis spans
        return max(abs(np.subtract(b[1:], r[1:])) / (span_a, span_a, span_b, span_b))

    for k, b in enumerate(boxes):
        # join the group whose first rectangle is nearest, if it is within tol
        near = min(groups, key=lambda g: distance(b, boxes[g[0]]), default=None)
        if near is not None and distance(b, boxes[near[0]]) <= tol:
            near.append(k)
        else:
            groups.append([k])
    return groups


def _write_tags(ax, boxes, groups, colors, xlim, ylim) -> None:
    """One tag per group ("1 = 2") at the upper right corner of its first rectangle."""
    placed: list[tuple[float, float]] = []  # tags' corners in axes fractions
    for g in groups:
        _, a0, a1, b0, b1 = boxes[g[0]]
        tag = " = ".join(str(k + 1) for k in g)
        color = colors[g[0]] if colors is not None else f"C{g[0] % 10}"
        # a tag whose corner is close to one already written moves up a line, never on top of it
        fx = (a1 - xlim[0]) / (xlim[1] - xlim[0])
        fy = (b1 - ylim[0]) / (ylim[1] - ylim[0])
        lift = sum(abs(fx - px) < 0.08 and abs(fy - py) < 0.05 for px, py in placed)
        placed.append((fx, fy + 0.045 * lift))
        ax.annotate(tag, (a1, b1), xytext=(2, 2 + 11 * lift), textcoords="offset points",
                    fontsize=9, color=color, fontweight="bold", ha="left", va="bottom")
