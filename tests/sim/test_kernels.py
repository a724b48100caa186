"""The simulator's compiled kernels against slow references and against their numpy references
(the option kernels="numpy"): the noise stream, the spot spectra, one switch between them and
one compile notice, said once, registered by no import."""

import inspect
import json
import os
import subprocess
import sys
import types
from pathlib import Path

import numpy as np
import pytest
from scipy import special

import sunlab
from sunlab.errors import ConfigurationError
from sunlab.sim import Bench, _jit, render, spots
from sunlab.sim import _adc as D
from sunlab.sim import _aperture as A
from sunlab.sim.detector import Detector, fixed_pattern

ROOT = Path(__file__).resolve().parents[2]
#: every compiled kernel of the simulator, beside the concept it serves
KERNELS = {"adc_frame": D.adc_frame, "adc_stamps": D.adc_stamps, "polygon_ft": A.polygon_ft,
           "_spectrum_tabulated": A._spectrum_tabulated, "fold_phase": spots.fold_phase,
           "_clip_convex": A.clip_convex}

_MASK64 = (1 << 64) - 1


def _splitmix_reference(state: int, n_out: int) -> list[int]:
    """SplitMix64 (Steele, Lea & Flood 2014) in Python integers."""
    out = []
    for _ in range(n_out):
        state = (state + 0x9E3779B97F4A7C15) & _MASK64
        z = state
        z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & _MASK64
        z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & _MASK64
        out.append(z ^ (z >> 31))
    return out


