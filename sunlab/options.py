"""Package-wide options (like :func:`xarray.set_options`): today only the progress switch.

Long computations show a progress bar unless the caller passes ``progress=False`` *or* the
switch is off. Notebooks turn it off once (``sunlab.set_options(progress=False)``) so that their
saved outputs hold figures and numbers, not bars; the environment variable
``SUNLAB_PROGRESS=0`` does the same for a whole process.

Examples
--------
>>> import sunlab
>>> with sunlab.set_options(progress=False):
...     sunlab.show_progress(True)
False
>>> sunlab.show_progress(True) == sunlab.OPTIONS["progress"]
True
"""

from __future__ import annotations

import os

from .errors import ConfigurationError

__all__ = ["OPTIONS", "set_options", "show_progress"]

#: Current values of the options (read them; change them with :func:`set_options`).
OPTIONS: dict[str, object] = {"progress": os.environ.get("SUNLAB_PROGRESS", "1") != "0"}


class set_options:  # noqa: N801 - used as a function, as xarray.set_options is
    """Set options for the process, or for a ``with`` block only.

    Parameters
    ----------
    progress : bool
        Allow progress bars (default True, or False when ``SUNLAB_PROGRESS=0``).

    Examples
    --------
    >>> _ = set_options(progress=False)   # from now on
    >>> OPTIONS["progress"]
    False
    >>> _ = set_options(progress=True)
    """

    def __init__(self, **options):
        unknown = sorted(set(options) - set(OPTIONS))
        if unknown:
            raise ConfigurationError(
                f"set_options: unknown option(s) {unknown}; expected one of {sorted(OPTIONS)}."
            )
        for name, value in options.items():
            if not isinstance(value, bool):
                raise ConfigurationError(
                    f"set_options({name}=...): found {value!r}; expected True or False."
                )
        self._old = {name: OPTIONS[name] for name in options}
        OPTIONS.update(options)

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        OPTIONS.update(self._old)


def show_progress(requested: bool) -> bool:
    """Whether to draw a progress bar: the caller asked for one and the switch allows it."""
    return bool(requested) and bool(OPTIONS["progress"])
