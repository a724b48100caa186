"""Spot centroids: the paper's two algorithms, estimators toward the Cramér–Rao bound, many spots.

Every single-spot estimator has the same signature ``method(frame, **options)`` and returns a
:class:`Centroid` ``(x, y, flux, window, status)``: ``x`` is the column and ``y`` the row of the
spot centroid in pixels (centre of the first pixel = 0), ``flux`` the background-subtracted flux
in DN, ``window`` the half-open pixel box ``(x0, x1, y0, y1)`` the estimate used, and ``status`` a
code of :data:`sunlab.schema.STATUS`. A frame without a usable spot gives NaN and a status, never
an exception; only a wrongly shaped argument (not 2-D) raises.

Estimators (docs/paper.md sec. 3 and beyond):

* :func:`threshold_window` — algorithm A, the group's earlier threshold + fixed 130 x 130 window;
* :func:`projection_window` — algorithm B, the paper's projection-profile window;
* :func:`tight_window` — a background-subtracted circular window fitted to the spot (fast);
* :func:`disk_fit` — a weighted least-squares fit of an edge-blurred disk (near the CRLB);
* :func:`crlb` — the Cramér–Rao lower bound of the centroid for a given spot, flux and noise.

Moments of a spot: :func:`~sunlab.centroid.moments.spot_moments`. Many spots of one frame at
given positions, any estimator: :func:`centroid_sources`. Many spots of a multi-hole mask, found
and indexed on their lattice: :func:`locate_spots`. A whole frame cube: :func:`locate`.

Package layout (one concept per module, all numpy and scipy; private helpers beside them):

* :mod:`~sunlab.centroid.result` -- :class:`Centroid`, frame checks and status rules;
* ``_paper`` -- the paper's algorithms A and B and their steps (:func:`border_mean`,
  :func:`first_hit`, :func:`projection_profiles`);
* :mod:`~sunlab.centroid.estimators` -- the tight window, the disk fit (its stages in
  ``_diskfit``) and :data:`METHODS`; ``_aperture`` holds the detection and aperture
  measurement that the tight window and the lattice share;
* :mod:`~sunlab.centroid.crlb` -- the Cramér–Rao bound;
* :mod:`~sunlab.centroid.moments` -- a spot's moments and the stamp variant
  :func:`stamp_moments` for cut-outs of multi-hole frames;
* :mod:`~sunlab.centroid.sources` -- :func:`centroid_sources`;
* :mod:`~sunlab.centroid.lattice` -- :func:`locate_spots` (its lattice fit and hole assignment in
  ``_grid``);
* :mod:`~sunlab.centroid.cube` -- :func:`locate` (a whole cube through Dask), :func:`locate_all`.

Status precedence when several apply: invalid > no_spot > ambiguous > clipped > saturated >
repaired > ok. ``saturated`` means the spot saturates (touching clipped pixels); an isolated clipped
pixel in the window (a hot pixel) is replaced by the median of its 8 neighbours and the spot keeps
a usable status, ``repaired`` (algorithms A and B).
``x, y`` are NaN only for ``invalid`` and ``no_spot``; a clipped, saturated or ambiguous spot
keeps its (possibly biased) estimate so that it can be inspected.

Examples
--------
>>> import numpy as np
>>> from sunlab import centroid
>>> yy, xx = np.mgrid[0:200, 0:240]
>>> frame = (30 + 400 * (np.hypot(xx - 120.5, yy - 90.0) < 17.5)).astype(np.uint16)
>>> c = centroid.projection_window(frame)
>>> round(c.x, 2), round(c.y, 2), c.status_name
(120.5, 90.0, 'ok')
"""

import lazy_loader as _lazy

__getattr__, __dir__, __all__ = _lazy.attach_stub(__name__, __file__)
