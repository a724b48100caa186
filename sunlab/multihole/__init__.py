"""The 100-hole mask: hole indexing, the paper's two strategies, defect metrics, bad-hole rejection.

With a mask of N holes every frame holds N spots. The paper (sec. 6) tries two ways to turn them
into one sun direction, both with polynomial calibration:

1. **Geometric centre** (:class:`GeometricCentre`): the mean of the N spot centroids is calibrated
   as if it were one spot.
2. **Per-hole calibration, then averaging** (:class:`PerHoleAverage`): one calibration per hole,
   and the mean of the N angle estimates.

Averaging N independent errors divides the variance by N, eq. (5); errors common to all holes
(platform pose error, mask mounting) do not average out, and "bad" holes (dust, defects) spoil the
mean. One module per concept:

===============================  ==============================================================
:mod:`~sunlab.multihole.holes`   grid indices, usable spots, cut-outs, centroiding a free layout
:mod:`~.strategies`              the two strategies, as :class:`sunlab.calibration.Calibration`
                                 subclasses, entries of the calibration registry (entry
                                 point group ``sunlab.calibrations``; ``calibration.load``
                                 reads them)
:mod:`~.defects`                 per-hole defect metrics, robust z-scores, bad-hole rejection
:mod:`~.budget`                  combining per-hole estimates, the error budget and the gain of
                                 N holes over one
:mod:`~.review`                  every hole's results, what the hole explorer shows
===============================  ==============================================================

Elsewhere: centroid-level synthetic tables are :func:`sunlab.sim.synthetic_centroids` (with
``layout="grid"``), a hole layout in mm is :class:`sunlab.sim.Mask`, the global statistics of an
estimate are :func:`sunlab.stats.error_summary`, and the figures (Figs. 13-15, the metric map) are
in :mod:`sunlab.plots`.

Conventions: pixel coordinates (x = column, y = row, centre of the first pixel = 0), angles in
degrees; centroid tables follow contract ``centroids/1`` on dims ``(pose, shot, hole)`` with the
commanded angles ``alpha``, ``beta`` as coordinates on ``pose`` and, where known, the hole's grid
row/column ``hole_i``, ``hole_j`` and design position ``hole_x_cf``, ``hole_y_cf`` (px) on ``hole``.

Examples
--------
>>> import numpy as np
>>> from sunlab import multihole as mh
>>> from sunlab.sim import synthetic_centroids
>>> cen = synthetic_centroids([0.0, 1.0], [0.0, 1.0], shots=2, layout="grid",
...                           defects={7: {"flux": 0.4}})
>>> np.flatnonzero(mh.reject_bad_holes(mh.defect_metrics(cen)).values).tolist()
[7]

References
----------
.. [1] docs/paper.md, sec. 6 and Table 5 (the 2005 preprint on the Naples APS sun sensor).
"""

import lazy_loader as _lazy

__getattr__, __dir__, __all__ = _lazy.attach_stub(__name__, __file__)
