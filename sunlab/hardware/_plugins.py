"""The entry point groups a lab's package registers its cameras and stages in, and a plug-in
that fails named in one line, when it loads, opens or is called during a run (the commonest
bench fault: a device not plugged in)."""

from __future__ import annotations

import contextlib
import sys
import weakref

from ..errors import ConfigurationError, SunlabError
from .errors import CameraError, StageError

#: What each plug-in loaded or device opened came from, for the messages of :func:`call`.
_MADE: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def entry_points(group: str) -> dict:
    """The installed entry points of ``group``, by name."""
    from importlib.metadata import entry_points

    return {ep.name: ep for ep in entry_points(group=group)}


def plugin_failed(what: str, action: str, err: BaseException, fix: str) -> ConfigurationError:
    """A lab's code that raised, named with its error, never a traceback."""
    text = " ".join(str(err).split()) or type(err).__name__
    return ConfigurationError(f"{what}: {action} ({type(err).__name__}: {text}). Fix: {fix}")


def load_plugin(ep, what: str, fix: str):
    """The object an entry point (or a ``module:attr`` spec as one) names; one that does not
    load is named."""
    try:
        loaded = ep.load()
    except (Exception, SystemExit) as err:  # noqa: BLE001 - a broken plug-in is named
        action, module = f"{ep.value!r} does not load", getattr(ep, "module", None)
        if isinstance(err, ModuleNotFoundError) and err.name == module:
            raise ConfigurationError(f"{what}: {action}: cannot import {module!r} ({err}). "
                                     "Fix: install the package that holds it, or run from its "
                                     "folder") from err
        if isinstance(err, AttributeError) and module in sys.modules:
            raise ConfigurationError(f"{what}: {action}: {ep.module!r} has no {ep.attr!r}. "
                                     "Fix: give module:Class exactly") from err
        raise plugin_failed(what, action, err, fix) from err
    dist = f" of the distribution {ep.dist.name} {ep.dist.version}" if ep.dist else ""
    with contextlib.suppress(TypeError):
        _MADE[loaded] = (f"the plug-in {ep.name!r} ({ep.group}: {ep.value}{dist})"
                         if ep.name != ep.value else ep.value)
    return loaded


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
    with contextlib.suppress(TypeError):
        _MADE[made] = _MADE.get(factory) or (f"{getattr(factory, '__module__', '')}:"
                                             f"{getattr(factory, '__qualname__', factory)}")
    return made


def plugin_name(device) -> str:
    """``device``'s class and the plug-in that opened it (entry point and distribution, or
    ``module:Class``): what a lab user recognises and reinstalls."""
    cls = type(device)
    with contextlib.suppress(TypeError):  # neither hashable nor weakly referable: the class
        if device in _MADE:
            return f"{cls.__qualname__} of {_MADE[device]}"
    return f"{cls.__module__}.{cls.__qualname__}"


def call(role: str, device, method: str, *args, **kwargs):
    """``device.method(*args, **kwargs)`` for the runner: an exception of a lab's device (a
    class outside sunlab raising anything but a :class:`~sunlab.SunlabError`) becomes a
    :class:`~sunlab.hardware.errors.StageError` (``role`` "stage") or
    :class:`~sunlab.hardware.errors.CameraError` naming the device, the method and the error,
    so that the run records it and the command ends in one line."""
    try:
        return getattr(device, method)(*args, **kwargs)
    except Exception as err:
        if isinstance(err, SunlabError) or type(device).__module__.split(".")[0] == "sunlab":
            raise
        text = " ".join(str(err).split()) or "no message"
        error = StageError if role == "stage" else CameraError
        raise error(f"{role} {plugin_name(device)}: {method}() raised {type(err).__name__}: "
                    f"{text}. Fix: mend the device or its plug-in; the poses done are kept "
                    "(--resume, or acquire(resume=True), continues the run)") from err
