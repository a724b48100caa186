"""sunlab's exceptions (sunlab.errors): one line with the field, the value found and the fix."""

import pytest

from sunlab.errors import ConfigurationError, SchemaError, SunlabError


def test_every_sunlab_error_is_a_value_error():
    # callers that guard bad input with `except ValueError` catch sunlab's errors too
    for cls in (SchemaError, ConfigurationError):
        assert issubclass(cls, SunlabError) and issubclass(SunlabError, ValueError)


def test_schema_error_message_names_field_found_expected_and_fix():
    err = SchemaError("attrs.pixel_pitch_mm", -7.0, "a positive pitch, mm", "write 0.007")
    assert str(err) == ("attrs.pixel_pitch_mm: found -7.0, expected a positive pitch, mm. "
                        "Fix: write 0.007")
    assert (err.field, err.found, err.expected, err.fix) == (
        "attrs.pixel_pitch_mm", -7.0, "a positive pitch, mm", "write 0.007")
    assert "\n" not in str(err)


def test_schema_error_without_a_fix_ends_at_the_expectation():
    err = SchemaError("frames", "3-d", "4-d (pose, shot, y, x)")
    assert str(err) == "frames: found '3-d', expected 4-d (pose, shot, y, x)" and err.fix is None


def test_configuration_error_carries_its_message():
    with pytest.raises(SunlabError, match="^order: found -1"):
        raise ConfigurationError("order: found -1, expected a non-negative integer")
