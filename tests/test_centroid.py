"""Tests of sunlab.centroid on synthetic frames with exactly known truth (tests/_spots.py)."""

from __future__ import annotations

import math

import _spots
import numpy as np
import pytest
from numpy.testing import assert_allclose

from sunlab import centroid as C
from sunlab.errors import ConfigurationError, SchemaError
from sunlab.schema import STATUS

SINGLE = ["threshold", "projection", "tight", "fit"]
EDGE = 3.25  # sun-disk blur at F = 5 mm, px


# ------------------------------------------------------------------------------------------------
# Noise-free exactness
# ------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("method", SINGLE)
@pytest.mark.parametrize("xy", [(640.3, 500.7), (100.13, 200.77), (1003.5, 880.25)])
@pytest.mark.parametrize("background", [0.0, 30.0])
def test_noise_free_symmetric_spot_to_1e_3_px(method, xy, background):
    frame = _spots.frame([xy], noise=False, edge=EDGE, background=background)
    c = C.METHODS[method](frame)
    assert c.status == STATUS["ok"], c
    assert_allclose([c.x, c.y], xy, atol=1e-3)
    x0, x1, y0, y1 = c.window
    assert x0 <= xy[0] < x1 and y0 <= xy[1] < y1


@pytest.mark.parametrize("method", ["projection", "tight"])
def test_flux_is_background_subtracted_total(method):
    frame = _spots.frame([(640.3, 500.7)], noise=False, edge=EDGE, background=30.0)
    truth = (frame - 30.0).sum()
    assert_allclose(C.METHODS[method](frame).flux, truth, rtol=1e-6)


# ------------------------------------------------------------------------------------------------
# Noisy frames at the paper's SNR: each algorithm within its expected error
# ------------------------------------------------------------------------------------------------
def _noisy_errors(method, n=12, **kw):
    rng = np.random.default_rng(7)
    err = []
    for k in range(n):
        xy = (rng.uniform(150, 1100), rng.uniform(150, 870))
        frame = _spots.frame([xy], edge=EDGE, seed=k, **kw)
        c = C.METHODS[method](frame)
        assert c.status == STATUS["ok"]
        err.append((c.x - xy[0], c.y - xy[1]))
    return np.array(err)


def _crlb():
    flux = 400.0 * math.pi * 17.5**2
    return C.crlb(flux, 30.0, 2.5, gain=4.0, radius=17.5, edge=EDGE)


@pytest.mark.parametrize("method, factor", [("projection", 3.0), ("tight", 2.5), ("fit", 1.8)])
def test_noisy_error_near_crlb(method, factor):
    """B, the tight window and the fit are unbiased; their scatter is a small multiple of the CRLB
    (COM: ~1.5-1.7x; fit: ~1.0-1.1x; the factors allow for 12 frames of sampling noise)."""
    err = _noisy_errors(method)
    bound = _crlb().sigma_x
    rms = np.sqrt((err**2).mean())
    assert rms < factor * bound
    assert np.abs(err).max() < 5 * factor * bound


def test_algorithm_a_bias_is_the_predicted_window_pull():
    """Algorithm A's 128 x 128 window is centred on the spot's top edge: positive noise above
    the ROI-border threshold pulls the centroid toward that window centre. The expected pull is
    E[max(n - t, 0)] over the window's background pixels times the offset, over the total."""
    rng = np.random.default_rng(3)
    errs, pred = [], []
    for k in range(6):
        xy = (rng.uniform(200, 1000), rng.uniform(200, 800))
        frame = _spots.frame([xy], edge=EDGE, seed=100 + k)
        c = C.threshold_window(frame)
        assert c.status == STATUS["ok"]
        x0, x1, y0, y1 = c.window
        roi = frame[y0 - 1 : y1 + 1, x0 - 1 : x1 + 1].astype(float)
        t = np.mean(np.concatenate([roi[:2].ravel(), roi[-2:].ravel(), roi[2:-2, :2].ravel(),
                                    roi[2:-2, -2:].ravel()]))
        yy, xx = np.mgrid[y0:y1, x0:x1]
        bg = np.hypot(xx - xy[0], yy - xy[1]) > 17.5 + EDGE + 1
        w = np.clip(frame[y0:y1, x0:x1] - t, 0, None) * bg   # the positive-noise pedestal
        flux = 400.0 * math.pi * 17.5**2
        pull = np.array([(w * (xx - xy[0])).sum(), (w * (yy - xy[1])).sum()])
        pred.append(pull / (flux + w.sum()))
        errs.append((c.x - xy[0], c.y - xy[1]))
    errs, pred = np.array(errs), np.array(pred)
    assert np.all(errs[:, 1] < -0.3)  # pulled up toward the spot's top edge
    assert_allclose(errs, pred, atol=0.05)


