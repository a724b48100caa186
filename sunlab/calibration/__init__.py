"""Calibration functions: from a spot centroid (x, y) to platform angles (alpha, beta).

Every method shares one interface (:class:`Calibration`): ``fit(train, validation=None)``,
``predict(centroids)``, ``predict_xy(x, y)``, ``to_dict()`` / :func:`from_dict`, ``save(path)``
/ :func:`load`. Each is registered once in :data:`KINDS` (:mod:`sunlab.calibration.registry`),
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
:data:`FRAME_KINDS` since it is fitted on frame cubes, not centroid tables).

Submodules load on first use; torch (the ``neural`` extra) is imported only when a
:class:`NeuralNet` is fitted, and its absence is an ImportError naming the extra.
:func:`calibration_summary` describes a saved calibration.

Examples
--------
>>> import sys, sunlab.calibration as cal
>>> sorted(cal.KINDS)[:2]
['ideal', 'interpolation-cubic']
>>> cal.NeuralNet.__name__
'NeuralNet'
"""

from __future__ import annotations

import importlib

_LAZY = {
    **dict.fromkeys(["KINDS", "FRAME_KINDS", "ALIASES", "available_kinds", "fit",
                     "method_class"], "registry"),
    **dict.fromkeys(["from_dict", "load"], "artifact"),
    **dict.fromkeys(["Calibration", "TrainingData", "combine", "training_data"], "base"),
    "calibration_summary": "summary",
    "table4_methods": "methods",
    "Polynomial": "polynomial",
    "Trigonometric": "trigonometric",
    "Interpolation": "interpolation",
    "NeuralNet": "neural",
    "FrameNet": "frames",
    "IdealModel": "model",
    "OptimisedModel": "model",
}

__all__ = list(_LAZY)


def __getattr__(name: str):
    if name in _LAZY:
        return getattr(importlib.import_module(f".{_LAZY[name]}", __name__), name)
    raise AttributeError(f"module 'sunlab.calibration' has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(_LAZY))
