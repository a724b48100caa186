"""Reproduce the paper's tables on the virtual bench: one pipeline, one module per table.

* :mod:`sunlab.reproduce.pipeline`: what every table shares: the plans of Table 3 and the one
  meaning of *quick* (``pipeline.QUICK``: every 2nd angle along each grid axis, 2 shots per pose),
  simulating and centroiding every frame in one Dask pass with the table's ``method`` on the
  caller's ``address`` / ``scheduler`` / ``workers``, the usable frames and the counts of the
  removed ones, and the one JSON writer;
* :mod:`sunlab.reproduce.table4`: Table 4 (one hole, every calibration method);
* :mod:`sunlab.reproduce.table5`: Table 5 (100 holes vs one hole) and Figs. 13-15;
* :mod:`sunlab.reproduce.platform`: beyond the paper, the platform fault diagnosed
  (:mod:`sunlab.reproduce.fault`) and removed (:mod:`sunlab.reproduce.remedy`);
* :mod:`sunlab.reproduce.learned`: beyond the paper, a calibration learned from the frames.

``sunlab reproduce --table 4|5|platform|all`` runs them (:mod:`sunlab.cli`).

Examples
--------
>>> from sunlab import reproduce
>>> reproduce.pipeline.QUICK
{'step': 2, 'shots': 2}
>>> {k: len(p) for k, p in reproduce.pipeline.experiment_plans(quick=True).items()}
{'I': 100, 'II': 49, 'III': 100}
"""

import lazy_loader as _lazy

__getattr__, __dir__, __all__ = _lazy.attach_stub(__name__, __file__)