# ------------------------------------------------------------------------------------------------
# Status codes: never an exception for a frame that cannot be processed
# ------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("method", SINGLE)
def test_no_spot(method):
    frame = _spots.frame([], seed=1)
    c = C.METHODS[method](frame)
    assert c.status == STATUS["no_spot"] and math.isnan(c.x) and math.isnan(c.y)
    assert c.window == (-1, -1, -1, -1)


@pytest.mark.parametrize("method", SINGLE)
def test_two_spots_are_ambiguous(method):
    frame = _spots.frame([(400.2, 300.6), (900.7, 700.1)], edge=EDGE, seed=2)
    c = C.METHODS[method](frame)
    assert c.status == STATUS["ambiguous"]
    # The estimate still belongs to one of the spots.
    d = min(math.hypot(c.x - 400.2, c.y - 300.6), math.hypot(c.x - 900.7, c.y - 700.1))
    assert d < 2.0


@pytest.mark.parametrize("method", SINGLE)
def test_saturated(method):
    frame = _spots.frame([(640.3, 500.7)], peak=1500.0, edge=EDGE, seed=3)
    assert frame.max() == 1023
    c = C.METHODS[method](frame, saturation=1023)  # the 10-bit ADC's full scale, declared
    assert c.status == STATUS["saturated"]
    assert math.hypot(c.x - 640.3, c.y - 500.7) < 1.5


def test_fit_ignores_saturated_pixels():
    frame = _spots.frame([(640.3, 500.7)], peak=1500.0, edge=EDGE, seed=3)
    c = C.disk_fit(frame, saturation=1023)
    assert_allclose([c.x, c.y], [640.3, 500.7], atol=0.03)


@pytest.mark.parametrize("method", SINGLE)
@pytest.mark.parametrize("xy", [(8.4, 500.2), (640.3, 1020.6), (1275.0, 3.0)])
def test_clipped_at_the_edge(method, xy):
    frame = _spots.frame([xy], edge=EDGE, seed=4)
    c = C.METHODS[method](frame)
    assert c.status == STATUS["clipped"], c


@pytest.mark.parametrize("method", SINGLE)
def test_hot_pixels_alone_are_no_spot(method):
    frame = _spots.frame([], seed=5)
    rng = np.random.default_rng(5)
    rows, cols = rng.integers(0, 1024, 40), rng.integers(0, 1280, 40)
    frame[rows, cols] = 1023
    c = C.METHODS[method](frame)
    assert c.status == STATUS["no_spot"], c


@pytest.mark.parametrize("method", SINGLE)
def test_hot_pixels_beside_a_spot_do_not_move_it(method):
    frame = _spots.frame([(640.3, 500.7)], edge=EDGE, seed=6)
    rng = np.random.default_rng(6)
    rows, cols = rng.integers(0, 1024, 40), rng.integers(0, 1280, 40)
    far = np.hypot(cols - 640.3, rows - 500.7) > 80
    frame[rows[far], cols[far]] = 1023
    c = C.METHODS[method](frame)
    assert c.status == STATUS["ok"], c
    tol = 1.5 if method == "threshold" else 0.05
    assert math.hypot(c.x - 640.3, c.y - 500.7) < tol


@pytest.mark.parametrize("method", SINGLE)
@pytest.mark.parametrize(
    "frame",
    [
        np.zeros((1024, 1280), np.uint16),
        np.full((1024, 1280), np.nan),
        _spots.frame([(640.3, 500.7)], noise=False).astype(float) * np.where(
            np.arange(1280) == 5, np.nan, 1.0),
        np.full((1024, 1280), np.inf, np.float32),
        np.zeros((4, 4), np.uint16),
    ],
    ids=["all-zero", "all-nan", "one-nan-column", "inf", "tiny"],
)
def test_invalid_frames(method, frame):
    c = C.METHODS[method](frame)
    assert c.status == STATUS["invalid"] and math.isnan(c.x)


