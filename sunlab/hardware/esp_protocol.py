"""The Newport ESP300 / ESP301 wire protocol: commands, replies, error codes, the byte link.

The controller's ASCII command set (Newport ESP300 and ESP301 user's manuals, "Command
Interface"): a command is ``[axis]MNEMONIC[parameter]`` terminated by a carriage return
(``CR``); only queries (a mnemonic followed by ``?``) are answered, each with one line terminated
by ``CR LF``. The subset :class:`~sunlab.hardware.ESP300` uses:

=============  =====================================  ==========================================
command        meaning                                reply
=============  =====================================  ==========================================
``VE?``        firmware version                       ``ESP301 Version 3.0.2 6/29/11``
``TB?``        pop the oldest error, with its text    ``code, timestamp, message``
``TE?``        pop the oldest error code               ``code``
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

Errors go to a first-in first-out buffer, ten deep, read with ``TB?``/``TE?`` (code 0 when
empty). Axis errors are coded ``axis * 100 + code`` (``104``: axis 1, positive hardware limit);
general errors are below 100 (:func:`decode_error`). Positions are sent as the shortest
fixed-point text (:func:`format_number`); replies are parsed strictly (a finite number, a 0/1
flag, a ``TB?`` triple, printable text), so a garbled reply is never taken for a value.

The transport is anything with ``write``, ``read_until``, ``reset_input_buffer`` and ``close``
(a :class:`serial.Serial`); :func:`open_transport` opens any :func:`serial.serial_for_url` URL
(``/dev/ttyUSB0``, ``COM3``, ``socket://host:port``, ``rfc2217://...``), so other controllers
can reuse the same plumbing.

Examples
--------
>>> format_number(12.5), decode_error(104)
('12.5', (1, 'positive hardware limit detected'))
"""

from __future__ import annotations

import math
import re
from typing import Protocol, runtime_checkable

from ..extras import require
from .errors import StageDisconnected

__all__ = []

WRITE_TERMINATOR = b"\r"
READ_TERMINATOR = b"\r\n"

#: ``SN`` unit codes of the ESP300/301 (the driver needs 7, degrees, on both axes).
UNITS = {
    0: "encoder count",
    1: "motor step",
    2: "millimeter",
    3: "micrometer",
    4: "inch",
    5: "milli-inch",
    6: "micro-inch",
    7: "degree",
    8: "gradian",
    9: "radian",
    10: "milliradian",
    11: "microradian",
}

#: General (controller) error codes, below 100 (ESP300/301 manuals, "Error Messages").
GENERAL_ERRORS = {
    0: "no error detected",
    1: "PCI communication time-out",
    4: "emergency stop activated",
    6: "command does not exist",
    7: "parameter out of range",
    8: "cable interlock error",
    9: "axis number out of range",
    13: "group number missing",
    14: "group number out of range",
    15: "group number not assigned",
    16: "group number already assigned",
    17: "group axis out of range",
    18: "group axis already assigned",
    19: "group axis duplicated",
    20: "data acquisition is busy",
    21: "data acquisition setup error",
    22: "data acquisition not enabled",
    23: "servo cycle (400 us) tick failure",
    25: "download in progress",
    26: "stored program not started",
    27: "command not allowed",
    28: "stored program flash area full",
    29: "group parameter missing",
    30: "group parameter out of range",
    31: "group maximum velocity exceeded",
    32: "group maximum acceleration exceeded",
    33: "group maximum deceleration exceeded",
    34: "group move not allowed during motion",
    35: "program not found",
    37: "axis number missing",
    38: "command parameter missing",
    39: "program label not found",
    40: "last command cannot be repeated",
    41: "maximum number of labels per program exceeded",
}

