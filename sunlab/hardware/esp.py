"""Newport ESP300 / ESP301 motion controller: a two-axis rotation stage over a serial link.

:class:`ESP300` drives the controller with the command subset of
:mod:`sunlab.hardware.esp_protocol` (``VE?``, ``TB?``, ``nSN?``, ``nSL?``/``nSR?``, ``nMO``,
``nPA``, ``nMD?``, ``nTP?``, ``nST``). Reading an error removes it from the controller's
buffer, so an error query is never retried blindly: a ``TB?`` reply that is lost or garbled
may have carried an error, the buffer is read again until a clean ``0, ..., NO ERROR
DETECTED`` proves it empty, and :class:`~sunlab.hardware.ErrorReplyLost` is raised (an error
may have been lost; the command is not reported as a success). The controller may go silent
for seconds after a limit: a query then gets no reply until it recovers, so every other query
is retried with a growing delay before :class:`~sunlab.hardware.StageTimeout` is raised.

Examples
--------
Drive the in-process fake controller (same protocol, over a pseudo-terminal):

>>> from sunlab.hardware import ESP300, FakeESP
>>> fake = FakeESP(velocity_deg_s=1e4)
>>> with ESP300(fake.serve_pty(), retry_delay_s=0.0, poll_s=0.001) as stage:
...     stage.move_to(12.5, -3.0)
(12.5, -3.0)
>>> fake.close()
"""

from __future__ import annotations

import logging
import math
import time
from collections.abc import Callable, Sequence

from ..errors import ConfigurationError
from .errors import (
    ControllerError,
    ControllerLimitError,
    ErrorReplyLost,
    LimitError,
    MotionTimeout,
    StageDisconnected,
    StageError,
    StageProtocolError,
    StageTimeout,
)
from .esp_protocol import (
    _LIMIT_CODES,
    READ_TERMINATOR,
    UNITS,
    WRITE_TERMINATOR,
    Transport,
    _parse_flag,
    _parse_float,
    _parse_tb,
    _parse_text,
    decode_error,
    format_number,
    open_transport,
)

__all__ = ["ESP300"]

log = logging.getLogger("sunlab.hardware")


class _NoReply(Exception):
    pass


class _Garbled(Exception):
    def __init__(self, raw: bytes):
        self.raw = raw


#: Time a query's retries may spend beyond their read timeouts, s: the back-off waits, or at
#: least this much for a resynchronisation to read a late reply (issue 37: a dead controller is
#: declared within the tries times the timeout plus about 1.5 s).
_SLACK_S = 1.5