@pytest.mark.parametrize("method", SINGLE)
def test_constant_frame_is_no_spot(method):
    assert C.METHODS[method](np.full((1024, 1280), 30, np.uint16)).status == STATUS["no_spot"]


@pytest.mark.parametrize("method", SINGLE)
def test_wrong_dimensions_raise_a_named_error(method):
    with pytest.raises(SchemaError, match="frame"):
        C.METHODS[method](np.zeros((2, 8, 8)))


@pytest.mark.parametrize("dtype", [np.uint8, np.int16, np.int32, np.float32, np.float64])
def test_dtypes(dtype):
    frame = _spots.frame([(200.4, 150.6)], noise=False, edge=EDGE, peak=200, shape=(300, 400))
    c = C.tight_window(frame.astype(dtype))
    assert c.ok
    assert_allclose([c.x, c.y], [200.4, 150.6], atol=0.02)


def test_result_type_is_a_named_tuple():
    c = C.projection_window(_spots.frame([(640.3, 500.7)], edge=EDGE))
    x, y, flux, window, status = c
    assert c.status_name == "ok" and c.ok and len(window) == 4 and flux > 0
    assert isinstance(c, C.Centroid)


def test_disk_fit_rejects_unknown_option():
    with pytest.raises(ConfigurationError, match="unknown option"):
        C.disk_fit(np.zeros((64, 64)), strid=4)


# ------------------------------------------------------------------------------------------------
# Cramér–Rao bound
# ------------------------------------------------------------------------------------------------
def test_crlb_gaussian_spot_matches_closed_form():
    """A Gaussian spot on zero background with pure Gaussian noise: sigma_x^2 = sigma_n^2 /
    sum (d mu / dx)^2 = 8 pi s^4 sigma_n^2 / F^2 for pixels small against s."""
    s, flux, rn = 3.0, 1e4, 2.0

    def model(dx, dy):
        return np.exp(-(dx**2 + dy**2) / (2 * s * s))

    b = C.crlb(flux, 0.0, rn, gain=1e12, model=model, half_size=25, quantisation=False)
    expected = math.sqrt(8 * math.pi * s**4 * rn**2 / flux**2)
    assert_allclose([b.sigma_x, b.sigma_y], expected, rtol=0.01)


def test_crlb_scales_with_flux_and_shape():
    b1 = C.crlb(4e5, 30, 2.5, gain=4.0)
    b4 = C.crlb(1.6e6, 30, 2.5, gain=4.0)
    # sigma ~ 1 / sqrt(flux) when photon-limited, ~ 1 / flux when read/background-limited.
    assert 2.0 < b1.sigma_x / b4.sigma_x < 4.0
    hard = C.crlb(4e5, 30, 2.5, gain=4.0, edge=0.0)
    assert hard.sigma_x < b1.sigma_x  # a sharper edge carries more position information
    assert_allclose(b1.sigma_x, b1.sigma_y, rtol=0.02)


def test_crlb_bad_input():
    with pytest.raises(ConfigurationError, match="flux"):
        C.crlb(-1.0, 30, 2.5)


# ------------------------------------------------------------------------------------------------
# Multi-spot frames
# ------------------------------------------------------------------------------------------------
def _grid_frame(angle=1.0, missing=(), dim=(), seed=3):
    pos, ii, jj = _spots.grid_spots(angle_deg=angle)
    peak = np.full(100, 400.0)
    peak[list(missing)] = 0.0
    peak[list(dim)] = 80.0
    return _spots.frame(pos, peak=peak, edge=EDGE, seed=seed), pos, ii, jj, peak


