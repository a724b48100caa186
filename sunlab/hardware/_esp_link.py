"""The link to a Newport ESP300 / ESP301 controller: its wire protocol and a query that
survives a lost, late or garbled reply (the layer under :class:`~sunlab.hardware.ESP300`).

A command is ``[axis]MNEMONIC[parameter]`` ending in a carriage return (``CR``); only queries
(a mnemonic followed by ``?``) are answered, each with one line ending ``CR LF`` (Newport ESP300
and ESP301 user's manuals, "Command Interface"). Replies are parsed strictly (a finite number, a
0/1 flag, a ``TB?`` triple, printable text), so a garbled reply is never taken for a value.

A query that times out or comes back garbled is retried with a growing delay, and a link
opened from a URL that drops is reopened, before :class:`~sunlab.hardware.errors.StageTimeout`
(or a protocol or link fault) is raised; after a lost or garbled reply the next query first
sends ``VE?`` and drops every line up to its reply, so a reply that arrives after its timeout is
never taken for the answer to a later query. Errors go to a first-in first-out buffer, ten
deep, read with ``TB?`` (code 0 when empty; :func:`~sunlab.hardware.errors.decode_error`).
Reading an error removes it from the buffer, so an error query is never retried blindly: a
``TB?`` reply that is lost or garbled may have carried an error, the buffer is read again until
a clean ``0, ..., NO ERROR DETECTED`` proves it empty, and
:class:`~sunlab.hardware.errors.ErrorReplyLost` is raised.
"""

from __future__ import annotations

import contextlib
import logging
import math
import re
import time
from collections.abc import Callable

from ..errors import ConfigurationError
from ..extras import require
from .errors import (
    ControllerError,
    ControllerLimitError,
    ErrorReplyLost,
    StageDisconnected,
    StageError,
    StageProtocolError,
    StageTimeout,
    decode_error,
)

log = logging.getLogger("sunlab.hardware")

WRITE_TERMINATOR, READ_TERMINATOR = b"\r", b"\r\n"

_TB_RE = re.compile(r"^\s*(\d+)\s*,\s*(\d+)\s*,\s*(.*?)\s*$")

#: Time a query's retries may spend beyond their read timeouts, s: the back-off waits, or at
#: least this much for a resynchronisation to read a late reply (issue 37: a dead controller is
#: declared within the tries times the timeout plus about 1.5 s).
_SLACK_S = 1.5


def open_transport(url: str, *, baudrate: int = 19200, timeout: float = 1.0, rtscts: bool = False):
    """Open a serial link from a device path or a :func:`serial.serial_for_url` URL.

    Parameters
    ----------
    url : str
        ``/dev/ttyUSB0``, ``COM3``, ``socket://127.0.0.1:5000``, ``rfc2217://host:port``, ...
    baudrate : int
        Bits per second (ESP300: 19200; ESP301 over USB: 921600).
    timeout : float
        Read and write timeout, s.
    rtscts : bool
        Hardware flow control (the ESP300's RS-232 port uses RTS/CTS).

    Returns
    -------
    serial.Serial
        The open port.

    Raises
    ------
    StageDisconnected
        When the port cannot be opened.

    Examples
    --------
    >>> port = open_transport("loop://", timeout=0.1)
    >>> port.write(b"1TP?\\r") and port.read_until(b"\\r")
    b'1TP?\\r'
    >>> port.close()
    """
    serial = require("serial", purpose="a serial stage (ESP300/301)")
    try:
        return serial.serial_for_url(url, baudrate=baudrate, timeout=timeout,
                                     write_timeout=timeout, rtscts=rtscts)
    except (OSError, ValueError) as err:  # serial.SerialException is an OSError
        raise StageDisconnected(url, f"cannot open: {err}") from err


def format_number(value: float) -> str:
    """A position as the shortest fixed-point text, to 1e-6 (the form sent after ``PA``).

    Parameters
    ----------
    value : float
        The position, in the axis's units (degrees for sunlab's rotation stages).

    Returns
    -------
    str
        Fixed-point text rounded to 6 decimals, trailing zeros dropped (``-0`` as ``0``).

    Examples
    --------
    >>> format_number(12.5), format_number(-3.0), format_number(0.1234567)
    ('12.5', '-3', '0.123457')
    """
    text = f"{float(value):.6f}".rstrip("0").rstrip(".")
    return "0" if text in ("", "-0") else text


def _valid(ok: bool, text: str, value):
    """``value`` parsed from a reply ``text``; a ValueError (a garbled reply) unless ``ok``."""
    if not ok:
        raise ValueError(text)
    return value


def _parse_float(text: str) -> float:
    return _valid(math.isfinite(value := float(text)), text, value)


def _parse_flag(text: str) -> bool:
    return _valid(text in ("0", "1"), text, text == "1")