#: Axis error codes: the controller reports ``axis * 100 + code``.
AXIS_ERRORS = {
    0: "motor type not defined",
    1: "parameter out of range",
    2: "amplifier fault detected",
    3: "following error threshold exceeded",
    4: "positive hardware limit detected",
    5: "negative hardware limit detected",
    6: "positive software limit detected",
    7: "negative software limit detected",
    8: "motor / stage not connected",
    9: "feedback signal fault detected",
    10: "maximum velocity exceeded",
    11: "maximum acceleration exceeded",
    13: "motor not enabled",
    15: "maximum jerk exceeded",
    16: "maximum DAC offset exceeded",
    17: "ESP critical settings are protected",
    18: "ESP stage device error",
    19: "ESP stage data invalid",
    20: "homing aborted",
    21: "motor current not defined",
    22: "unidrive communications error",
    23: "unidrive not detected",
    24: "speed out of range",
    25: "invalid trajectory master axis",
    26: "parameter change not allowed",
    27: "invalid trajectory mode for homing",
    28: "invalid encoder step ratio",
    29: "digital I/O interlock detected",
    30: "command not allowed during homing",
    31: "command not allowed due to group assignment",
    32: "invalid trajectory mode for moving",
}

_LIMIT_CODES = (4, 5, 6, 7)
_TB_RE = re.compile(r"^\s*(\d+)\s*,\s*(\d+)\s*,\s*(.*?)\s*$")


@runtime_checkable
class Transport(Protocol):
    """The byte link to a controller: what :class:`serial.Serial` offers."""

    def write(self, data: bytes) -> int | None:
        """Send bytes to the controller.

        Parameters
        ----------
        data : bytes
            One ASCII command line, ending in the terminator (``\\r``).

        Returns
        -------
        int or None
            The number of bytes written (None where the link does not say).
        """
        ...

    def read_until(self, expected: bytes = ..., size: int | None = None) -> bytes:
        """Read up to and including ``expected``, or until the link's timeout.

        Parameters
        ----------
        expected : bytes
            The terminator to stop at (the link's default: ``\\n``; the ESP's replies end
            ``\\r\\n``).
        size : int, optional
            Stop after this many bytes.

        Returns
        -------
        bytes
            What was read; without ``expected`` at its end on a timeout (possibly empty).
        """
        ...

    def reset_input_buffer(self) -> None: ...

    def close(self) -> None: ...


def open_transport(url: str, *, baudrate: int = 19200, timeout: float = 1.0, rtscts: bool = False):
    """Open a serial link from a device path or a :func:`serial.serial_for_url` URL.

    Parameters
    ----------
    url : str
        ``/dev/ttyUSB0``, ``COM3``, ``socket://127.0.0.1:5000``, ``rfc2217://host:port``, ...
    baudrate : int
        Bits per second (ESP300: 19200; ESP301 over USB: 921600).
    timeout : float
        Read timeout, s.
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
        return serial.serial_for_url(
            url, baudrate=baudrate, timeout=timeout, write_timeout=timeout, rtscts=rtscts
        )
    except (serial.SerialException, OSError, ValueError) as err:
        raise StageDisconnected(url, f"cannot open: {err}") from err


def decode_error(code: int) -> tuple[int | None, str]:
    """Axis and meaning of an ESP300/301 error code.

    Parameters
    ----------
    code : int
        Code from ``TE?`` or ``TB?``; axis errors are ``axis * 100 + code``.

    Returns
    -------
    axis : int or None
        The axis (1, 2, 3) of an axis error; None for a general error.
    message : str
        The meaning of the code.

    Examples
    --------
    >>> decode_error(104)
    (1, 'positive hardware limit detected')
    >>> decode_error(6)
    (None, 'command does not exist')
    """
    code = int(code)
    if code >= 100:
        axis, sub = divmod(code, 100)
        return axis, AXIS_ERRORS.get(sub, f"unknown axis error {sub}")
    return None, GENERAL_ERRORS.get(code, f"unknown error {code}")


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


def _parse_float(text: str) -> float:
    value = float(text)
    if not math.isfinite(value):
        raise ValueError(text)
    return value


def _parse_flag(text: str) -> bool:
    if text not in ("0", "1"):
        raise ValueError(text)
    return text == "1"


def _parse_tb(text: str) -> tuple[int, int, str]:
    match = _TB_RE.match(text)
    if match is None:
        raise ValueError(text)
    return int(match.group(1)), int(match.group(2)), match.group(3)


def _parse_text(text: str) -> str:
    if not text or not text.isprintable():
        raise ValueError(text)
    return text

