"""Exceptions raised by the bench: stage, camera and acquisition faults, and the controller's
error codes (:func:`decode_error`).

Every fault of the hardware has its own class so that a script can catch exactly what it can
recover from; every message names the device, the command or field, what was found and the fix.
All derive from :class:`sunlab.SunlabError`, so ``sunlab acquire`` reports them on one line.
"""

from __future__ import annotations

import functools
import json
from importlib import resources

from ..errors import SunlabError

__all__ = ["BenchError", "MotionTimeout"]


class BenchError(SunlabError):
    """Base class of every bench fault (stage, camera, acquisition store)."""


class StageError(BenchError):
    """A fault of the rotation stage or of its controller link."""


class StageTimeout(StageError):
    """The controller sent no complete reply within the timeout, after every retry.

    Parameters
    ----------
    command : str
        The command whose reply never came.
    attempts : int
        How many times it was sent.
    timeout_s : float
        Read timeout of each attempt, s.
    """

    def __init__(self, command: str, attempts: int, timeout_s: float):
        self.command, self.attempts, self.timeout_s = command, attempts, timeout_s
        super().__init__(
            f"stage: no reply to {command!r} after {attempts} attempt(s) of {timeout_s:g} s. "
            "Fix: check the cable, the port and the baud rate (ESP300: 19200 8N1, RTS/CTS), "
            "that the controller is powered, and raise `timeout` if it goes silent after a limit")


class StageProtocolError(StageError):
    """The controller's replies could not be parsed (garbled line, wrong terminator).

    Parameters
    ----------
    command : str
        The command sent.
    reply : bytes
        The last reply received.
    expected : str
        What a valid reply looks like.
    attempts : int
        How many times the command was sent.
    """

    def __init__(self, command: str, reply: bytes, expected: str, attempts: int = 1):
        self.command, self.reply, self.expected, self.attempts = command, reply, expected, attempts
        super().__init__(
            f"stage: reply {reply!r} to {command!r} is not {expected} (after {attempts} "
            "attempt(s)). Fix: check the baud rate and flow control, and that no other program "
            "is using the port")


class StageDisconnected(StageError):
    """The link to the controller was lost (port closed, cable pulled, server gone).

    Parameters
    ----------
    port : str
        The port or URL of the link.
    detail : str
        What happened.
    """

    def __init__(self, port: str, detail: str):
        self.port, self.detail = port, detail
        super().__init__(
            f"stage: link to {port!r} lost ({detail}). Fix: reconnect the cable or restart the "
            "controller, then resume the run with `--resume`")


