"""Interactive explorers (ipywidgets + matplotlib) for JupyterLab and Voila.

:class:`HoleExplorer` shows the holes of a multi-hole mask as a clickable map coloured by a
defect metric (:data:`sunlab.multihole.DEFECT_METRICS`); selecting a hole shows its spot stamp
at a chosen pose and shot, its metrics and its residual map over the field of view; toggling a
hole in or out of the average updates the global statistics (docs/paper.md sec. 5 and 6) live.

Figures are rendered to PNG and placed in ``ipywidgets.Output`` widgets as display data, which
works the same in a kernel, in Voila and in a plain Python process (tests drive the widgets by
setting ``.value`` and calling ``.click()``).

Examples
--------
>>> from sunlab import multihole as mh
>>> import numpy as np
>>> a = np.repeat(np.linspace(-8, 2, 5), 5); b = np.tile(np.linspace(-2, 8, 5), 5)
>>> cen = mh.synthetic_centroids(a, b, shots=2, noise_px=0.01, defects={7: {"sigma_px": 1.0}})
>>> ex = HoleExplorer(None, cen, order=2)
>>> ex.buttons[7].click()
>>> ex.selected
7
"""

from __future__ import annotations

import base64
import html
import io

import numpy as np
import xarray as xr

from . import multihole as mh
from ._errors import ConfigurationError

__all__ = ["HoleExplorer", "figure_output"]


def _png(fig) -> bytes:
    import matplotlib.pyplot as plt

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=80)
    plt.close(fig)
    return buf.getvalue()


def figure_output(out, fig, text: str = "figure") -> None:
    """Show a matplotlib figure in an ``ipywidgets.Output`` (replacing what it showed).

    The figure is rendered to PNG and set as the Output's display data, so it appears as an
    ``<img>`` in JupyterLab and Voila, and can be inspected in ``out.outputs`` without a kernel.
    The figure is closed.
    """
    data = base64.b64encode(_png(fig)).decode("ascii")
    out.outputs = (
        {"output_type": "display_data", "data": {"image/png": data, "text/plain": text},
         "metadata": {}},
    )


def _text_color(rgb) -> str:
    lum = 0.299 * rgb[0] + 0.587 * rgb[1] + 0.114 * rgb[2]
    return "black" if lum > 0.5 else "white"


