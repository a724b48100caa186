"""A Newport ESP300/301 driven through PyMeasure's own driver, behind sunlab's Stage protocol.

sunlab ships its own ESP300 driver (:class:`~sunlab.hardware.ESP300`, pyserial). A lab whose
instruments already go through PyMeasure and PyVISA (a GPIB card, a VISA resource manager, the
driver their other scripts use) can keep it: :class:`PymeasureStage` wraps
``pymeasure.instruments.newport.esp300.ESP300`` so that :func:`sunlab.hardware.acquire` drives
it like any :class:`~sunlab.hardware.Stage`: ``move_to`` checks the travel limits before any
motion, moves both axes, waits for the stop (``WS`` and ``MD?``, PyMeasure's
``wait_for_stop``), reads the error buffer (``TE?``) and raises a
:class:`~sunlab.hardware.ControllerError` for any error it holds, then settles and reads back.

``sunlab acquire --stage pymeasure:RESOURCE`` opens one (:func:`~sunlab.hardware.open_stage`),
e.g. ``pymeasure:ASRL/dev/ttyUSB0::INSTR`` or ``pymeasure:GPIB0::1::INSTR``. Needs the
``hardware`` extra's ``pymeasure`` (and ``pyvisa-py`` without a vendor VISA).

Examples
--------
>>> from sunlab.hardware import FakeESP
>>> fake = FakeESP(velocity_deg_s=1e4)
>>> port = fake.serve_tcp().rsplit(":", 1)[1]
>>> import warnings
>>> with warnings.catch_warnings():
...     warnings.simplefilter("ignore", FutureWarning)  # pymeasure's SCPI notice
...     stage = PymeasureStage(f"TCPIP::127.0.0.1::{port}::SOCKET", settle_s=0.0)
>>> stage.move_to(2.5, -1.0)
(2.5, -1.0)
>>> stage.close(); fake.close()
"""

from __future__ import annotations

import time

from ..errors import ConfigurationError
from .errors import ControllerError, LimitError, StageError

__all__ = ["PymeasureStage"]


class PymeasureStage:
    """sunlab's :class:`~sunlab.hardware.Stage` over PyMeasure's ESP300 driver.

    Parameters
    ----------
    resource : str or pymeasure ESP300
        A VISA resource name (``TCPIP::HOST::PORT::SOCKET``, ``ASRL/dev/ttyUSB0::INSTR``,
        ``GPIB0::1::INSTR``), or an ESP300 instrument already opened.
    axes : (int, int)
        Controller axes of alpha (outer) and beta (inner); default 1 and 2.
    settle_s : float
        Wait after the stop, s (the platform rings down before a frame is taken).
    limits : ((lo, hi), (lo, hi)), optional
        Travel of alpha and beta, deg, intersected with the controller's ``SL``/``SR``.
    visa_library : str
        PyVISA backend (``"@py"``: pyvisa-py, no vendor VISA needed).
    timeout_ms : int
        VISA read timeout, ms.
    """

    def __init__(self, resource, *, axes=(1, 2), settle_s: float = 0.5, limits=None,
                 visa_library: str = "@py", timeout_ms: int = 5000):
        try:
            from pymeasure.instruments.newport.esp300 import ESP300, Axis
        except ImportError as err:  # pragma: no cover - the extra is installed in the tests
            raise ConfigurationError(
                "PymeasureStage needs pymeasure (and pyvisa-py). Fix: pip install "
                "'sunlab[hardware]' or pip install pymeasure pyvisa-py"
            ) from err
        if isinstance(resource, str):
            self.resource = resource
            self.esp = ESP300(resource, visa_library=visa_library, read_termination="\r\n",
                              write_termination="\r", timeout=int(timeout_ms))
        else:
            self.resource, self.esp = repr(resource), resource
        self.axes = tuple(int(a) for a in axes)
        if len(self.axes) != 2 or len(set(self.axes)) != 2 or min(self.axes) < 1:
            raise ConfigurationError(
                f"axes: found {axes!r}, expected two distinct axes, e.g. (1, 2)")
        self._axis = [Axis(a, self.esp) for a in self.axes]
        if settle_s < 0:
            raise ConfigurationError(f"settle_s: found {settle_s!r}, expected >= 0 s")
        self.settle_s = float(settle_s)
        self.limits = [self._travel(k, None if limits is None else limits[k]) for k in (0, 1)]

    def _travel(self, k: int, user) -> tuple[float, float]:
        """The controller's software limits of axis k, intersected with the user's."""
        lo, hi = float(self._axis[k].left_limit), float(self._axis[k].right_limit)
        if user is not None:
            lo, hi = max(lo, float(user[0])), min(hi, float(user[1]))
        return lo, hi

    def _raise_errors(self, command: str) -> None:
        """Read the controller's error buffer (``TE?``); raise the first error it holds."""
        errors = self.esp.errors
        if errors:
            err = errors[0]  # pymeasure's AxisError (axis, error) or GeneralError (code)
            if hasattr(err, "axis"):
                axis, code = int(err.axis), int(err.axis) * 100 + int(err.error)
            else:
                axis, code = None, int(getattr(err, "code", 0) or 0)
            raise ControllerError(code, str(getattr(err, "message", err)), axis=axis,
                                  command=command)

    def move_to(self, alpha: float, beta: float) -> tuple[float, float]:
        """Move alpha and beta, wait for the stop and the settle time, return the read-back.

        Nothing moves when a target is outside the travel.

        Parameters
        ----------
        alpha, beta : float
            Target angles of the outer and inner axis, degrees.

        Returns
        -------
        (float, float)
            Read-back (alpha, beta) after the settle time, degrees.

        Raises
        ------
        LimitError
            A target outside ``limits``.
        ControllerError
            The controller's error buffer (``TE?``) held an error after the move.
        """
        for name, value, (lo, hi) in zip(("alpha", "beta"), (alpha, beta), self.limits,
                                         strict=True):
            if not lo <= float(value) <= hi:
                raise LimitError.outside(name, float(value), lo, hi)
        for axis, value in zip(self._axis, (alpha, beta), strict=True):
            axis.position = float(value)
        for axis in self._axis:
            axis.wait_for_stop()
        self._raise_errors(f"move to ({alpha}, {beta})")
        if self.settle_s:
            time.sleep(self.settle_s)
        return self.position()

    def position(self) -> tuple[float, float]:
        """Read-back of the two axes.

        Returns
        -------
        (float, float)
            (alpha, beta), degrees.

        Raises
        ------
        StageError
            A position reply that is not a number.
        """
        try:
            return float(self._axis[0].position), float(self._axis[1].position)
        except (TypeError, ValueError) as err:
            raise StageError(f"stage: unreadable position reply ({err}). Fix: check the link "
                             f"to {self.resource}") from err

    def describe(self) -> dict:
        """What the run metadata records about the stage (asks the controller's ``VE?``).

        Returns
        -------
        dict
            JSON-ready: class, VISA resource, axes, limits (deg), ``settle_s`` and the
            controller's version.
        """
        return {"stage": "sunlab.hardware.PymeasureStage", "resource": self.resource,
                "axes": list(self.axes), "limits": [list(v) for v in self.limits],
                "settle_s": self.settle_s, "version": str(self.esp.ask("VE?")).strip()}

    def close(self) -> None:
        """Close the VISA resource."""
        adapter = getattr(self.esp, "adapter", None)
        if adapter is not None:
            adapter.close()