@functools.cache
def _codes() -> dict:
    """The ESP300/301 error tables (``sunlab/data/esp_errors.json``, from the manuals' "Error
    Messages"): ``general`` codes below 100, ``axis`` codes reported as ``axis * 100 + code``."""
    return json.loads((resources.files("sunlab") / "data" / "esp_errors.json")
                      .read_text(encoding="utf-8"))


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
    >>> decode_error(104), decode_error(6)
    ((1, 'positive hardware limit detected'), (None, 'command does not exist'))
    """
    axis, sub = divmod(int(code), 100)
    if axis:
        return axis, _codes()["axis"].get(str(sub), f"unknown axis error {sub}")
    return None, _codes()["general"].get(str(sub), f"unknown error {sub}")


#: The fix of a controller error: by axis sub-code (axis errors) or by general code.
_AXIS_FIXES = {
    (4, 5): "move the axis back inside its travel, then check the plan's angle range",
    (6, 7): "keep targets inside the software limits (SL/SR) or widen them on the controller",
    (2, 3, 9): "check the motor cable and the load, re-enable the motor (MO) and home the axis",
    (8, 13): "connect the stage and enable the motor (MO)",
}
_GENERAL_FIXES = {
    (6, 7, 9, 37, 38): "the command sent is invalid for this controller; report it as a sunlab bug",
    (4,): "release the emergency stop and re-enable the motors",
}


class ControllerError(StageError):
    """The controller reported an error code (read from its error buffer with ``TB?``).

    Parameters
    ----------
    code : int
        The controller's error code; axis errors are ``axis * 100 + code``.
    message : str
        The decoded meaning.
    axis : int or None
        The axis of an axis error, None for a general error.
    command : str
        The command after which the error was read.
    """

    def __init__(self, code: int, message: str, axis: int | None = None, command: str = ""):
        self.code, self.message, self.axis, self.command = int(code), message, axis, command
        sub, fixes = (code % 100, _AXIS_FIXES) if code >= 100 else (code, _GENERAL_FIXES)
        fix = next((text for codes, text in fixes.items() if sub in codes),
                   "see the controller manual's error table for this code")
        where = f"axis {axis}" if axis is not None else "controller"
        after = f" after {command!r}" if command else ""
        super().__init__(f"stage: {where} reported error {self.code} ({message}){after}. "
                         f"Fix: {fix}")


class ErrorReplyLost(StageError):
    """A reply to an error query (``TB?``) was lost or garbled: a controller error may be lost.

    Every ``TB?`` (and ``TE?``) pops one entry from the controller's error buffer, so a reply
    that never arrives, or arrives garbled, may have carried an error that can never be read
    again; resending the query reads the *next* entry. The driver therefore never takes an
    unreadable error query for "no error": it re-queries until the buffer is provably empty
    (a clean ``0, ..., NO ERROR DETECTED`` reply) and then raises this fault, whatever it read.

    Parameters
    ----------
    command : str
        The command the errors follow (``'PA'``), or ``''``.
    lost : int
        Error-query replies that timed out, came back garbled, or were cut by a dropped link.
    errors : list of ControllerError
        The errors that were read cleanly (oldest first); more may have been lost.
    empty : bool
        True when a clean "no error" reply proved the buffer empty afterwards.
    detail : str
        What happened to the last unreadable reply.

    Examples
    --------
    >>> err = ErrorReplyLost("PA", 1, [], True, "no reply within 1 s")
    >>> err.lost, err.empty, "may have been lost" in str(err)
    (1, True, True)
    """

    def __init__(self, command: str, lost: int, errors: list[ControllerError], empty: bool,
                 detail: str = ""):
        self.command, self.lost, self.errors = command, int(lost), list(errors)
        self.empty, self.detail = bool(empty), detail
        after = f" after {command!r}" if command else ""
        read = ("; read cleanly: " + "; ".join(f"error {e.code} ({e.message})" for e in errors)
                if errors else "")
        state = "was then read" if empty else "could not be read"
        why = f" (last: {detail})" if detail else ""
        replies = "1 reply" if self.lost == 1 else f"{self.lost} replies"
        super().__init__(
            f"stage: {replies} to the error query 'TB?'{after} lost or garbled{why}; each "
            "'TB?' pops one error from the controller's buffer, so a controller error may "
            f"have been lost{read}; the buffer {state} to empty. The command is not known to have "
            "succeeded. Fix: check the stage position and the controller's front panel for an "
            "error, then the cable, baud rate and flow control, and resume the run")


class LimitError(StageError):
    """A target outside the travel limits of an axis.

    Raised by the driver before any motion command is sent when a target lies outside the
    software limits (the controller's ``SL``/``SR`` intersected with the user's limits); its
    subclass :class:`ControllerLimitError` is the controller's own report of a limit.
    """

    @classmethod
    def outside(cls, field: str, value: float, low: float, high: float) -> LimitError:
        """The error for ``field = value`` outside ``[low, high]``.

        Parameters
        ----------
        field : str
            What is out of travel (an axis or a plan column, e.g. ``"alpha"``).
        value : float
            The asked position, degrees.
        low, high : float
            The travel limits, degrees.

        Returns
        -------
        LimitError
            The error, with ``field``, ``value``, ``low`` and ``high`` kept as attributes.
        """
        err = cls(
            f"stage: {field} = {value!r} deg is outside the travel [{low:g}, {high:g}] deg; "
            "nothing was moved. Fix: drop the pose from the plan, or widen the limits "
            "(controller SL/SR, or the driver's `limits`) if the mechanics allow it")
        err.field, err.value, err.low, err.high = field, value, low, high
        return err


class ControllerLimitError(ControllerError, LimitError):
    """The controller reported a hardware or software limit (axis error codes 4 to 7)."""


class MotionTimeout(StageError):
    """A move did not finish (``MD?`` stayed 0) within the motion timeout: a stuck axis.

    Parameters
    ----------
    axes : list of int
        The controller axes still moving.
    target : dict
        Their targets, degrees, by axis.
    timeout_s : float
        The motion timeout, s.
    """

    def __init__(self, axes: list[int], target: dict[int, float], timeout_s: float):
        self.axes, self.target, self.timeout_s = axes, target, timeout_s
        super().__init__(
            f"stage: axis {axes} did not reach {target} within {timeout_s:g} s and was stopped. "
            "Fix: check for a mechanical block or a disabled motor, then raise `motion_timeout` "
            "if the move is just long")


class CameraError(BenchError):
    """A camera fault: a frame of the wrong shape or type, an unreadable image file."""


class CameraTimeout(CameraError):
    """No frame arrived within the camera timeout."""