@pytest.mark.parametrize("angle", [0.0, 1.0, -2.0])
def test_locate_spots_indexes_a_grid_with_missing_and_dim_holes(angle):
    frame, pos, ii, jj, peak = _grid_frame(angle, missing=(5, 37, 62), dim=(11, 48))
    s = C.locate_spots(frame)
    present = peak > 0
    assert np.all(s.status[~present] == STATUS["no_spot"])
    assert np.all(s.status[present] == STATUS["ok"])
    assert_allclose(s.x[present], pos[present, 0], atol=0.1)
    assert_allclose(s.y[present], pos[present, 1], atol=0.1)
    assert np.array_equal(s.i, ii) and np.array_equal(s.j, jj)
    assert_allclose(np.hypot(*s.lattice[1]), 500 / 7, rtol=1e-3)
    assert np.nanmax(s.metrics["ellipticity"]) < 0.05
    assert_allclose(np.nanmedian(s.metrics["radius"]), math.hypot(17.5, EDGE / 2), rtol=0.03)
    df = s.to_dataframe()
    assert len(df) == 100 and {"i", "j", "x", "asymmetry"} <= set(df.columns)


def test_locate_spots_missing_outer_column_needs_expected_positions():
    frame, pos, ii, jj, peak = _grid_frame(0.0, missing=range(0, 100, 10))
    s = C.locate_spots(frame, expected=pos + np.array([3.0, -4.0]))
    present = peak > 0
    assert np.all(s.status[~present] == STATUS["no_spot"])
    assert_allclose(s.x[present], pos[present, 0], atol=0.1)


def test_locate_spots_occluded_hole_is_asymmetric():
    frame, pos, *_ = _grid_frame(0.0)
    x, y = pos[44]
    yy, xx = np.mgrid[0:1024, 0:1280]
    occ = (xx > x + 6) & (np.hypot(xx - x, yy - y) < 25)
    frame = np.where(occ, 30, frame).astype(np.uint16)  # dust over a third of one hole
    s = C.locate_spots(frame)
    others = np.delete(s.metrics["asymmetry"], 44)
    assert s.metrics["asymmetry"][44] > 10 * np.nanmax(others)


@pytest.mark.parametrize("frame", [np.zeros((1024, 1280), np.uint16),
                                   np.full((1024, 1280), 30, np.uint16)])
def test_locate_spots_empty_frames(frame):
    s = C.locate_spots(frame)
    expected = STATUS["invalid"] if frame.max() == 0 else STATUS["no_spot"]
    assert np.all(s.status == expected) and np.all(np.isnan(s.x))


# ------------------------------------------------------------------------------------------------
# Cube level and command line
# ------------------------------------------------------------------------------------------------
def _small_cube():
    from sunlab import schema

    truth = np.array([[[200.3, 150.6], [201.1, 149.2]], [[120.7, 90.4], [0.0, 0.0]]])
    frames = np.empty((2, 2, 300, 400), np.uint16)
    for p in range(2):
        for s in range(2):
            spots = [] if (p, s) == (1, 1) else [tuple(truth[p, s])]
            frames[p, s] = _spots.frame(spots, edge=EDGE, seed=10 * p + s, shape=(300, 400))
    cube = schema.frames_dataset(frames, alpha=[0.0, -1.0], beta=[0.5, 0.0],
                                 experiment="test")
    cube["true_x"] = (("pose", "shot"), truth[..., 0])
    return cube, truth


@pytest.mark.parametrize("method", SINGLE)
def test_locate_cube(method):
    from sunlab.schema import validate_centroids

    cube, truth = _small_cube()
    import dask.array as da

    cube["frames"] = cube["frames"].copy(data=da.from_array(cube["frames"].values,
                                                            chunks=(1, 1, 300, 400)))
    cen = C.locate(cube, method, progress=False)
    validate_centroids(cen)
    assert cen.attrs["method"] == method and cen.attrs["experiment"] == "test"
    assert_allclose(cen.alpha.values, [0.0, -1.0])
    assert cen.status.values.tolist() == [[0, 0], [0, 1]]
    tol = 1.5 if method == "threshold" else 0.05
    ok = cen.status.values == 0
    assert_allclose(cen.x.values[ok], truth[..., 0][ok], atol=tol)
    assert_allclose(cen.y.values[ok], truth[..., 1][ok], atol=tol)
    assert "true_x" in cen


