"""The virtual bench (sunlab.sim.bench): presets, switches, lazy cubes, determinism, errors."""

import dask.array as da
import numpy as np
import pytest

from sunlab import ConfigurationError, plans, schema
from sunlab.sim import Bench, Mask, render_frame, simulate
from sunlab.sim.holes import Hole
from sunlab.sim.platform import platform_pose
from sunlab.sim.render import ray_positions
from sunlab.sim.spots import spot_truth


@pytest.fixture(scope="module")
def cube():
    return simulate(plans.experiment("III").subset(90), seed=4)


def test_cube_is_lazy_and_follows_the_contract(cube):
    schema.validate_frames(cube)
    assert isinstance(cube.frames.data, da.Array)
    assert cube.frames.data.chunksize == (1, 1, 1024, 1280)
    assert dict(cube.frames.sizes) == {"pose": 5, "shot": 8, "y": 1024, "x": 1280}
    assert cube.true_x.dims == ("pose", "shot") and isinstance(cube.true_x.data, da.Array)
    assert cube.attrs["experiment"] == "III" and cube.attrs["mask"] == "single"
    # the identified bench: F = 5 mm, the hole 0.52 mm right of the detector centre
    assert cube.attrs["x_cf_px"] == pytest.approx(639.5 + 0.52 / 0.007)
    assert cube.attrs["mask_distance_mm"] == 5.0


def test_pose_chunks_render_the_same_frames(cube):
    by_pose = simulate(plans.experiment("III").subset(90), seed=4, chunks="pose")
    assert by_pose.frames.data.chunksize == (1, 8, 1024, 1280)
    assert np.array_equal(by_pose.frames[1:3].values, cube.frames[1:3].values)
    with pytest.raises(ConfigurationError, match="chunks"):
        simulate(plans.experiment("III").subset(90), chunks="shot")


def test_cube_frames_are_deterministic_per_seed_pose_shot(cube):
    f = cube.frames[2, 3].values
    again = simulate(plans.experiment("III").subset(90), seed=4).frames[2, 3].values
    assert np.array_equal(f, again)
    assert not np.array_equal(f, cube.frames[2, 4].values)  # another shot, other noise
    other = simulate(plans.experiment("III").subset(90), seed=5).frames[2, 3].values
    assert not np.array_equal(f, other)
    # the cube's truth is platform_pose and its frame render_frame, of its key
    key = cube.attrs["sim_key"]
    bench = Bench.paper_single_hole()
    # the true angles depend on the motion history: the inner axis's approach direction at the
    # pose and the run (experiment) whose homing the pose shares
    assert platform_pose(
        bench, float(cube.alpha[2]), float(cube.beta[2]), seed=key, pose=2, shot=3,
        approach=int(cube.beta_approach[2]), run=cube.attrs["experiment"],
    ) == (float(cube.true_alpha[2, 3]), float(cube.true_beta[2, 3]))
    same = render_frame(
        Bench.paper_single_hole(),
        float(cube.true_alpha[2, 3]),
        float(cube.true_beta[2, 3]),
        seed=key,
        pose=2,
        shot=3,
        shape_angles=(float(cube.true_alpha[2, 0]), float(cube.true_beta[2, 0])),
    )
    assert np.array_equal(f, same)


def test_cube_truth_matches_its_frames(cube):
    # truth vs the high-SNR centroid of the cube's frame rendered without the correlated response
    # pattern: that pattern (12 % RMS) is a detector error, left out of the truth on purpose; it
    # moves the 51 px spot's centroid by about 0.3 px RMS (Bench._paper_detector)
    p, s = 1, 0
    bench = Bench.paper_single_hole().replace(detector__prnu_correlated=0.0)
    f = render_frame(bench, float(cube.true_alpha[p, s]), float(cube.true_beta[p, s]),
                     seed=cube.attrs["sim_key"], pose=p, shot=s).astype(float)
    x, y = float(cube.true_x[p, s]), float(cube.true_y[p, s])
    x0, y0 = int(round(x)) - 30, int(round(y)) - 30
    w = f[y0 : y0 + 60, x0 : x0 + 60] - np.median(f[y0 - 40 : y0 - 20, x0 : x0 + 60])
    w = np.where(w > 15, w, 0.0)
    yy, xx = np.mgrid[y0 : y0 + 60, x0 : x0 + 60]
    assert abs((w * xx).sum() / w.sum() - x) < 0.3 and abs((w * yy).sum() / w.sum() - y) < 0.3
    # truth is near the geometric ray and close to eq. (1) with the mounting errors
    assert float(np.abs(cube.true_x - cube.ray_x).max()) < 0.05


