"""Physics of sunlab.sim.render: spot positions, sizes, fluxes, true centroids and defects."""

import math

import numpy as np
import pytest
from numpy.testing import assert_allclose

from sunlab.errors import ConfigurationError
from sunlab.geometry import ideal_centroid
from sunlab.sim import Bench, Mask, render, spots
from sunlab.sim import frame as simframe
from sunlab.sim.holes import Dust, Hole
from sunlab.sim.mask import Burred

P = 0.007  # pixel pitch, mm
F = 5.0  # nominal mask distance, mm


def _centred(bench):
    """The bench with one 0.2 mm hole above the detector centre at exactly F = 5 mm (a short
    sensor: 0.08 deg per px, the spot on the detector over the paper's whole test range), no
    glass lid: the rays of eq. (1)."""
    return bench.ideal_platform().ideal_mask().without_lid().replace(
        mask__distance_mm=F, mask__holes=(Hole(0.0, 0.0, 0.2),))


@pytest.fixture(scope="module")
def ideal():
    """One 0.2 mm hole at exactly F = 5 mm above the detector centre, perfect platform."""
    return _centred(Bench.paper_single_hole())


def _window_centroid(frame, x, y, bg, half=30):
    x0, y0 = int(round(x)) - half, int(round(y)) - half
    w = (
        frame[y0 : y0 + 2 * half, x0 : x0 + 2 * half].astype(float)
        - bg[y0 : y0 + 2 * half, x0 : x0 + 2 * half]
    )
    yy, xx = np.mgrid[y0 : y0 + 2 * half, x0 : x0 + 2 * half]
    return (w * xx).sum() / w.sum(), (w * yy).sum() / w.sum()


@pytest.mark.parametrize(("alpha", "beta"), [(0.0, 0.0), (-16.5, 16.5), (-8.2, 3.7), (1.5, -1.5)])
def test_rendered_spot_centroid_matches_eq1(ideal, alpha, beta):
    # A high-SNR frame (shot, dark and read noise on; fixed patterns off, so the background is
    # known): its background-subtracted centroid sits at F (tan a, tan b / cos a) within 0.01 px.
    bench = ideal.replace(detector__fixed_pattern=False)
    frame = simframe.render_frame(bench, alpha, beta, seed=5, pose=1, shot=2)
    xi, yi = ideal_centroid(alpha, beta, F, P, 639.5, 511.5)
    mean_bg, _ = simframe.expected_frame(
        bench.replace(source__fluence_photons_per_um2=0.0), alpha, beta
    )
    xc, yc = _window_centroid(frame, xi, yi, mean_bg)
    assert abs(xc - xi) < 0.01 and abs(yc - yi) < 0.01


@pytest.mark.parametrize(("alpha", "beta"), [(0.0, 0.0), (-16.5, 16.5), (-3.3, 9.9)])
def test_truth_is_the_centroid_of_the_expected_signal(ideal, alpha, beta):
    x, y = spots.spot_truth(ideal, alpha, beta)
    img, x0, y0, _ = spots.spot_image(ideal, alpha, beta)
    yy, xx = np.mgrid[0 : img.shape[0], 0 : img.shape[1]]
    assert_allclose((img * (xx + x0)).sum() / img.sum(), x[0], atol=1e-4)
    assert_allclose((img * (yy + y0)).sum() / img.sum(), y[0], atol=1e-4)
    # and it is the analytic position: the sun disk and the fill factor move it by < 0.01 px
    xi, yi = ideal_centroid(alpha, beta, F, P, 639.5, 511.5)
    assert abs(x[0] - xi) < 0.01 and abs(y[0] - yi) < 0.01
    xr, yr = render.ray_positions(ideal, alpha, beta)
    assert_allclose([xr[0], yr[0]], [xi, yi], atol=1e-9)


def test_spot_diameter_is_hole_plus_sun_disk(ideal):
    # Irradiance of a normally incident spot, 8 samples per pixel: the plateau ends at
    # R_hole - r_sun and the light at R_hole + r_sun, with r_sun = F tan(0.26 deg).
    img, x0, y0, step = spots.spot_image(ideal, 0.0, 0.0, oversample=8, pixel=False)
    xc, yc = spots.spot_truth(ideal, 0.0, 0.0)
    yy, xx = np.mgrid[0 : img.shape[0], 0 : img.shape[1]]
    r = np.hypot(x0 + xx * step - xc[0], y0 + yy * step - yc[0]).ravel()
    v = img.ravel() / img.max()
    r_hole = 0.1 / P
    r_sun = F * math.tan(math.radians(ideal.source.diameter_deg / 2)) / P
    assert r[v > 1e-3].max() == pytest.approx(r_hole + r_sun, abs=0.25)
    assert r[v < 0.999].min() == pytest.approx(r_hole - r_sun, abs=0.25)
    # the half-intensity contour lies at the hole's edge (slightly inside: curvature)
    half = r[(v > 0.45) & (v < 0.55)]
    assert half.mean() == pytest.approx(r_hole, abs=0.2)