def test_locate_lazy_and_bad_method():
    cube, _ = _small_cube()
    lazy = C.locate(cube, "tight", compute=False)
    assert hasattr(lazy.x.data, "dask")
    assert_allclose(lazy.x.compute().values, C.locate(cube, "tight", progress=False).x.values)
    with pytest.raises(ConfigurationError, match="method"):
        C.locate(cube, "nope")


def test_locate_acquisition_store_with_read_back_coordinates():
    # An acquisition run keeps alpha_read / beta_read as (pose, shot) coordinates (frames/1
    # allows it); the table carries them over as variables without a coordinate clash.
    cube, _ = _small_cube()
    read = np.array([[0.001, -0.002], [-1.003, -0.999]])
    cube = cube.assign_coords(alpha_read=(("pose", "shot"), read),
                              beta_read=(("pose", "shot"), read + 0.5))
    cen = C.locate(cube, "tight", progress=False)
    assert_allclose(cen["alpha_read"].values, read)
    assert_allclose(cen["beta_read"].values, read + 0.5)
    assert cen.status.values.tolist() == [[0, 0], [0, 1]]


def test_cli_centroid(tmp_path, capsys):
    from sunlab import io
    from sunlab.cli import main

    cube, truth = _small_cube()
    io.save_frames(cube, tmp_path / "cube.zarr")
    out = tmp_path / "cen.nc"
    assert main(["centroid", str(tmp_path / "cube.zarr"), "--method", "projection", "--out",
                 str(out), "--no-progress"]) == 0
    cen = io.open_centroids(out)
    assert_allclose(cen.x.values[0], truth[0, :, 0], atol=0.05)
    assert "3 ok" in capsys.readouterr().out


def test_locate_spots_on_a_rendered_bench_frame_matches_truth():
    # The virtual bench's 10 x 10 mask at the paper's SNR, full detector model (PRNU, DSNU,
    # fill factor, hot pixels): every hole found, indexed as the truth orders them, and the
    # centroids within the fixed-pattern error of the identified bench (its 2.97 % response
    # pattern moves a 35 px spot by about 0.05 px per axis; defective holes more); the
    # pattern's predicted shift (sunlab.sim.surrogate.spot_error_maps) explains most of it.
    from scipy import ndimage

    from sunlab import sim
    from sunlab.sim.render import mask_play
    from sunlab.sim.surrogate import spot_error_maps

    bench = sim.Bench.paper_multi_hole()
    a, b = sim.platform.platform_pose(bench, -8.0, 7.0, seed=0, pose=0, shot=0)
    frame = sim.render_frame(bench, a, b, seed=0)
    # the mask's play of pose 0 moves every spot: the truth with it
    tx, ty = sim.spots.spot_truth(bench, a, b, play_mm=mask_play(bench, 0, 0))
    s = C.locate_spots(frame)
    assert np.all(np.isfinite(tx)) and tx.size == 100
    assert np.all(s.status == STATUS["ok"]) and s.unassigned.shape == (0, 2)
    err = np.hypot(s.x - tx, s.y - ty)
    assert np.sqrt(np.mean(err**2) / 2) < 0.1 and err.max() < 0.5
    dx, dy = spot_error_maps(bench)
    yx = np.stack([ty, tx])
    px = tx + ndimage.map_coordinates(dx, yx, order=1)
    py = ty + ndimage.map_coordinates(dy, yx, order=1)
    good = np.array([h.defect_flags == 0 for h in bench.mask.holes])
    left = np.hypot(s.x - px, s.y - py)[good]
    assert np.sqrt(np.mean(left**2)) < 0.75 * np.sqrt(np.mean(err[good] ** 2))
    assert_allclose(np.hypot(*s.lattice[1]), 500 / 7, rtol=5e-3)
    assert_allclose(np.hypot(*s.lattice[2]), 500 / 7, rtol=5e-3)
    assert np.all((s.window[0] <= s.x) & (s.x < s.window[1]))
    assert np.all((s.window[2] <= s.y) & (s.y < s.window[3]))
    assert np.nanmax(s.metrics["lattice_residual"]) < 2.0  # a flat-lattice fit: ~1 px
    assert np.all(s.metrics["radius"] > 10) and np.all(s.metrics["radius"] < 25)


