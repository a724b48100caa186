"""Studies over the paper's tables: which bench explains them (:mod:`.identification`)."""

__all__ = ["identification"]


def __getattr__(name):
    if name in __all__:
        import importlib

        return importlib.import_module(f"{__name__}.{name}")
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
