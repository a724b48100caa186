"""The fake ESP controller: its protocol, and the driver end to end over a pty and over TCP,
with every injected fault either survived (retry, reconnect) or reported with a clear error."""

from __future__ import annotations

import math
import time

import pytest

from sunlab.hardware import ESP300, MotionTimeout, open_stage
from sunlab.hardware.errors import (
    ControllerError,
    ControllerLimitError,
    ErrorReplyLost,
    StageDisconnected,
    StageTimeout,
)
from sunlab.hardware.fake import DISCONNECT, FakeESP


class ManualClock:
    """A monotonic clock that moves only when told to (``advance``), for timed behaviour."""

    def __init__(self):
        self.now = 0.0

    def __call__(self) -> float:
        return self.now

    def advance(self, seconds: float) -> None:
        assert seconds >= 0  # monotonic
        self.now += seconds


FAST = {"timeout": 0.08, "retries": 3, "retry_delay_s": 0.01, "poll_s": 0.001}


@pytest.fixture
def fake():
    controller = FakeESP(velocity_deg_s=2000.0)
    yield controller
    controller.close()


@pytest.fixture(params=["pty", "tcp"])
def link(request, fake):
    """(fake controller, connected driver) over a pseudo-terminal or loopback TCP.

    pyserial's socket:// close sleeps 0.3 s, so most fault tests use ``pty_link``."""
    url = fake.serve_pty() if request.param == "pty" else fake.serve_tcp()
    stage = ESP300(url, **FAST)
    yield fake, stage, request.param
    stage.close()


@pytest.fixture
def pty_link(fake):
    """(fake controller, connected driver) over a pseudo-terminal."""
    stage = ESP300(fake.serve_pty(), **FAST)
    yield fake, stage, "pty"
    stage.close()


# -- the fake's protocol ------------------------------------------------------------------------
def _protocol_round(fake):
    assert fake.handle(b"VE?").startswith(b"ESP301") and fake.handle(b"VE?").endswith(b"\r\n")
    assert fake.handle(b"1PA-12.25") is None
    assert fake.handle(b"1TP?") == b"-12.250000\r\n"
    assert fake.handle(b"1MD?") == b"1\r\n"
    assert fake.handle(b"1TP") == b"-12.250000\r\n"  # the manual's form without "?"
    assert fake.handle(b"1WS;1DP?;TS") == b"-12.250000\r\nP\r\n"
    assert fake.handle(b"TB?").startswith(b"0, ")


def test_fake_protocol_has_no_wall_clock_race():
    """Instant motion: the reply never depends on how soon after a move the query comes
    (a finite 1e6 deg/s once read an in-between position in 17 % of fresh processes)."""
    for _ in range(200):
        _protocol_round(FakeESP(velocity_deg_s=math.inf))


def test_fake_replies_end_with_cr_lf_and_writes_have_none():
    fake = FakeESP(velocity_deg_s=math.inf)
    assert fake.handle(b"VE?").startswith(b"ESP301") and fake.handle(b"VE?").endswith(b"\r\n")
    assert fake.handle(b"1PA-12.25") is None
    assert fake.handle(b"1TP?") == b"-12.250000\r\n"
    assert fake.handle(b"1MD?") == b"1\r\n"
    assert fake.handle(b"TB?").startswith(b"0, ")


@pytest.mark.parametrize(
    "command, code",
    [(b"XX", 6), (b"1QQ?", 6), (b"9TP?", 9), (b"TP?", 37), (b"1PA", 38), (b"1PAabc", 7),
     (b"2PA171", 206), (b"2PA-171", 207)],
)
def test_fake_queues_the_controller_error_codes(command, code):
    fake = FakeESP()
    fake.handle(command)
    assert fake.handle(b"TE?") == f"{code}\r\n".encode()
    assert fake.handle(b"TE?") == b"0\r\n"


def test_fake_motor_off_refuses_moves_and_semicolons_chain_commands():
    fake = FakeESP(motors_on=False, velocity_deg_s=math.inf)
    assert fake.handle(b"1MO?;1PA5;TE?") == b"0\r\n113\r\n"
    assert fake.handle(b"1MO;1PA5;1MO?") == b"1\r\n"
    assert fake.handle(b"1TP?") == b"5.000000\r\n"