def test_experiments_differ_even_with_one_seed():
    e1 = simulate(plans.experiment("I")[:3], seed=0)
    e3 = simulate(plans.experiment("III")[:3], seed=0)
    err1 = e1.true_alpha.values - e1.alpha.values[:, None]
    err3 = e3.true_alpha.values - e3.alpha.values[:, None]
    assert not np.allclose(err1, err3)


def test_ideal_platform_truth_equals_commanded():
    c = simulate(plans.custom([-5.0, 1.0], [2.0, 3.0], shots=2), Bench().ideal_platform(), seed=1)
    assert np.array_equal(c.true_alpha.values, np.repeat(c.alpha.values[:, None], 2, axis=1))


def test_rehoming_shifts_the_inner_axis_zero_of_runs_ii_and_iii_and_their_zero_checks():
    # experiment I in one session, II and III in the next: the shift is in the true beta of
    # every pose of II and III and of their zero-pose checks, and in nothing of I or of alpha
    bench = Bench().ideal_platform().replace(platform__beta_rehoming_deg=0.02)
    for run, shift in (("I", 0.0), ("II", 0.02), ("III", 0.02)):
        plan = plans.experiment(run, shots=1).subset(3)
        for p in (plan, plans.zero_check(plan, 1)):
            c = simulate(p, bench, seed=0)
            assert np.allclose(c.true_beta.values - c.beta.values[:, None], shift), run
            assert np.allclose(c.true_alpha.values - c.alpha.values[:, None], 0.0), run


def test_multi_hole_cube_has_hole_coordinates_and_its_spots_where_the_detector_is():
    bench = Bench.paper_multi_hole()
    c = simulate(plans.custom([-16.5, 1.5], [16.5, -1.5], shots=1), bench, seed=2)
    assert c.true_x.dims == ("pose", "shot", "hole") and c.sizes["hole"] == 100
    assert c.hole_i.values.tolist()[:12] == [0] * 10 + [1, 1]
    assert int(np.count_nonzero(c.hole_defect.values)) == 6
    assert np.all(np.diff(c.hole_x_cf.values[:10]) == pytest.approx(0.5 / 0.007))
    # F = 5 mm: the 100 spots (a 640 px pattern) travel about 250 x 260 px over experiments
    # I-III, so at every corner of the range every spot is on the 1280 x 1024 detector, its
    # light whole on it (ray >= the spot's radius from every edge) and its truth finite
    nx, ny = bench.detector.nx, bench.detector.ny
    r_spot = 0.5 * (0.2 + bench.mask.true_distance_mm * np.radians(bench.source.diameter_deg))
    r_spot /= 0.007
    for a, b in ((-7.5, 7.5), (0.0, 0.0), (-17.0, -2.0), (-17.0, 17.0), (2.0, -2.0), (2.0, 17.0)):
        ta, tb = platform_pose(bench, a, b, seed=0, pose=0, shot=0)
        x, y = spot_truth(bench, ta, tb)
        rx, ry = ray_positions(bench, ta, tb)
        margin = np.minimum.reduce([rx + 0.5, nx - 0.5 - rx, ry + 0.5, ny - 0.5 - ry])
        assert np.all(margin > r_spot + 1.0) and np.all(np.isfinite(x)), (a, b)
    f = c.frames[0, 0].values
    tx, ty = c.true_x.values[0, 0], c.true_y.values[0, 0]
    on = np.isfinite(tx)
    assert on.all()
    vals = f[np.round(ty[on]).astype(int), np.round(tx[on]).astype(int)]
    good = c.hole_defect.values[on] == 0
    assert np.all(vals[good] > 200)  # a bright spot at every good hole's true centroid


