"""Protocol tests of the Newport ESP300/301 driver: exact bytes out, exact bytes in.

In the style of PyMeasure's ``expected_protocol``: an in-memory transport holds the list of
(bytes the driver must send, bytes the controller answers) and fails on the first byte that
differs, on a missing exchange and on an unread reply.
"""

from __future__ import annotations

from contextlib import contextmanager

import pytest
import serial

from sunlab import ConfigurationError
from sunlab.hardware import ESP300, MotionTimeout
from sunlab.hardware._esp_link import (
    READ_TERMINATOR,
    WRITE_TERMINATOR,
    format_number,
    open_transport,
)
from sunlab.hardware.errors import (
    ControllerError,
    ControllerLimitError,
    ErrorReplyLost,
    LimitError,
    StageDisconnected,
    StageError,
    StageProtocolError,
    StageTimeout,
    decode_error,
)
from sunlab.hardware.esp import UNITS

NO_ERROR = b"0, 451322, NO ERROR DETECTED\r\n"
#: The marker query the driver sends to get back in step after a lost reply, and its answer.
SYNC = b"VE?\r"
IDENTITY = b"ESP301 Version 3.0.0 (fake)\r\n"


class ProtocolTransport:
    """A transport that asserts the exact byte exchange.

    ``pairs`` is a list of ``(sent, reply)``: ``sent`` the bytes the driver must write next,
    ``reply`` the bytes then readable (None: silence, a read times out; an exception instance:
    the link breaks on the read). The driver's ``VE?`` resynchronisation after a lost or
    garbled reply is answered without a script entry, and counted in ``syncs``.
    """

    def __init__(self, pairs):
        self.pairs = list(pairs)
        self.index = 0
        self.pending = b""
        self.broken: Exception | None = None
        self.flushes = 0
        self.syncs = 0

    def write(self, data: bytes) -> int:
        if data == SYNC and (self.index >= len(self.pairs) or self.pairs[self.index][0] != SYNC):
            # the driver's resynchronisation after a lost reply: answered, not scripted
            self.syncs += 1
            self.pending += IDENTITY
            return len(data)
        assert self.index < len(self.pairs), f"unexpected write {data!r} after the last exchange"
        sent, reply = self.pairs[self.index]
        assert data == sent, f"exchange {self.index}: driver sent {data!r}, expected {sent!r}"
        self.index += 1
        if isinstance(reply, Exception):
            self.broken = reply
        elif reply is not None:
            self.pending += reply
        return len(data)

    def read_until(self, expected: bytes = b"\n", size: int | None = None) -> bytes:
        if self.broken is not None:
            err, self.broken = self.broken, None
            raise err
        end = self.pending.find(expected)
        if end < 0:  # no terminator: what arrived before the timeout
            out, self.pending = self.pending, b""
            return out
        out, self.pending = self.pending[: end + len(expected)], self.pending[end + len(expected):]
        return out

    def reset_input_buffer(self) -> None:
        self.flushes += 1
        self.pending = b""

    def close(self) -> None:
        pass


@contextmanager
def expected_protocol(pairs, **kwargs):
    """Yield an unconnected ESP300 on a :class:`ProtocolTransport`; check every pair was used."""
    transport = ProtocolTransport(pairs)
    options = {"retry_delay_s": 0.0, "poll_s": 0.0, "sleep": lambda s: None}
    options.update(kwargs)
    stage = ESP300(transport, connect=False, **options)
    yield stage
    assert transport.index == len(transport.pairs), (
        f"exchanges never made: {transport.pairs[transport.index:]}"
    )
    assert transport.pending == b"", f"reply left unread: {transport.pending!r}"


def connected(stage, limits=((-170.0, 170.0), (-170.0, 170.0))):
    stage.limits = {"alpha": limits[0], "beta": limits[1]}
    return stage


HANDSHAKE = [
    (b"VE?\r", b"ESP301 Version 3.0.2 6/29/11\r\n"),
    (b"TB?\r", NO_ERROR),
    (b"1SN?\r", b"7\r\n"),
    (b"1SL?\r", b"-170.00000\r\n"),
    (b"1SR?\r", b"170.00000\r\n"),
    (b"1MO?\r", b"1\r\n"),
    (b"2SN?\r", b"7\r\n"),
    (b"2SL?\r", b"-45.00000\r\n"),
    (b"2SR?\r", b"45.00000\r\n"),
    (b"2MO?\r", b"0\r\n"),
    (b"2MO\r", None),
    (b"TB?\r", NO_ERROR),
]


