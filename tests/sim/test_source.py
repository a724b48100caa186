"""The solar simulator (sunlab.sim.source): the paper's 0.52 deg disk and its radial profile."""

import math

import numpy as np
import pytest

from sunlab.errors import ConfigurationError
from sunlab.sim.source import PAPER_SOURCE_DIAMETER_DEG, Source


def test_paper_source_is_the_sphere_port_through_the_lens():
    # R = 6.82 mm at f = 1500 mm: 2 atan(R / f) = 0.5210 deg, the Sun's size seen from Earth
    assert PAPER_SOURCE_DIAMETER_DEG == pytest.approx(0.5210, abs=5e-5)
    src = Source()
    assert src.diameter_deg == PAPER_SOURCE_DIAMETER_DEG
    assert src.radius_rad == pytest.approx(6.82 / 1500.0, rel=1e-5)  # atan(x) ~ x


def test_profile_is_uniform_for_the_sphere_and_limb_darkened_for_the_sun():
    r = np.array([0.0, 0.5, 0.99, 1.0, 1.01])
    np.testing.assert_array_equal(Source().profile(r), [1.0, 1.0, 1.0, 1.0, 0.0])
    sun = Source(limb_darkening=0.6).profile(r)
    # I = 1 - u (1 - mu), mu = sqrt(1 - r^2): 1 at the centre, 1 - u at the limb
    np.testing.assert_allclose(sun, [1.0, 1 - 0.6 * (1 - math.sqrt(0.75)),
                                     1 - 0.6 * (1 - math.sqrt(1 - 0.99**2)), 0.4, 0.0])


@pytest.mark.parametrize("u", [0.0, 0.3, 0.6, 1.0])
def test_second_moment_is_the_profiles_by_quadrature(u):
    # <x^2> of the normalised profile over the unit disk, by the midpoint rule in r (2000
    # rings: the error is O(1/n^2) ~ 1e-7, the limb's sqrt singularity keeps it below 1e-5)
    src = Source(limb_darkening=u)
    n = 2000
    r = (np.arange(n) + 0.5) / n
    w = src.profile(r) * r  # ring area 2 pi r dr; <x^2> = <r^2> / 2
    expected = np.sum(w * r**2) / np.sum(w) / 2
    assert src.second_moment() == pytest.approx(expected, abs=1e-5)
    if u == 0.0:
        assert src.second_moment() == 0.25


@pytest.mark.parametrize("kwargs, field", [
    ({"diameter_deg": -0.1}, "diameter_deg"),
    ({"diameter_deg": float("nan")}, "diameter_deg"),
    ({"limb_darkening": 1.5}, "limb_darkening"),
    ({"fluence_photons_per_um2": -1.0}, "fluence_photons_per_um2"),
])
def test_bad_source_names_the_field_and_the_fix(kwargs, field):
    with pytest.raises(ConfigurationError, match=f"source.{field}: found .* Fix:"):
        Source(**kwargs)
