"""The entry point groups a lab's package registers its cameras and stages in, and the one-line
error that names a plug-in that fails (the commonest bench fault: a device not plugged in)."""

from __future__ import annotations

from ..errors import ConfigurationError


def entry_points(group: str) -> dict:
    """The installed entry points of ``group``, by name."""
    from importlib.metadata import entry_points

    return {ep.name: ep for ep in entry_points(group=group)}


def plugin_failed(what: str, action: str, err: BaseException, fix: str) -> ConfigurationError:
    """A lab's code that raised, named with its error, never a traceback."""
    text = " ".join(str(err).split()) or type(err).__name__
    return ConfigurationError(f"{what}: {action} ({type(err).__name__}: {text}). Fix: {fix}")