def test_connect_handshake_bytes():
    with expected_protocol(HANDSHAKE) as stage:
        stage.connect()
    assert stage.identity == "ESP301 Version 3.0.2 6/29/11"
    assert stage.limits == {"alpha": (-170.0, 170.0), "beta": (-45.0, 45.0)}


def test_connect_intersects_user_limits_and_reports_stale_errors():
    pairs = [HANDSHAKE[0], (b"TB?\r", b"108, 1200, AXIS 1 MOTOR NOT CONNECTED\r\n"),
             (b"TB?\r", NO_ERROR), *HANDSHAKE[2:]]
    with expected_protocol(pairs, limits={"alpha": (-20.0, 5.0)}) as stage:
        stage.connect()
    assert stage.limits["alpha"] == (-20.0, 5.0)
    assert [e.code for e in stage.stale_errors] == [108]
    assert stage.stale_errors[0].axis == 1


def test_connect_rejects_an_axis_not_in_degrees():
    pairs = [*HANDSHAKE[:2], (b"1SN?\r", b"2\r\n")]
    with pytest.raises(ConfigurationError, match=r"1SN7"):
        with expected_protocol(pairs) as stage:
            stage.connect()


def test_connect_refuses_a_motor_that_is_off_when_asked_not_to_enable():
    with pytest.raises(StageError, match="motor is off"):
        with expected_protocol(HANDSHAKE[:10], enable_motors=False) as stage:
            stage.connect()


def test_move_bytes_with_motion_polling_and_readback():
    pairs = [
        (b"1PA12.5\r", None),
        (b"2PA-3\r", None),
        (b"TB?\r", NO_ERROR),
        (b"1MD?\r", b"0\r\n"),
        (b"2MD?\r", b"1\r\n"),
        (b"1MD?\r", b"1\r\n"),  # only the pending axis is polled again
        (b"TB?\r", NO_ERROR),
        (b"1TP?\r", b"12.50010\r\n"),
        (b"2TP?\r", b"-2.99990\r\n"),
    ]
    with expected_protocol(pairs) as stage:
        read = connected(stage).move_to(12.5, -3.0)
    assert read == (12.5001, -2.9999)


def test_move_uses_the_configured_axes():
    pairs = [(b"3PA1\r", None), (b"1PA2\r", None), (b"TB?\r", NO_ERROR),
             (b"3MD?\r", b"1\r\n"), (b"1MD?\r", b"1\r\n"), (b"TB?\r", NO_ERROR),
             (b"3TP?\r", b"1.00000\r\n"), (b"1TP?\r", b"2.00000\r\n")]
    with expected_protocol(pairs, axes=(3, 1)) as stage:
        assert connected(stage).move_to(1, 2) == (1.0, 2.0)


@pytest.mark.parametrize("alpha, beta, field", [(171.0, 0.0, "alpha"), (0.0, -45.5, "beta"),
                                                (float("nan"), 0.0, "alpha")])
def test_limits_are_checked_before_anything_is_sent(alpha, beta, field):
    with expected_protocol([]) as stage:  # no exchange allowed
        connected(stage, ((-170.0, 170.0), (-45.0, 45.0)))
        with pytest.raises(LimitError, match=field):
            stage.move_to(alpha, beta)


def test_a_refused_move_is_reported_with_its_decoded_code():
    pairs = [(b"1PA1\r", None), (b"2PA2\r", None),
             (b"TB?\r", b"213, 9001, AXIS 2 MOTOR NOT ENABLED\r\n"), (b"TB?\r", NO_ERROR)]
    with expected_protocol(pairs) as stage:
        with pytest.raises(ControllerError) as info:
            connected(stage).move_to(1, 2)
    assert (info.value.code, info.value.axis) == (213, 2)
    assert "motor not enabled" in str(info.value) and "'PA'" in str(info.value)