@pytest.mark.parametrize(
    ("alpha", "beta"), [(-16.5, 0.0), (0.0, 16.5), (-12.0, 12.0), (-30.0, 20.0)]
)
def test_flux_follows_projected_hole_area(ideal, alpha, beta):
    def flux(a, b):
        img, *_ = spots.spot_image(ideal, a, b, size=96)
        return img.sum()

    ratio = flux(alpha, beta) / flux(0.0, 0.0)
    assert ratio == pytest.approx(
        math.cos(math.radians(alpha)) * math.cos(math.radians(beta)), rel=2e-4
    )


def test_flux_absolute(ideal):
    # fluence x hole area x QE x fill factor, in electrons
    img, *_ = spots.spot_image(ideal, 0.0, 0.0)
    det = ideal.detector
    expected = ideal.source.fluence_photons_per_um2 * math.pi * 100.0**2 * det.qe * det.fill_factor
    assert img.sum() == pytest.approx(expected, rel=1e-4)


def test_fill_factor_makes_centroid_depend_on_subpixel_position():
    # A sharp-edged spot (point source) on pixels with a small sensitive area: the sampled
    # centroid departs from the geometric ray by an amount that depends on the sub-pixel phase.
    bench = _centred(Bench.paper_single_hole()).replace(
        source__diameter_deg=0.0, detector__fill_factor=0.16)
    errs = []
    for a in np.linspace(0.0, 0.08, 9):  # 0.08 deg = one pixel of travel
        x, _ = spots.spot_truth(bench, a, 0.0)
        xr, _ = render.ray_positions(bench, a, 0.0)
        errs.append(x[0] - xr[0])
    errs = np.array(errs)
    assert 1e-4 < np.ptp(errs) < 0.05


def test_polygon_path_agrees_with_jinc_path(ideal):
    # A burr of zero amplitude forces the polygon transform of a circle.
    poly = ideal.replace(mask=Mask(holes=(Hole(0.0, 0.0, 0.2, defect=Burred(0.0)),)))
    for a, b in [(0.0, 0.0), (-10.0, 6.0)]:
        x1, y1 = spots.spot_truth(ideal, a, b)
        x2, y2 = spots.spot_truth(poly, a, b)
        assert_allclose([x2[0], y2[0]], [x1[0], y1[0]], atol=1e-4)
        f1 = spots.spot_image(ideal, a, b)[0].sum()
        f2 = spots.spot_image(poly, a, b)[0].sum()
        assert f2 == pytest.approx(f1, rel=1e-3)


def test_dust_above_the_mask_makes_a_pose_dependent_error(ideal):
    def bias(height):
        m = Mask(holes=(Hole(0.0, 0.0, 0.2, defect=Dust(0.07, 0.0, 0.06, height)),))
        b = ideal.replace(mask=m)
        out = []
        for a in (-15.0, 0.0):
            x, _ = spots.spot_truth(b, a, 0.0)
            xr, _ = render.ray_positions(b, a, 0.0)
            out.append(x[0] - xr[0])
        return np.array(out)

    flat = bias(0.0)
    raised = bias(0.05)
    assert np.all(flat < -0.1)  # dust on the +x side pulls the centroid to -x ...
    assert abs(flat[0] - flat[1]) < 0.05  # ... by a nearly constant amount when it lies flat
    assert abs(raised[0] - raised[1]) > 0.1  # its shadow slides when it stands above the mask


def test_tilted_mask_and_dF_move_the_spot(ideal):
    x0, _ = spots.spot_truth(ideal, -10.0, 0.0)
    x1, _ = spots.spot_truth(ideal.replace(mask__delta_f_mm=0.094), -10.0, 0.0)
    assert x1[0] - x0[0] == pytest.approx(0.094 * math.tan(math.radians(-10.0)) / P, abs=0.01)