def _parse_tb(text: str) -> tuple[int, int, str]:
    match = _TB_RE.match(text)
    return _valid(match is not None, text, match and (int(match[1]), int(match[2]), match[3]))


def _parse_text(text: str) -> str:
    return _valid(bool(text) and text.isprintable(), text, text)


class _NoReply(Exception):
    """No complete reply within the read timeout."""


class _Garbled(Exception):
    """A reply of the wrong shape; its bytes are ``args[0]``."""


def _check_settings(**values) -> None:
    """A timeout must be positive, a count or another time non-negative (NaN is neither)."""
    for name, value in values.items():
        if not (value > 0 if "timeout" in name else value >= 0):
            raise ConfigurationError(f"{name}: found {value!r}, expected a value "
                                     f"{'> 0 s' if 'timeout' in name else '>= 0'}")


class _Link:
    """A query/reply link to an ESP controller, with retries, resynchronisation and the error
    buffer (its parameters are :class:`~sunlab.hardware.ESP300`'s)."""

    def __init__(self, port, *, timeout: float = 1.0, retries: int = 3,
                 retry_delay_s: float = 0.2, baudrate: int = 19200, rtscts: bool = False,
                 sleep: Callable[[float], None] = time.sleep,
                 clock: Callable[[], float] = time.monotonic):
        _check_settings(timeout=timeout, retries=retries, retry_delay_s=retry_delay_s)
        self.timeout, self.retries = float(timeout), int(retries)
        self.retry_delay_s = float(retry_delay_s)
        self._sleep, self._clock = sleep, clock
        self.url = port if isinstance(port, str) else None
        self._port = port if self.url is None else open_transport(
            port, baudrate=baudrate, timeout=timeout, rtscts=rtscts)
        self.port_name = self.url or type(port).__name__
        self.identity, self.reconnects = "", 0
        self._out_of_step = False  # a reply was lost: resynchronise before the next query
        self._deadline: float | None = None  # of the query being retried

    def _reopen(self, detail: str) -> None:
        """Reopen a dropped link with its own settings (pyserial's ``close`` and ``open``)."""
        if self.url is None:
            raise StageDisconnected(self.port_name, detail)
        with contextlib.suppress(OSError):  # the old link is already broken
            self._port.close()
        try:
            self._port.open()
        except OSError as err:
            raise StageDisconnected(self.url, f"cannot reopen: {err}") from err
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
        """Send ``command`` once; with ``parse``, read and parse its reply. A reply that does
        not come, or does not have the shape ``parse`` wants, marks the link out of step."""
        if parse is None:
            return self._send(command)
        self._sync()
        self._send(command)
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
        also send ``VE?`` and drop every line up to its reply (the controller answers in
        order). A read timeout of silence sends the marker again. The wait lasts up to five
        read timeouts, and never into the time the query's remaining retries need, so that a
        dead controller, silent or flooding the line with noise, is declared in bounded time.
        """
        self._port.reset_input_buffer()
        if not self._out_of_step:
            return
        limit = math.inf if self._deadline is None else self._deadline
        deadline, ask = min(self._clock() + 5 * self.timeout, limit), True
        while self._clock() + self.timeout <= deadline + 1e-9:  # no read may end past it
            if ask:
                self._send("VE?")
            raw = self._port.read_until(READ_TERMINATOR, 256)
            if self._is_identity(raw):
                self._out_of_step = False
                log.info("stage: link back in step after a lost reply")
                return
            if raw:
                log.info("stage: dropped a late or stray reply %r", raw)
            ask = not raw
        raise _NoReply

    def _is_identity(self, raw: bytes) -> bool:
        """Whether a line read is the controller's reply to ``VE?`` (the marker)."""
        text = raw[: -len(READ_TERMINATOR)] if raw.endswith(READ_TERMINATOR) else b""
        return bool(text) and (text.decode("ascii", "replace") == self.identity
                               or text.startswith(b"ESP"))

    def _try(self, command: str, parse, attempt: int, expected: str):
        """Attempt number ``attempt`` (from 1) of ``command``, after its back-off wait; a fault
        is raised as StageTimeout, StageProtocolError or StageDisconnected."""
        try:
            if attempt > 1:
                self._sleep(self.retry_delay_s * 2 ** (attempt - 2))
                self._port.reset_input_buffer()  # a late reply to the failed attempt
            return self._once(command, parse)
        except _NoReply:
            log.info("stage: no reply to %r (attempt %d)", command, attempt)
            raise StageTimeout(command, attempt, self.timeout) from None
        except _Garbled as err:
            log.info("stage: garbled reply %r to %r (attempt %d)", err.args[0], command, attempt)
            raise StageProtocolError(command, err.args[0], expected, attempt) from None
        except OSError as err:  # serial.SerialException is an OSError
            raise StageDisconnected(self.port_name, str(err)) from err

    def query(self, command: str, parse: Callable[[str], object] | None = _parse_text,
              expected: str = "a line of printable ASCII"):
        """Send a query and return its parsed reply, retrying timeouts and garbled replies.

        Parameters
        ----------
        command : str
            E.g. ``"1TP?"`` (without the terminator).
        parse : callable or None
            Turns the reply text (terminator removed) into a value; raises ValueError when the
            reply is not valid. None: a command without a reply (see :meth:`write`).
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
        # A dead controller is declared within (retries + 1) read timeouts plus the back-off
        # waits, however its silence or its noise falls across the attempts (issue 37).
        delays = [self.retry_delay_s * 2**k for k in range(self.retries)]
        end = self._clock() + (self.retries + 1) * self.timeout + max(sum(delays), _SLACK_S)
        try:
            for attempt in range(self.retries + 1):
                # a resynchronisation leaves the back-off waits of the later retries their time
                self._deadline = end - sum(delays[attempt:])
                try:
                    return self._try(command, parse, attempt + 1, expected)
                except StageDisconnected as err:
                    last = err
                    if attempt < self.retries:
                        t0 = self._clock()
                        self._reopen(err.detail)
                        end += self._clock() - t0  # a new link: the reconnection is not waiting
                except StageError as err:
                    last = err
        finally:
            self._deadline = None
        raise last

    def write(self, command: str) -> None:
        """Send a command that has no reply (``1PA12.5``).

        A link that drops is reopened (when opened from a path or URL) and the command resent,
        up to ``retries`` times; nothing is read back, so a lost command shows only in the
        error buffer or the read-back.

        Parameters
        ----------
        command : str
            The command, without the terminator.
        """
        self.query(command, None, "")

    def close(self) -> None:
        """Close the link (motors stay as they are)."""
        self._port.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def _drain(self, command: str = ""):
        """Read the error buffer (``TB?``) until a clean "no error" reply; never retry blindly.

        Each ``TB?`` pops one entry, so an unreadable reply (timeout, garbled, dropped link) is
        counted as lost, since it may have carried an error, and the buffer is queried again,
        up to ``retries`` unreadable replies in a row. Returns ``(errors, lost)``: the errors
        read cleanly (oldest first), and None or, when any reply was unreadable, the
        :class:`ErrorReplyLost` to raise (chained to the last link fault when the buffer was
        never proved empty, else to the first error read).
        """
        found, lost, bad, empty, last = [], 0, 0, False, None
        while len(found) < 10:  # the buffer holds 10
            try:
                code, _, text = self._try("TB?", _parse_tb, bad + 1,
                                          "'code, timestamp, message'")
            except StageError as err:
                last, lost, bad = err, lost + 1, bad + 1
                log.warning("stage: reply to 'TB?' lost (%s): an error may have been lost", err)
                if bad > self.retries:
                    break
                if isinstance(err, StageDisconnected):
                    self._reopen(err.detail)
                continue
            bad = 0
            if code == 0:
                empty = True
                break
            found.append(self._error(code, text, command))
        if not lost:
            return found, None
        detail = (f"no reply within {self.timeout:g} s" if isinstance(last, StageTimeout) else
                  f"garbled reply {last.reply!r}" if isinstance(last, StageProtocolError) else
                  f"link dropped: {last.detail}")
        fault = ErrorReplyLost(command, lost, found, empty, detail)
        fault.__cause__ = last if not empty else (found[0] if found else None)
        return found, fault

    def errors(self, command: str = "") -> list[ControllerError]:
        """Drain the controller's error buffer (``TB?`` until code 0), oldest first.

        Parameters
        ----------
        command : str
            The command the errors follow, for the messages.

        Returns
        -------
        list of ControllerError
            The errors read (at most 10, the buffer's depth), oldest first; empty when the
            first clean reply is code 0.

        Raises
        ------
        ErrorReplyLost
            When any ``TB?`` reply was lost or garbled (each ``TB?`` pops an error, so one may
            be gone): raised even when the buffer then reads empty, and when it never does.

        Examples
        --------
        >>> from sunlab.hardware import ESP300
        >>> from sunlab.hardware.errors import ErrorReplyLost
        >>> from sunlab.hardware.fake import FakeESP
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
        found, lost = self._drain(command)
        if lost is not None:
            raise lost
        return found

    def _error(self, code: int, text: str = "", command: str = "") -> ControllerError:
        axis, meaning = decode_error(code)
        message = meaning if not text else f"{meaning}; controller says {text!r}"
        limit = axis is not None and code % 100 in (4, 5, 6, 7)
        return (ControllerLimitError if limit else ControllerError)(code, message, axis, command)

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
        for extra in found[1:]:
            log.warning("stage: further error: %s", extra)
        if found:
            raise found[0]