def test_fake_axes_move_at_finite_speed():
    clock = ManualClock()
    fake = FakeESP(velocity_deg_s=50.0, clock=clock)
    fake.handle(b"1PA5")  # 0.1 s
    assert fake.handle(b"1MD?") == b"0\r\n"
    clock.advance(0.04)
    assert float(fake.handle(b"1TP?")) == pytest.approx(2.0)
    clock.advance(0.06)
    assert fake.handle(b"1MD?") == b"1\r\n"
    assert fake.handle(b"1TP?") == b"5.000000\r\n"


def test_fake_encoder_reads_in_resolution_steps():
    fake = FakeESP(velocity_deg_s=math.inf, resolution_deg=0.001)
    fake.handle(b"1PA1.23456")
    assert fake.handle(b"1TP?") == b"1.235000\r\n"


# -- the manual's other forms and commands (any client of the controller may send them) -----------
def _no_error(fake):
    assert fake.handle(b"TE?") == b"0\r\n", "the fake queued an error"


def test_fake_reads_the_position_without_question_mark():
    fake = FakeESP(velocity_deg_s=math.inf)
    fake.handle(b"2PA-7.125")
    assert fake.handle(b"2TP") == fake.handle(b"2TP?") == b"-7.125000\r\n"
    assert fake.handle(b"2 TP") == b"-7.125000\r\n"  # blanks between fields are ignored
    _no_error(fake)


def test_fake_blanks_between_fields_are_ignored():
    fake = FakeESP(velocity_deg_s=math.inf)
    assert fake.handle(b"1 PA 5 ; 1 TP ?") == b"5.000000\r\n"
    _no_error(fake)


def test_fake_id_reads_the_positioner_model_and_serial():
    fake = FakeESP(stage_model="URS75BCC")
    assert fake.handle(b"1ID?") == b"URS75BCC, SN0001\r\n"
    assert fake.handle(b"3 ID ?") == b"URS75BCC, SN0003\r\n"
    _no_error(fake)
    fake.handle(b"ID?")
    assert fake.handle(b"TE?") == b"37\r\n"  # axis number missing


def test_fake_ts_status_byte():
    clock = ManualClock()
    fake = FakeESP(velocity_deg_s=10.0, clock=clock)
    assert fake.handle(b"TS") == b"P\r\n"  # 0x50: motor power on, nothing moving
    fake.handle(b"1PA1;3PA1")  # 0.1 s moves
    assert ord(fake.handle(b"TS")[:1]) == 0x40 | 0x10 | 0b101  # axes 1 and 3 moving
    clock.advance(0.1)
    assert fake.handle(b"TS") == b"P\r\n"
    fake.handle(b"1MF;2MF;3MF")
    assert fake.handle(b"TS") == b"@\r\n"  # all motors off
    _no_error(fake)


def test_fake_dp_reads_the_desired_position_during_a_move():
    clock = ManualClock()
    fake = FakeESP(velocity_deg_s=10.0, clock=clock)
    fake.handle(b"1PA4")
    clock.advance(0.2)
    assert fake.handle(b"1DP?") == b"4.000000\r\n"
    assert fake.handle(b"1TP?") == b"2.000000\r\n"
    _no_error(fake)


def test_fake_ws_holds_later_commands_until_the_axis_stops():
    clock = ManualClock()
    fake = FakeESP(velocity_deg_s=10.0, clock=clock)
    assert fake.handle(b"1PA5") is None and fake.handle(b"1MD?") == b"0\r\n"  # 0.5 s move
    assert fake.handle(b"1WS250") is None  # wait for stop, then 250 ms
    # the controller runs what follows once the wait is over: the move is done by then
    assert fake.handle(b"1MD?;1TP?") == b"1\r\n5.000000\r\n"
    assert fake.position()[0] == 5.0  # the platform agrees with the controller's time
    assert fake.handle(b"1PA6;1MD?") == b"0\r\n"  # a move after the wait starts at its end
    clock.advance(0.75 + 0.1)
    assert fake.handle(b"1MD?") == b"1\r\n"
    assert fake.handle(b"1WS") is None  # default: no delay
    _no_error(fake)