@pytest.mark.parametrize("dtype", [np.uint16, np.float64])
def test_aperture_moments_match_direct_sums(dtype):
    # The moments come from matrix products of each stamp with column and row powers, moved
    # to the centre of mass; compare with the textbook per-pixel central moments of (I - b).
    from sunlab.centroid import _aperture as K

    rng = np.random.default_rng(3)
    frame = rng.integers(20, 900, (120, 140)).astype(dtype)
    xc, yc, r_ap, bkg = 70.37, 58.81, 21.3, 41.7
    one = (np.array([xc]), np.array([yc]))
    got = K._moments(frame, *one, np.array([r_ap]), np.array([bkg]), 880.0)[0]
    yy, xx = np.mgrid[0:120, 0:140]
    sel = np.hypot(xx - xc, yy - yc) <= r_ap
    w = frame[sel].astype(float) - bkg
    s = w.sum()
    x, y = xc + (w * (xx[sel] - xc)).sum() / s, yc + (w * (yy[sel] - yc)).sum() / s
    dx, dy = xx[sel] - x, yy[sel] - y
    mom = [(w * dx**p * dy**q).sum() / s for p, q in
           [(2, 0), (0, 2), (1, 1), (3, 0), (2, 1), (1, 2), (0, 3)]]
    assert_allclose(got[:3], [s, x, y], rtol=1e-12)
    assert_allclose(got[3:10], mom, rtol=1e-9, atol=1e-9)
    assert got[10] == frame[sel].max() and got[11] == sel.sum()
    assert got[12] == (frame[sel] >= 880.0).sum()
    m, sd, n = K._annulus(frame, *one, np.array([r_ap]), np.array([r_ap + 6]), 100.0, 800.0)
    ring = (np.hypot(xx - xc, yy - yc) > r_ap) & (np.hypot(xx - xc, yy - yc) <= r_ap + 6)
    v = frame[ring].astype(float)
    v = v[(v >= 100) & (v <= 800)]
    assert n[0] == v.size
    assert_allclose([m[0], sd[0]], [v.mean(), v.std()], rtol=1e-10)


def test_metric_fields_follow_spot_metrics():
    from sunlab.centroid import _grid as K

    assert K.METRIC_FIELDS == tuple(C.lattice.SPOT_METRICS)


@pytest.mark.parametrize("stride", [3, 8])
def test_detected_groups_match_8_connected_labels(stride):
    # The detection groups strided samples above threshold; compare its sums with a direct
    # pass over scipy.ndimage.label's groups (8-connectivity) of the same samples.
    from scipy import ndimage

    from sunlab.centroid import _aperture as K

    rng = np.random.default_rng(5)
    frame = rng.integers(0, 40, (203, 257)).astype(np.uint16)
    yy, xx = np.mgrid[0:203, 0:257]
    for x0, y0, r in [(40, 30, 14), (200, 60, 9), (120, 150, 20), (5, 195, 12), (250, 2, 6)]:
        frame[np.hypot(xx - x0, yy - y0) < r] += 500
    frame[100, 100] = 900  # a lone hot sample (maybe on the grid)
    off = stride // 2
    samples = frame[off::stride, off::stride].astype(float)
    thr, bkg = 300.0, 20.0
    lab, n = ndimage.label(samples > thr, structure=np.ones((3, 3)))
    cnt, flux, cx, cy = K._groups(frame, stride, thr, bkg)
    assert cnt.size == n
    rows, cols = np.mgrid[off:203:stride, off:257:stride]
    # Both number the groups in raster order of their first sample.
    for k in range(n):
        sel = lab == k + 1
        w = samples[sel] - bkg
        assert cnt[k] == sel.sum()
        assert_allclose([flux[k], cx[k], cy[k]],
                        [w.sum(), (w * cols[sel]).sum() / w.sum(), (w * rows[sel]).sum() / w.sum()],
                        rtol=1e-12)


def _neighbour_vectors_all_pairs(q, pitch, k):
    # Reference: the k nearest of each point by a scan of all points in index order (a stable
    # sort by distance), kept when 0.7 pitch < distance < 1.3 pitch.
    out = []
    for i in range(len(q)):
        d2 = ((q - q[i]) ** 2).sum(axis=1)
        for j in np.argsort(d2, kind="stable")[:k]:
            if 0.7 * pitch < np.hypot(*(q[j] - q[i])) < 1.3 * pitch:
                out.append(q[j] - q[i])
    return np.array(out).reshape(-1, 2)


