"""Physics of sunlab.sim.diffraction and its opt-in use by the renderer (mask.diffraction)."""

import json
import math

import numpy as np
import pytest
from scipy import special

from sunlab.errors import ConfigurationError
from sunlab.sim import Bench, Mask, _aperture, diffraction, render, spots
from sunlab.sim import frame as simframe
from sunlab.sim.holes import Hole


def test_fresnel_number_of_the_paper_hole():
    # a = 0.1 mm, lambda = 550 nm: N = 0.01 / (0.00055 F)
    assert diffraction.fresnel_number(0.1, 5.0) == pytest.approx(3.636, abs=1e-3)
    assert diffraction.fresnel_number(0.1, 17.0) == pytest.approx(1.070, abs=1e-3)


def test_large_fresnel_number_gives_the_geometric_disk():
    # s = q / N -> 0: the lens is the whole disk, M -> 2 J1(2 pi q) / (2 pi q). To first order
    # in s, |dM/ds| <= 2/pi (the moving lower limit) + pi q (the phase's shift), so
    # |M - jinc| <= (q / N_min) (2/pi + pi q) with N_min the band's smallest (at 1100 nm).
    z = 0.01 / (1.1e-3 * 1e4)  # N = 1e4 at 1100 nm: z = 0.9 um
    q = np.linspace(0.0, 3.0, 61)
    dev = np.abs(diffraction.broadband_transform(q, 0.1, z) - diffraction.jinc(2 * math.pi * q))
    assert np.all(dev <= (q / 1e4) * (2 / math.pi + math.pi * q) + 1e-12)
    assert dev.max() > 0  # and it is not the jinc itself


@pytest.mark.parametrize("n", [0.3, 1.0, 2.5, 3.64])
def test_on_axis_intensity_is_the_closed_form(n):
    # I(0) / I0 = |exp(i pi N) - 1|^2 = 4 sin^2(pi N / 2) (Hecht, Optics, sec. 10.3): the
    # Kirchhoff integral by quadrature, and the inverse transform of Guigay's lens
    # I(0) = int M(f) d^2f = 2 pi^2 int_0^{2N} M(q) q dq (trapezoid on 4001 points, 1e-6)
    exact = 4 * math.sin(math.pi * n / 2) ** 2
    assert diffraction.monochromatic_intensity([0.0], n)[0] == pytest.approx(exact, abs=1e-10)
    q = np.linspace(0.0, 2 * n, 4001)
    via_ft = 2 * math.pi**2 * np.trapezoid(diffraction.monochromatic_transform(q, n) * q, q)
    assert via_ft == pytest.approx(exact, abs=1e-5)


def test_small_fresnel_number_gives_the_airy_pattern():
    # N << 1: the Fresnel phase pi N s^2 <= pi N over the hole changes the Fraunhofer (Airy)
    # pattern [2 J1(x) / x]^2, x = 2 pi N rho, by order (pi N)^2 relative (inside its first zero)
    n = 0.02
    x = np.array([0.5, 2.0, 3.0])
    i = diffraction.monochromatic_intensity(np.r_[0.0, x / (2 * math.pi * n)], n)
    assert np.all(np.abs(i[1:] / i[0] / (2 * special.j1(x) / x) ** 2 - 1) < (math.pi * n) ** 2)
    assert i[0] == pytest.approx((math.pi * n) ** 2, rel=(math.pi * n) ** 2)


def test_energy_is_the_aperture_area():
    # the transform is 1 at f = 0 (the lens of zero shift is the disk, area pi a^2) ...
    zero = np.array([0.0])
    assert diffraction.monochromatic_transform(zero, 1.0)[0] == pytest.approx(1.0, abs=1e-14)
    assert diffraction.broadband_transform(zero, 0.1, 17.0)[0] == pytest.approx(1.0, abs=1e-14)
    # ... and the pattern integrated to R = 10 radii misses the Airy tail's 1 / (pi^2 N R)
    r = np.linspace(0.0, 10.0, 4001)
    e = np.trapezoid(diffraction.monochromatic_intensity(r, 1.0) * 2 * math.pi * r, r) / math.pi
    tail = 1 / (math.pi**2 * 1.0 * 10.0)
    assert 0.9 * tail < 1 - e < 1.1 * tail


def test_broadband_damps_the_on_axis_oscillation():
    # monochromatic, I(0) swings over 0..4 as N goes 3 -> 6; the electrons' spectrum (350-1100
    # nm) spans N by 3x, so the broadband centre swings by under a quarter of that
    n = np.linspace(3.0, 6.0, 13)
    bb = [diffraction.broadband_intensity([0.0], 0.1, 0.01 / (0.00055 * k))[0] for k in n]
    assert np.ptp(bb) < 0.25 * 4.0
    lam, w = diffraction.spectral_weights()
    assert w.sum() == pytest.approx(1.0) and 0.5 <= lam[np.argmax(w)] <= 0.7


def test_table_matches_the_direct_sum():
    k = np.linspace(0.0, 30.0, 301)
    direct = diffraction.broadband_transform(k / (2 * math.pi), 0.1, 17.0)
    # the spline (1e-6) at the Fresnel number rounded to 1e-4 (M changes by 1e-4 x dM/dln N)
    assert np.abs(diffraction.aperture_ft(k, 0.1, 17.0) - direct).max() < 1e-5