class HoleExplorer:
    """Explore the holes of a multi-hole mask: defect map, spot stamps, residuals, live statistics.

    Parameters
    ----------
    cube : xarray.Dataset or None
        Frame cube (contract ``frames/1``) of ``centroids``; gives the spot stamps (None: no
        stamps).
    centroids : xarray.Dataset
        Centroid table on (pose, shot, hole), the experiment whose statistics are shown
        (usually the test experiment III).
    strategy : sunlab.multihole.PerHoleAverage, optional
        Fitted per-hole calibrations. Default: fitted on ``train`` (or on ``centroids`` itself,
        in which case the statistics are training residuals).
    train : xarray.Dataset, optional
        Training centroid table (experiment I) for the calibrations and the defect metrics.
    metrics : xarray.Dataset, optional
        Defect metrics (:func:`sunlab.multihole.defect_metrics`); default computed from
        ``train`` (or ``centroids``) and the strategy.
    order : int
        Polynomial order when the strategy is fitted here.
    metric : str, optional
        Metric colouring the map first (default ``scatter`` when present).
    pose, shot : int
        First pose and shot of the stamp.
    half : int
        Half-size of the stamp, px.

    Attributes
    ----------
    buttons : list of ipywidgets.Button
        One per hole, in a 10 x 10 ``grid`` (GridBox); ``click()`` selects the hole.
    metric : ipywidgets.Dropdown
        The metric colouring the map.
    include : ipywidgets.ToggleButton
        Whether the selected hole is in the average.
    reject, include_all : ipywidgets.Button
        Apply the automatic bad-hole rejection / put every hole back.
    pose, shot : ipywidgets.IntSlider
        Frame of the stamp.
    stamp_out, residual_out : ipywidgets.Output
        The selected hole's stamp and residual map (PNG display data).
    info, stats_html : ipywidgets.HTML
        The selected hole's metrics; the global statistics table.
    included : numpy.ndarray of bool
        Holes in the average.
    stats : dict
        Current global statistics: ``{"included": ..., "all": ..., "hole": ...}`` as returned
        by :func:`sunlab.multihole.global_stats`.
    ui : ipywidgets.VBox
        The whole explorer (displayed when the object is the last expression of a cell).
    """

    def __init__(self, cube, centroids: xr.Dataset, *, strategy=None, train=None, metrics=None,
                 order: int = 5, metric: str | None = None, pose: int = 0, shot: int = 0,
                 half: int = 30):
        import ipywidgets as w

        if "hole" not in centroids.dims:
            raise ConfigurationError(
                "centroids: found dims " f"{tuple(centroids.dims)}, expected (pose, shot, hole); "
                "centroid the cube with a multi-spot method"
            )
        self.cube = cube
        self.centroids = centroids
        self.half = int(half)
        base = train if train is not None else centroids
        self.strategy = strategy or mh.PerHoleAverage(order=order).fit(base)
        self.metrics = metrics if metrics is not None else mh.defect_metrics(
            base, strategy=self.strategy)
        self.flagged = mh.reject_bad_holes(self.metrics).values
        self.estimates = self.strategy.predict_holes(centroids)
        self._i, self._j, nr, nc = mh.hole_grid(centroids)
        n_h = centroids.sizes["hole"]
        self.included = np.ones(n_h, dtype=bool)
        self.selected = 0
        self._frame_cache: dict = {}
        self._all_stats = mh.global_stats(self.strategy.combine(self.estimates,
                                                                holes=np.ones(n_h, bool)))

        names = list(self.metrics.data_vars)
        if metric is None:
            metric = "scatter" if "scatter" in names else names[0]
        if metric not in names:
            raise ConfigurationError(f"metric: found {metric!r}, expected one of {names}")
        self.metric = w.Dropdown(options=names, value=metric, description="colour by")
        self.buttons = []
        for h in range(n_h):
            b = w.Button(description=str(h), layout=w.Layout(width="42px", height="30px",
                                                             padding="0px"))
            b.hole = h
            b.on_click(lambda btn: self.select(btn.hole))
            self.buttons.append(b)
        order_ = np.lexsort((self._j, self._i))  # row-major placement on the grid
        self.grid = w.GridBox(
            [self.buttons[h] for h in order_],
            layout=w.Layout(grid_template_columns=f"repeat({nc}, 44px)", grid_gap="2px",
                            width=f"{46 * nc}px", overflow="visible"),
        )
        self.colorbar = w.HTML()
        self.include = w.ToggleButton(value=True, description="in the average",
                                      icon="check", tooltip="toggle the selected hole")
        self.reject = w.Button(description="reject flagged holes", button_style="warning")
        self.include_all = w.Button(description="include all holes")
        n_p, n_s = centroids.sizes["pose"], centroids.sizes["shot"]
        self.pose = w.IntSlider(value=int(pose), min=0, max=n_p - 1, description="pose")
        self.shot = w.IntSlider(value=int(shot), min=0, max=n_s - 1, description="shot")
        self.stamp_out = w.Output(layout=w.Layout(min_height="260px"))
        self.residual_out = w.Output(layout=w.Layout(min_height="260px"))
        self.info = w.HTML()
        self.stats_html = w.HTML()

        self.metric.observe(lambda ch: self._paint(), names="value")
        self.include.observe(self._on_include, names="value")
        self.reject.on_click(lambda _: self.set_included(~self.flagged))
        self.include_all.on_click(lambda _: self.set_included(np.ones(n_h, bool)))
        self.pose.observe(lambda ch: self._show_stamp(), names="value")
        self.shot.observe(lambda ch: self._show_stamp(), names="value")

        left = w.VBox([self.metric, self.grid, self.colorbar,
                       w.HBox([self.reject, self.include_all])],
                      layout=w.Layout(min_width=f"{46 * nc + 20}px", flex="0 0 auto"))
        right = w.VBox([w.HBox([self.include, self.info]), self.pose, self.shot,
                        w.HBox([self.stamp_out, self.residual_out])],
                       layout=w.Layout(flex="1 1 auto"))
        self.ui = w.VBox([w.HTML("<b>Holes of the mask</b>: click a hole; colour = defect "
                                 "metric; ✕ = left out of the average"),
                          w.HBox([left, right]), self.stats_html])
        self._paint()
        self.select(self.selected)

    # ---------------------------------------------------------------------- display
    def _repr_mimebundle_(self, **kwargs):
        return self.ui._repr_mimebundle_(**kwargs)

    # ---------------------------------------------------------------------- state changes
    def select(self, hole: int) -> None:
        """Select a hole: show its stamp, metrics and residual map."""
        hole = int(hole)
        if not 0 <= hole < len(self.buttons):
            raise ConfigurationError(f"hole: found {hole}, expected 0 .. {len(self.buttons) - 1}")
        self.selected = hole
        self.include.unobserve(self._on_include, names="value")
        self.include.value = bool(self.included[hole])
        self.include.observe(self._on_include, names="value")
        for h, b in enumerate(self.buttons):
            b.layout.border = "3px solid #d62728" if h == hole else ""
        self._show_info()
        self._show_stamp()
        self._show_residuals()
        self._update_stats()

    def set_included(self, included) -> None:
        """Set which holes enter the average; repaint the map and update the statistics."""
        inc = np.asarray(included, dtype=bool)
        if inc.shape != self.included.shape:
            raise ConfigurationError(f"included: shape {inc.shape}, expected {self.included.shape}")
        self.included = inc.copy()
        self.include.unobserve(self._on_include, names="value")
        self.include.value = bool(self.included[self.selected])
        self.include.observe(self._on_include, names="value")
        self._paint()
        self._update_stats()
        self._show_residuals()

    def _on_include(self, change) -> None:
        inc = self.included.copy()
        inc[self.selected] = bool(change["new"])
        self.set_included(inc)

    # ---------------------------------------------------------------------- drawing
    def _paint(self) -> None:
        import matplotlib as mpl

        v = np.asarray(self.metrics[self.metric.value].values, dtype=float)
        finite = v[np.isfinite(v)]
        lo, hi = (np.percentile(finite, [2, 98]) if finite.size else (0.0, 1.0))
        if hi <= lo:
            hi = lo + 1e-12
        cmap = mpl.colormaps["viridis"]
        for h, b in enumerate(self.buttons):
            if np.isfinite(v[h]):
                rgb = cmap(np.clip((v[h] - lo) / (hi - lo), 0, 1))[:3]
                b.style.button_color = mpl.colors.to_hex(rgb)
                b.style.text_color = _text_color(rgb)
            else:
                b.style.button_color = "#bbbbbb"
                b.style.text_color = "black"
            b.description = str(h) if self.included[h] else "✕"
            b.tooltip = f"hole {h}: {self.metric.value} = {v[h]:.3g}"
        self.colorbar.value = (
            f"<small>{html.escape(self.metric.value)}: dark {lo:.3g} → yellow {hi:.3g}; "
            f"flagged: {np.flatnonzero(self.flagged).tolist()}</small>"
        )

    def _show_info(self) -> None:
        h = self.selected
        rows = "".join(
            f"<tr><td>{html.escape(k)}</td><td>{float(self.metrics[k][h]):.4g}</td></tr>"
            for k in self.metrics.data_vars
        )
        flag = " <b style='color:#d62728'>flagged</b>" if self.flagged[h] else ""
        self.info.value = (f"<b>hole {h}</b> (row {self._i[h]}, column {self._j[h]}){flag}"
                           f"<table>{rows}</table>")

    def _frame(self, p, s):
        key = (p, s)
        if key not in self._frame_cache:
            self._frame_cache.clear()
            self._frame_cache[key] = np.asarray(self.cube["frames"].isel(pose=p, shot=s).values)
        return self._frame_cache[key]

    def _show_stamp(self) -> None:
        import matplotlib.pyplot as plt

        h, p, s = self.selected, int(self.pose.value), int(self.shot.value)
        fig, ax = plt.subplots(figsize=(3.2, 3.0))
        fig.subplots_adjust(left=0.2, right=0.97, bottom=0.15, top=0.9)
        x = float(self.centroids["x"].values[p, s, h])
        y = float(self.centroids["y"].values[p, s, h])
        if self.cube is None:
            ax.text(0.5, 0.5, "no frame cube given", ha="center", transform=ax.transAxes)
        elif not np.isfinite(x):
            ax.text(0.5, 0.5, "no spot in this frame", ha="center", transform=ax.transAxes)
        else:
            st, (x0, y0) = mh._stamp(self._frame(p, s), x, y, self.half)
            ax.imshow(st, cmap="magma", origin="upper",
                      extent=(x0 - 0.5, x0 + st.shape[1] - 0.5, y0 + st.shape[0] - 0.5,
                              y0 - 0.5))
            ax.plot(x, y, "+", color="cyan", ms=10)
        a = float(self.centroids["alpha"].values[p])
        b = float(self.centroids["beta"].values[p])
        ax.set_title(f"hole {h}, pose {p} (α={a:.2f}°, β={b:.2f}°), shot {s}", fontsize=8)
        ax.set_xlabel("x, px")
        ax.set_ylabel("y, px")
        figure_output(self.stamp_out, fig, f"stamp of hole {h}")

    def _combined(self):
        return self.strategy.combine(self.estimates, holes=self.included)

    def _show_residuals(self) -> None:
        import matplotlib.pyplot as plt

        h = self.selected
        comb = self._combined()
        fig, axes = plt.subplots(1, 2, figsize=(6.0, 2.8), sharey=True)
        a_cmd = self.estimates["alpha_cmd"].values
        b_cmd = self.estimates["beta_cmd"].values
        for ax, name in zip(axes, ("alpha", "beta"), strict=True):
            r = (self.estimates[name].isel(hole=h) - comb[name]).mean("shot").values
            lim = np.nanmax(np.abs(r)) if np.isfinite(r).any() else 1.0
            sc = ax.scatter(a_cmd, b_cmd, c=r, cmap="coolwarm", vmin=-lim, vmax=lim, s=18)
            fig.colorbar(sc, ax=ax, shrink=0.8)
            ax.set_title(f"{name}: hole {h} − average, deg", fontsize=8)
            ax.set_xlabel("α, deg")
        axes[0].set_ylabel("β, deg")
        fig.subplots_adjust(left=0.1, right=0.97, bottom=0.17, top=0.9, wspace=0.15)
        figure_output(self.residual_out, fig, f"residual map of hole {h}")

    def _update_stats(self) -> None:
        h = self.selected
        n = int(self.included.sum())
        inc = mh.global_stats(self._combined()) if n else None
        one = mh.global_stats(self.estimates.isel(hole=h))
        self.stats = {"included": inc, "all": self._all_stats, "hole": one}
        cols = [(f"average of {n} included holes", inc),
                (f"average of all {len(self.included)} holes", self._all_stats),
                (f"hole {h} alone", one)]
        head = "".join(f"<th>{html.escape(c)}</th>" for c, _ in cols)
        body = ""
        for a in ("alpha", "beta"):
            for k in ("mu", "sigma", "M", "sigma_M"):
                cells = "".join(
                    f"<td>{s[a][k]:.5f}</td>" if s is not None else "<td>–</td>" for _, s in cols
                )
                body += f"<tr><td>{a}</td><td>{k}</td>{cells}</tr>"
        self.stats_html.value = (
            "<b>Global statistics (deg), per-hole calibration then average</b>"
            f"<table><tr><th>angle</th><th>stat</th>{head}</tr>{body}</table>"
        )
