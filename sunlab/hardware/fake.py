"""A fake Newport ESP300/ESP301 controller: the same byte protocol, a simulated platform.

:class:`FakeESP` answers the manual's commands below exactly as the controller does: commands
end with ``CR``, query replies end with ``CR LF``, errors queue in a 10-deep buffer, axis errors
are ``axis * 100 + code``. Axes move at a finite velocity (``math.inf``: instant moves, for
protocol tests) on any monotonic clock (one that a test advances by hand, say). It
serves a pseudo-terminal (:meth:`FakeESP.serve_pty`) and a loopback TCP port
(:meth:`FakeESP.serve_tcp`), which the driver opens like any serial port.

Commands (``n`` an axis; blanks between fields are ignored, ``;`` chains commands on a line):

======================  ========================================================================
``VE?``                 firmware version
``TB?``, ``TE?``        pop the oldest error (``code, timestamp, message``; the code); 0 when empty
``TS``                  status byte, one character: bit n-1 axis n moving, bit 4 a motor on
``nTP?``, ``nTP``       actual position (the manual also reads it without ``?``)
``nDP?``                desired position (the destination of the move)
``nMD?``                motion done (1) or moving (0)
``nID?``                positioner model and serial number: ``URS100BCC, SN0001``
``nPA<x>``              move to x (errors ``n06``/``n07`` past a limit, ``n13`` motor off)
``nWS[ms]``             wait for stop: later commands run once axis n has stopped, plus ms (the
                        fake answers them at once, its time moved on to the end of the wait)
``nOR[mode]``           home search (mode 0 to 6): the axis moves to its home position
``nDH[x]``, ``nDH?``    define home: the position here reads x (default 0); read the home value
``nSN[u]``, ``nSN?``    units (0 to 11; 7 degree)
``nSL``/``nSR``         software limits (set, or read with ``?``); ``nVA`` velocity
``nMO``, ``nMF``        motor on / off; ``nMO?`` motor state; ``nST`` stop; ``AB`` abort all
======================  ========================================================================

Anything else queues error 6 (command does not exist), 37 (axis number missing), 9 (axis out of
range), 38 (parameter missing) or 7 (parameter out of range), as the controller does.

The encoders read the commanded angles; :meth:`FakeESP.true_pose` gives the angles the virtual
bench's platform really takes (:func:`sunlab.sim.platform.platform_pose`; ideal without a bench).

Faults are injected with :meth:`FakeESP.inject`:

==============  ==============================================================================
kind            effect on the next ``count`` commands that contain ``match``
==============  ==============================================================================
``timeout``     the reply is not sent
``garble``      the reply's bytes are corrupted (high bit set), the terminator kept
``error``       the command runs, then error ``code`` is queued; a limit code (axis 4 to 7)
                also stops the axis and silences the controller (as ``silent``) for
                ``silent_s``
``silent``      after the command, nothing is executed or answered for ``silent_s`` seconds
``stuck``       a ``PA`` move stops half-way and never reports motion done (until ``ST``)
``disconnect``  the link is closed (the TCP server then accepts a new connection)
``late``        the reply is sent ``silent_s`` seconds late (after the driver's timeout); later
                commands wait behind it, as on a busy controller (served links only)
==============  ==============================================================================

Examples
--------
>>> fake = FakeESP(velocity_deg_s=math.inf)   # instant moves: no wall-clock race
>>> fake.handle(b"1PA2.5")
>>> fake.handle(b"1TP?")
b'2.500000\\r\\n'
>>> fake.handle(b"3PA999"); fake.handle(b"TB?").split(b", ")[0]
b'306'
>>> fake.handle(b"1TP"), fake.handle(b"1 ID ?"), fake.handle(b"TS")
(b'2.500000\\r\\n', b'URS100BCC, SN0001\\r\\n', b'P\\r\\n')
"""

from __future__ import annotations

import math
import re
import threading
import time
from collections import deque
from dataclasses import dataclass

from ..errors import ConfigurationError
from . import _serve
from ._serve import DISCONNECT
from .errors import decode_error

__all__ = []

FAULT_KINDS = ("timeout", "garble", "error", "silent", "stuck", "disconnect", "late")

_CMD_RE = re.compile(r"^(\d*)([A-Za-z]{2})(.*)$")
#: Commands that need an axis number (error 37 without one).
#: Commands of an axis that take a number; WS, OR and DH without one take 0.
_SETTERS = frozenset({"WS", "OR", "DH", "SN", "PA", "SL", "SR", "VA"})
_AXIS_COMMANDS = _SETTERS | {"TP", "DP", "MD", "MO", "MF", "ST", "ID"}


