"""The bench's faults (sunlab.hardware.errors): a class per fault a script can recover from, each
message one line naming the device, the command or field, what was found and the fix."""

import pytest

from sunlab.errors import SunlabError
from sunlab.hardware import errors as E


def test_every_fault_is_a_bench_error_and_a_sunlab_error():
    for name in [*E.__all__, "StageTimeout", "StageProtocolError", "StageDisconnected"]:
        cls = getattr(E, name)
        assert issubclass(cls, E.BenchError) and issubclass(cls, SunlabError), name
    assert issubclass(E.CameraTimeout, E.CameraError)
    # the controller's own limit report is caught by both handlers a script may write
    assert issubclass(E.ControllerLimitError, E.ControllerError)
    assert issubclass(E.ControllerLimitError, E.LimitError)


@pytest.mark.parametrize("err, words", [
    (E.StageTimeout("1TP?", 3, 0.5), ["'1TP?'", "3 attempt(s)", "0.5 s", "Fix:"]),
    (E.StageProtocolError("1MD?", b"\x00garbled", "a 0/1 flag", attempts=2),
     ["'1MD?'", "a 0/1 flag", "2 attempt(s)", "Fix:"]),
    (E.StageDisconnected("/dev/ttyUSB0", "cable pulled"),
     ["'/dev/ttyUSB0'", "cable pulled", "--resume"]),
    (E.MotionTimeout([1], {1: 12.5}, 30.0), ["[1]", "12.5", "30 s", "motion_timeout"]),
])
def test_messages_are_one_line_with_the_fix(err, words):
    text = str(err)
    assert "\n" not in text and text.startswith("stage: ")
    for w in words:
        assert w in text


@pytest.mark.parametrize("code, axis, fix", [
    (104, 1, "back inside its travel"),
    (207, 2, "software limits"),
    (103, 1, "re-enable the motor"),
    (213, 2, "enable the motor"),
    (4, None, "emergency stop"),
    (6, None, "sunlab bug"),
    (99, None, "controller manual"),
])
def test_controller_error_names_axis_code_and_a_fix_for_its_code(code, axis, fix):
    err = E.ControllerError(code, "meaning", axis=axis, command="1PA5")
    where = f"axis {axis}" if axis is not None else "controller"
    assert str(err).startswith(f"stage: {where} reported error {code} (meaning) after '1PA5'")
    assert fix in str(err) and err.code == code and err.axis == axis


def test_limit_error_outside_keeps_the_numbers_and_says_nothing_moved():
    err = E.LimitError.outside("alpha", 185.0, -170.0, 170.0)
    assert isinstance(err, E.LimitError)
    assert (err.field, err.value, err.low, err.high) == ("alpha", 185.0, -170.0, 170.0)
    assert "[-170, 170] deg" in str(err) and "nothing was moved" in str(err)


def test_lost_error_replies_never_read_as_no_error():
    read = [E.ControllerError(104, "positive hardware limit detected", axis=1)]
    err = E.ErrorReplyLost("PA", 2, read, empty=False, detail="garbled")
    assert (err.lost, err.empty, err.errors) == (2, False, read)
    text = str(err)
    assert "2 replies" in text and "error 104" in text and "could not be read to empty" in text
    assert "not known to have succeeded" in text
