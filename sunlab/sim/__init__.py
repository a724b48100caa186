"""The virtual bench: a physically faithful simulator of the paper's laboratory bench.

The paper's raw frames are not public, so every table sunlab reproduces comes from this simulator.
A :class:`Bench` is a dataclass of dataclasses -- :class:`Source` (the 0.52 deg solar simulator),
:class:`Mask` (holes with defects, F, dF, tilt, rotation, offset, play), :class:`Detector` (an
Ibis4-like APS with fill factor, PRNU, DSNU, hot pixels, noise and a 10-bit ADC) and
:class:`Platform` (two axes, mounting errors, per-pose error, jitter) -- and every default is
documented with its rationale where it is defined; the module docstring of
:mod:`sunlab.sim.bench` summarises the error budget (docs/paper.md sec. 8).

Main entry points: :func:`simulate` (a lazy cube of a plan), :func:`render_frame` (one frame),
``platform.platform_pose`` (true angles for commanded ones), ``spots.spot_truth`` (true centroids);
:func:`synthetic_centroids` (centroid tables with known truth, no frames rendered).

Examples
--------
>>> from sunlab import sim, plans
>>> bench = sim.Bench.paper_single_hole()
>>> a, b = sim.platform.platform_pose(bench, -8.0, 4.0, seed=0, pose=0, shot=0)
>>> frame = sim.render_frame(bench, a, b, seed=0)
>>> frame.shape, int(frame.max()) <= 1023
((1024, 1280), True)
"""

import lazy_loader as _lazy

__getattr__, __dir__, __all__ = _lazy.attach_stub(__name__, __file__)
