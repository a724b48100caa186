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
        """Move, wait for motion done and settle; return the read-back (alpha, beta), deg."""
        ...

    def position(self) -> tuple[float, float]:
        """Read-back (alpha, beta), degrees."""
        ...

    def describe(self) -> dict:
        """JSON-able description for the run metadata."""
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


def open_stage(url: str, *, bench=None, seed: int = 0, **driver_kwargs):
    """Open an ESP300/301 stage from a URL.

    Parameters
    ----------
    url : str
        ``fake://`` (an in-process :class:`~sunlab.hardware.FakeESP` served on a pseudo-terminal;
        query options ``velocity`` in deg/s and ``transport=tcp``), ``socket://HOST:PORT``, any
        other :func:`serial.serial_for_url` URL, a device path (``/dev/ttyUSB0``, ``COM3``), or
        ``pymeasure:RESOURCE`` (a VISA resource driven through PyMeasure's ESP300 driver,
        :class:`~sunlab.hardware.PymeasureStage`; of ``driver_kwargs`` it takes ``settle_s``).
    bench : sunlab.sim.Bench, optional
        Platform model of the fake controller (``fake://`` only).
    seed : int
        Seed of the fake controller's platform model.
    **driver_kwargs
        Passed to :class:`~sunlab.hardware.ESP300` (timeout, retries, settle_s, limits, ...).

    Returns
    -------
    ESP300
        The connected driver; for ``fake://`` its ``fake`` attribute is the controller, and
        closing the driver also stops the controller.
    """
    from .esp import ESP300

    if not isinstance(url, str) or not url:
        raise ConfigurationError(
            f"stage: found {url!r}, expected 'fake://', 'socket://HOST:PORT' or a serial device "
            "path"
        )
    if url.startswith("pymeasure:"):  # a VISA resource through PyMeasure's ESP300 driver
        from .pymeasure_stage import PymeasureStage

        keep = {k: v for k, v in driver_kwargs.items() if k in ("settle_s", "limits", "axes")}
        return PymeasureStage(url[len("pymeasure:"):], **keep)
    if not url.startswith("fake://"):
        return ESP300(url, **driver_kwargs)
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