def test_presets_and_switches():
    b = Bench.paper_single_hole()
    from sunlab.sim import bench as bench_module

    assert b.platform.alpha0_deg == bench_module.PAPER_ALPHA0_DEG
    assert b.mask.delta_f_mm == bench_module.PAPER_DELTA_F_MM
    nf = b.noise_free()
    assert not nf.detector.temporal_noise and not nf.detector.fixed_pattern
    assert b.ideal_mask().mask.true_distance_mm == 5.0
    assert b.without_lid().detector.lid_thickness_mm == 0.0 < b.detector.lid_thickness_mm
    assert b.replace(source__limb_darkening=0.6).source.limb_darkening == 0.6
    with pytest.raises(ConfigurationError, match="replace"):
        b.replace(lens__f=1.0)
    assert f'"alpha0_deg":{bench_module.PAPER_ALPHA0_DEG}' in b.to_json()


@pytest.mark.parametrize(
    ("call", "field"),
    [
        (lambda: Mask.single_hole(distance_mm=-5.0), "distance_mm"),
        (lambda: Mask(holes=(Hole(7.0, 0.0),)), "holes"),
        (lambda: Mask(holes=()), "holes"),
        (lambda: Hole(0.0, 0.0, diameter_mm=-0.2), "diameter_mm"),
        (lambda: plans.experiment("III", shots=0), "shots"),
        (lambda: render_frame(Bench(), 91.0, 0.0, seed=0), "alpha_true"),
        (lambda: simulate(plans.custom([0.0], [0.0]), seed=-1), "seed"),
        (lambda: simulate("III"), "plan"),
        (lambda: Mask.single_hole(delta_f_mm=-6.0), "delta_f_mm"),
    ],
)
def test_bad_configuration_raises(call, field):
    with pytest.raises(ConfigurationError, match=field):
        call()


def test_presets_are_the_identified_hypothesis_as_its_one_preset_fit_gives_it():
    # the presets are the hypothesis the protocol's rule picks from the shipped evidence, fitted
    # once with every nuisance at its prior median on the preset seed (protocol version 4,
    # sunlab/data/presets.json), to three significant figures (0.5 %)
    from studies import evidence, profiles
    from studies import identification as idn

    protocol = idn.load_protocol()
    name = evidence.identified_hypothesis()
    presets = profiles.load_presets()
    assert presets["hypothesis"] == name
    assert presets["nuisances"] == idn.draw_nuisances(protocol, None)
    fitted, med = presets["fitted"], presets["nuisances"]
    for multi in (False, True):
        want = idn.hypothesis_bench(protocol, name, med, fitted, multi=multi)
        got = Bench.paper_multi_hole() if multi else Bench.paper_single_hole()
        assert got.mask_distance_mm == want.mask_distance_mm
        for part, fields in (("platform", ("alpha_pose_error_deg", "beta_pose_error_deg",
                                           "beta_rehoming_deg", "beta_gear_deg",
                                           "beta_gear_period_deg", "beta_wobble_deg",
                                           "nonorthogonality_deg", "beta_drift_deg",
                                           "beta_backlash_deg", "alpha_jitter_deg",
                                           "beta_jitter_deg")),
                             ("mask", ("play_x_mm", "play_y_mm")),
                             ("detector", ("prnu", "prnu_correlated", "prnu_correlation_px",
                                           "read_noise_e", "fill_factor", "lid_thickness_mm"))):
            for f in fields:
                assert getattr(getattr(got, part), f) == pytest.approx(
                    getattr(getattr(want, part), f), rel=5e-3, abs=1e-12), (multi, part, f)