@pytest.mark.parametrize("case", ["grid", "jittered", "sparse", "spread"])
def test_neighbour_vectors_match_all_pairs(case):
    # The vectorised search must give the vectors of the scan, in the same order, ties
    # (exact lattice points) included.
    from sunlab.centroid import _grid as K

    rng = np.random.default_rng(11)
    pitch = 70.0
    jj, ii = np.meshgrid(np.arange(10), np.arange(8))
    q = np.column_stack([100 + pitch * jj.ravel(), 50 + pitch * ii.ravel()]).astype(float)
    if case == "jittered":
        q += rng.normal(0, 4, q.shape)
    elif case == "sparse":
        q = q[rng.random(len(q)) < 0.5]
    elif case == "spread":  # two clumps far apart
        q = np.vstack([q[:5], q[:5] + 1e5])
    got = K._neighbour_vectors(np.ascontiguousarray(q), pitch, 5)
    ref = _neighbour_vectors_all_pairs(q, pitch, 5)
    assert got.shape == ref.shape
    assert np.array_equal(got, ref)


def test_fit_lattice_affine_fit_matches_lstsq():
    # The fitted lattice against numpy's SVD least squares on a sheared, rotated lattice with
    # noise and missing nodes.
    from sunlab.centroid import _grid as K

    rng = np.random.default_rng(3)
    jj, ii = np.meshgrid(np.arange(10), np.arange(10))
    keep = rng.random(100) > 0.2
    nodes = np.column_stack([jj.ravel(), ii.ravel()])[keep]
    basis = np.array([[71.0, -2.5], [1.8, 70.2]])
    origin = np.array([140.3, 97.9])
    p = origin + nodes @ basis.T + rng.normal(0, 0.3, (keep.sum(), 2))
    ij, o, b, resid = K._fit_lattice(p, np.ones(len(p), bool), 71.0, 0.3)
    a = np.column_stack([np.ones(len(p)), ij])
    sol = np.linalg.lstsq(a, p, rcond=None)[0]
    assert_allclose(o, sol[0], rtol=0, atol=1e-9)
    assert_allclose(b, sol[1:].T, rtol=0, atol=1e-9)
    assert_allclose(resid, np.hypot(*(p - a @ sol).T), rtol=0, atol=1e-9)


def test_fit_lattice_nodes_on_one_line_keep_the_first_estimate():
    # Three spots on a diagonal of the grid: no affine map is defined, the fit keeps the
    # orientation estimate instead of dividing by zero.
    from sunlab.centroid import _grid as K

    p = np.array([[100.0, 100.0], [170.0, 170.0], [240.0, 240.0]])
    ij, o, b, resid = K._fit_lattice(p, np.ones(3, bool), 70.0, 0.3)
    assert np.all(np.isfinite(b)) and np.all(np.isfinite(resid))


@pytest.mark.parametrize("method", ["projection", "threshold", "tight"])
def test_isolated_hot_pixel_is_repaired_not_saturated(method):
    # A hot pixel clipped at full scale inside the window (the paper bench's row 508, column
    # 471 kind) is not spot saturation: it is replaced by the median of its neighbours, the
    # centroid equals the clean frame's, and the status says 'repaired' (usable). Touching
    # clipped pixels are the spot saturating.
    yy, xx = np.mgrid[0:300, 0:400]
    clean = (30 + 400 * (np.hypot(xx - 200.3, yy - 150.6) < 25)).astype(np.uint16)
    def func(frame):
        return C.METHODS[method](frame, saturation=1023)

    ref = func(clean)
    hot = clean.copy()
    hot[162, 214] = 1023
    c = func(hot)
    assert c.status_name == "repaired" and c.ok
    # the tight window's ring is a sigma-clipped mean in the compiled pass and a clipped
    # least-squares constant in the repair pass: equal to 1e-6 px on this flat background
    assert_allclose((c.x, c.y), (ref.x, ref.y), atol=1e-9 if method != "tight" else 1e-6)
    sat = clean.copy()
    sat[150, 199:202] = 1023
    assert func(sat).status_name == "saturated"


