"""A lab's stage or camera that raises during a run, named in one line (the commonest bench
fault: a device not plugged in); the plug-ins themselves load through :mod:`sunlab.extras`."""

from __future__ import annotations

from ..errors import SunlabError
from ..extras import plugin_name
from .errors import CameraError, StageError


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
