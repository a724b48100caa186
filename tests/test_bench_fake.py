"""The fake ESP controller: its protocol, and the driver end to end over a pty and over TCP,
with every injected fault either survived (retry, reconnect) or reported with a clear error."""

from __future__ import annotations

import math
import time

import pytest

from sunlab.bench import (
    ESP300,
    ControllerError,
    ControllerLimitError,
    FakeESP,
    MotionTimeout,
    StageDisconnected,
    StageTimeout,
    open_stage,
)
from sunlab.bench.fake import DISCONNECT, ManualClock

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
                                         ("timeout", "1MD?"), ("garble", "TB?")])
def test_transient_faults_are_survived(pty_link, kind, match):
    fake, stage, _ = pty_link
    fake.inject(kind, match, count=2)
    assert stage.move_to(3.0, -4.0) == (3.0, -4.0)
    assert fake.received.count(match) >= 3  # two lost replies, one good one


def test_short_silence_after_a_limit_is_survived(pty_link):
    fake, stage, _ = pty_link
    fake.inject("silent", "2PA", silent_s=0.15)
    assert stage.move_to(1.0, 1.0) == (1.0, 1.0)


def test_long_silence_is_a_timeout(pty_link):
    fake, stage, _ = pty_link
    stage.retries, stage.retry_delay_s, stage.timeout = 1, 0.0, 0.05
    fake.inject("silent", "2PA", silent_s=5.0)
    with pytest.raises(StageTimeout, match=r"'TB\?' after 2 attempt"):
        stage.move_to(1.0, 1.0)


@pytest.mark.parametrize("code, cls, text", [
    (104, ControllerLimitError, "positive hardware limit"),
    (202, ControllerError, "amplifier fault"),
    (4, ControllerError, "emergency stop"),
])
def test_controller_errors_are_reported(pty_link, code, cls, text):
    fake, stage, _ = pty_link
    fake.inject("error", "1PA", code=code, silent_s=0.05)
    with pytest.raises(cls, match=text) as info:
        stage.move_to(2.0, 2.0)
    assert info.value.code == code


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
