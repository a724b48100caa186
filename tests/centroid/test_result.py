"""The single-spot result (sunlab.centroid.result): the Centroid record and its status rules,
and the frame checks every estimator shares (bad frames end in one line naming the fix)."""

import math

import numpy as np
import pytest

from sunlab import centroid as C
from sunlab.centroid.result import SATURATION_10BIT, Centroid
from sunlab.errors import SchemaError
from sunlab.schema import STATUS, STATUS_NAMES


@pytest.mark.parametrize("name", sorted(STATUS))
def test_status_name_and_usability_follow_the_schema(name):
    c = Centroid(120.5, 90.0, 1.0e5, (100, 141, 70, 111), STATUS[name])
    assert c.status_name == name == STATUS_NAMES[STATUS[name]]
    # only an ok or a repaired (hot pixels replaced) centroid is usable
    assert c.ok is (name in ("ok", "repaired"))


def test_saturation_10bit_is_the_full_scale_of_ten_bits():
    assert SATURATION_10BIT == 2**10 - 1


def test_a_clipped_spot_at_10bit_full_scale_is_flagged_saturated():
    yy, xx = np.mgrid[0:64, 0:64]
    frame = np.where(np.hypot(xx - 31.5, yy - 30.0) < 8, SATURATION_10BIT, 20).astype(np.uint16)
    c = C.tight_window(frame, saturation=SATURATION_10BIT)
    assert c.status_name == "saturated" and not c.ok
    # the geometry is still measured: the flat top is symmetric about its centre
    assert c.x == pytest.approx(31.5, abs=1e-6) and c.y == pytest.approx(30.0, abs=1e-6)


@pytest.mark.parametrize("frame, match", [
    (np.zeros((3, 8, 8)), "frame"),
    (np.array([["a"] * 8] * 8), "frame.dtype"),
])
def test_a_frame_that_is_not_an_image_is_refused_with_its_fix(frame, match):
    with pytest.raises(SchemaError, match=match):
        C.tight_window(frame)


@pytest.mark.parametrize("frame", [np.zeros((64, 64), np.uint16), np.full((4, 4), 50.0),
                                   np.full((64, 64), np.nan)])
def test_unusable_frames_give_an_invalid_centroid_not_an_error(frame):
    c = C.tight_window(frame)
    assert c.status_name == "invalid" and math.isnan(c.x) and c.window == (-1, -1, -1, -1)
