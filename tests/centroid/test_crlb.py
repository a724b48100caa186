"""The Cramér–Rao bound of a spot centroid (sunlab.centroid.crlb) against closed forms.

For a circular Gaussian spot of width s and flux F (continuous limit, pixel width 1):
pure Poisson noise (gain 1 e-/DN) gives I_xx = F / s**2, so sigma_x = s / sqrt(F); pure read
noise sigma_n gives I_xx = F**2 / sigma_n**2 * integral (dP/dx)**2 = F**2 / (8 pi s**4 sigma_n**2).
Pixel integration widens the spot's variance by 1/12 px**2: at s = 3 px that moves the bound by
under 1 %, so the closed forms are held to 2 %.
"""

import math

import numpy as np
import pytest

from sunlab.centroid.crlb import CRLB, crlb, disk_profile
from sunlab.errors import ConfigurationError

S = 3.0  # Gaussian width, px


def _gauss(dx, dy):
    return np.exp(-(dx**2 + dy**2) / (2 * S**2))


def test_pure_poisson_limit_is_width_over_root_flux():
    flux = 1e5
    b = crlb(flux, 0.0, 0.0, gain=1.0, model=_gauss, half_size=8 * S, quantisation=False,
             position=(0.0, 0.0))
    assert isinstance(b, CRLB)
    assert b.sigma_x == pytest.approx(S / math.sqrt(flux), rel=0.02)
    assert b.sigma_y == pytest.approx(b.sigma_x, rel=1e-9)  # a round spot on the pixel centre


def test_pure_read_noise_limit_and_its_scaling():
    flux, noise = 1e4, 5.0
    kw = dict(gain=1e12, model=_gauss, half_size=8 * S, quantisation=False, position=(0.0, 0.0))
    b = crlb(flux, 0.0, noise, **kw)
    assert b.sigma_x == pytest.approx(noise * math.sqrt(8 * math.pi) * S**2 / flux, rel=0.02)
    # read-noise limited: the bound is linear in the noise and inverse in the flux
    assert crlb(flux, 0.0, 2 * noise, **kw).sigma_x == pytest.approx(2 * b.sigma_x, rel=1e-6)
    assert crlb(2 * flux, 0.0, noise, **kw).sigma_x == pytest.approx(b.sigma_x / 2, rel=1e-6)


def test_background_and_quantisation_only_raise_the_bound():
    base = crlb(3e5, 0.0, 2.5, gain=4.0, quantisation=False)
    assert crlb(3e5, 30.0, 2.5, gain=4.0, quantisation=False).sigma_x > base.sigma_x
    assert crlb(3e5, 0.0, 2.5, gain=4.0, quantisation=True).sigma_x > base.sigma_x


def test_paper_spot_is_located_to_hundredths_of_a_pixel():
    # the paper's spot: 17.5 px radius, 3.25 px edge, ~385 000 DN over a 30 DN background
    b = crlb(385000.0, 30.0, 2.5, gain=4.0)
    assert 0.002 < b.sigma_x < 0.02 and 0.002 < b.sigma_y < 0.02


def test_disk_profile_is_the_source_disk_in_a_half_plane():
    assert [float(disk_profile(r, 0.0)) for r in (0.0, 17.5, 30.0)] == [1.0, 0.5, 0.0]
    # the blurred edge is symmetric about the hole's radius: f(-d) = 1 - f(d)
    d = np.linspace(0.0, 3.25, 7)
    np.testing.assert_allclose(disk_profile(17.5 - d, 0.0) + disk_profile(17.5 + d, 0.0), 1.0,
                               atol=1e-12)
    # and it depends only on the distance from the centre
    assert float(disk_profile(12.0, 9.0)) == pytest.approx(float(disk_profile(15.0, 0.0)))
    hard = disk_profile(np.array([17.4, 17.6]), 0.0, edge=0.0)
    assert hard.tolist() == [1.0, 0.0]


@pytest.mark.parametrize("args, match", [
    ((0.0, 30.0, 2.5), "flux"),
    ((1e5, -1.0, 2.5), "background"),
    ((1e5, 30.0, -2.5), "read_noise"),
])
def test_bad_input_names_the_argument(args, match):
    with pytest.raises(ConfigurationError, match=match):
        crlb(*args)


def test_a_spot_of_no_brightness_is_refused():
    with pytest.raises(ConfigurationError, match="zero brightness"):
        crlb(1e5, 0.0, 1.0, model=lambda dx, dy: 0.0 * dx * dy, half_size=5.0)
