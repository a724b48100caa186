"""The detector model of sunlab.sim: noise statistics, fixed patterns, ADC and validation."""

import numpy as np
import pytest

from sunlab import ConfigurationError
from sunlab.sim import Bench, Detector
from sunlab.sim import frame as simframe
from sunlab.sim.detector import fixed_pattern
from sunlab.sim.holes import Hole


@pytest.fixture(scope="module")
def small():
    """A 200 x 160 px detector with the hole above its centre, the spot in the middle (fast
    frames)."""
    return (
        Bench.paper_single_hole()
        .ideal_platform()
        .ideal_mask()
        .replace(detector__nx=200, detector__ny=160, mask__holes=(Hole(0.0, 0.0, 0.2),))
    )


def test_pixel_mean_and_variance_follow_the_model(small):
    n = 400
    frames = np.stack(
        [simframe.render_frame(small, 0.0, 0.0, seed=11, pose=0, shot=s) for s in range(n)]
    ).astype(float)
    mean, var = simframe.expected_frame(small, 0.0, 0.0)
    ok = mean < small.detector.max_dn - 10  # away from saturation
    m = frames.mean(axis=0)
    v = frames.var(axis=0, ddof=1)
    model_var = var + 1.0 / 12.0  # rounding to the nearest DN adds 1/12 DN^2
    z = (m - mean) / np.sqrt(model_var / n)
    assert abs(z[ok].mean()) < 0.05  # no bias overall
    assert np.abs(z[ok]).max() < 5.5  # every pixel's mean within 5.5 sigma (32 000 pixels)
    ratio = v[ok] / model_var[ok]
    assert ratio.mean() == pytest.approx(1.0, abs=0.01)
    # per pixel, the sample variance follows the chi-square law of n - 1 degrees of freedom
    assert np.std(ratio) == pytest.approx(np.sqrt(2.0 / (n - 1)), rel=0.15)
    # the spot is there: signal pixels have a much larger variance (photon shot noise)
    assert var.max() > 8 * np.median(var)


def test_fixed_patterns_have_the_configured_statistics():
    det = Detector(nx=512, ny=512, hot_pixel_fraction=0.0)
    fp = fixed_pattern(det)
    assert fp.gain.mean() == pytest.approx(1.0, abs=0.005)
    assert fp.gain.std() == pytest.approx(np.hypot(det.prnu, det.prnu_correlated), rel=0.08)
    assert fp.dark_e.mean() == pytest.approx(det.dark_signal_e, rel=0.01)
    assert fp.dark_e.std() / det.dark_signal_e == pytest.approx(det.dsnu, rel=0.05)
    col = fp.offset_dn.mean(axis=0)
    assert col.std() == pytest.approx(det.column_fpn_dn, rel=0.15)
    assert np.ptp(fp.offset_dn, axis=0).max() == 0  # a column pattern: constant down a column
    hot = fixed_pattern(Detector(nx=512, ny=512, hot_pixel_fraction=1e-2)).dark_e
    frac = np.mean(hot > det.dark_signal_e * (1 + 6 * det.dsnu))
    assert frac == pytest.approx(1e-2 * np.exp(-6 * det.dsnu * det.dark_signal_e / 8000), rel=0.2)
    ideal = fixed_pattern(Detector(nx=64, ny=64, fixed_pattern=False))
    assert np.all(ideal.gain == 1) and np.ptp(ideal.dark_e) == 0


def test_correlated_prnu_has_its_correlation_length():
    det = Detector(nx=512, ny=512, prnu=0.0, prnu_correlated=0.03, prnu_correlation_px=4.0)
    g = fixed_pattern(det).gain - 1.0
    # white noise filtered by a Gaussian of sigma L has autocorrelation exp(-d^2 / (4 L^2))
    for d in (2, 4, 8):
        rho = np.mean(g[:, :-d] * g[:, d:]) / np.mean(g * g)
        assert rho == pytest.approx(np.exp(-d * d / 64.0), abs=0.03)


def test_noise_free_frames_are_the_rounded_expectation(small):
    b = small.noise_free()
    f = simframe.render_frame(b, -0.5, 0.3, seed=0)
    mean, var = simframe.expected_frame(b, -0.5, 0.3)
    assert np.all(var == 0)
    assert np.array_equal(f, np.clip(np.floor(mean + 0.5), 0, 1023).astype(np.uint16))


def test_saturation_and_quantisation(small):
    bright = small.replace(source__fluence_photons_per_um2=5000.0)
    f = simframe.render_frame(bright, 0.0, 0.0, seed=1)
    assert f.dtype == np.uint16 and f.max() == 1023
    assert np.sum(f == 1023) > 300  # the whole plateau clips
    dark = simframe.render_frame(small.replace(source__fluence_photons_per_um2=0.0), 0.0, 0.0,
                                 seed=1)
    assert 30 < np.median(dark) < 60  # background of a few tens of DN


@pytest.mark.parametrize(
    ("kwargs", "field"),
    [
        ({"fill_factor": 0.0}, "fill_factor"),
        ({"fill_factor": 1.5}, "fill_factor"),
        ({"nx": 0}, "nx"),
        ({"read_noise_e": -1.0}, "read_noise_e"),
        ({"bit_depth": 20}, "bit_depth"),
        ({"fill_factor": 0.25, "sensitive_offset_px": (0.3, 0.0)}, "sensitive_offset_px"),
    ],
)
def test_bad_detector_raises(kwargs, field):
    with pytest.raises(ConfigurationError, match=field):
        Detector(**kwargs)