@dataclass
class Fault:
    """One injected fault (see the module docstring for the kinds)."""

    kind: str
    match: str = ""
    count: int = 1
    code: int = 0
    silent_s: float = 2.0
    after: int = 0


class _Axis:
    def __init__(self, low: float, high: float, velocity: float, motor_on: bool):
        self.low, self.high, self.velocity, self.motor_on = low, high, velocity, motor_on
        self.units, self.home, self.stuck, self.start = 7, 0.0, False, 0.0
        self.target = self.t0 = self.t1 = 0.0

    def position(self, now: float) -> float:
        if self.stuck:
            return self.start + 0.5 * (self.target - self.start)
        if now >= self.t1:
            return self.target
        if now <= self.t0:  # a move that starts after a WS wait has not started yet
            return self.start
        return self.start + (self.target - self.start) * (now - self.t0) / (self.t1 - self.t0)

    def done(self, now: float) -> bool:
        return not self.stuck and now >= self.t1

    def move(self, target: float, now: float, stuck: bool = False) -> None:
        self.start, self.target, self.t0, self.stuck = self.position(now), target, now, stuck
        # an infinite velocity (instant motion) ends the move now, exactly
        self.t1 = now + (0.0 if math.isinf(self.velocity) else
                         abs(target - self.start) / self.velocity)

    def halt(self, now: float) -> None:
        self.start = self.target = self.position(now)
        self.t0, self.t1, self.stuck = now, now, False