def test_a_limit_hit_during_the_move_is_a_limit_error():
    pairs = [(b"1PA1\r", None), (b"2PA2\r", None), (b"TB?\r", NO_ERROR),
             (b"1MD?\r", b"1\r\n"), (b"2MD?\r", b"1\r\n"),
             (b"TB?\r", b"104, 9001, AXIS 1 POSITIVE HARDWARE LIMIT DETECTED\r\n"),
             (b"TB?\r", NO_ERROR)]
    with expected_protocol(pairs) as stage:
        with pytest.raises(ControllerLimitError, match="positive hardware limit") as info:
            connected(stage).move_to(1, 2)
    assert isinstance(info.value, LimitError) and info.value.axis == 1


def test_a_stuck_axis_times_out_and_is_stopped():
    pairs = [(b"1PA1\r", None), (b"2PA2\r", None), (b"TB?\r", NO_ERROR),
             (b"1MD?\r", b"1\r\n"), (b"2MD?\r", b"0\r\n"),
             (b"1ST\r", None), (b"2ST\r", None), (b"TB?\r", NO_ERROR)]
    with expected_protocol(pairs, motion_timeout_s=1e-9) as stage:
        with pytest.raises(MotionTimeout, match=r"axis \[2\]") as info:
            connected(stage).move_to(1, 2)
    assert info.value.axes == [2]


MOVE_1_2 = [(b"1PA1\r", None), (b"2PA2\r", None), (b"TB?\r", NO_ERROR),
            (b"1MD?\r", b"1\r\n"), (b"2MD?\r", b"1\r\n"), (b"TB?\r", NO_ERROR)]


def test_a_lost_move_command_is_sent_again():
    """Motion commands have no reply: a command lost while the controller was busy shows only
    in the read-back, and the (idempotent) absolute move is sent once more."""
    pairs = [*MOVE_1_2, (b"1TP?\r", b"1.00000\r\n"), (b"2TP?\r", b"-7.00000\r\n"),
             *MOVE_1_2, (b"1TP?\r", b"1.00000\r\n"), (b"2TP?\r", b"2.00000\r\n")]
    with expected_protocol(pairs) as stage:
        assert connected(stage).move_to(1, 2) == (1.0, 2.0)


def test_a_readback_that_stays_off_target_is_an_error():
    pairs = [*MOVE_1_2, (b"1TP?\r", b"1.00000\r\n"), (b"2TP?\r", b"2.50000\r\n")] * 2
    with expected_protocol(pairs, tolerance_deg=0.01) as stage:
        with pytest.raises(StageError, match="after 2 move.*tolerance_deg"):
            connected(stage).move_to(1, 2)


def test_settle_time_is_waited_after_motion_done():
    waits = []
    pairs = [(b"1PA0\r", None), (b"2PA0\r", None), (b"TB?\r", NO_ERROR),
             (b"1MD?\r", b"1\r\n"), (b"2MD?\r", b"1\r\n"), (b"TB?\r", NO_ERROR),
             (b"1TP?\r", b"0.00000\r\n"), (b"2TP?\r", b"0.00000\r\n")]
    with expected_protocol(pairs, settle_s=0.25, sleep=waits.append) as stage:
        connected(stage).move_to(0, 0)
    assert waits == [0.25]


@pytest.mark.parametrize("bad", [None, b"12.5", b"\xb1\xb2.5\r\n", b"twelve\r\n", b"nan\r\n"])
def test_one_bad_reply_is_retried_after_a_flush(bad):
    pairs = [(b"1TP?\r", bad), (b"1TP?\r", b"12.50000\r\n"),
             (b"2TP?\r", b"-1.00000\r\n")]
    waits = []
    with expected_protocol(pairs, retry_delay_s=0.2, sleep=waits.append) as stage:
        assert stage.position() == (12.5, -1.0)
    assert waits == [0.2]


def test_silence_outlasting_the_retries_is_a_timeout_with_backoff():
    waits = []
    pairs = [(b"1MD?\r", None)] * 4
    with expected_protocol(pairs, retries=3, retry_delay_s=0.1, timeout=0.5,
                           sleep=waits.append) as stage:
        with pytest.raises(StageTimeout, match=r"'1MD\?' after 4 attempt") as info:
            stage.motion_done()
    assert waits == [0.1, 0.2, 0.4]
    assert info.value.attempts == 4