def test_sun_behind_the_mask_gives_no_spot(ideal):
    bench = ideal.replace(mask__tilt_y_deg=20.0)
    g = render.spot_geometry(bench, 80.0, 0.0)
    assert not g.lit
    x, y = spots.spot_truth(bench, 80.0, 0.0)
    assert np.isnan(x[0]) and np.isnan(y[0])


def test_render_into_out_is_the_same_frame():
    # a pose's block is rendered shot by shot in place; the frame must not depend on where it
    # is written, and a wrong buffer names the field and the fix
    bench = Bench.paper_single_hole()
    new = simframe.render_frame(bench, 3.0, -2.0, seed=4, pose=2, shot=1)
    block = np.zeros((2,) + bench.detector.shape, dtype=np.uint16)
    got = simframe.render_frame(bench, 3.0, -2.0, seed=4, pose=2, shot=1, out=block[1])
    assert np.shares_memory(got, block[1])
    np.testing.assert_array_equal(block[1], new)
    assert not block[0].any()
    with pytest.raises(ConfigurationError, match="out: found float32"):
        simframe.render_frame(bench, 3.0, -2.0, seed=4, out=np.empty(bench.detector.shape,
                                                                    dtype=np.float32))


@pytest.mark.parametrize("bench", [Bench.paper_single_hole(), Bench.paper_multi_hole()],
                         ids=["one-hole", "100-hole"])
def test_pose_shared_shape_is_within_its_bound(bench):
    # The shots of a pose share the spots' shape, evaluated at the first shot; each shot keeps
    # its own position and flux. At 4x the jitter's RMS (0.002 deg per axis) the expected stamps
    # differ from the exact ones by under 1e-4 of the peak (the projected aperture and the
    # sun-disk kernel change by parts in 1e5; burred and dusty polygons the most) and their
    # centroids by under 1e-4 px, far below one photo-electron and the 0.001 px of the truth.
    d = 0.002
    for a, b in [(-12.0, 7.3), (9.0, -11.0), (0.3, 0.2)]:
        exact = _stamps(bench, [a + d], [b - d], (a + d, b - d))[0]
        shared = _stamps(bench, [a, a + d], [b, b - d], (a, b))
        assert [(x, y) for _, x, y in shared[1]] == [(x, y) for _, x, y in exact]
        for (i1, _, _), (i2, _, _) in zip(exact, shared[1], strict=True):
            assert np.abs(i1 - i2).max() < 1e-4 * i1.max()
            yy, xx = np.mgrid[: i1.shape[0], : i1.shape[1]]
            c1 = np.array([(i1 * xx).sum(), (i1 * yy).sum()]) / i1.sum()
            c2 = np.array([(i2 * xx).sum(), (i2 * yy).sum()]) / i2.sum()
            assert np.abs(c1 - c2).max() < 1e-4
            assert abs(i2.sum() / i1.sum() - 1) < 1e-5
        # the first shot is the exact frame's: its shape is its own
        for (i1, x1, y1), (i0, x0, y0) in zip(_stamps(bench, [a], [b], (a, b))[0], shared[0],
                                              strict=True):
            assert (x1, y1) == (x0, y0) and np.array_equal(i1, i0)


def test_render_pose_is_render_frame_with_the_pose_shape():
    bench = Bench.paper_multi_hole()
    a, b = np.array([-5.0, -5.0007, -4.9996]), np.array([5.0, 5.0002, 4.9991])
    frames = simframe.render_pose(bench, a, b, seed=3, pose=4)
    for s in range(3):
        one = simframe.render_frame(bench, a[s], b[s], seed=3, pose=4, shot=s,
                                  shape_angles=(a[0], b[0]))
        np.testing.assert_array_equal(frames[s], one)
    exact = simframe.render_frame(bench, a[1], b[1], seed=3, pose=4, shot=1)
    diff = frames[1].astype(int) - exact
    assert np.abs(diff).max() <= 1 and np.count_nonzero(diff) < 100  # rounding flips only
    with pytest.raises(ConfigurationError, match="alpha_true, beta_true: found shapes"):
        simframe.render_pose(bench, a, b[:2], seed=3)


def _stamps(bench, alphas, betas, shape_angles):
    """Per shot, the list of (image, x0, y0) of _pose_stamps' buffer and boxes."""
    buf, boxes = simframe._pose_stamps(bench, alphas, betas, (0.0, 0.0), shape_angles)
    return [[(buf[o : o + ny * nx].reshape(ny, nx), x0, y0) for o, y0, x0, ny, nx in box]
            for box in boxes]


