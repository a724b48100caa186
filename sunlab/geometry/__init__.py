"""Geometric models of the pinhole sun sensor: the ideal model (1), the optimised model (3)-(4),
an exact pinhole forward model with mounting errors, and sun-vector conversions.

The models, their sign convention and the equations are :mod:`sunlab.geometry.model`, the fit of
the optimised model (:func:`fit_optimised_model`) its private ``_fit``; this package exports their
public names, loaded on first use.

Examples
--------
>>> from sunlab import geometry
>>> x, y = geometry.ideal_centroid(45.0, 0.0, 5.0, 0.007, 640.0, 512.0)
>>> round(float(x - 640.0), 6)  # F / p * tan(45 deg)
714.285714
"""

import lazy_loader as _lazy

__getattr__, __dir__, __all__ = _lazy.attach_stub(__name__, __file__)
