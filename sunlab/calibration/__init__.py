"""Calibration functions: from a spot centroid (x, y) to platform angles (alpha, beta).

Every method shares one interface (:class:`Calibration`): ``fit(train, validation=None)``,
``predict(centroids)``, ``predict_xy(x, y)``, ``to_dict()`` / ``artifact.from_dict``, ``save(path)``
/ :func:`load`. Each is registered once in ``registry.KINDS`` (:mod:`sunlab.calibration.registry`),
and :func:`fit` builds and fits one by its kind: ``fit(table, "polynomial", order=3)``.

========================  ========================================================= ===========
class                     method (docs/paper.md sec. 4)                                  kind
========================  ========================================================= ===========
:class:`IdealModel`       ideal geometric model, eq. (1); nothing fitted            ideal
:class:`OptimisedModel`   optimised model, eqs. (3)-(4): dF, alpha0, beta0          optimised
:class:`Polynomial`       polynomial of total degree n in (x, y), one per angle     polynomial
:class:`Trigonometric`    2-D Fourier expansion                                     trigonometric
:class:`Interpolation`    linear / cubic interpolation of the calibration table     interpolation-
                                                                                    linear / -cubic
:class:`NeuralNet`        one tanh hidden layer per angle, strategies 1-4 (Table 2) neural
========================  ========================================================= ===========

Beyond the paper, :class:`FrameNet` learns the angles from the frames themselves (a CNN on each
spot's window, a set network for many holes; kind ``learned-frames``, registered in
:data:`~sunlab.calibration.registry.FRAME_KINDS` since it is fitted on frame cubes, not centroid
tables).

Submodules load on first use; torch (the ``neural`` extra) is imported only when a
:class:`NeuralNet` is fitted, and its absence is an ImportError naming the extra.
``summary.calibration_summary`` describes a saved calibration.

Examples
--------
>>> import sys, sunlab.calibration as cal
>>> sorted(cal.registry.KINDS)[:2]
['ideal', 'interpolation-cubic']
>>> cal.NeuralNet.__name__
'NeuralNet'
"""

import lazy_loader as _lazy

__getattr__, __dir__, __all__ = _lazy.attach_stub(__name__, __file__)