def test_garbage_outlasting_the_retries_is_a_lost_error_reply():
    """Three garbled TB? replies in a row: three errors may be gone and the buffer was never
    read to empty; the fault says so and chains the protocol error."""
    pairs = [(b"TB?\r", b"0; 1; ok\r\n")] * 3
    with expected_protocol(pairs, retries=2) as stage:
        with pytest.raises(ErrorReplyLost, match="may have been lost") as info:
            stage.errors()
    assert (info.value.lost, info.value.empty, info.value.errors) == (3, False, [])
    assert isinstance(info.value.__cause__, StageProtocolError)
    assert "code, timestamp, message" in str(info.value.__cause__)


# -- an error query whose reply is lost is never read as "no error" ------------------------------
LIMIT_104 = b"104, 9001, AXIS 1 POSITIVE HARDWARE LIMIT DETECTED\r\n"
MOTOR_213 = b"213, 9002, AXIS 2 MOTOR NOT ENABLED\r\n"
BAD_REPLIES = {
    "timeout": None,
    "high bit": bytes(b | 0x80 for b in LIMIT_104[:-2]) + b"\r\n",
    "truncated": LIMIT_104[:9],
    "no message": b"104\r\n",
    "noise": b"\x00\xff\r\n",
}
MOVE_START = [(b"1PA1\r", None), (b"2PA2\r", None)]
MOVE_DONE = [(b"1MD?\r", b"1\r\n"), (b"2MD?\r", b"1\r\n")]


@pytest.mark.parametrize("bad", BAD_REPLIES.values(), ids=BAD_REPLIES.keys())
@pytest.mark.parametrize(
    "position, before, after, read",
    [
        # the reply to the TB? right after the PA commands (an error of the command)
        ("after PA", MOVE_START, [(b"TB?\r", NO_ERROR)], []),
        # the reply to the TB? after motion done (a limit hit during the move)
        ("after motion", [*MOVE_START, (b"TB?\r", NO_ERROR), *MOVE_DONE],
         [(b"TB?\r", NO_ERROR)], []),
        # the second of two errors: the first was read cleanly, the next reply is lost
        ("second error", [*MOVE_START, (b"TB?\r", MOTOR_213)], [(b"TB?\r", NO_ERROR)], [213]),
        # an unreadable reply, then a clean error, then the clean "no error"
        ("before an error", MOVE_START, [(b"TB?\r", LIMIT_104), (b"TB?\r", NO_ERROR)], [104]),
    ],
)
def test_a_lost_error_reply_raises_and_the_buffer_is_read_to_empty(position, before, after,
                                                                   read, bad):
    """Each TB? pops one error, so whatever the lost reply carried is gone: the driver reads
    the buffer until a clean code 0, then raises ErrorReplyLost; never a success."""
    waits = []
    pairs = [*before, (b"TB?\r", bad), *after]
    with expected_protocol(pairs, retry_delay_s=0.1, sleep=waits.append) as stage:
        with pytest.raises(ErrorReplyLost, match="may have been lost") as info:
            connected(stage).move_to(1, 2)
    err = info.value
    assert (err.lost, err.empty, err.command) == (1, True, "PA")
    assert [e.code for e in err.errors] == read
    assert waits == [0.1]  # one back-off before the re-query (and a flush, checked below)
    if read:
        assert err.__cause__ is err.errors[0] and f"error {read[0]}" in str(err)


def test_a_lost_reply_on_an_empty_buffer_is_still_reported():
    """The driver cannot tell a lost "no error" from a lost error: it never guesses."""
    pairs = [*MOVE_START, (b"TB?\r", None), (b"TB?\r", NO_ERROR)]
    with expected_protocol(pairs) as stage:
        with pytest.raises(ErrorReplyLost) as info:
            connected(stage).move_to(1, 2)
    assert info.value.empty and info.value.errors == []


def test_error_replies_lost_in_a_row_are_counted_and_flushed():
    transport = ProtocolTransport([*MOVE_START, (b"TB?\r", None), (b"TB?\r", b"10\r\n"),
                                   (b"TB?\r", MOTOR_213), (b"TB?\r", NO_ERROR)])
    stage = ESP300(transport, connect=False, retry_delay_s=0.0, sleep=lambda s: None)
    with pytest.raises(ErrorReplyLost, match="2 replies") as info:
        connected(stage).move_to(1, 2)
    assert (info.value.lost, [e.code for e in info.value.errors]) == (2, [213])
    # flushed before each query and at each retry, and back in step after each lost reply
    assert transport.flushes == 4 + 2 and transport.syncs == 2
    assert transport.index == len(transport.pairs)


