"""The stage interface the acquisition runner drives, and :func:`open_stage` for a URL.

Any two-axis platform works with :func:`sunlab.hardware.acquire` if it offers :class:`Stage`:
``move_to(alpha, beta)`` that returns only once the platform has settled, with the encoder
read-back, ``position()``, ``describe()`` and ``close()``. :class:`~sunlab.hardware.ESP300` is
the driver shipped; another controller is one class with these four methods, opened by a
``NAME:...`` URL through the entry point group ``sunlab.stages``.

Examples
--------
>>> from sunlab.hardware import open_stage
>>> stage = open_stage("fake://?velocity=1e4", retry_delay_s=0.0, poll_s=0.001)
>>> stage.move_to(1.0, 2.0)
(1.0, 2.0)
>>> stage.close()
"""

from __future__ import annotations

import math
from typing import Protocol, runtime_checkable
from urllib.parse import parse_qs, urlsplit

from ..errors import ConfigurationError
from ..extras import entry_points, load_plugin, open_device

__all__ = ["open_stage"]

#: The entry point group a lab's package registers its stages in: name -> a callable
#: ``open(url, **options)`` returning a :class:`Stage`; ``--stage NAME:REST`` opens it.
ENTRY_POINT_GROUP = "sunlab.stages"


@runtime_checkable
class Stage(Protocol):
    """A two-axis rotation platform (outer axis alpha, inner axis beta, degrees)."""

    def move_to(self, alpha: float, beta: float) -> tuple[float, float]:
        """Move, wait for motion done and settle; return the read-back.

        Parameters
        ----------
        alpha, beta : float
            Target angles of the outer and inner axis, degrees.

        Returns
        -------
        (float, float)
            Encoder read-back (alpha, beta) once settled, degrees.
        """
        ...

    def position(self) -> tuple[float, float]:
        """Read the encoders.

        Returns
        -------
        (float, float)
            Read-back (alpha, beta), degrees.
        """
        ...

    def describe(self) -> dict:
        """Describe the stage for the run metadata.

        Returns
        -------
        dict
            JSON-ready description (driver, link, limits, settings).
        """
        ...

    def close(self) -> None: ...


def available_stages() -> dict:
    """URL schemes ``--stage`` opens: ``fake`` and every registered entry point of
    :data:`ENTRY_POINT_GROUP`; any other URL or a device path is an ESP300/301.

    Returns
    -------
    dict of str to str
        Scheme -> ``module:callable`` that opens it; a registered ``fake`` is ignored.

    Examples
    --------
    >>> available_stages()["fake"]
    'sunlab.hardware.stage:_open_fake'
    """
    found = {name: ep.value for name, ep in entry_points(ENTRY_POINT_GROUP).items()}
    return {**found, "fake": "sunlab.hardware.stage:_open_fake"}


def open_stage(url: str, *, bench=None, seed: int = 0, **driver_kwargs):
    """Open a stage from a URL.

    Parameters
    ----------
    url : str
        ``fake://`` (an in-process :class:`~sunlab.hardware.fake.FakeESP` served on a
        pseudo-terminal; query options ``velocity`` in deg/s and ``transport=tcp``),
        ``socket://HOST:PORT``, any other :func:`serial.serial_for_url` URL, a device path
        (``/dev/ttyUSB0``, ``COM3``), or ``NAME:...`` of a stage registered in the entry point
        group ``sunlab.stages`` (:func:`available_stages`), called as
        ``open(url, bench=, seed=, **driver_kwargs)``.
    bench : sunlab.sim.Bench, optional
        Platform model of the fake controller (``fake://`` only).
    seed : int
        Seed of the fake controller's platform model.
    **driver_kwargs
        Passed to :class:`~sunlab.hardware.ESP300` (timeout, retries, settle_s, limits, ...).

    Returns
    -------
    Stage
        The connected stage; for ``fake://`` an ESP300 whose ``fake`` attribute is the
        controller (closing the driver also stops the controller).
    """
    from .esp import ESP300

    if not isinstance(url, str) or not url:
        raise ConfigurationError(f"stage: found {url!r}, expected 'fake://', "
                                 "'socket://HOST:PORT' or a serial device path")
    scheme = url.partition(":")[0] if ":" in url else ""
    if scheme == "fake":
        return _open_fake(url, bench, seed, driver_kwargs)
    eps = entry_points(ENTRY_POINT_GROUP) if len(scheme) > 1 else {}  # "C:" is a drive
    if scheme not in eps:
        return ESP300(url, **driver_kwargs)
    what = f"stage {url!r}"
    opener = load_plugin(eps[scheme], what, "reinstall the package that provides it")
    return open_device(opener, Stage, ("move_to", "position", "describe", "close"), what,
                       "check that the controller is connected and powered, and its options",
                       url, bench=bench, seed=seed, **driver_kwargs)


def _open_fake(url: str, bench, seed: int, driver_kwargs: dict):
    """``fake://``: an in-process fake controller on a pseudo-terminal (or TCP)."""
    from .esp import ESP300
    from .fake import FakeESP

    query = parse_qs(urlsplit(url).query, keep_blank_values=True)  # "velocity=" is an error
    options = {k: v[-1] for k, v in query.items()}
    if unknown := sorted(set(options) - {"velocity", "transport"}):
        raise ConfigurationError(f"stage {url!r}: unknown options {unknown}, expected "
                                 "'velocity' (deg/s) and 'transport' (pty or tcp)")
    text, transport = options.get("velocity", "200"), options.get("transport", "pty")
    try:
        velocity = float(text)
    except ValueError:
        velocity = math.nan
    if not (1e-3 <= velocity <= 1e9 or (velocity == math.inf and text.strip().isalpha())):
        raise ConfigurationError(
            f"stage {url!r}: velocity={text!r}, expected a number of deg/s from 0.001 to 1e9 "
            "(or inf: instant moves). Fix: e.g. fake://?velocity=200")
    if transport not in ("pty", "tcp"):
        raise ConfigurationError(f"stage {url!r}: transport={transport!r}, expected pty or tcp")
    fake = FakeESP(bench=bench, seed=seed, velocity_deg_s=velocity)
    try:
        stage = ESP300(fake.serve_pty() if transport == "pty" else fake.serve_tcp(),
                       **driver_kwargs)
    except BaseException:
        fake.close()
        raise
    stage.fake, close = fake, stage.close

    def close_both() -> None:
        close()
        fake.close()

    stage.close = close_both
    return stage