class FakeESP:
    """An ESP301-like controller behind a pseudo-terminal or a loopback TCP port.

    Parameters
    ----------
    bench : sunlab.sim.Bench, optional
        Virtual bench whose platform model maps commanded to true angles; None: ideal platform.
    seed : int
        Seed of the platform model (per-pose error and per-shot jitter).
    velocity_deg_s : float
        Slew rate of every axis, deg/s; ``math.inf`` makes every move instant.
    resolution_deg : float
        Encoder resolution; ``TP?`` reads the position rounded to it, degrees.
    motors_on : bool
        Motor power at start.
    stage_model : str
        Positioner model in the ``nID?`` reply (``URS100BCC, SN0001`` for axis 1).
    clock : callable, optional
        Monotonic clock in seconds (default :func:`time.monotonic`); a clock advanced by hand
        makes timed behaviour (moves, silences, error time stamps) deterministic.

    Notes
    -----
    Three axes, alpha on axis 1 and beta on axis 2 (:meth:`true_pose`), each with the software
    limits ``SL``, ``SR`` of -170 and 170 degrees; ``VE?`` answers :attr:`version`.
    """

    version = "ESP301 Version 3.0.2 6/29/11 (sunlab fake)"

    def __init__(self, *, bench=None, seed: int = 0, velocity_deg_s: float = 20.0,
                 resolution_deg: float = 1e-4, motors_on: bool = True,
                 stage_model: str = "URS100BCC", clock=None):
        if not velocity_deg_s > 0:
            raise ConfigurationError(f"velocity_deg_s: found {velocity_deg_s!r}, expected > 0")
        self.bench, self.seed, self.resolution_deg = bench, int(seed), resolution_deg
        self.stage_model = stage_model
        self._axes = {n: _Axis(-170.0, 170.0, float(velocity_deg_s), motors_on) for n in (1, 2, 3)}
        self._errors: deque[int] = deque(maxlen=10)
        self._faults: list[Fault] = []
        self._silent_until = self._wait_until = -math.inf
        self._late_s, self._lock, self._stop = 0.0, threading.RLock(), threading.Event()
        self._clock = time.monotonic if clock is None else clock
        self._t_boot = self._clock()
        self._threads, self._closers, self.received = [], [], []  # received: the command lines

    # -- faults -------------------------------------------------------------------------------
    def inject(self, kind: str, match: str = "", *, count: int = 1, code: int = 0,
               silent_s: float = 2.0, after: int = 0) -> Fault:
        """Queue a fault for the next ``count`` commands containing ``match`` (see module doc),
        once ``after`` such commands have passed untouched.

        Parameters
        ----------
        kind : str
            One of :data:`FAULT_KINDS` (effects in the module docstring).
        match : str
            Substring a command must contain (one command of a ``;`` chain, blanks removed,
            e.g. ``"1TP?"``); ``""`` matches every command.
        count : int
            How many matching commands the fault hits.
        code : int
            Error code queued by an ``error`` fault (``axis * 100 + code`` for an axis error).
        silent_s : float
            Silence of ``silent`` (and of a limit ``error``), or delay of ``late``, s.
        after : int
            Matching commands let through before the fault starts.

        Returns
        -------
        Fault
            The queued fault; its ``count`` falls as it hits (0: used up, dropped).
        """
        if kind not in FAULT_KINDS:
            raise ConfigurationError(f"fault kind: found {kind!r}, expected one of {FAULT_KINDS}")
        fault = Fault(kind, match, int(count), int(code), float(silent_s), int(after))
        with self._lock:
            self._faults.append(fault)
        return fault

    def _take_fault(self, command: str) -> Fault | None:
        for fault in [f for f in self._faults if f.count > 0 and f.match in command]:
            if fault.after > 0:  # let this one pass
                fault.after -= 1
                continue
            fault.count -= 1
            if fault.count == 0:
                self._faults.remove(fault)
            return fault
        return None

    # -- protocol -----------------------------------------------------------------------------
    def handle(self, line: bytes):
        """Run one received line as the controller does, with the injected faults.

        Parameters
        ----------
        line : bytes
            One command line without its ``CR``; ``;`` chains commands.

        Returns
        -------
        bytes or None or object
            The replies of the line's queries, each ending ``CR LF``, concatenated; None when
            nothing is answered; ``DISCONNECT`` when a ``disconnect`` fault closes the link.
        """
        text = line.decode("ascii", "replace").strip()
        if not text:
            return None
        out = []
        with self._lock:
            # commands after a WS run when its wait is over (answered at once, as if it were)
            now = max(self._clock(), self._wait_until)
            self.received.append(text)
            # the manual: blanks between the fields of a command are ignored ("2 PA 1000")
            for command in filter(None, (c.replace(" ", "") for c in text.split(";"))):
                now = max(now, self._wait_until)
                if now < self._silent_until:  # busy recovering: the command is lost
                    continue
                fault = self._take_fault(command)
                kind = fault.kind if fault is not None else None
                if kind == "disconnect":
                    return DISCONNECT
                reply = self._execute(command, now, kind == "stuck")
                if kind == "timeout":
                    reply = None
                elif kind == "garble" and reply is not None:
                    reply = bytes(b | 0x80 for b in reply.encode("ascii")).decode("latin-1")
                elif kind == "silent":
                    self._silent_until = now + fault.silent_s
                elif kind == "late":
                    self._late_s = fault.silent_s
                elif kind == "error":
                    self._errors.append(fault.code)
                    axis = self._axes.get(fault.code // 100)
                    if axis is not None and fault.code % 100 in (4, 5, 6, 7):
                        axis.halt(now)
                        self._silent_until = now + fault.silent_s
                if reply is not None and now >= self._silent_until:  # no reply if silenced now
                    out.append(reply.encode("latin-1") + b"\r\n")
        return b"".join(out) or None

    def _status(self, now: float) -> str:
        """``TS``: bit n-1 set while axis n moves, bit 4 while any motor is on; bit 6 is set
        as in the manual's example replies, which keeps the byte a printable character."""
        moving = sum(1 << (n - 1) for n, ax in self._axes.items() if not ax.done(now))
        return chr(0x40 | moving | (0x10 if any(a.motor_on for a in self._axes.values()) else 0))

    def _execute(self, command: str, now: float, stuck: bool) -> str | None:
        """Run one command; its reply text, or None (an error is queued where the controller
        queues one)."""
        match = _CMD_RE.match(command)
        if match is None:
            return self._errors.append(6)
        axis, mn, rest = match.groups()
        mn = mn.upper()
        # a read: "?" after the mnemonic, or TP without it (the manual reads it both ways)
        query = rest == "?" or (rest == "" and mn == "TP")
        if not axis:
            if query and mn in ("TB", "TE"):
                code = self._errors.popleft() if self._errors else 0
                message = "NO ERROR DETECTED" if code == 0 else decode_error(code)[1].upper()
                return str(code) if mn == "TE" else (
                    f"{code}, {int((now - self._t_boot) * 1000)}, {message}")
            if mn == "AB":
                for each in self._axes.values():
                    each.halt(now)
                return None
            reply = {("VE", "?"): self.version, ("TS", ""): self._status(now)}.get((mn, rest))
            return self._errors.append(37 if mn in _AXIS_COMMANDS else 6) if reply is None \
                else reply
        n = int(axis)
        ax = self._axes.get(n)
        if ax is None:
            return self._errors.append(9)
        if query:
            value = {"MD": ax.done(now), "MO": ax.motor_on, "SN": ax.units, "PA": ax.target,
                     "DP": ax.target, "DH": ax.home, "SL": ax.low, "SR": ax.high,
                     "VA": ax.velocity, "ID": f"{self.stage_model}, SN{n:04d}",
                     "TP": round(ax.position(now) / self.resolution_deg) * self.resolution_deg,
                     }.get(mn)
            if value is None:
                return self._errors.append(6)
            return value if isinstance(value, str) else (
                str(int(value)) if isinstance(value, int) else f"{value:.6f}")
        if rest == "" and mn in ("MO", "MF", "ST"):
            if mn != "MO":
                ax.halt(now)
            ax.motor_on = mn == "MO" or (ax.motor_on and mn == "ST")
            return None
        if mn not in _SETTERS:
            return self._errors.append(6)
        try:
            value = 0.0 if rest == "" and mn in ("WS", "OR", "DH") else float(rest)
        except ValueError:
            return self._errors.append(38 if rest == "" else 7)
        if not math.isfinite(value) or (mn == "WS" and value < 0) or (
                mn in ("SN", "OR") and value not in range(12 if mn == "SN" else 7)):
            return self._errors.append(7)
        if mn == "WS":  # wait for stop, then ``value`` ms; a stuck axis is not awaited
            if not ax.stuck:
                self._wait_until = max(self._wait_until, max(ax.t1, now) + value / 1000.0)
        elif mn == "DH":  # the position here now reads value (the whole move shifts with it)
            shift = value - ax.position(now)
            ax.start, ax.target, ax.home = ax.start + shift, ax.target + shift, value
        elif mn in ("SN", "SL", "SR"):
            setattr(ax, {"SN": "units", "SL": "low", "SR": "high"}[mn],
                    int(value) if mn == "SN" else value)
        elif mn == "VA":
            if not value > 0:
                return self._errors.append(100 * n + 1)
            ax.velocity = value
        elif not ax.motor_on:  # PA, OR
            return self._errors.append(100 * n + 13)
        elif mn == "OR":  # home search: to the home switch, where DH's value reads
            ax.move(ax.home, now)
        elif not ax.low <= value <= ax.high:
            return self._errors.append(100 * n + (6 if value > ax.high else 7))
        else:
            ax.move(value, now, stuck=stuck)
        return None

    # -- the platform -------------------------------------------------------------------------
    def position(self) -> tuple[float, float]:
        """Commanded-frame position of the alpha and beta axes now (a ``WS`` wait moves the
        controller's time on to its end).

        Returns
        -------
        (float, float)
            (alpha, beta), degrees, mid-move positions included, not rounded as ``TP?`` is.
        """
        with self._lock:
            now = max(self._clock(), self._wait_until)
            return self._axes[1].position(now), self._axes[2].position(now)

    def true_pose(self, pose: int = 0, shot: int = 0) -> tuple[float, float]:
        """True platform angles now, from the virtual bench's platform
        (:func:`sunlab.sim.platform.platform_pose`: deterministic in seed, pose, shot and position).

        Parameters
        ----------
        pose : int
            Pose index (draws the per-pose platform error).
        shot : int
            Shot index within the pose (draws the per-shot jitter).

        Returns
        -------
        (float, float)
            (alpha_true, beta_true), degrees; the commanded position when there is no bench.
        """
        alpha, beta = self.position()
        if self.bench is None:
            return alpha, beta
        from ..sim.platform import platform_pose

        a, b = platform_pose(self.bench, alpha, beta, seed=self.seed, pose=pose, shot=shot)
        return float(a), float(b)

    # -- transports ---------------------------------------------------------------------------
    def serve_pty(self) -> str:
        """Serve the protocol on a new pseudo-terminal, in a background thread.

        Returns
        -------
        str
            The slave's device path (e.g. ``/dev/pts/5``), to open as a serial port; POSIX
            only. :meth:`close` stops the thread and closes the terminal.
        """
        return _serve.serve_pty(self)

    def serve_tcp(self, port: int = 0) -> str:
        """Serve the protocol on 127.0.0.1:``port``, in a background thread.

        One client at a time; after a ``disconnect`` fault the server accepts the next one.

        Parameters
        ----------
        port : int
            TCP port to listen on; 0 takes any free one.

        Returns
        -------
        str
            The ``socket://127.0.0.1:PORT`` URL (:func:`serial.serial_for_url` form).
        """
        return _serve.serve_tcp(self, port)

    def close(self) -> None:
        """Stop serving and close every transport."""
        self._stop.set()
        for thread in self._threads:
            thread.join(timeout=2.0)
        for closer in self._closers:
            closer()

    def __enter__(self) -> FakeESP:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