def test_error_replies_lost_past_the_retries_never_read_empty():
    pairs = [*MOVE_START, (b"TB?\r", LIMIT_104), *[(b"TB?\r", None)] * 3]
    with expected_protocol(pairs, retries=2) as stage:
        with pytest.raises(ErrorReplyLost, match="could not be read to empty") as info:
            connected(stage).move_to(1, 2)
    assert (info.value.lost, info.value.empty) == (3, False)
    assert [e.code for e in info.value.errors] == [104]
    assert isinstance(info.value.__cause__, StageTimeout)


def test_a_clean_buffer_still_passes_and_clean_errors_keep_their_type():
    with expected_protocol([*MOVE_START, (b"TB?\r", NO_ERROR), *MOVE_DONE, (b"TB?\r", NO_ERROR),
                            (b"1TP?\r", b"1.00000\r\n"), (b"2TP?\r", b"2.00000\r\n")]) as stage:
        assert connected(stage).move_to(1, 2) == (1.0, 2.0)
    pairs = [*MOVE_START, (b"TB?\r", LIMIT_104), (b"TB?\r", NO_ERROR)]
    with expected_protocol(pairs) as stage:
        with pytest.raises(ControllerLimitError):
            connected(stage).move_to(1, 2)


def test_stale_errors_lost_at_connect_are_logged_not_raised(caplog):
    """Stale errors never fail the handshake; a lost one is logged once the buffer reads
    empty (and the handshake goes on)."""
    pairs = [HANDSHAKE[0], (b"TB?\r", None), (b"TB?\r", NO_ERROR), *HANDSHAKE[2:]]
    with expected_protocol(pairs) as stage:
        stage.connect()
    assert stage.stale_errors == []
    assert "may have been lost" in caplog.text


def test_a_stale_buffer_that_never_reads_empty_fails_the_connect():
    pairs = [HANDSHAKE[0], *[(b"TB?\r", b"garbage\r\n")] * 2]
    with expected_protocol(pairs, retries=1) as stage:
        with pytest.raises(ErrorReplyLost, match="could not be read to empty"):
            stage.connect()


def test_a_lost_reply_after_stopping_a_stuck_axis_keeps_the_motion_timeout(caplog):
    pairs = [*MOVE_START, (b"TB?\r", NO_ERROR), (b"1MD?\r", b"1\r\n"), (b"2MD?\r", b"0\r\n"),
             (b"1ST\r", None), (b"2ST\r", None), (b"TB?\r", None), (b"TB?\r", NO_ERROR)]
    with expected_protocol(pairs, motion_timeout_s=1e-9) as stage:
        with pytest.raises(MotionTimeout):
            connected(stage).move_to(1, 2)
    assert "may have been lost" in caplog.text


def test_a_broken_link_without_url_is_reported():
    pairs = [(b"1TP?\r", serial.SerialException("device reports readiness to read but "
                                                  "returned no data"))]
    with expected_protocol(pairs) as stage:
        with pytest.raises(StageDisconnected, match="resume"):
            stage.position()


@pytest.mark.parametrize(
    "code, axis, text, cls",
    [
        (0, None, "no error detected", ControllerError),
        (6, None, "command does not exist", ControllerError),
        (104, 1, "positive hardware limit detected", ControllerLimitError),
        (205, 2, "negative hardware limit detected", ControllerLimitError),
        (306, 3, "positive software limit detected", ControllerLimitError),
        (107, 1, "negative software limit detected", ControllerLimitError),
        (203, 2, "following error threshold exceeded", ControllerError),
        (113, 1, "motor not enabled", ControllerError),
    ],
)
def test_error_codes_decode(code, axis, text, cls):
    assert decode_error(code) == (axis, text)
    err = ESP300(ProtocolTransport([]), connect=False)._error(code)
    assert type(err) is cls and err.code == code and err.axis == axis


@pytest.mark.parametrize("value, text", [(12.5, "12.5"), (-3.0, "-3"), (0.0, "0"), (-0.0, "0"),
                                         (1e-7, "0"), (0.1234567, "0.123457"), (90, "90")])
def test_numbers_are_sent_in_short_fixed_point(value, text):
    assert format_number(value) == text


