"""The stage interface the acquisition runner drives, and :func:`open_stage` for a URL.

Any two-axis platform works with :func:`sunlab.hardware.acquire` if it offers
:class:`Stage`: ``move_to(alpha, beta)`` that returns only once the platform has settled, with
the encoder read-back, ``position()``, ``describe()`` and ``close()``.
:class:`~sunlab.hardware.ESP300` is the driver shipped; another controller is one class with
these four methods.

Examples
--------
>>> from sunlab.hardware import open_stage
>>> stage = open_stage("fake://?velocity=1e4", retry_delay_s=0.0, poll_s=0.001)
>>> stage.move_to(1.0, 2.0)
(1.0, 2.0)
>>> stage.close()
"""

from __future__ import annotations

from typing import Protocol, runtime_checkable
from urllib.parse import parse_qs, urlsplit

from ..errors import ConfigurationError

__all__ = ["Stage", "open_stage"]


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

        Raises
        ------
        LimitError
            A target outside the travel (nothing moves).
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


def _velocity(url: str, options: dict) -> float:
    """The ``velocity`` option of a ``fake://`` URL: a positive number of deg/s, or ``inf``."""
    import math

    text = options.get("velocity", "200")
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (value > 0 and (math.isfinite(value) or text.strip().lower() in ("inf", "infinity"))
            and (math.isinf(value) or 1e-3 <= value <= 1e9)):
        raise ConfigurationError(
            f"stage {url!r}: velocity={text!r}, expected a number of deg/s from 0.001 to 1e9 "
            "(or inf: instant moves). Fix: e.g. fake://?velocity=200"
        )
    return value


#: The entry point group a lab's package registers its stages in: name -> a callable
#: ``open(url, **options)`` returning a :class:`Stage`; ``--stage NAME:REST`` opens it.
ENTRY_POINT_GROUP = "sunlab.stages"

#: The stages sunlab brings, by URL scheme: ``fake://`` and ``pymeasure:RESOURCE``. Any other
#: URL or device path goes to the ESP300/301 serial driver.
_BUILTIN = {"fake": "sunlab.hardware.stage:_open_fake",
            "pymeasure": "sunlab.hardware.stage:_open_pymeasure"}


def _entry_points() -> dict:
    from importlib.metadata import entry_points

    return {ep.name: ep for ep in entry_points(group=ENTRY_POINT_GROUP)}


def available_stages() -> dict:
    """URL schemes ``--stage`` opens: the built-ins and every registered entry point of
    :data:`ENTRY_POINT_GROUP` (scheme -> where it comes from); any other URL or a device path
    is an ESP300/301 on a serial link.

    Returns
    -------
    dict of str to str
        Scheme -> ``module:callable`` that opens it (or the entry point's value); a
        registered scheme never shadows a built-in.

    Examples
    --------
    >>> sorted(available_stages())[:2]
    ['fake', 'pymeasure']
    """
    found = dict(_BUILTIN)
    found.update({n: ep.value for n, ep in _entry_points().items() if n not in _BUILTIN})
    return found


def _opener(url: str):
    """The registered opener of ``url``'s scheme, or None (the serial driver)."""
    import importlib

    scheme = url.partition(":")[0] if ":" in url else ""
    if scheme in _BUILTIN:
        module, _, name = _BUILTIN[scheme].partition(":")
        return getattr(importlib.import_module(module), name)
    eps = _entry_points() if scheme and len(scheme) > 1 else {}  # "C:" is a drive
    if scheme not in eps:
        return None
    try:
        return eps[scheme].load()
    except (Exception, SystemExit) as err:  # noqa: BLE001 - a broken plug-in is named
        raise ConfigurationError(
            f"stage {url!r}: the entry point {eps[scheme].value!r} does not load "
            f"({type(err).__name__}: {err}). Fix: reinstall the package that provides it"
        ) from err


def open_stage(url: str, *, bench=None, seed: int = 0, **driver_kwargs):
    """Open a stage from a URL, through the registry of stages.

    Parameters
    ----------
    url : str
        ``fake://`` (an in-process :class:`~sunlab.hardware.FakeESP` served on a pseudo-terminal;
        query options ``velocity`` in deg/s and ``transport=tcp``), ``socket://HOST:PORT``, any
        other :func:`serial.serial_for_url` URL, a device path (``/dev/ttyUSB0``, ``COM3``),
        ``pymeasure:RESOURCE`` (a VISA resource driven through PyMeasure's ESP300 driver,
        :class:`~sunlab.hardware.PymeasureStage`; of ``driver_kwargs`` it takes ``settle_s``),
        or ``NAME:...`` of a stage registered in the entry point group ``sunlab.stages``
        (:func:`available_stages`), called as ``open(url, bench=, seed=, **driver_kwargs)``.
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
        raise ConfigurationError(
            f"stage: found {url!r}, expected 'fake://', 'socket://HOST:PORT' or a serial device "
            "path"
        )
    opener = _opener(url)
    if opener is None:
        return ESP300(url, **driver_kwargs)
    if opener in (_open_fake, _open_pymeasure):
        return opener(url, bench=bench, seed=seed, **driver_kwargs)
    try:
        stage = opener(url, bench=bench, seed=seed, **driver_kwargs)
    except (Exception, SystemExit) as err:  # noqa: BLE001 - the lab's stage did not open
        raise ConfigurationError(
            f"stage {url!r}: {getattr(opener, '__name__', opener)} did not open "
            f"({type(err).__name__}: {' '.join(str(err).split())}). Fix: check that the "
            "controller is connected and powered, and its options") from err
    if not isinstance(stage, Stage):
        missing = [m for m in ("move_to", "position", "describe", "close")
                   if not hasattr(stage, m)]
        raise ConfigurationError(
            f"stage {url!r}: {type(stage).__name__} lacks {missing} of the Stage protocol. "
            "Fix: give the class move_to, position, describe and close")
    return stage


def _open_pymeasure(url: str, *, bench=None, seed: int = 0, **driver_kwargs):
    """``pymeasure:RESOURCE``: a VISA resource through PyMeasure's ESP300 driver."""
    from .pymeasure_stage import PymeasureStage

    keep = {k: v for k, v in driver_kwargs.items() if k in ("settle_s", "limits", "axes")}
    return PymeasureStage(url[len("pymeasure:"):], **keep)


def _open_fake(url: str, *, bench=None, seed: int = 0, **driver_kwargs):
    """``fake://``: an in-process fake controller on a pseudo-terminal (or TCP)."""
    from .esp import ESP300
    from .fake import FakeESP

    query = parse_qs(urlsplit(url).query, keep_blank_values=True)  # "velocity=" is an error
    options = {k: v[-1] for k, v in query.items()}
    unknown = set(options) - {"velocity", "transport"}
    if unknown:
        raise ConfigurationError(
            f"stage {url!r}: unknown options {sorted(unknown)}, expected 'velocity' (deg/s) "
            "and 'transport' (pty or tcp)"
        )
    fake = FakeESP(bench=bench, seed=seed, velocity_deg_s=_velocity(url, options))
    transport = options.get("transport", "pty")
    if transport not in ("pty", "tcp"):
        raise ConfigurationError(f"stage {url!r}: transport={transport!r}, expected pty or tcp")
    try:
        address = fake.serve_pty() if transport == "pty" else fake.serve_tcp()
        stage = ESP300(address, **driver_kwargs)
    except BaseException:
        fake.close()
        raise
    stage.fake = fake
    close = stage.close

    def close_both() -> None:
        close()
        fake.close()

    stage.close = close_both
    return stage