def test_fake_or_homes_and_dh_defines_home():
    clock = ManualClock()
    fake = FakeESP(velocity_deg_s=10.0, clock=clock)
    fake.handle(b"1PA3")
    clock.advance(0.3)
    fake.handle(b"1DH")  # here reads 0
    assert fake.handle(b"1TP") == b"0.000000\r\n" and fake.handle(b"1DH?") == b"0.000000\r\n"
    fake.handle(b"1DH2.5")  # here reads 2.5
    assert fake.handle(b"1TP") == b"2.500000\r\n" and fake.handle(b"1DH?") == b"2.500000\r\n"
    fake.handle(b"1PA-1.5")
    clock.advance(0.4)
    assert fake.handle(b"1OR1") is None and fake.handle(b"1MD?") == b"0\r\n"  # home search
    clock.advance(0.4)
    assert fake.handle(b"1MD?") == b"1\r\n" and fake.handle(b"1TP") == b"2.500000\r\n"
    _no_error(fake)


def test_fake_sn_sets_the_units():
    fake = FakeESP()
    fake.handle(b"2SN2")
    assert fake.handle(b"2SN?") == b"2\r\n"
    _no_error(fake)


@pytest.mark.parametrize("command, code", [(b"1OR9", 7), (b"1SN12", 7), (b"1WS-5", 7),
                                           (b"OR1", 37), (b"WS", 37), (b"1DHx", 7),
                                           (b"TS?", 6), (b"1DP", 6)])
def test_fake_new_commands_refuse_bad_forms(command, code):
    fake = FakeESP()
    assert fake.handle(command) is None
    assert fake.handle(b"TE?") == f"{code}\r\n".encode()


def test_fake_or_refuses_a_motor_that_is_off():
    fake = FakeESP(motors_on=False)
    fake.handle(b"2OR1")
    assert fake.handle(b"TE?") == b"213\r\n"


def test_fake_fault_matching_and_counts():
    fake = FakeESP()
    fake.inject("timeout", "2TP?", count=2)
    assert fake.handle(b"1TP?") is not None
    assert fake.handle(b"2TP?") is None and fake.handle(b"2TP?") is None
    assert fake.handle(b"2TP?") is not None
    fake.inject("garble", "VE?")
    assert fake.handle(b"VE?")[0] >= 0x80
    fake.inject("disconnect", "1MD?")
    assert fake.handle(b"1MD?") is DISCONNECT
    fake.inject("timeout", "TB?", after=2)  # the third TB? loses its reply
    assert [fake.handle(b"TB?") is None for _ in range(4)] == [False, False, True, False]


# -- end to end through a real pty / socket -----------------------------------------------------
def test_connect_move_and_read_back(link):
    fake, stage, _ = link
    assert stage.identity.startswith("ESP301")
    assert stage.limits == {"alpha": (-170.0, 170.0), "beta": (-170.0, 170.0)}
    assert stage.move_to(-16.5, 12.25) == (-16.5, 12.25)
    assert fake.position() == (-16.5, 12.25)
    assert "1PA-16.5" in fake.received and "2PA12.25" in fake.received


def test_moves_wait_for_motion_done(fake):
    slow = FakeESP(velocity_deg_s=40.0)
    try:
        stage = ESP300(slow.serve_pty(), **FAST)
        t0 = time.monotonic()
        stage.move_to(4.0, 2.0)  # 0.1 s at 40 deg/s
        assert time.monotonic() - t0 >= 0.095
        assert slow.received.count("1MD?") >= 2  # it did poll while moving
        stage.close()
    finally:
        slow.close()


@pytest.mark.parametrize("kind, match", [("timeout", "1TP?"), ("garble", "2TP?"),
                                         ("timeout", "1MD?"), ("garble", "2MD?")])
def test_transient_faults_are_survived(pty_link, kind, match):
    fake, stage, _ = pty_link
    fake.inject(kind, match, count=2)
    assert stage.move_to(3.0, -4.0) == (3.0, -4.0)
    assert fake.received.count(match) >= 3  # two lost replies, one good one


def test_short_silence_on_a_query_is_survived(pty_link):
    fake, stage, _ = pty_link
    fake.inject("silent", "1MD?", silent_s=0.15)  # 1MD? and what follows: no reply, 0.15 s
    assert stage.move_to(1.0, 1.0) == (1.0, 1.0)


def test_long_silence_on_a_query_is_a_timeout(pty_link):
    fake, stage, _ = pty_link
    stage.retries, stage.retry_delay_s, stage.timeout = 1, 0.0, 0.05
    fake.inject("silent", "1MD?", silent_s=5.0)
    with pytest.raises(StageTimeout, match=r"'1MD\?' after 2 attempt"):
        stage.move_to(1.0, 1.0)