@pytest.mark.parametrize("method", SINGLE)
def test_saturation_comes_from_the_declared_depth_not_a_hidden_1023(method):
    # A 16-bit camera's spot peaks at 3000 DN: nothing is clipped at its full scale (65535),
    # so the default (the frame type's full scale) says ok; declared as a 10-bit full scale
    # the same frame saturates.
    frame = (_spots.frame([(640.3, 500.7)], edge=EDGE, seed=3).astype(np.uint16) * 4)
    assert 1023 < frame.max() < 65535
    assert C.METHODS[method](frame).status_name == "ok"
    assert C.METHODS[method](frame, saturation=1023).status_name == "saturated"


@pytest.mark.parametrize("method", ["projection", "threshold"])
def test_locate_multi_hole_cube_refuses_a_single_spot_algorithm(method):
    # No silent substitution: algorithms A and B have no multi-spot form; the error names the
    # method and the fix.
    cube, _ = _small_cube()
    cube = cube.assign_coords(hole_i=("hole", [0]), hole_j=("hole", [0]))
    with pytest.raises(ConfigurationError, match=f"{method}.*multi-hole.*'tight'"):
        C.locate(cube, method, progress=False)
    cen = C.locate(cube, "tight", progress=False)
    assert cen.attrs["method"] == "tight" and cen.sizes["hole"] == 1


def test_plane_background_takes_out_a_ramp_that_the_ring_mean_leaves():
    # A dark-offset ramp of 1.7 DN/px in x and 0.5 DN/px in y (250 DN across 150 px, a 10-bit
    # APS without dark subtraction) under a 17.5 px spot of 1500 DN: the ring's mean leaves
    # the slope in the window and moves the centroid by g pi r^4 / 4 / flux (about 0.25 px
    # here, r the 22.5 px window); a plane fitted to the ring takes it out exactly for a
    # noise-free frame.
    yy, xx = np.mgrid[0:300, 0:400]
    spot = _spots.frame([(200.3, 150.6)], peak=1500.0, noise=False, background=0.0,
                        shape=(300, 400), bit_depth=16)
    frame = spot + 60.0 + 1.7 * xx + 0.5 * yy
    ring = C.tight_window(frame)
    plane = C.tight_window(frame, background="plane")
    assert math.hypot(ring.x - 200.3, ring.y - 150.6) > 0.15
    assert plane.status_name == "ok"
    assert_allclose((plane.x, plane.y), (200.3, 150.6), atol=0.01)
    with pytest.raises(ConfigurationError, match="background.*'plane'"):
        C.tight_window(frame, background="quadric")


def test_one_hot_pixel_does_not_drop_a_spot_of_a_multi_hole_frame():
    # A 3 x 4 mask, a hot pixel at the 10-bit full scale inside the window of spot (1, 1):
    # repaired (the median of its neighbours), the spot measured as on the clean frame, every
    # other spot untouched; touching clipped pixels still mean saturation.
    yy, xx = np.mgrid[0:400, 0:500]
    clean = np.full((400, 500), 30.0)
    for i in range(3):
        for j in range(4):
            clean += 400 * (np.hypot(xx - 100.5 - 80 * j, yy - 90 - 80 * i) < 15)
    clean = clean.astype(np.uint16)
    ref = C.locate_spots(clean, shape=(3, 4), pitch=80, saturation=1023)
    hot = clean.copy()
    hot[175, 186] = 1023  # inside spot (1, 1) at (180.5, 170)
    got = C.locate_spots(hot, shape=(3, 4), pitch=80, saturation=1023)
    assert got.status[5] == STATUS["repaired"]
    assert np.all(np.delete(got.status, 5) == STATUS["ok"])
    # the repair pass fits the ring's constant by clipped least squares, the compiled pass by
    # a sigma-clipped mean: equal to 1e-6 px on a flat background
    assert_allclose((got.x[5], got.y[5]), (ref.x[5], ref.y[5]), atol=1e-6)
    sat = clean.copy()
    sat[170, 179:182] = 1023
    assert C.locate_spots(sat, shape=(3, 4), pitch=80, saturation=1023).status[5] == \
        STATUS["saturated"]
