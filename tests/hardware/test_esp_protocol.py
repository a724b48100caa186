"""The ESP300/301 wire protocol (sunlab.hardware.esp_protocol): error codes, numbers, the link."""

import pytest

from sunlab.hardware import esp_protocol as P
from sunlab.hardware.errors import StageDisconnected


def test_terminators_are_the_manuals():
    # commands end in CR; the controller answers queries with CR LF
    assert P.WRITE_TERMINATOR == b"\r" and P.READ_TERMINATOR == b"\r\n"
    assert P.UNITS[7] == "degree"


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
    assert P.decode_error(code) == (axis, text)


def test_every_limit_code_decodes_to_a_limit():
    for sub in (4, 5, 6, 7):
        assert "limit" in P.decode_error(100 + sub)[1]


@pytest.mark.parametrize("value, text", [
    (12.5, "12.5"), (-3.0, "-3"), (0.1234567, "0.123457"), (0.0, "0"), (-0.0000001, "0"),
    (170, "170"), (-169.999999, "-169.999999"),
])
def test_format_number_is_the_shortest_fixed_point_to_a_microdegree(value, text):
    assert P.format_number(value) == text
    assert float(text) == pytest.approx(value, abs=5e-7)


def test_loopback_transport_echoes_and_is_a_transport():
    port = P.open_transport("loop://", timeout=0.1)
    try:
        assert isinstance(port, P.Transport)
        port.write(b"1TP?" + P.WRITE_TERMINATOR)
        assert port.read_until(P.WRITE_TERMINATOR) == b"1TP?\r"
    finally:
        port.close()


def test_a_port_that_cannot_open_is_a_disconnected_stage():
    with pytest.raises(StageDisconnected, match="cannot open"):
        P.open_transport("nosuchscheme://x", timeout=0.1)