@pytest.mark.parametrize("silent_s, empty", [(0.15, True), (5.0, False)])
def test_silence_after_a_move_is_a_lost_error_reply(pty_link, silent_s, empty):
    """The TB? after the move gets no reply: it may have popped an error, so the move is not
    reported as a success, whether the buffer then reads empty or the silence outlasts the
    retries."""
    fake, stage, _ = pty_link
    stage.retries, stage.retry_delay_s = 1, 0.1
    fake.inject("silent", "2PA", silent_s=silent_s)
    with pytest.raises(ErrorReplyLost) as info:
        stage.move_to(1.0, 1.0)
    assert info.value.empty is empty
    if not empty:
        assert isinstance(info.value.__cause__, StageTimeout)


@pytest.mark.parametrize("code, cls, text", [
    (104, ControllerLimitError, "positive hardware limit"),
    (202, ControllerError, "amplifier fault"),
    (4, ControllerError, "emergency stop"),
])
def test_controller_errors_are_reported(pty_link, code, cls, text):
    fake, stage, _ = pty_link
    fake.inject("error", "1PA", code=code, silent_s=0.0)
    with pytest.raises(cls, match=text) as info:
        stage.move_to(2.0, 2.0)
    assert type(info.value) is cls and info.value.code == code


@pytest.mark.parametrize("kind", ["timeout", "garble"])
@pytest.mark.parametrize("match, code, tb", [("1PA", 104, 0), ("2PA", 202, 0), ("1MD?", 113, 1),
                                            ("2MD?", 205, 1)])
def test_an_error_whose_reply_is_lost_is_never_a_success(pty_link, kind, match, code, tb):
    """The controller queues an error, then the reply to the TB? that pops it (the first, after
    the PA commands, or the second, after motion done) is lost or garbled: before the fix,
    move_to reported success (3 of 3)."""
    fake, stage, _ = pty_link
    fake.inject("error", match, code=code, silent_s=0.0)
    fake.inject(kind, "TB?", count=1, after=tb)
    tb_before = fake.received.count("TB?")
    with pytest.raises(ErrorReplyLost, match="may have been lost") as info:
        stage.move_to(2.0, 2.0)
    assert info.value.lost == 1 and info.value.empty and info.value.errors == []
    assert fake.handle(b"TE?") == b"0\r\n"  # the error really is gone from the controller
    assert fake.received.count("TB?") - tb_before >= 2  # re-queried until a clean "no error"


def test_a_stuck_axis_is_a_motion_timeout_and_gets_stopped(pty_link):
    fake, stage, _ = pty_link
    stage.motion_timeout_s = 0.1
    fake.inject("stuck", "2PA")
    with pytest.raises(MotionTimeout, match=r"axis \[2\]"):
        stage.move_to(0.0, 10.0)
    assert "2ST" in fake.received
    assert stage.motion_done()  # stopped: the axis is idle again
    assert stage.move_to(0.0, 10.0) == (0.0, 10.0)  # and the next move works


def test_disconnect_is_survived_over_tcp_by_reconnecting(fake):
    stage = ESP300(fake.serve_tcp(), **FAST)
    fake.inject("disconnect", "1TP?")
    fake.inject("garble", "2MD?")  # a transient fault over TCP as well
    assert stage.move_to(5.0, 6.0) == (5.0, 6.0)
    assert stage.reconnects == 1
    stage.close()


def test_disconnect_of_a_pty_is_reported(fake):
    stage = ESP300(fake.serve_pty(), **FAST)
    fake.inject("disconnect", "1TP?")
    with pytest.raises(StageDisconnected, match="resume"):
        stage.move_to(5.0, 6.0)
    stage.close()


def test_open_stage_fake_url_and_its_options():
    stage = open_stage("fake://?velocity=1e4&transport=tcp", **FAST)
    assert stage.url.startswith("socket://127.0.0.1:")
    assert stage.move_to(1.5, 2.5) == (1.5, 2.5)
    assert stage.fake.position() == (1.5, 2.5)
    stage.close()


@pytest.mark.parametrize("url", ["fake://?speed=3", "fake://?transport=usb", ""])
def test_open_stage_rejects_bad_urls(url):
    from sunlab import ConfigurationError

    with pytest.raises(ConfigurationError):
        open_stage(url)
