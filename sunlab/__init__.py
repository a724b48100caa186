"""sunlab: reproduce, teach and extend the laboratory calibration of a pinhole APS sun sensor.

Submodules are loaded on first use so that ``import sunlab`` stays light (no torch, no serial
ports, no widgets until asked for): every package's ``__init__.pyi`` lists its public submodules
and names, and ``lazy_loader.attach_stub`` (scikit-image's pattern) loads each from it on first
access; IDEs and type checkers read the same stubs. The
optional parts are extras of ``pip install "sunlab[...]"`` (:mod:`sunlab.extras`).

Examples
--------
>>> import sunlab
>>> sunlab.schema.FRAMES_SCHEMA
'frames/1'
"""

import lazy_loader as _lazy

__version__ = "0.1.0"

__getattr__, __dir__, __all__ = _lazy.attach_stub(__name__, __file__)
