"""The paper's figures as functions returning matplotlib Figures.

- :mod:`sunlab.plots.accuracy`: calibration accuracy, Figs. 10-12 (:func:`error_maps`,
  :func:`error_histogram`, :func:`error_rectangles`), built without pyplot as figures that show
  themselves in any Jupyter kernel (``plots.accuracy.new_figure``);
- :mod:`sunlab.plots.mask`: the 100-hole mask, Figs. 13-15 (:func:`fig13_frame`,
  :func:`fig14_bad_holes`, :func:`fig15_rectangles`) and the map of a defect metric
  (:func:`plot_metric_map`).

Examples
--------
>>> from sunlab import plots, stats
>>> len(plots.error_rectangles(stats.paper_table4()).axes[0].patches)
4
"""

import lazy_loader as _lazy

__getattr__, __dir__, __all__ = _lazy.attach_stub(__name__, __file__)