@pytest.mark.parametrize("kwargs", [{"axes": (1, 1)}, {"axes": (1,)}, {"timeout": 0},
                                    {"retries": -1}, {"motion_timeout_s": -1}])
def test_bad_driver_settings_are_configuration_errors(kwargs):
    with pytest.raises(ConfigurationError):
        ESP300(ProtocolTransport([]), connect=False, **kwargs)


def test_an_unopenable_port_is_a_clear_error(tmp_path):
    with pytest.raises(StageDisconnected, match="cannot open"):
        ESP300(str(tmp_path / "no-such-tty"), timeout=0.1)


# -- a dead controller is declared in bounded time (issue 37) -----------------------------------
class _DeadLink:
    """A link on a virtual clock: ``silent`` never answers (each read waits one timeout),
    otherwise a flood of binary noise arrives at 19200 baud (a read returns 256 bytes in the
    time they take on the wire). ``sleep`` advances the same clock."""

    def __init__(self, timeout: float, silent: bool):
        self.now, self.timeout, self.silent = 0.0, timeout, silent

    def clock(self) -> float:
        return self.now

    def sleep(self, seconds: float) -> None:
        self.now += seconds

    def write(self, data: bytes) -> int:
        return len(data)

    def read_until(self, expected: bytes = b"\n", size: int | None = None) -> bytes:
        if self.silent:
            self.now += self.timeout
            return b""
        self.now += 256 * 10 / 19200
        return bytes(range(128, 256)) * 2

    def reset_input_buffer(self) -> None:
        pass

    def close(self) -> None:
        pass


@pytest.mark.parametrize("silent", [True, False], ids=["silent", "flood"])
def test_a_dead_controller_is_declared_within_tries_times_timeout_plus_the_backoff(silent):
    timeout, retries, delay = 0.25, 3, 0.2
    link = _DeadLink(timeout, silent)
    stage = ESP300(link, connect=False, timeout=timeout, retries=retries, retry_delay_s=delay,
                   sleep=link.sleep, clock=link.clock)
    with pytest.raises(StageTimeout if silent else (StageTimeout, StageProtocolError)):
        stage.position()
    # the bound: tries x timeout + about 1.5 s (the back-off waits, 0.2 + 0.4 + 0.8 s,
    # or the driver's 1.5 s of slack for a late reply, whichever is longer)
    assert link.now <= (retries + 1) * timeout + 1.5 + 1e-9


# -- the wire protocol: terminators, error codes, numbers, the link ------------------------------
def test_terminators_are_the_manuals():
    # commands end in CR; the controller answers queries with CR LF
    assert WRITE_TERMINATOR == b"\r" and READ_TERMINATOR == b"\r\n"
    assert UNITS[7] == "degree"


@pytest.mark.parametrize("code, axis, text", [
    (0, None, "no error detected"),
    (6, None, "command does not exist"),
    (104, 1, "positive hardware limit detected"),
    (205, 2, "negative hardware limit detected"),
    (313, 3, "motor not enabled"),
    (99, None, "unknown error 99"),
    (112, 1, "unknown axis error 12"),
])
def test_decode_error_splits_axis_and_code(code, axis, text):
    assert decode_error(code) == (axis, text)


def test_every_limit_code_decodes_to_a_limit():
    for sub in (4, 5, 6, 7):
        assert "limit" in decode_error(100 + sub)[1]


@pytest.mark.parametrize("value, text", [
    (12.5, "12.5"), (-3.0, "-3"), (0.1234567, "0.123457"), (0.0, "0"), (-0.0000001, "0"),
    (170, "170"), (-169.999999, "-169.999999"),
])
def test_format_number_is_the_shortest_fixed_point_to_a_microdegree(value, text):
    assert format_number(value) == text
    assert float(text) == pytest.approx(value, abs=5e-7)


def test_loopback_transport_echoes_and_is_a_serial_port():
    port = open_transport("loop://", timeout=0.1)
    try:
        assert isinstance(port, serial.SerialBase)
        port.write(b"1TP?" + WRITE_TERMINATOR)
        assert port.read_until(WRITE_TERMINATOR) == b"1TP?\r"
    finally:
        port.close()


def test_a_port_that_cannot_open_is_a_disconnected_stage():
    with pytest.raises(StageDisconnected, match="cannot open"):
        open_transport("nosuchscheme://x", timeout=0.1)
