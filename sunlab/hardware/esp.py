"""Newport ESP300 / ESP301 motion controller: a two-axis rotation stage over a serial link.

:class:`ESP300` drives the controller with the command subset below, over a link (the private
module ``_esp_link``: timeouts, retries, resynchronisation after a lost reply, the
error buffer read to empty):

=============  =====================================  ==========================================
command        meaning                                reply
=============  =====================================  ==========================================
``VE?``        firmware version                       ``ESP301 Version 3.0.2 6/29/11``
``TB?``        pop the oldest error, with its text    ``code, timestamp, message``
``nSN?``       displacement units of axis n           ``7`` (degree)
``nSL?``       left (negative) software limit          ``-170.00000``
``nSR?``       right (positive) software limit         ``170.00000``
``nMO?``       motor power of axis n                  ``1`` on, ``0`` off
``nMO``        motor on                               (none)
``nPA<x>``     move axis n to absolute position x      (none)
``nMD?``       motion done                            ``1`` done, ``0`` moving
``nTP?``       actual position (encoder)              ``12.50000``
``nST``        stop motion of axis n                  (none)
=============  =====================================  ==========================================

Examples
--------
Drive the in-process fake controller (same protocol, over a pseudo-terminal):

>>> from sunlab.hardware import ESP300
>>> from sunlab.hardware.fake import FakeESP
>>> fake = FakeESP(velocity_deg_s=1e4)
>>> with ESP300(fake.serve_pty(), retry_delay_s=0.0, poll_s=0.001) as stage:
...     stage.move_to(12.5, -3.0)
(12.5, -3.0)
>>> fake.close()
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from ..errors import ConfigurationError
from ._esp_link import _check_settings, _Link, _parse_flag, _parse_float, format_number, log
from .errors import LimitError, MotionTimeout, StageError

__all__ = ["ESP300"]

#: ``SN`` unit codes 0 to 11 of the ESP300/301 (the driver needs 7, degrees, on both axes).
UNITS = ("encoder count", "motor step", "millimeter", "micrometer", "inch", "milli-inch",
         "micro-inch", "degree", "gradian", "radian", "milliradian", "microradian")


class ESP300(_Link):
    """A two-axis rotation platform on a Newport ESP300 or ESP301 controller.

    The outer platform axis (alpha) and the inner one (beta) are two controller axes, in degrees
    (``SN7``). The driver checks targets against the travel limits before sending any motion
    command, retries queries that time out or come back garbled, reconnects a link that drops
    when it was opened from a URL, decodes the controller's error buffer after each move, and
    waits for motion done plus a settle time before reading the encoders back.

    Parameters
    ----------
    port : str or serial.Serial
        A device path or :func:`serial.serial_for_url` URL, or an open link (anything with
        ``write``, ``read_until``, ``reset_input_buffer`` and ``close``).
    axes : (int, int)
        Controller axes of alpha and beta.
    timeout : float
        Read timeout of one attempt, s.
    retries : int
        Extra attempts of a query (or a write whose link dropped) before giving up.
    retry_delay_s : float
        Delay before the first retry, s; doubled at each further retry.
    settle_s : float
        Wait after motion done, before the read-back and the first frame, s.
    motion_timeout_s : float
        Longest wait for motion done, s; a stuck axis is then stopped (``ST``).
    poll_s : float
        Interval of the ``MD?`` polls, s.
    limits : dict, optional
        ``{"alpha": (low, high), "beta": (low, high)}`` in degrees, intersected with the
        controller's software limits read at :meth:`connect`.
    tolerance_deg : float
        Largest accepted ``|read-back - target|`` after a move, degrees.
    move_retries : int
        Extra moves when the read-back is off target (a motion command the controller lost
        while busy: commands have no reply, so only the read-back reveals it).
    enable_motors : bool
        Turn a motor that is off on at :meth:`connect` (``MO``); otherwise raise.
    baudrate : int
        Used when ``port`` is a path or URL.
    rtscts : bool
        Hardware flow control, used when ``port`` is a path or URL.
    connect : bool
        Run the :meth:`connect` handshake at once.
    sleep, clock : callable
        The waits (:func:`time.sleep`) and the clock of the deadlines (resynchronisation,
        motion timeout; :func:`time.monotonic`), replaceable to test the driver's timing.

    Notes
    -----
    A move is ``nPA`` for both axes, ``TB?`` (a refused command is reported at once), ``nMD?``
    polls until both axes are done, ``TB?`` again (a limit or following error during the move),
    the settle wait, and ``nTP?`` for the read-back. Position queries and absolute moves are
    idempotent, which makes resending them after a fault safe. Every query starts by dropping
    what the link holds; after a lost or garbled reply the next query first sends ``VE?`` and
    drops every line up to its reply, so a reply that arrives after its timeout is never taken
    for the answer to a later query.

    Examples
    --------
    >>> from sunlab.hardware.fake import FakeESP
    >>> fake = FakeESP(velocity_deg_s=1e4)
    >>> stage = ESP300(fake.serve_pty(), retry_delay_s=0.0, poll_s=0.001)
    >>> stage.identity.startswith("ESP301"), stage.limits["alpha"]
    (True, (-170.0, 170.0))
    >>> stage.close(); fake.close()
    """

    def __init__(self, port, *, axes: Sequence[int] = (1, 2), settle_s: float = 0.0,
                 motion_timeout_s: float = 60.0, poll_s: float = 0.05,
                 limits: dict[str, tuple[float, float]] | None = None,
                 tolerance_deg: float = 0.01, move_retries: int = 1, enable_motors: bool = True,
                 connect: bool = True, **link):
        self.axes = tuple(int(a) for a in axes)
        if len(self.axes) != 2 or len(set(self.axes)) != 2 or min(self.axes) < 1:
            raise ConfigurationError(
                f"axes: found {axes!r}, expected two distinct controller axes (1, 2 or 3) for "
                "alpha and beta. Fix: pass axes=(1, 2)")
        _check_settings(motion_timeout_s=motion_timeout_s, move_retries=move_retries,
                        settle_s=settle_s, poll_s=poll_s)
        self.settle_s, self.motion_timeout_s = float(settle_s), float(motion_timeout_s)
        self.poll_s, self.tolerance_deg = float(poll_s), float(tolerance_deg)
        self.move_retries, self.enable_motors = int(move_retries), bool(enable_motors)
        self._user_limits, self.limits, self.stale_errors = dict(limits or {}), {}, []
        super().__init__(port, **link)
        if connect:
            try:
                self.connect()
            except BaseException:
                if self.url is not None:  # we opened it: do not leak the port
                    self._port.close()
                raise

    # -- controller state ---------------------------------------------------------------------
    def connect(self) -> ESP300:
        """Handshake: identify, drain stale errors, check units, read limits, enable motors.

        Returns
        -------
        ESP300
            This driver, with ``identity`` (the ``VE?`` reply), ``stale_errors`` and
            ``limits`` (alpha and beta travel in degrees, the controller's ``SL``/``SR``
            intersected with the driver's ``limits``) set.

        Raises
        ------
        ConfigurationError
            When an axis is not in degrees.
        StageError
            When a motor is off and ``enable_motors`` is False.
        """
        self.identity = self.query("VE?")  # the query drops what the link holds first
        self.stale_errors, lost = self._drain()
        if lost is not None and not lost.empty:
            raise lost
        for err in ([lost] if lost else []) + self.stale_errors:  # never fail the handshake
            log.warning("stage: at connect, stale error in the controller buffer: %s", err)
        limits = {}
        for name, ax in zip(("alpha", "beta"), self.axes, strict=True):
            units = self.query(f"{ax}SN?", int, "a unit code")
            if units != 7:
                meaning = UNITS[units] if 0 <= units < len(UNITS) else "unknown"
                raise ConfigurationError(
                    f"stage axis {ax} ({name}) units: found {units} ({meaning}), expected 7 "
                    f"(degree). Fix: send '{ax}SN7' and save with 'SM', or use the controller's "
                    "front panel")
            low, high = (self.query(f"{ax}S{side}?", _parse_float, "a number") for side in "LR")
            user = self._user_limits.get(name, (low, high))
            low, high = max(low, float(user[0])), min(high, float(user[1]))
            if not low < high:
                raise ConfigurationError(
                    f"stage {name} limits: found [{low}, {high}], expected low < high. Fix: check "
                    "`limits` against the controller's SL/SR")
            limits[name] = (low, high)
            if not self.query(f"{ax}MO?", _parse_flag, "0 or 1"):
                if not self.enable_motors:
                    raise StageError(
                        f"stage axis {ax} ({name}): motor is off. Fix: pass enable_motors=True "
                        f"or send '{ax}MO'")
                self.write(f"{ax}MO")
                self.check_errors(f"{ax}MO")
        self.limits = limits
        return self

    def position(self) -> tuple[float, float]:
        """Encoder read-back of the two axes (``nTP?``).

        Returns
        -------
        (float, float)
            (alpha, beta), degrees.
        """
        return tuple(self.query(f"{ax}TP?", _parse_float, "a number") for ax in self.axes)

    def motion_done(self) -> bool:
        """Whether both axes report motion done (``nMD?``).

        Returns
        -------
        bool
            True when both axes are done.
        """
        return all(self.query(f"{ax}MD?", _parse_flag, "0 or 1") for ax in self.axes)

    def stop(self) -> None:
        """Stop both axes (``ST``)."""
        for ax in self.axes:
            self.write(f"{ax}ST")

    def check_target(self, alpha: float, beta: float) -> None:
        """Raise :class:`LimitError` if (alpha, beta) is outside the limits; sends nothing.

        Parameters
        ----------
        alpha, beta : float
            Target angles, degrees, checked against ``limits`` (read at :meth:`connect`).

        Raises
        ------
        LimitError
            A target that is not a finite number, or outside its axis's travel.
        """
        for name, value in (("alpha", alpha), ("beta", beta)):
            if not isinstance(value, int | float) or not math.isfinite(value):
                raise LimitError(f"stage: {name} = {value!r} is not a finite angle in degrees. "
                                 "Fix: check the plan")
            low, high = self.limits.get(name, (-math.inf, math.inf))
            if not low <= value <= high:
                raise LimitError.outside(name, value, low, high)

    def move_to(self, alpha: float, beta: float) -> tuple[float, float]:
        """Move to (alpha, beta) degrees, wait for motion done and settle; return the read-back.

        Parameters
        ----------
        alpha, beta : float
            Target angles of the outer and inner axis, degrees.

        Returns
        -------
        (float, float)
            Encoder read-back of (alpha, beta) after the settle time, degrees.

        Raises
        ------
        LimitError
            Target outside the limits (nothing sent), or the controller hit a limit.
        ControllerError
            Any other error the controller reported for the move.
        ErrorReplyLost
            A reply to ``TB?`` was lost or garbled, so an error of the move may have been lost.
        MotionTimeout
            An axis did not finish within ``motion_timeout_s`` (it was stopped).
        StageError
            The read-back is further than ``tolerance_deg`` from the target after
            ``move_retries`` extra moves.
        StageTimeout, StageProtocolError, StageDisconnected
            Link faults that outlasted the retries.
        """
        target = float(alpha), float(beta)
        self.check_target(*target)
        for attempt in range(self.move_retries + 1):
            read = self._move_once(dict(zip(self.axes, target, strict=True)))
            off = [(name, ax, want, got) for name, ax, want, got
                   in zip(("alpha", "beta"), self.axes, target, read, strict=True)
                   if abs(got - want) > self.tolerance_deg]
            if not off:
                return read
            log.warning("stage: read-back %s after a move to %s (attempt %d): move again",
                        read, target, attempt + 1)
        name, ax, want, got = off[0]
        raise StageError(
            f"stage axis {ax} ({name}): read back {got} deg after {self.move_retries + 1} "
            f"move(s) to {want} deg, more than tolerance_deg = {self.tolerance_deg} off. Fix: "
            "check the encoder and the servo tuning, or raise tolerance_deg")

    def _move_once(self, target: dict[int, float]) -> tuple[float, float]:
        for ax, value in target.items():
            self.write(f"{ax}PA{format_number(value)}")
        self.check_errors("PA")
        t_end = self._clock() + self.motion_timeout_s
        pending = list(self.axes)
        while pending := [ax for ax in pending if not self.query(f"{ax}MD?", _parse_flag,
                                                                   "0 or 1")]:
            if self._clock() > t_end:
                self.stop()
                found, lost = self._drain("ST")
                for err in found if lost is None else [lost]:
                    log.warning("stage: after stopping a stuck move: %s", err)
                raise MotionTimeout(pending, {ax: target[ax] for ax in pending},
                                    self.motion_timeout_s)
            self._sleep(self.poll_s)
        self.check_errors("PA")
        if self.settle_s:
            self._sleep(self.settle_s)
        return self.position()

    def describe(self) -> dict:
        """What the run metadata records about the stage.

        Returns
        -------
        dict
            JSON-ready: driver, port, controller identity, axes, ``limits_deg``, ``settle_s``
            and ``tolerance_deg``.
        """
        return {"driver": "sunlab.hardware.ESP300", "port": self.port_name,
                "identity": self.identity, "axes": list(self.axes),
                "limits_deg": {k: list(v) for k, v in self.limits.items()},
                "settle_s": self.settle_s, "tolerance_deg": self.tolerance_deg}