def test_overlapping_stamps_add_and_clip_to_the_frame():
    # without noise, at unit gain and no dark signal, every stamped pixel is the rounded sum of
    # all stamps over it, clipped to the detector; the pixels under no stamp keep their value
    from sunlab.sim import _adc as D

    shape = (150, 200)
    rng = np.random.default_rng(1)
    ones, zeros = np.ones(shape, np.float32), np.zeros(shape, np.float32)
    for _ in range(100):
        sizes = rng.integers(5, 40, rng.integers(1, 12))
        offsets = np.concatenate([[0], np.cumsum(sizes**2)])
        buf = rng.uniform(0.0, 300.0, offsets[-1])
        boxes = np.array([(o, rng.integers(-30, 150), rng.integers(-30, 200), n, n)
                          for o, n in zip(offsets, sizes, strict=False)], dtype=np.int64)
        full, hit = np.zeros(shape), np.zeros(shape, bool)
        for o, y0, x0, ny, nx in boxes:
            big = np.zeros((shape[0] + 80, shape[1] + 80))  # room beyond every edge
            big[y0 + 40 : y0 + 40 + ny, x0 + 40 : x0 + 40 + nx] = buf[o : o + ny * nx].reshape(
                ny, nx)
            full += big[40:-40, 40:-40]
            hit |= big[40:-40, 40:-40] > 0
        out = np.full(shape, 7, np.uint16)
        D.adc_stamps(boxes, buf, ones, zeros, zeros, np.empty(0, np.float32),
                     np.zeros(1, np.uint64), 0.0, 1.0, 1e9, 65535.0, out)
        np.testing.assert_array_equal(out[hit], np.floor(full[hit] + 0.5))
        assert (out[~hit] == 7).all()


@pytest.mark.parametrize("theta_deg", [5.0, 17.0])
def test_glass_lid_shifts_an_oblique_ray_as_snells_law_says(ideal, theta_deg):
    # a plane-parallel plate of thickness t and index n under a ray at theta shifts it toward
    # the hole's foot by t (tan theta - sin theta / sqrt(n^2 - sin^2 theta)): for t = 0.5 mm,
    # n = 1.523 and 17 deg, 0.0548 mm = 7.8 px (docs/paper.md sec. 10)
    t, n = 0.5, 1.523
    lid = ideal.replace(detector__lid_thickness_mm=t, detector__lid_index=n)
    foot, _ = render.ray_positions(ideal, 0.0, 0.0)
    x0, _ = render.ray_positions(ideal, -theta_deg, 0.0)
    x1, _ = render.ray_positions(lid, -theta_deg, 0.0)
    th = np.radians(theta_deg)
    expected = t * (np.tan(th) - np.sin(th) / np.sqrt(n**2 - np.sin(th) ** 2)) / 0.007
    # the lid brings the ray closer to the hole's foot (the zenith spot) by that much
    assert_allclose(float(abs(x0[0] - foot[0]) - abs(x1[0] - foot[0])), expected, rtol=1e-9)
    # at zenith the lid does nothing
    assert_allclose(render.ray_positions(lid, 0.0, 0.0)[0], foot, atol=1e-12)


def test_spot_centres_equal_the_per_frame_geometry_for_one_and_100_holes():
    """The batched centroids are the same formula as spot_geometry's ray + kernel mean."""
    from sunlab.sim.render import spot_centres, spot_geometry

    rng = np.random.default_rng(5)
    for bench in (Bench.paper_single_hole(), Bench.paper_multi_hole()):
        a, b = rng.uniform(-20, 20, 40), rng.uniform(-20, 20, 40)
        play = rng.uniform(-0.003, 0.003, (40, 2))
        x, y = spot_centres(bench, a, b, play)
        for k in range(40):
            g = spot_geometry(bench, a[k], b[k], tuple(play[k]))
            # float64 sums in another order: agreement far below any centroid noise (1e-3 px)
            np.testing.assert_allclose(x[k], g.ray[:, 0] + g.kernel_mu[0] * g.height_mm,
                                       rtol=0, atol=1e-9)
            np.testing.assert_allclose(y[k], g.ray[:, 1] + g.kernel_mu[1] * g.height_mm,
                                       rtol=0, atol=1e-9)


def test_spot_centres_refuse_angles_behind_the_mask():
    from sunlab.sim.render import spot_centres

    with pytest.raises(ConfigurationError, match="alpha_true, beta_true"):
        spot_centres(Bench.paper_single_hole(), [95.0], [0.0], [[0.0, 0.0]])