@pytest.mark.parametrize("shape", [(6, 8), (5, 7), (1, 3)])
def test_adc_frame_is_the_documented_stream(shape):
    # Pixel k (row-major) takes bits 16 (k % 4) .. 16 (k % 4) + 15 of SplitMix64 output k // 4 as
    # an index into the quantile table; the value is rounded half up and clipped to the ADC; the
    # state moves one step per four pixels, rounded up. Bit for bit, clipping on both sides.
    rng = np.random.default_rng(3)
    mean = rng.uniform(-40.0, 1060.0, shape).astype(np.float32)
    sigma = rng.uniform(0.5, 30.0, shape).astype(np.float32)
    mean.flat[0], mean.flat[-1] = -500.0, 1600.0  # one pixel clipped at each end
    table = D.normal_table()
    seed = 0xFEDCBA9876543210
    state = np.array([seed], dtype=np.uint64)
    out = np.empty(shape, dtype=np.uint16)
    D.adc_frame(mean, sigma, table, state, 1023.0, out)
    n = mean.size
    words = _splitmix_reference(seed, -(-n // 4))
    idx = np.array([(words[k // 4] >> (16 * (k % 4))) & 0xFFFF for k in range(n)])
    v = mean.ravel() + sigma.ravel() * table[idx]  # float32, as the kernel computes it
    ref = np.clip(np.floor(v.astype(np.float64) + 0.5), 0, 1023).astype(np.uint16)
    np.testing.assert_array_equal(out.ravel(), ref)
    assert int(state[0]) == (seed + len(words) * 0x9E3779B97F4A7C15) & _MASK64
    assert (ref == 0).any() and (ref == 1023).any()


def test_adc_frame_without_noise_is_the_rounded_mean():
    det = Detector(nx=9, ny=4, temporal_noise=False)
    fp = fixed_pattern(det)
    state = np.array([5], dtype=np.uint64)
    out = np.empty(det.shape, dtype=np.uint16)
    D.adc_frame(fp.bg_mean_dn, fp.bg_sigma_dn, np.empty(0, np.float32), state, 1023.0, out)
    np.testing.assert_array_equal(out, np.floor(fp.bg_mean_dn.astype(np.float64) + 0.5))
    assert int(state[0]) == 5


def test_disk_table_matches_the_transforms():
    i = np.array([1, 2, 100, 3000, 9001, 16385])
    k = (i - 1) * A.TABLE_STEP  # entry i holds k = (i - 1) h
    tab = A.disk_ft_table(0.0)
    jinc = np.where(k > 0, 2 * special.j1(np.maximum(k, 1e-30)) / np.maximum(k, 1e-30), 1.0)
    np.testing.assert_allclose(tab[i], jinc, atol=2e-8)  # scipy's J1, as the truth's
    assert not tab.flags.writeable
    longer = A.disk_ft_table(0.0, 4 * 16384)  # a longer table: the same entries, and more
    np.testing.assert_array_equal(longer[: tab.size], tab)


@pytest.mark.parametrize("bench", [Bench.paper_single_hole(), Bench.paper_multi_hole(),
                                   Bench.paper_single_hole().replace(
                                       source__limb_darkening=0.6)],
                         ids=["one-hole", "100-hole", "limb-darkened"])
def test_tabulated_spectrum_and_stamps_match_the_direct_ones(bench):
    # The images use the tabulated transforms, the truth the direct ones, both of scipy's J1:
    # the spectra agree to 1e-9 of their peak (cubic interpolation, h = 1/64: bound
    # (3/128) h^4 max|f''''|), and the stamps' pixels to 1e-9 of the peak pixel, far below one
    # photo-electron.
    for alpha, beta in [(0.0, 0.0), (-12.0, 7.3), (9.0, -11.0)]:
        geom = render.spot_geometry(bench, alpha, beta)
        for g in spots._groups(bench, geom):
            m = g.stamp_size()
            al = np.arange(-1, 2)
            fx = (al[:, None] + (np.arange(m // 2 + 1) / m)[None, :]).ravel()
            fy = (al[:, None] + np.fft.fftfreq(m)[None, :]).ravel()
            exact = g.common(fx, fy)
            tab = g.common(fx, fy, tabulated=True)
            assert np.abs(tab - exact).max() < 1e-9 * np.abs(exact).max()
    img, *_ = spots.spot_image(bench, -3.0, 4.0)
    orig = spots._Group.common
    try:
        spots._Group.common = lambda self, fx, fy, pixel=True, tabulated=False: orig(
            self, fx, fy, pixel, False)
        ref, *_ = spots.spot_image(bench, -3.0, 4.0)
    finally:
        spots._Group.common = orig
    assert np.abs(img - ref).max() < 1e-9 * ref.max()
    assert img.max() > 1e4  # photo-electrons: the bound is far below one


def test_fold_phase_real_is_the_complex_fold_of_a_real_spectrum():
    # an affine aperture's spectrum is real: its fold skips the zero imaginary parts and must
    # give the complex kernel's sums bit for bit; both against the defining einsum
    rng = np.random.default_rng(4)
    t4 = rng.normal(size=(3, 10, 3, 6))
    w = [np.exp(2j * np.pi * rng.uniform(size=(5, k))) for k in (3, 3, 10, 6)]
    real = spots.fold_phase(t4, *w)
    np.testing.assert_array_equal(real, spots.fold_phase(t4.astype(np.complex128), *w))
    wy, wx, ey, ex = w
    ref = np.einsum("aibj,na,nb,ni,nj->nij", t4, wy, wx, ey, ex)
    np.testing.assert_allclose(real, ref, rtol=1e-12, atol=1e-12)


# ------------------------------------------------------------------------------------------
# The numpy references (sunlab.set_options(kernels="numpy")) against the compiled kernels
# ------------------------------------------------------------------------------------------
@pytest.mark.parametrize("noisy", [True, False])
@pytest.mark.parametrize("shape", [(6, 8), (5, 7), (1, 3), (33, 41)])
def test_the_adc_references_draw_the_same_stream_bit_for_bit(shape, noisy):
    # the same frame, the same region and the same state afterwards: uint64 array arithmetic
    # wraps as the compiled code's does, so the stream is the same, not merely alike
    rng = np.random.default_rng(5)
    mean = rng.uniform(-40.0, 1060.0, shape).astype(np.float32)
    sigma = rng.uniform(0.5, 30.0, shape).astype(np.float32)
    gain, dark, offset = (rng.uniform(lo, hi, shape).astype(np.float32)
                          for lo, hi in ((0.9, 1.1), (0.0, 50.0), (10.0, 40.0)))
    # stamps over the frame, one overlapping another and one off its edge (saturating some)
    boxes = np.array([[0, 0, 1, shape[0], max(shape[1] - 2, 1)], [0, -2, shape[1] - 3, 4, 5],
                      [20, shape[0] - 1, -3, 3, 4]], dtype=np.int64)
    signal = rng.uniform(0.0, 4e4, shape[0] * shape[1] + 40)
    table = D.normal_table() if noisy else np.empty(0, np.float32)
    frames, states = [], []
    for run in (lambda k: k.compiled, lambda k: k.numpy):
        state = np.array([0xFEDCBA9876543210], dtype=np.uint64)
        out = np.empty(shape, dtype=np.uint16)
        run(D.adc_frame)(mean, sigma, table, state, 1023.0, out)
        run(D.adc_stamps)(boxes, signal, gain, dark, offset, table, state, 100.0, 1 / 20.0,
                          3e4, 1023.0, out)
        frames.append(out)
        states.append(int(state[0]))
    np.testing.assert_array_equal(frames[1], frames[0])
    assert states[1] == states[0]


def _spectrum_args(u):
    fx, fy = np.linspace(-1.5, 1.5, 31), np.linspace(-1.2, 1.3, 27)
    ap, km = np.array([[20.0, 1.0], [0.5, 18.0]]), np.array([[30.0, 2.0], [2.0, 29.0]])
    return fx, fy, ap, 1000.0, km, u, 0.8, 0.7, 0.3


@pytest.mark.parametrize("u", [0.0, 0.6])
@pytest.mark.parametrize("use_ap", [True, False])
def test_the_spectrum_references_agree_to_the_interpolation(u, use_ap):
    # both use scipy's J1; the kernel interpolates it in tables (2e-10 of the peak per factor):
    # 3e-8 of the peak bounds it with room
    args = (*_spectrum_args(u), use_ap)
    ref = A.spectrum_direct(*args)
    peak = np.abs(ref).max()
    tabs = (A.disk_ft_table(0.0, 65536), A.disk_ft_table(u, 65536))  # to k = 1024
    assert np.abs(A._spectrum_tabulated.compiled(*args, *tabs) - ref).max() < 3e-8 * peak
    np.testing.assert_array_equal(A._spectrum_tabulated.numpy(*args, *tabs), ref)
    with sunlab.set_options(kernels="numpy"):
        np.testing.assert_array_equal(A.spectrum_tabulated(*args), ref)
    # a grid beyond the default table's reach (k = 2 pi |f| |km| = 540 > 256): longer tables
    far = (args[0] * 3, args[1] * 3, *args[2:])
    peak = np.abs(A.spectrum_direct(*far)).max()
    assert np.abs(A.spectrum_tabulated(*far) - A.spectrum_direct(*far)).max() < 3e-8 * peak


def test_clip_convex_cuts_a_polygon_by_a_convex_one():
    sq = np.array([0.0, 2.0, 2.0, 0.0]), np.array([0.0, 0.0, 2.0, 2.0])
    x, y = A.clip_convex(*sq, np.array([1.0, 3.0, 3.0, 1.0]), np.array([1.0, 1.0, 3.0, 3.0]))
    assert 0.5 * abs(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y)) == pytest.approx(1.0)
    x, _ = A.clip_convex(*sq, np.array([5.0, 6.0, 6.0]), np.array([5.0, 5.0, 6.0]))
    assert x.size == 0
    tri = np.array([0.5, 3.0, 0.5]), np.array([0.5, 1.0, 3.0])
    for a, b in zip(A.clip_convex.compiled(*sq, *tri), A.clip_convex.numpy(*sq, *tri),
                    strict=True):
        np.testing.assert_array_equal(a, b)


def test_the_polygon_and_fold_references_agree_to_rounding():
    vx, vy = np.array([0.0, 3.0, 4.0, 1.0]), np.array([0.0, 0.0, 2.0, 3.0])  # CCW
    fx, fy = np.linspace(-1, 1, 17), np.append(np.linspace(-0.7, 0.9, 13), 0.0)
    ref = A.polygon_ft.numpy(vx, vy, fx, fy)
    assert ref[-1, 8] == 8.0  # at f = 0 (fx[8] = fy[-1] = 0): the shoelace area
    np.testing.assert_allclose(A.polygon_ft.compiled(vx, vy, fx, fy), ref, rtol=0, atol=1e-13)
    rng = np.random.default_rng(4)
    t4 = rng.normal(size=(3, 10, 3, 6))
    w = [np.exp(2j * np.pi * rng.uniform(size=(5, k))) for k in (3, 3, 10, 6)]
    for t in (t4, t4 + 1j * rng.normal(size=t4.shape)):
        np.testing.assert_allclose(spots.fold_phase.compiled(t, *w), spots.fold_phase.numpy(t, *w),
                                   rtol=0, atol=1e-13)


def test_a_frame_rendered_on_the_references_is_the_compiled_frame():
    # the same noise stream bit for bit; the spectra differ by 1e-8 of the peak, which moves
    # a pixel's mean across a rounding boundary with a probability of about 1e-8 per pixel
    import sunlab
    from sunlab import sim

    bench = Bench.paper_single_hole()
    compiled = sim.render_frame(bench, -7.0, 6.0, seed=3, pose=1, shot=0)
    with sunlab.set_options(kernels="numpy"):
        ref = sim.render_frame(bench, -7.0, 6.0, seed=3, pose=1, shot=0)
    diff = ref.astype(int) - compiled.astype(int)
    assert np.abs(diff).max() <= 1 and np.count_nonzero(diff) <= 2
    assert compiled.max() > 3 * np.median(compiled)  # a spot, not only the dark frame


# ------------------------------------------------------------------------------------------
# The switch and the compile notice (sunlab.sim._jit)
# ------------------------------------------------------------------------------------------
def _run(code: str, **env) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          cwd=ROOT, env={**os.environ, "PYTHONPATH": str(ROOT), **env})


def test_the_first_compile_is_announced_once():
    # two fresh functions compiled (no cache: defined in -c): one line, however many compiles
    err = _run("import numba\nfrom sunlab.sim import _jit\n_jit.announce_first_compile()\n"
               "_jit.announce_first_compile()\n"
               "f = numba.njit(lambda x: x + 1)\ng = numba.njit(lambda x: x * 2)\n"
               "assert f(1) == 2 and g(2.0) == 4.0 and f(1.5) == 2.5\n").stderr
    assert err.count(_jit.MESSAGE) == 1


def test_nothing_is_printed_without_a_compile():
    err = _run("from sunlab.sim import _jit\n_jit.announce_first_compile()\n").stderr
    assert _jit.MESSAGE not in err


def test_a_kernel_registers_the_notice_on_its_first_compiled_call(monkeypatch):
    registered = []
    monkeypatch.setattr(_jit, "_STATE", {"registered": False, "announced": False})
    monkeypatch.setattr(_jit, "event", types.SimpleNamespace(
        register=lambda kind, listener: registered.append(kind)))
    k = _jit.kernel(lambda x: x + 1, cache=False)(lambda x: x + 1)
    with sunlab.set_options(kernels="numpy"):
        assert k(1) == 2
    assert registered == []  # the reference compiles nothing: nothing to announce
    assert k(1) == 2 and k(2) == 3
    assert registered == ["numba:compile"]


def test_every_kernel_has_a_reference_with_its_signature():
    for name, k in KERNELS.items():
        assert k.__name__ == name
        params = list(inspect.signature(k.compiled.py_func).parameters)
        assert list(inspect.signature(k.numpy).parameters) == params, name


def test_the_option_picks_the_reference_and_compiles_nothing():
    k = _jit.kernel(lambda a: float(np.sum(a)) + 2.0, cache=False)(lambda a: a.sum() + 1.0)
    with sunlab.set_options(kernels="numpy"):
        assert k(np.ones(3)) == 5.0  # a different value: which one ran
        assert os.environ["SUNLAB_KERNELS"] == "numpy"  # for workers started inside
    assert k.compiled.signatures == []
    assert k(np.ones(3)) == 4.0 and len(k.compiled.signatures) == 1
    assert sunlab.options.OPTIONS["kernels"] == "numba"


def test_bad_values_of_the_switch_are_refused_with_the_fix():
    with pytest.raises(ConfigurationError, match=r"kernels=.*'cuda'.*'numba', 'numpy'"):
        sunlab.set_options(kernels="cuda")
    with pytest.raises(ConfigurationError, match="True or False"):
        sunlab.set_options(progress="no")
    out = _run("import sunlab.options", SUNLAB_KERNELS="cuda")
    assert out.returncode != 0
    assert "SUNLAB_KERNELS: found 'cuda'" in out.stderr and "Fix:" in out.stderr


_REFERENCES_RUN = """
import json
from numba.core import event
from sunlab import centroid, plans, sim
from sunlab.sim import _jit

compiles = []

class Count(event.Listener):
    def on_start(self, ev):
        compiles.append(1)

    def on_end(self, ev):
        pass

event.register("numba:compile", Count())
registered_at_import = _jit._STATE["registered"]
cube = sim.simulate(plans.custom([-8.0], [4.0], shots=1), sim.Bench.paper_single_hole())
cen = centroid.locate(cube, method="projection", progress=False, scheduler="synchronous")
from tests.sim.test_kernels import KERNELS
print(json.dumps({"compiles": len(compiles), "registered_at_import": registered_at_import,
                  "compiled": [n for n, k in KERNELS.items() if k.compiled.signatures],
                  "error": float(abs(cen.x - cube.true_x).max())}))
"""


def test_a_references_only_run_renders_and_centroids_without_compiling_anything():
    out = _run(_REFERENCES_RUN, SUNLAB_KERNELS="numpy")
    assert out.returncode == 0, out.stderr
    res = json.loads(out.stdout.strip().splitlines()[-1])
    assert res == {"compiles": 0, "compiled": [], "registered_at_import": False,
                   "error": res["error"]}
    assert _jit.MESSAGE not in out.stderr
    assert res["error"] < 0.1  # the paper's algorithm B on a rendered frame: a real centroid
