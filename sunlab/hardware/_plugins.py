"""The entry point groups a lab's package registers its cameras and stages in, and a plug-in
that fails named in one line (the commonest bench fault: a device not plugged in)."""

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


def load_plugin(ep, what: str, fix: str):
    """The object an entry point names; one that does not load is named."""
    try:
        return ep.load()
    except (Exception, SystemExit) as err:  # noqa: BLE001 - a broken plug-in is named
        raise plugin_failed(what, f"the entry point {ep.value!r} does not load", err,
                            fix) from err


def open_device(factory, protocol, members: tuple, what: str, fix: str, /, *args, **kwargs):
    """``factory(*args, **kwargs)``, checked against ``protocol`` (a runtime-checkable
    Protocol of ``members``); a factory that raises, or an object that lacks one, is named."""
    try:
        made = factory(*args, **kwargs)
    except (Exception, SystemExit) as err:  # noqa: BLE001 - the lab's device did not open
        raise plugin_failed(what, f"{getattr(factory, '__name__', factory)!s} did not open",
                            err, fix) from err
    if not isinstance(made, protocol):
        missing = [m for m in members if not hasattr(made, m)]
        raise ConfigurationError(
            f"{what}: {type(made).__name__} lacks {missing} of the {protocol.__name__} "
            f"protocol. Fix: give the class {', '.join(members)} (docs/hardware.md)")
    return made