# ------------------------------------------------------------------------------ the renderer
def _bench(distance_mm, on):
    return (Bench.paper_single_hole().ideal_platform().ideal_mask().noise_free()
            .replace(mask__distance_mm=distance_mm, mask__diffraction=on))


def test_switch_off_is_the_geometric_path_bit_for_bit():
    # off: no Fresnel hole, and the spectrum is the kernel's jinc path exactly as before
    b = _bench(5.0, False)
    geom = render.spot_geometry(b, -8.0, 4.0)
    g = spots._groups(b, geom)[0]
    assert g.fresnel is None
    fx, fy = np.linspace(-1.5, 1.5, 31), np.linspace(-1.5, 1.5, 29)
    ref = _aperture.spectrum_tabulated(fx, fy, g.affine, g.area, g.kernel_m, g.u, g.ax, g.ay,
                                       g.diff, True)
    assert np.array_equal(g.common(fx, fy, tabulated=True), ref)
    default = Bench.paper_single_hole()
    assert default.mask.diffraction is False
    assert np.array_equal(simframe.render_frame(default, -8.0, 4.0, seed=1),
                          simframe.render_frame(default.replace(mask__diffraction=False),
                                                -8.0, 4.0, seed=1))


def test_rendered_pattern_is_the_broadband_fresnel_intensity():
    # no sun disk, no pixel: the image is q_e x the pattern, which the renderer takes from the
    # transform's table and diffraction.broadband_intensity from the Kirchhoff integral; the
    # pattern is band-limited below 2 a p / (lambda_min z) = 0.24 cycles/px, so sampling is exact
    b = _bench(17.0, True).without_lid().replace(source__diameter_deg=0.0)
    img, x0, y0, _ = spots.spot_image(b, 0.0, 0.0, pixel=False)
    q_e = render.spot_geometry(b, 0.0, 0.0).q_e
    (x,), (y,) = render.ray_positions(b, 0.0, 0.0)
    yy, xx = np.mgrid[-30:31:3, -30:31:3] + np.array([[[round(y) - y0]], [[round(x) - x0]]])
    rho = np.hypot(xx + x0 - x, yy + y0 - y) / (0.1 / 0.007)
    ref = diffraction.broadband_intensity(rho, 0.1, 17.0)
    assert ref.max() > 3  # N ~ 1: the first Fresnel zone's bright centre
    assert np.abs(img[yy, xx] / q_e - ref).max() < 1e-4


def test_fresnel_spot_at_17_mm_keeps_its_centroid_and_grows_a_halo():
    geo, fre = _bench(17.0, False), _bench(17.0, True)
    (xg, yg), (xf, yf) = spots.spot_truth(geo, 0.0, 0.0), spots.spot_truth(fre, 0.0, 0.0)
    # a normally incident sun: the pattern is symmetric about the geometric ray
    assert abs(xf[0] - xg[0]) < 1e-3 and abs(yf[0] - yg[0]) < 1e-3
    img, x0, y0, _ = spots.spot_image(fre, 0.0, 0.0)
    yy, xx = np.indices(img.shape)
    cx, cy = (img * xx).sum() / img.sum() + x0, (img * yy).sum() / img.sum() + y0
    # the stamp wraps 0.5 % of the energy (the halo): a pull under 0.005 px toward its centre
    assert abs(cx - xg[0]) < 0.005 and abs(cy - yg[0]) < 0.005
    ig, xg0, yg0, _ = spots.spot_image(geo, 0.0, 0.0, size=img.shape[0])
    assert img.sum() == pytest.approx(ig.sum(), rel=1e-4)  # the same energy
    # the geometric spot ends at the hole's radius plus the sun disk's, 14.3 + 11.0 px; the
    # Fresnel spot spreads about 1 / (pi^2 N rho) of its energy beyond any radius rho
    r = np.hypot(xx + x0 - xg[0], yy + y0 - yg[0])
    out = r > (0.1 + 17.0 * math.radians(0.521 / 2)) / 0.007 + 2.0
    assert ig[out].sum() / ig.sum() < 1e-5
    assert img[out].sum() / img.sum() > 0.05


def test_bench_record_round_trips_the_switch():
    b = Bench.paper_single_hole().replace(mask__diffraction=True)
    rec = json.loads(b.to_json())["mask"]
    assert rec["diffraction"] is True
    again = Mask(holes=b.mask.holes, **{k: v for k, v in rec.items() if k != "holes"})
    assert again == b.mask
    assert json.loads(Bench.paper_single_hole().to_json())["mask"]["diffraction"] is False
    with pytest.raises(ConfigurationError, match="mask.diffraction"):
        Bench.paper_single_hole().replace(mask__diffraction="yes")


def test_out_of_range_fresnel_number_is_refused():
    # a 2 mm hole at 5 mm: N = 364, where the geometric shadow is the model
    big = Mask(holes=(Hole(0.0, 0.0, 4.0),), size_mm=(11.0, 9.0), diffraction=True)
    with pytest.raises(ConfigurationError, match="mask.diffraction"):
        spots.spot_truth(Bench.paper_single_hole().replace(mask=big), 0.0, 0.0)
