"""Studies asked of the paper's tables with the virtual bench, apart from the simulator itself.

:mod:`.identification` (which bench explains the tables, under a fixed protocol),
:mod:`.surrogate_tables` (the paper's tables computed on the centroid-level surrogate),
:mod:`.averaging` (why averaging per-hole calibrations loses to the geometric centre) and
:mod:`.platform_fault` (the inner axis's fault that makes beta worse than alpha: diagnosis
and joint fit). Each loads on first use.
"""

__all__ = ["identification", "surrogate_tables", "averaging", "platform_fault"]


def __getattr__(name):
    if name in __all__:
        import importlib

        return importlib.import_module(f"{__name__}.{name}")
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
