"""Interactive explorers (ipywidgets + matplotlib) for JupyterLab and Voila.

:class:`HoleExplorer` shows the holes of a multi-hole mask as a clickable map coloured by a
defect metric (``sunlab.multihole.defects.DEFECT_METRICS``), on one colour scale
(:func:`sunlab.multihole.defects.metric_scale`) shown as a colour bar beside it. Holes that the
automatic rejection flags carry a ⚑ and an orange frame from the start; in simulated data the
holes the bench gave defects (``hole_defect``) are underlined, so flagged and injected can be
compared at a glance. Selecting a hole shows its spot close-up at a chosen pose and shot with
its residual maps over the field of view beside it, and its metrics; toggling a hole in or out
of the average updates the global statistics (docs/paper.md sec. 5 and 6) live. "reject flagged
holes" leaves the flagged holes out and keeps the holes left out by hand; only "reset" puts
every hole back.

Figures are rendered to PNG and placed in ``ipywidgets.Output`` widgets as display data, which
works the same in a kernel, in Voila and in a plain Python process (tests drive the widgets by
setting ``.value`` and calling ``.click()``). Everything shown lives in the widgets' state, so a
notebook executed with its widget state saved (Jupyter's default, nbclient's
``store_widget_state``) exports to HTML with the explorer's last view.

Examples
--------
>>> import numpy as np
>>> from sunlab.sim import synthetic_centroids
>>> a = np.repeat(np.linspace(-8, 2, 5), 5); b = np.tile(np.linspace(-2, 8, 5), 5)
>>> cen = synthetic_centroids(a, b, shots=2, layout="grid", noise_px=0.01,
...                           defects={7: {"sigma_px": 1.0}})
>>> ex = HoleExplorer(None, cen, order=2)
>>> ex.buttons[7].click()
>>> ex.selected, ex.buttons[7].description          # hole 7 is flagged from the start
(7, '7⚑')
"""

from __future__ import annotations

import base64
import functools
import html
import io

import numpy as np
import pandas as pd
import xarray as xr

from .errors import ConfigurationError
from .extras import require
from .multihole.defects import metric_scale
from .multihole.holes import cutout
from .multihole.review import HoleReview, review_holes
from .stats import ANGLES

__all__ = ["HoleExplorer"]


def figure_output(out, fig, text: str = "figure") -> None:
    """Show a matplotlib figure in an ``ipywidgets.Output`` (replacing what it showed).

    The figure is rendered to PNG and set as the Output's display data, so it appears as an
    ``<img>`` in JupyterLab and Voila, and can be inspected in ``out.outputs`` without a kernel.
    The figure is closed.

    Parameters
    ----------
    out : ipywidgets.Output
        The output area.
    fig : matplotlib.figure.Figure
        The figure, rendered at 100 dpi.
    text : str
        The plain-text form of the display data (shown where images are not).
    """
    import matplotlib.pyplot as plt

    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=100)
    plt.close(fig)
    data = base64.b64encode(buf.getvalue()).decode("ascii")
    out.outputs = ({"output_type": "display_data", "metadata": {},
                    "data": {"image/png": data, "text/plain": text}},)


