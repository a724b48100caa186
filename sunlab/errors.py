"""Exceptions raised by sunlab.

Every error names the field, the value found and the fix, so that a user at a bench can act on it
without reading the source.
"""

from __future__ import annotations

__all__ = ["SunlabError", "SchemaError", "ConfigurationError"]


class SunlabError(ValueError):
    """Base class of every error sunlab raises on bad input."""


class SchemaError(SunlabError):
    """A dataset or file does not follow the on-disk contract of ``data_schema/``.

    Parameters
    ----------
    field : str
        The variable, coordinate, attribute or column at fault.
    found : object
        What was found.
    expected : str
        What the contract expects.
    fix : str, optional
        How to mend it.
    """

    def __init__(self, field: str, found: object, expected: str, fix: str | None = None):
        self.field = field
        self.found = found
        self.expected = expected
        self.fix = fix
        msg = f"{field}: found {found!r}, expected {expected}"
        if fix:
            msg += f". Fix: {fix}"
        super().__init__(msg)


class ConfigurationError(SunlabError):
    """A bench, plan or method configuration is physically or logically invalid."""