class ESP300:
    """A two-axis rotation platform on a Newport ESP300 or ESP301 controller.

    The outer platform axis (alpha) and the inner one (beta) are two controller axes, in degrees
    (``SN7``). The driver checks targets against the travel limits before sending any motion
    command, retries queries that time out or come back garbled, reconnects a link that drops
    when it was opened from a URL, decodes the controller's error buffer after each move, and
    waits for motion done plus a settle time before reading the encoders back.

    Parameters
    ----------
    port : str or Transport
        A device path or :func:`serial.serial_for_url` URL, or an open transport.
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
        The waits (:func:`time.sleep`) and the clock of the resynchronisation's deadline
        (:func:`time.monotonic`), replaceable to test the driver's timing.

    Notes
    -----
    A move is ``nPA`` for both axes, ``TB?`` (a refused command is reported at once), ``nMD?``
    polls until both axes are done, ``TB?`` again (a limit or following error during the move),
    the settle wait, and ``nTP?`` for the read-back. An unreadable ``TB?`` reply is never
    read as "no error" (:class:`~sunlab.hardware.ErrorReplyLost`). Position queries are
    idempotent and so are absolute moves, which makes resending them after a fault safe. After
    a timeout the input buffer is flushed before the resend, and every query starts by dropping
    what the link holds; after a lost or garbled reply the next query first sends ``VE?`` and
    drops every line up to its reply, so a reply that arrives after its timeout is never taken
    for the answer to a later query (replies are matched to queries, not read one late).

    Examples
    --------
    >>> from sunlab.hardware import FakeESP
    >>> fake = FakeESP(velocity_deg_s=1e4)
    >>> stage = ESP300(fake.serve_pty(), retry_delay_s=0.0, poll_s=0.001)
    >>> stage.identity.startswith("ESP301")
    True
    >>> stage.limits["alpha"]
    (-170.0, 170.0)
    >>> stage.close(); fake.close()
    """

    def __init__(
        self,
        port: str | Transport,
        *,
        axes: Sequence[int] = (1, 2),
        timeout: float = 1.0,
        retries: int = 3,
        retry_delay_s: float = 0.2,
        settle_s: float = 0.0,
        motion_timeout_s: float = 60.0,
        poll_s: float = 0.05,
        limits: dict[str, tuple[float, float]] | None = None,
        tolerance_deg: float = 0.01,
        move_retries: int = 1,
        enable_motors: bool = True,
        baudrate: int = 19200,
        rtscts: bool = False,
        connect: bool = True,
        sleep: Callable[[float], None] = time.sleep,
        clock: Callable[[], float] = time.monotonic,
    ):
        axes = tuple(int(a) for a in axes)
        if len(axes) != 2 or len(set(axes)) != 2 or min(axes) < 1:
            raise ConfigurationError(
                f"axes: found {axes!r}, expected two distinct controller axes (1, 2 or 3) for "
                "alpha and beta. Fix: pass axes=(1, 2)"
            )
        for name, value in (("timeout", timeout), ("motion_timeout_s", motion_timeout_s)):
            if not value > 0:
                raise ConfigurationError(f"{name}: found {value!r}, expected a positive time in s")
        for name, value in (("retries", retries), ("move_retries", move_retries),
                            ("retry_delay_s", retry_delay_s),
                            ("settle_s", settle_s), ("poll_s", poll_s)):
            if not value >= 0:
                raise ConfigurationError(f"{name}: found {value!r}, expected a value >= 0")
        self.axes = axes
        self.timeout = float(timeout)
        self.retries = int(retries)
        self.retry_delay_s = float(retry_delay_s)
        self.settle_s = float(settle_s)
        self.motion_timeout_s = float(motion_timeout_s)
        self.poll_s = float(poll_s)
        self.tolerance_deg = float(tolerance_deg)
        self.move_retries = int(move_retries)
        self.enable_motors = bool(enable_motors)
        self._user_limits = dict(limits or {})
        self._baudrate = int(baudrate)
        self._rtscts = bool(rtscts)
        self._sleep = sleep
        self._clock = clock
        if isinstance(port, str):
            self.url: str | None = port
            self._port = open_transport(port, baudrate=baudrate, timeout=timeout, rtscts=rtscts)
        else:
            self.url = None
            self._port = port
        self.port_name = self.url or type(port).__name__
        self.identity = ""
        self.limits: dict[str, tuple[float, float]] = {}
        self.stale_errors: list[ControllerError] = []
        self.reconnects = 0
        self._out_of_step = False  # a reply was lost: resynchronise before the next query
        self._deadline: float | None = None  # of the query being retried (_exchange)
        if connect:
            try:
                self.connect()
            except BaseException:
                if self.url is not None:  # we opened it: do not leak the port
                    self._port.close()
                raise

    # -- link ---------------------------------------------------------------------------------
    def _reopen(self, detail: str) -> None:
        if self.url is None:
            raise StageDisconnected(self.port_name, detail)
        try:
            self._port.close()
        except Exception:  # noqa: BLE001 - the old link is already broken
            pass
        self._port = open_transport(
            self.url, baudrate=self._baudrate, timeout=self.timeout, rtscts=self._rtscts
        )
        self.reconnects += 1
        log.warning("stage: reconnected to %s after: %s", self.url, detail)

    def _send(self, command: str) -> None:
        self._port.write(command.encode("ascii") + WRITE_TERMINATOR)

    def _readline(self) -> bytes:
        raw = self._port.read_until(READ_TERMINATOR, 256)
        if not raw:
            raise _NoReply
        if not raw.endswith(READ_TERMINATOR):
            raise _Garbled(raw)
        return raw

    def _once(self, command: str, parse: Callable[[str], object] | None):
        """Send ``command`` once; with ``parse``, read and parse its reply (no retry).

        A query first drops whatever the link holds (:meth:`_sync`), so a reply is only ever
        read as the answer to the query just sent; a reply that does not come, or does not
        have the shape ``parse`` wants, marks the link out of step for the next query.

        Raises _NoReply, _Garbled, or the link's own exception."""
        if parse is not None:
            self._sync()
        self._send(command)
        if parse is None:
            return None
        try:
            raw = self._readline()
            for _ in range(4):  # a marker sent twice by _sync is answered twice: drop it
                if command == "VE?" or not self._is_identity(raw):
                    break
                raw = self._readline()
            try:
                return parse(raw[: -len(READ_TERMINATOR)].decode("ascii"))
            except (UnicodeDecodeError, ValueError) as err:
                raise _Garbled(raw) from err
        except BaseException:
            self._out_of_step = True  # its reply may still come: never take it for the next
            raise

    def _sync(self) -> None:
        """Before a query: drop the bytes already received; after a lost or garbled reply,
        also send ``VE?`` and read and drop every line up to its reply (the controller answers
        in order, so a late reply to an earlier query comes before it). A read timeout of
        silence means the marker (or its reply) was lost too: it is sent again. The wait lasts
        up to five read timeouts, and never into the time that the query's remaining retries
        need (:meth:`_exchange`), so that a dead controller, silent or flooding the line with
        noise, is declared within ``(retries + 1) * timeout`` plus the back-off waits.

        Raises _NoReply when the marker's reply does not come (the link stays out of step)."""
        self._port.reset_input_buffer()
        if not self._out_of_step:
            return
        deadline = self._clock() + 5 * self.timeout
        if self._deadline is not None:
            deadline = min(deadline, self._deadline)
        ask = True
        while self._clock() + self.timeout <= deadline + 1e-9:  # no read may end past it
            if ask:
                self._send("VE?")
                ask = False
            raw = self._port.read_until(READ_TERMINATOR, 256)
            if self._is_identity(raw):
                self._out_of_step = False
                log.info("stage: link back in step after a lost reply")
                return
            if raw:
                log.info("stage: dropped a late or stray reply %r", raw)
            else:
                ask = True
        raise _NoReply

    def _is_identity(self, raw: bytes) -> bool:
        """Whether a line read is the controller's reply to ``VE?`` (the marker)."""
        text = raw[: -len(READ_TERMINATOR)] if raw.endswith(READ_TERMINATOR) else b""
        return bool(text) and (text.decode("ascii", "replace") == self.identity
                               or text.startswith(b"ESP"))

    def _fault(self, command: str, err: BaseException, attempt: int, expected: str) -> StageError:
        """The driver's error for one failed attempt of ``command`` (attempt counts from 1)."""
        if isinstance(err, _NoReply):
            log.info("stage: no reply to %r (attempt %d)", command, attempt)
            return StageTimeout(command, attempt, self.timeout)
        if isinstance(err, _Garbled):
            log.info("stage: garbled reply %r to %r (attempt %d)", err.raw, command, attempt)
            return StageProtocolError(command, err.raw, expected, attempt)
        return StageDisconnected(self.port_name, str(err))

    def _backoff(self, attempt: int) -> None:
        """Wait before retry number ``attempt`` (1, 2, ...) and flush any late reply."""
        self._sleep(self.retry_delay_s * 2 ** (attempt - 1))
        self._port.reset_input_buffer()

    def _exchange(self, command: str, parse: Callable[[str], object] | None, expected: str):
        """Send ``command``; with ``parse``, read and parse its reply. Retries on faults."""
        import serial

        last: Exception | None = None
        # A dead controller is declared within (retries + 1) read timeouts plus the back-off
        # waits, however its silence or its noise falls across the attempts (issue 37).
        delays = [self.retry_delay_s * 2 ** (k - 1) for k in range(1, self.retries + 1)]
        end = self._clock() + (self.retries + 1) * self.timeout + max(sum(delays), _SLACK_S)
        try:
            for attempt in range(self.retries + 1):
                # a resynchronisation leaves the back-off waits of the later retries their time
                self._deadline = end - sum(delays[attempt:])
                try:
                    if attempt:
                        self._backoff(attempt)
                    return self._once(command, parse)
                except (_NoReply, _Garbled) as err:
                    last = self._fault(command, err, attempt + 1, expected)
                except (serial.SerialException, OSError) as err:
                    last = self._fault(command, err, attempt + 1, expected)
                    if attempt == self.retries:
                        break
                    t0 = self._clock()
                    self._reopen(str(err))
                    end += self._clock() - t0  # a new link: the reconnection is not waiting
        finally:
            self._deadline = None
        assert last is not None
        raise last

    def query(self, command: str, parse: Callable[[str], object] = _parse_text,
              expected: str = "a line of printable ASCII"):
        """Send a query and return its parsed reply, retrying timeouts and garbled replies.

        Parameters
        ----------
        command : str
            E.g. ``"1TP?"`` (without the terminator).
        parse : callable
            Turns the reply text (terminator removed) into a value; raises ValueError when the
            reply is not valid.
        expected : str
            How a valid reply looks, for the error message.

        Returns
        -------
        object
            ``parse`` of the reply text (``str`` with the default ``parse``).

        Raises
        ------
        StageTimeout, StageProtocolError, StageDisconnected
        """
        return self._exchange(command, parse, expected)

    def write(self, command: str) -> None:
        """Send a command that has no reply (``1PA12.5``).

        A link that drops is reopened (when opened from a path or URL) and the command resent,
        up to ``retries`` times; nothing is read back, so a lost command shows only in the
        error buffer or the read-back.

        Parameters
        ----------
        command : str
            The command, without the terminator.

        Raises
        ------
        StageDisconnected
            The link dropped and cannot be reopened.
        """
        self._exchange(command, None, "")

    def close(self) -> None:
        """Close the link (motors stay as they are)."""
        self._port.close()

    def __enter__(self) -> ESP300:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

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
        self._port.reset_input_buffer()
        self.identity = self.query("VE?")
        self.stale_errors, lost = self._drain()
        if lost is not None and not lost.empty:
            raise lost
        if lost is not None:  # stale errors never fail the handshake: a lost one is logged
            log.warning("stage: at connect, %s", lost)
        for err in self.stale_errors:
            log.warning("stage: stale error in the controller buffer: %s", err)
        limits = {}
        for name, ax in zip(("alpha", "beta"), self.axes, strict=True):
            units = self.query(f"{ax}SN?", int, "a unit code")
            if units != 7:
                raise ConfigurationError(
                    f"stage axis {ax} ({name}) units: found {units} "
                    f"({UNITS.get(units, 'unknown')}), expected 7 (degree). Fix: send "
                    f"'{ax}SN7' and save with 'SM', or use the controller's front panel"
                )
            low = self.query(f"{ax}SL?", _parse_float, "a number")
            high = self.query(f"{ax}SR?", _parse_float, "a number")
            user = self._user_limits.get(name)
            if user is not None:
                low, high = max(low, float(user[0])), min(high, float(user[1]))
            if not low < high:
                raise ConfigurationError(
                    f"stage {name} limits: found [{low}, {high}], expected low < high. Fix: check "
                    "`limits` against the controller's SL/SR"
                )
            limits[name] = (low, high)
            if not self.query(f"{ax}MO?", _parse_flag, "0 or 1"):
                if not self.enable_motors:
                    raise StageError(
                        f"stage axis {ax} ({name}): motor is off. Fix: pass enable_motors=True "
                        f"or send '{ax}MO'"
                    )
                self.write(f"{ax}MO")
                self.check_errors(f"{ax}MO")
        self.limits = limits
        return self

    def _drain(self, command: str = "", max_errors: int = 10):
        """Read the error buffer (``TB?``) until a clean "no error" reply; never retry blindly.

        Each ``TB?`` pops one entry, so an unreadable reply (timeout, garbled, dropped link) is
        counted as lost, since it may have carried an error, and the buffer is queried again,
        up to ``retries`` unreadable replies in a row. Returns ``(errors, lost)``: the errors
        read cleanly (oldest first), and None or, when any reply was unreadable, the
        :class:`ErrorReplyLost` to raise (chained to the last link fault when the buffer was
        never proved empty, else to the first error read).
        """
        import serial

        expected = "'code, timestamp, message'"
        found: list[ControllerError] = []
        lost = bad_in_a_row = 0
        detail = ""
        last: StageError | None = None
        empty = False
        while len(found) < max_errors:
            try:
                if bad_in_a_row:
                    self._backoff(bad_in_a_row)
                code, _stamp, text = self._once("TB?", _parse_tb)
            except (_NoReply, _Garbled, serial.SerialException, OSError) as err:
                last = self._fault("TB?", err, bad_in_a_row + 1, expected)
                lost += 1
                bad_in_a_row += 1
                detail = (f"no reply within {self.timeout:g} s" if isinstance(err, _NoReply)
                          else f"garbled reply {err.raw!r}" if isinstance(err, _Garbled)
                          else f"link dropped: {err}")
                log.warning("stage: reply to 'TB?' lost (%s): an error may have been lost",
                            detail)
                if bad_in_a_row > self.retries:
                    break
                if isinstance(last, StageDisconnected):
                    self._reopen(str(err))
                continue
            bad_in_a_row = 0
            if code == 0:
                empty = True
                break
            found.append(self._error(code, text, command))
        if not lost:
            return found, None
        fault = ErrorReplyLost(command, lost, found, empty, detail)
        fault.__cause__ = last if not empty else (found[0] if found else None)
        return found, fault

    def errors(self, command: str = "", max_errors: int = 10) -> list[ControllerError]:
        """Drain the controller's error buffer (``TB?`` until code 0), oldest first.

        Parameters
        ----------
        command : str
            The command the errors follow, for the messages.
        max_errors : int
            At most this many are read (the ESP buffer holds 10).

        Returns
        -------
        list of ControllerError
            The errors read, oldest first; empty when the first clean reply is code 0.

        Raises
        ------
        ErrorReplyLost
            When any ``TB?`` reply was lost or garbled (each ``TB?`` pops an error, so one may
            be gone): raised even when the buffer then reads empty, and when it never does.

        Examples
        --------
        >>> from sunlab.hardware import ErrorReplyLost, FakeESP
        >>> fake = FakeESP()
        >>> stage = ESP300(fake.serve_pty(), retry_delay_s=0.0, timeout=0.2)
        >>> stage.write("9PA1"); [err.code for err in stage.errors("9PA1")]
        [9]
        >>> _ = fake.inject("garble", "TB?")      # line noise on the reply that carries error 9
        >>> stage.write("9PA1")
        >>> try:
        ...     stage.errors("9PA1")
        ... except ErrorReplyLost as err:
        ...     print(err.lost, err.empty, err.errors)
        1 True []
        >>> stage.close(); fake.close()
        """
        found, lost = self._drain(command, max_errors)
        if lost is not None:
            raise lost
        return found

    def _error(self, code: int, text: str = "", command: str = "") -> ControllerError:
        axis, meaning = decode_error(code)
        message = meaning if not text else f"{meaning}; controller says {text!r}"
        cls = ControllerLimitError if axis is not None and code % 100 in _LIMIT_CODES else (
            ControllerError
        )
        return cls(code, message, axis, command)

    def check_errors(self, command: str = "") -> None:
        """Raise the oldest error in the controller's buffer, if any (the rest are logged).

        Parameters
        ----------
        command : str
            The command the errors follow, named in the messages.

        Raises
        ------
        ControllerError
            The oldest error read (a :class:`ControllerLimitError` for codes 4-7).
        ErrorReplyLost
            A ``TB?`` reply was lost or garbled (see :meth:`errors`).
        """
        found = self.errors(command)
        if found:
            for extra in found[1:]:
                log.warning("stage: further error: %s", extra)
            raise found[0]

    def position(self) -> tuple[float, float]:
        """Encoder read-back of the two axes (``nTP?``).

        Returns
        -------
        (float, float)
            (alpha, beta), degrees.
        """
        a, b = (self.query(f"{ax}TP?", _parse_float, "a number") for ax in self.axes)
        return a, b

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
                raise LimitError(
                    f"stage: {name} = {value!r} is not a finite angle in degrees. Fix: check "
                    "the plan"
                )
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
        alpha, beta = float(alpha), float(beta)
        self.check_target(alpha, beta)
        target = dict(zip(self.axes, (alpha, beta), strict=True))
        for attempt in range(self.move_retries + 1):
            read = self._move_once(target)
            off = [(name, ax, want, got) for name, ax, want, got
                   in zip(("alpha", "beta"), self.axes, (alpha, beta), read, strict=True)
                   if abs(got - want) > self.tolerance_deg]
            if not off:
                return read
            log.warning("stage: read-back %s after a move to %s (attempt %d): move again",
                        read, (alpha, beta), attempt + 1)
        name, ax, want, got = off[0]
        raise StageError(
            f"stage axis {ax} ({name}): read back {got} deg after {self.move_retries + 1} "
            f"move(s) to {want} deg, more than tolerance_deg = {self.tolerance_deg} off. Fix: "
            "check the encoder and the servo tuning, or raise tolerance_deg"
        )

    def _move_once(self, target: dict[int, float]) -> tuple[float, float]:
        for ax, value in target.items():
            self.write(f"{ax}PA{format_number(value)}")
        self.check_errors("PA")
        t_end = time.monotonic() + self.motion_timeout_s
        pending = list(self.axes)
        while pending:
            pending = [ax for ax in pending
                       if not self.query(f"{ax}MD?", _parse_flag, "0 or 1")]
            if not pending:
                break
            if time.monotonic() > t_end:
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
        return {
            "driver": "sunlab.hardware.ESP300",
            "port": self.port_name,
            "identity": self.identity,
            "axes": list(self.axes),
            "limits_deg": {k: list(v) for k, v in self.limits.items()},
            "settle_s": self.settle_s,
            "tolerance_deg": self.tolerance_deg,
        }