class HoleExplorer:
    """Explore the holes of a multi-hole mask: defect map, spot close-ups, residuals, statistics.

    Parameters
    ----------
    cube : xarray.Dataset or None
        Frame cube (contract ``frames/1``) of ``centroids``; gives the spot close-ups (None: no
        close-ups).
    centroids : xarray.Dataset
        Centroid table on (pose, shot, hole), the experiment whose statistics are shown
        (usually the test experiment III).
    review : sunlab.multihole.review.HoleReview, optional
        The per-hole results shown (:func:`sunlab.multihole.review.review_holes` of ``centroids``);
        the explorer is a view over them. Default: reviewed here from the arguments below.
    strategy : sunlab.multihole.PerHoleAverage, optional
        Fitted per-hole calibrations. Default: fitted on ``train`` (or on ``centroids`` itself,
        in which case the statistics are training residuals).
    train : xarray.Dataset, optional
        Training centroid table (experiment I) for the calibrations and the defect metrics.
    metrics : xarray.Dataset, optional
        Defect metrics (:func:`sunlab.multihole.defect_metrics`); default computed from
        ``train`` (or ``centroids``) and the strategy. Pass metrics computed with the training
        frames (``cube=``) to include the edge roughness that finds burred holes.
    order : int
        Polynomial order when the strategy is fitted here.
    metric : str, optional
        Metric colouring the map first (default ``scatter`` when present).
    pose, shot : int
        First pose and shot of the close-up.
    half : int
        Half-size of the close-up, px.
    kappa : float
        Rejection threshold of :func:`sunlab.multihole.reject_bad_holes`.

    Attributes
    ----------
    buttons : list of ipywidgets.Button
        One per hole, in a 10 x 10 ``grid`` (GridBox); ``click()`` selects the hole. The label is
        the hole number, with ⚑ when flagged, or ✕ and the number when left out of the average.
    metric : ipywidgets.Dropdown
        The metric colouring the map.
    include : ipywidgets.ToggleButton
        Whether the selected hole is in the average.
    reject, include_all : ipywidgets.Button
        Leave the flagged holes out (manual exclusions stay) / reset: every hole back in.
    pose, shot : ipywidgets.IntSlider
        Frame of the close-up.
    colorbar_out, stamp_out, residual_out : ipywidgets.Output
        The colour bar of the map, the selected hole's close-up and its residual maps (PNG).
    legend, info, stats_html : ipywidgets.HTML
        Flagged and injected holes; the selected hole's metrics; the global statistics table.
    flagged : numpy.ndarray of bool
        Holes flagged by the automatic rejection.
    injected : dict of int to str
        Holes the simulator gave defects, with their kinds (empty for real data).
    included : numpy.ndarray of bool
        Holes in the average.
    stats : dict
        Current global statistics: ``{"included": ..., "all": ..., "hole": ...}`` as returned
        by :meth:`sunlab.multihole.review.HoleReview.stats` (:func:`sunlab.stats.error_summary`).
    ui : ipywidgets.VBox
        The whole explorer (displayed when the object is the last expression of a cell).
    """

    def __init__(self, cube, centroids: xr.Dataset, *, review: HoleReview | None = None,
                 strategy=None, train=None, metrics=None, order: int = 5,
                 metric: str | None = None, pose: int = 0, shot: int = 0, half: int = 30,
                 kappa: float = 5.0):
        self.review = review or review_holes(centroids, strategy=strategy, train=train,
                                             metrics=metrics, order=order, kappa=kappa)
        self.cube = cube
        self.centroids = centroids
        self.half = int(half)
        r = self.review
        self.strategy, self.metrics, self.estimates = r.strategy, r.metrics, r.estimates
        self.flagged, self.injected = r.flagged, r.injected
        self._i, self._j = r.hole_i, r.hole_j
        self.included = np.ones(r.n_holes, dtype=bool)
        self.selected = 0
        # the frame of the close-up, read once per pose and shot (a lazy cube reads from disk)
        self._frame = functools.lru_cache(maxsize=1)(
            lambda p, s: np.asarray(cube["frames"].isel(pose=p, shot=s).values))
        names = list(self.metrics.data_vars)
        if metric is None:
            metric = "scatter" if "scatter" in names else names[0]
        if metric not in names:
            raise ConfigurationError(f"metric: found {metric!r}, expected one of {names}")
        self._build_widgets(names, metric, pose, shot)
        self._paint()
        self.select(self.selected)

    def _build_widgets(self, names, metric, pose, shot) -> None:
        """The widgets, their callbacks and their layout (:attr:`ui`)."""
        w = require("ipywidgets", purpose="the hole explorer")
        nc = self.review.n_cols
        self.metric = w.Dropdown(options=names, value=metric, description="colour by")
        self.buttons = []
        for h in range(self.review.n_holes):
            b = w.Button(description=str(h), layout=w.Layout(width="46px", height="30px",
                                                             padding="0px"))
            b.hole = h
            b.on_click(lambda btn: self.select(btn.hole))
            self.buttons.append(b)
        order_ = np.lexsort((self._j, self._i))  # row-major placement on the grid
        self.grid = w.GridBox(
            [self.buttons[h] for h in order_],
            layout=w.Layout(grid_template_columns=f"repeat({nc}, 48px)", grid_gap="2px",
                            width=f"{50 * nc}px", overflow="visible"),
        )
        self.colorbar_out = w.Output(layout=w.Layout(width=f"{50 * nc}px", margin="8px 0 0 0"))
        self.legend = w.HTML(layout=w.Layout(width=f"{50 * nc}px"))
        self.include = w.ToggleButton(value=True, description="in the average",
                                      icon="check", tooltip="toggle the selected hole")
        self.reject = w.Button(description="reject flagged holes", button_style="warning",
                               tooltip="leave the flagged holes out; holes left out by hand "
                                       "stay out")
        self.include_all = w.Button(description="reset: include all",
                                    tooltip="put every hole back into the average")
        n_p, n_s = self.centroids.sizes["pose"], self.centroids.sizes["shot"]
        self.pose = w.IntSlider(value=int(pose), min=0, max=n_p - 1, description="pose")
        self.shot = w.IntSlider(value=int(shot), min=0, max=n_s - 1, description="shot")
        self.stamp_out = w.Output(layout=w.Layout(width="330px", min_height="300px"))
        self.residual_out = w.Output(layout=w.Layout(width="560px", min_height="300px"))
        self.info = w.HTML()
        self.stats_html = w.HTML()
        for widget, css in ((self.stamp_out, "sunlab-closeup"),
                            (self.residual_out, "sunlab-residuals"),
                            (self.colorbar_out, "sunlab-colorbar"), (self.info, "sunlab-info")):
            widget.add_class(css)  # stable handles for browser tests and styling
        self.metric.observe(lambda ch: self._paint(), names="value")
        self.include.observe(self._on_include, names="value")
        self.reject.on_click(lambda _: self.set_included(self.included & ~self.flagged))
        self.include_all.on_click(lambda _: self.set_included(np.ones(self.review.n_holes, bool)))
        self.pose.observe(lambda ch: self._show_stamp(), names="value")
        self.shot.observe(lambda ch: self._show_stamp(), names="value")
        left = w.VBox([self.metric, self.grid, self.colorbar_out, self.legend,
                       w.HBox([self.reject, self.include_all])],
                      layout=w.Layout(width=f"{50 * nc + 20}px", flex="0 0 auto"))
        right = w.VBox([w.HBox([self.include, self.pose, self.shot]),
                        w.HBox([self.stamp_out, self.residual_out]), self.info],
                       layout=w.Layout(flex="1 1 auto"))
        self.ui = w.VBox([w.HTML("<b>Holes of the mask</b>: click a hole; colour = defect "
                                 "metric; ⚑ = flagged by the automatic rejection; "
                                 "✕ = left out of the average"
                                 + ("; <u>underlined</u> = defect injected by the simulator"
                                    if self.injected else "")),
                          w.HBox([left, right]), self.stats_html])

    # ---------------------------------------------------------------------- display
    def _repr_mimebundle_(self, **kwargs):
        return self.ui._repr_mimebundle_(**kwargs)

    # ---------------------------------------------------------------------- state changes
    def select(self, hole: int) -> None:
        """Select a hole: show its close-up, residual maps and metrics.

        Parameters
        ----------
        hole : int
            The hole, ``0 .. n_holes - 1``; when it has no spot at the current pose and shot the
            close-up moves to the nearest pose that shows it.

        Raises
        ------
        ConfigurationError
            ``hole`` is out of range.
        """
        hole = int(hole)
        if not 0 <= hole < len(self.buttons):
            raise ConfigurationError(f"hole: found {hole}, expected 0 .. {len(self.buttons) - 1}")
        self.selected = hole
        self._show_included()
        self._borders()
        self._show_info()
        # a hole off the detector at the current frame: go to the nearest pose that shows it
        seen = np.flatnonzero(np.isfinite(self.centroids["x"].values[:, int(self.shot.value),
                                                                       hole]))
        if seen.size and int(self.pose.value) not in seen:
            with self.pose.hold_trait_notifications():
                self.pose.value = int(seen[np.argmin(np.abs(seen - int(self.pose.value)))])
        self._show_stamp()
        self._show_residuals()
        self._update_stats()

    def set_included(self, included) -> None:
        """Set which holes enter the average; repaint the map and update the statistics.

        Parameters
        ----------
        included : array_like of bool, shape (n_holes,)
            True for a hole that enters the average.

        Raises
        ------
        ConfigurationError
            ``included`` has another shape.
        """
        inc = np.asarray(included, dtype=bool)
        if inc.shape != self.included.shape:
            raise ConfigurationError(f"included: shape {inc.shape}, expected {self.included.shape}")
        self.included = inc.copy()
        self._show_included()
        self._paint()
        self._update_stats()
        self._show_residuals()

    def _show_included(self) -> None:
        """The toggle shows whether the selected hole is in the average (without firing)."""
        self.include.unobserve(self._on_include, names="value")
        self.include.value = bool(self.included[self.selected])
        self.include.observe(self._on_include, names="value")

    def _on_include(self, change) -> None:
        inc = self.included.copy()
        inc[self.selected] = bool(change["new"])
        self.set_included(inc)

    # ---------------------------------------------------------------------- drawing
    def _borders(self) -> None:
        for h, b in enumerate(self.buttons):
            if h == self.selected:
                b.layout.border = "3px solid #d62728"
            elif self.flagged[h]:
                b.layout.border = "3px solid #ff7f0e"
            else:
                b.layout.border = ""

    def _paint(self) -> None:
        import matplotlib as mpl

        name = self.metric.value
        v = np.asarray(self.metrics[name].values, dtype=float)
        lo, hi = metric_scale(v)
        cmap = mpl.colormaps["viridis"]
        for h, b in enumerate(self.buttons):
            if np.isfinite(v[h]):
                rgb = cmap(np.clip((v[h] - lo) / (hi - lo), 0, 1))[:3]
                b.style.button_color = mpl.colors.to_hex(rgb)  # text legible on it:
                lum = 0.299 * rgb[0] + 0.587 * rgb[1] + 0.114 * rgb[2]
                b.style.text_color = "black" if lum > 0.5 else "white"
            else:
                b.style.button_color = "#bbbbbb"
                b.style.text_color = "black"
            label = str(h) + ("⚑" if self.flagged[h] else "")
            b.description = label if self.included[h] else f"✕{h}"
            b.style.font_weight = "bold" if h in self.injected else ""
            b.style.text_decoration = "underline" if h in self.injected else ""
            notes = [f"hole {h}: {name} = {v[h]:.3g}"] + ["flagged"] * bool(self.flagged[h])
            if h in self.injected:
                notes.append(f"injected: {self.injected[h]}")
            b.tooltip = "; ".join(notes)
        self._borders()
        self._show_colorbar(name, lo, hi)
        flagged = set(np.flatnonzero(self.flagged).tolist())
        parts = [f"flagged ⚑: {sorted(flagged)}",
                 f"left out ✕: {np.flatnonzero(~self.included).tolist()}"]
        if self.injected:
            inj = set(self.injected)
            parts.append("injected (simulation): " + ", ".join(
                f"{h} {k}" for h, k in sorted(self.injected.items())))
            parts.append(f"caught {sorted(inj & flagged)}, missed {sorted(inj - flagged)}, "
                         f"flagged good holes {sorted(flagged - inj)}")
        self.legend.value = "<small>" + "<br>".join(html.escape(p) for p in parts) + "</small>"

    def _show_colorbar(self, name, lo, hi) -> None:
        import matplotlib as mpl
        import matplotlib.pyplot as plt

        fig = plt.figure(figsize=(4.9, 1.0))
        ax = fig.add_axes((0.05, 0.42, 0.9, 0.25))
        fig.colorbar(mpl.cm.ScalarMappable(mpl.colors.Normalize(lo, hi), "viridis"), cax=ax,
                     orientation="horizontal", extend="both")
        units = self.metrics[name].attrs.get("units", "")
        ax.set_title(f"{name}{', ' + units if units else ''} (same scale as the buttons)",
                     fontsize=9)
        ax.tick_params(labelsize=8)
        figure_output(self.colorbar_out, fig, f"colour bar of {name}")

    def _show_info(self) -> None:
        h = self.selected
        z = self.review.z
        rows = "".join(
            f"<tr><td>{html.escape(k)}</td><td>{float(self.metrics[k][h]):.4g}</td>"
            f"<td>{float(z[k][h]):+.1f}</td></tr>"
            for k in self.metrics.data_vars
        )
        flag = " <b style='color:#ff7f0e'>⚑ flagged</b>" if self.flagged[h] else ""
        inj = (f" <u>injected defect (simulation): {html.escape(self.injected[h])}</u>"
               if h in self.injected else "")
        self.info.value = (f"<b>hole {h}</b> (row {self._i[h]}, column {self._j[h]}){flag}{inj}"
                           "<table><tr><th>metric</th><th>value</th><th>robust z</th></tr>"
                           f"{rows}</table>")

    def _show_stamp(self) -> None:
        import matplotlib.pyplot as plt

        h, p, s = self.selected, int(self.pose.value), int(self.shot.value)
        fig, ax = plt.subplots(figsize=(3.3, 3.0))
        x = float(self.centroids["x"].values[p, s, h])
        y = float(self.centroids["y"].values[p, s, h])
        if self.cube is None:
            ax.text(0.5, 0.5, "no frame cube given", ha="center", transform=ax.transAxes)
        elif not np.isfinite(x):
            ax.text(0.5, 0.5, "no spot in this frame", ha="center", transform=ax.transAxes)
        else:
            st, (x0, y0) = cutout(self._frame(p, s), x, y, self.half)
            ax.imshow(st, cmap="magma", origin="upper",
                      extent=(x0 - 0.5, x0 + st.shape[1] - 0.5, y0 + st.shape[0] - 0.5,
                              y0 - 0.5))
            ax.plot(x, y, "+", color="cyan", ms=10)
        a = float(self.centroids["alpha"].values[p])
        b = float(self.centroids["beta"].values[p])
        ax.set_title(f"hole {h}, pose {p}, shot {s}\n(α = {a:.1f}°, β = {b:.1f}°)", fontsize=9)
        ax.set_xlabel("x, px", fontsize=9)
        ax.set_ylabel("y, px", fontsize=9)
        ax.tick_params(labelsize=8)
        fig.subplots_adjust(left=0.2, right=0.97, bottom=0.15, top=0.86)
        figure_output(self.stamp_out, fig, f"close-up of hole {h}")

    def _show_residuals(self) -> None:
        import matplotlib.pyplot as plt

        h = self.selected
        res = self.review.residual_map(h, self.included)
        fig, axes = plt.subplots(1, 2, figsize=(5.6, 3.0), sharey=True, layout="constrained")
        a_cmd = self.estimates["alpha_cmd"].values
        b_cmd = self.estimates["beta_cmd"].values
        for ax, name in zip(axes, ("alpha", "beta"), strict=True):
            r = res[name] * 1e3
            lim = np.nanmax(np.abs(r)) if np.isfinite(r).any() else 1.0
            sc = ax.scatter(a_cmd, b_cmd, c=r, cmap="coolwarm", vmin=-lim, vmax=lim, s=22)
            cb = fig.colorbar(sc, ax=ax, shrink=0.85, location="bottom", pad=0.02)
            cb.ax.tick_params(labelsize=8)
            cb.set_label("mdeg", fontsize=8)
            ax.set_title(f"{'α' if name == 'alpha' else 'β'}: hole {h} − average", fontsize=9)
            ax.set_xlabel("α, deg", fontsize=8)
            ax.tick_params(labelsize=8)
        axes[0].set_ylabel("β, deg", fontsize=8)
        figure_output(self.residual_out, fig, f"residual maps of hole {h}")

    def _update_stats(self) -> None:
        h = self.selected
        n = int(self.included.sum())
        self.stats = self.review.stats(self.included, h)
        cols = {f"average of {n} included holes": self.stats["included"],
                f"average of all {len(self.included)} holes": self.stats["all"],
                f"hole {h} alone": self.stats["hole"]}
        table = pd.DataFrame({c: {(a, k): np.nan if s is None else s[a][k] for a in ANGLES
                                  for k in ("mu", "sigma", "M", "sigma_M")}
                              for c, s in cols.items()}).rename_axis(["angle", "stat"])
        self.stats_html.value = ("<b>Global statistics (deg), per-hole calibration then "
                                 "average</b>" + table.to_html(float_format="{:.5f}".format,
                                                               na_rep="–"))
