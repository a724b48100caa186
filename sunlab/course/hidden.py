"""Hidden checks: each exercise's answer run on fresh inputs the student never saw.

A check cell of the teacher edition ends with nbgrader's hidden-test block::

    ### BEGIN HIDDEN TESTS
    from sunlab.course import hidden
    hidden.check("01.1", globals())
    ### END HIDDEN TESTS

The student edition leaves the block out; nbgrader's ``autograde`` puts it back and runs it in
the student's kernel. ``sunlab course --grade`` instead runs the check **in the grader's
process** (:mod:`sunlab.course.grading`): the namespace is then a
:class:`sunlab.course.kernel.NotebookRun`, the student's function is called in its kernel
on the fresh inputs and only its outputs come back, as data. :func:`check` takes the student's
function from the namespace and runs it on inputs drawn from a seed the grader picks (the
environment variable :data:`SEED_VARIABLE`; ``sunlab course --grade --seed``): other angles,
another bench geometry (the notebook's constants such as ``F`` are rebound for the call), other
frames, other benches. The reference is computed by the library or by the simulator on the same
inputs, never stated here. An answer that returns a constant, reads a variable of the notebook
that the exercise does not name, or calls the library function that the exercise asks the
student to write fails with an AssertionError that says which, without stating the answer. The
forbidden call is seen by a profiler when the namespace is a dict (nbgrader, the tests), and by
tripwires in a fresh process when the grader runs the check (:mod:`sunlab.course.probe`).
"""

from __future__ import annotations

import os
import re
import sys
import tempfile
from pathlib import Path

import numpy as np

from . import wire
from .capstone import write_recording
from .editions import _HIDDEN_BLOCK

__all__ = ["check"]

#: environment variable that carries the grader's seed into the notebook's kernel
SEED_VARIABLE = "SUNLAB_COURSE_SEED"
#: the seed when none is given (a teacher running the teacher edition by hand)
DEFAULT_SEED = 38
#: exercise number -> hidden check ``f(namespace, rng)``: the functions ``_exNN_k_...`` below
CHECKS: dict = {}


def seed() -> int:
    """The grader's seed of the hidden checks' inputs.

    Returns
    -------
    int
        The integer in the environment variable :data:`SEED_VARIABLE`, or
        :data:`DEFAULT_SEED` when it is unset or blank.
    """
    text = os.environ.get(SEED_VARIABLE, "").strip()
    return int(text) if text else DEFAULT_SEED


def check(number: str, namespace: dict, seed_value: int | None = None) -> None:
    """Run exercise ``number``'s hidden check on the student's ``namespace``.

    Parameters
    ----------
    number : str
        ``"NN.k"``.
    namespace : dict
        The notebook's globals (``globals()`` in the check cell).
    seed_value : int, optional
        Draws the fresh inputs; default :func:`seed`.

    Raises
    ------
    AssertionError
        The answer fails on the fresh inputs; the message says how, not what the answer is.
    """
    s = seed() if seed_value is None else int(seed_value)
    rng = np.random.default_rng([s, int(number.replace(".", ""))])
    try:
        CHECKS[number](namespace, rng)
    except AssertionError as err:
        raise AssertionError(f"hidden check {number} (fresh inputs, seed {s}): {err}") from None
    if isinstance(namespace, dict):
        print(f"Hidden check {number} passed (fresh inputs, seed {s}).")


#: the body of the standard hidden-test block, which the grader runs in its own process
_STANDARD = re.compile(r"\s*from sunlab\.course import hidden\s*\n"
                       r"\s*hidden\.check\(\s*[\"'](\d\d\.\d+)[\"']\s*,\s*globals\(\)\s*\)\s*")


def call_of(source: str) -> str | None:
    """The exercise whose standard hidden check a check cell holds: the grader runs it in its
    own process.

    Parameters
    ----------
    source : str
        A check cell's source.

    Returns
    -------
    str or None
        ``"NN.k"`` when the cell's one hidden-test block is ``hidden.check("NN.k",
        globals())`` for an exercise of :data:`CHECKS`; None for any other cell.
    """
    blocks = _HIDDEN_BLOCK.findall(source)
    m = len(blocks) == 1 and _STANDARD.fullmatch(blocks[0])
    return m.group(1) if m and m.group(1) in CHECKS else None


def _call(ns, name, *args, forbidden=(), bind=None, **kwargs):
    """``ns[name](*args, **kwargs)`` with the notebook's names ``bind`` rebound for the call,
    failing when it calls one of ``forbidden`` (library functions) or raises; its output
    always comes back as data (:mod:`sunlab.course.wire`).

    ``ns`` is the notebook's globals (a dict: the call runs here, the forbidden calls are seen
    by a profiler), or, when the grader runs the check in its own process, a
    :class:`sunlab.course.kernel.NotebookRun`: the call runs in the student's kernel, and the
    first call with forbidden functions is kept in its ``calls`` for the check in a fresh
    process (:mod:`sunlab.course.probe`)."""
    if not isinstance(ns, dict):
        out = ns.call(name, args, kwargs, bind)
        if forbidden and not any(c["name"] == name for c in ns.calls):
            ns.calls.append({"name": name, "args": tuple(args), "kwargs": dict(kwargs),
                             "bind": dict(bind or {}), "output": out, "forbidden": [
                                 f"{f.__module__}:{f.__qualname__}" for f in forbidden]})
        return out
    codes = {code: f"{f.__module__}.{f.__qualname__}" for f in forbidden
             if (code := getattr(getattr(f, "__func__", f), "__code__", None))}
    hits: list[str] = []

    def profile(frame, event, arg):
        if event == "call" and frame.f_code in codes:
            hits.append(codes[frame.f_code])

    old = sys.getprofile()
    sys.setprofile(profile if codes else old)
    try:
        text = wire.answer(ns, name, args, kwargs, bind)
    finally:
        sys.setprofile(old)
    assert not hits, (
        f"your `{name}` calls {hits[0]}, the library's version of what this exercise asks you "
        "to write: write it yourself (numpy is enough)")
    return wire.reply(text, name)


def _close(mine, ref, tol, what):
    mine = np.asarray(mine, dtype=float)
    ref = np.asarray(ref, dtype=float)
    assert mine.shape == ref.shape or mine.size == ref.size, (
        f"{what}: {mine.size} values for {ref.size} inputs")
    worst = float(np.nanmax(np.abs(mine.reshape(ref.shape) - ref)))
    assert np.isfinite(mine).all() and worst <= tol, f"{what}: off by up to {worst:.3g}"


def _entries(mine, ref, what):
    """Each entry of ``ref`` (a mapping) in ``mine``, within 1e-9 of it (relative)."""
    for key, value in ref.items():
        got = mine.get(key) if hasattr(mine, "get") else None
        assert got is not None and abs(float(got) - value) <= 1e-9 * abs(value), (
            what.format(key) + ": "
            + ("missing" if got is None else f"{float(got) / value:.6f} times the truth"))


# --------------------------------------------------------------------------- notebook 01

def _ex01_1_flux(ns, rng):
    from sunlab import geometry

    a, b = rng.uniform(-30, 30, 6), rng.uniform(-30, 30, 6)

    ref = np.array([geometry.sun_vector(x, y)[2] for x, y in zip(a, b, strict=True)])
    mine = [float(_call(ns, "flux_ratio", x, y, forbidden=(geometry.sun_vector,)))
            for x, y in zip(a, b, strict=True)]
    _close(mine, ref, 1e-9, f"flux ratio at poses you have not seen, e.g. ({a[0]:.2f}, "
           f"{b[0]:.2f}) deg")


def _ex01_2_motion(ns, rng):
    from sunlab import geometry

    f_mm, p_mm = rng.uniform(3, 20), rng.uniform(0.004, 0.012)
    a = rng.uniform(-25, 25, 5)
    h = 1e-4  # deg: the numerical derivative's error is ~h^2, far below the tolerance
    ref = (geometry.ideal_centroid(a + h, 0 * a, f_mm, p_mm, 0, 0)[0]
           - geometry.ideal_centroid(a - h, 0 * a, f_mm, p_mm, 0, 0)[0]) / (2 * h)
    mine = [float(_call(ns, "px_per_degree", x, bind=dict(F=f_mm, p=p_mm))) for x in a]
    _close(np.array(mine) / ref, np.ones_like(ref), 1e-6,
           f"another bench (F = {f_mm:.2f} mm, p = {p_mm * 1e3:.1f} um), px per degree over "
           "the truth")


# --------------------------------------------------------------------------- notebook 02

def _spot_frame(rng):
    ny, nx = rng.integers(60, 110), rng.integers(70, 130)
    r = rng.uniform(8, 18)
    yc, xc = rng.uniform(r + 4, ny - r - 4), rng.uniform(r + 4, nx - r - 4)
    yy, xx = np.mgrid[0:ny, 0:nx]
    level = rng.uniform(20, 60)
    spot = rng.uniform(300, 900) * np.clip(r + 0.5 - np.hypot(xx - xc, yy - yc), 0, 1)
    return level + spot + rng.normal(0, 2.0, (ny, nx))


def _ex02_1_window(ns, rng):
    from sunlab import centroid as C

    for _ in range(3):
        frame = _spot_frame(rng)
        ref_im = C.border_mean(frame, 2)
        ref_hit = C.first_hit(frame, 3 * ref_im, test_size=5, test_count=18)
        mine = _call(ns, "window_search", frame, forbidden=(C.border_mean, C.first_hit))
        assert abs(float(mine[0]) - ref_im) <= 1e-9 * ref_im, (
            f"I_m on a {frame.shape[0]} x {frame.shape[1]} frame you have not seen is wrong")
        assert tuple(int(v) for v in mine[1:]) == tuple(ref_hit), (
            f"the first hit on a {frame.shape[0]} x {frame.shape[1]} frame you have not seen "
            "is wrong")


def _ex02_2_centre_of_mass(ns, rng):
    from sunlab import centroid as C

    for _ in range(3):
        ny, nx = rng.integers(30, 90), rng.integers(30, 90)
        r = rng.uniform(3, 10)
        xc, yc = rng.uniform(r + 2, nx - r - 2), rng.uniform(r + 2, ny - r - 2)
        yy, xx = np.mgrid[0:ny, 0:nx]
        img = rng.uniform(10, 60) + rng.uniform(200, 900) * np.clip(
            r + 0.5 - np.hypot(xx - xc, yy - yc), 0, 1) + rng.normal(0, 3.0, (ny, nx))
        threshold = float(np.percentile(img, rng.uniform(60, 90)))
        w = np.clip(img - threshold, 0, None)
        ref = ((w * xx).sum() / w.sum(), (w * yy).sum() / w.sum())
        mine = _call(ns, "centre_of_mass", img, threshold,
                     forbidden=(C.threshold_window, C.projection_window, C.tight_window))
        _close(np.asarray(mine, dtype=float).ravel(), np.array(ref), 1e-9,
               f"a {ny} x {nx} spot you have not seen, (x, y) in px")


def _ex02_3_crlb(ns, rng):
    from sunlab import centroid as C

    for _ in range(2):
        n_e, b_e = 10 ** rng.uniform(5, 7), rng.uniform(5, 200)
        radius, edge = rng.uniform(8, 22), rng.uniform(1, 4)
        ref = C.crlb(n_e, b_e, 0.0, gain=1.0, radius=radius, edge=edge,
                     quantisation=False).sigma_x
        mine = float(_call(ns, "photon_crlb", n_e, b_e, radius, edge, forbidden=(C.crlb,)))
        # sub-sampling and a finite difference: within 3 % of the exact integral
        assert abs(mine - ref) < 0.03 * ref, (
            f"for {n_e:.3g} e- over {b_e:.0f} e-/px, radius {radius:.1f} px, edge {edge:.1f} px "
            f"your bound is {mine / ref:.3f} times the exact one")


# --------------------------------------------------------------------------- notebook 03

def _geometry(rng):
    return dict(F=rng.uniform(3, 20), P=rng.uniform(0.004, 0.012),
                X_CF=rng.uniform(200, 1000), Y_CF=rng.uniform(150, 850))


def _ex03_1_inverse(ns, rng):
    from sunlab import geometry

    g = _geometry(rng)
    a, b = rng.uniform(-25, 25, 50), rng.uniform(-25, 25, 50)
    x, y = geometry.ideal_centroid(a, b, g["F"], g["P"], g["X_CF"], g["Y_CF"])
    mine = _call(ns, "angles_from_centroid", x, y, bind=g,
                 forbidden=(geometry.ideal_angles, geometry.sun_angles))
    _close(np.asarray(mine, dtype=float), np.array([a, b]), 1e-9,
           f"another bench (F = {g['F']:.2f} mm), angles back from centroids, deg")


def _ex03_2_delta_f(ns, rng):
    from sunlab import geometry

    g = _geometry(rng)
    grid = np.linspace(-25.0, 25.0, 41)
    dF = float(rng.choice([-1, 1]) * rng.uniform(0.003, 0.01) * g["F"])
    xg, yg = geometry.optimised_centroid(grid, np.full_like(grid, 5.0), g["F"], g["P"], dF,
                                         0.0, 0.0, g["X_CF"], g["Y_CF"])
    measured = geometry.ideal_angles(xg, yg, g["F"], g["P"], g["X_CF"], g["Y_CF"])[0] - grid
    mine = _call(ns, "ideal_alpha_error", grid, dF, bind=g,
                 forbidden=(geometry.ideal_angles, geometry.optimised_centroid))
    # the second order in dF / F (below 1 %) is all that may differ
    _close(mine, measured, 0.02 * np.abs(measured).max(),
           f"another bench (F = {g['F']:.2f} mm, dF = {dF:+.3f} mm), error in deg")


# --------------------------------------------------------------------------- notebook 04

def _tables(rng):
    from sunlab import plans, sim

    g = _geometry(rng)
    bench = dict(delta_f_mm=rng.uniform(-0.1, 0.1), mounting_deg=tuple(rng.uniform(-2, 2, 3)),
                 pose_error_deg=tuple(rng.uniform(0.005, 0.03, 2)), noise_px=0.005)
    out = []
    for name in ("I", "II", "III"):
        plan = plans.experiment(name, shots=2)
        out.append(sim.synthetic_centroids(plan.alpha, plan.beta, plan.shots,
                                           seed=int(rng.integers(1 << 30)), experiment=name,
                                           mask_distance_mm=g["F"], pixel_pitch_mm=g["P"],
                                           x_cf=g["X_CF"], y_cf=g["Y_CF"], **bench))
    return out


def _ex04_1_orders(ns, rng):
    from sunlab import calibration
    from sunlab.calibration import Polynomial

    train, val, _ = _tables(rng)
    orders = sorted(rng.choice(np.arange(1, 8), 3, replace=False).tolist())
    _, scores = Polynomial.select_order(train, val, orders=orders)
    ref = scores["alpha_mean_abs"] + scores["beta_mean_abs"]
    for n in orders:
        mine = _call(ns, "validation_errors", train, val, n,
                     forbidden=(Polynomial.select_order, Polynomial.fit, calibration.fit))
        # the same least squares; only the rounding of an ill-conditioned fit may differ
        assert abs(float(mine[1]) - ref[n]) < 1e-3 * ref[n], (
            f"order {n} on experiments you have not seen: your validation error is "
            f"{float(mine[1]) / ref[n]:.4f} times the library's")


def _ex04_2_global(ns, rng):
    from sunlab import stats
    from sunlab.calibration import Polynomial

    train, _, test = _tables(rng)
    est = Polynomial(order=int(rng.integers(2, 5))).fit(train).predict(test)
    ref = stats.evaluate(est).iloc[:, 0]
    mine = _call(ns, "global_statistics", stats.shot_errors(est),
                 forbidden=(stats.evaluate, stats.error_summary))
    _entries(mine, ref, "{} on errors you have not seen")


# --------------------------------------------------------------------------- notebook 05

def _ex05_1_areas(ns, rng):
    import pandas as pd

    from sunlab import stats

    methods = [f"method {k}" for k in rng.permutation(9)[: int(rng.integers(3, 6))]]
    index = pd.MultiIndex.from_product([["alpha", "beta"], ["mu", "sigma", "M", "sigma_M"]],
                                       names=["angle", "stat"])
    table = pd.DataFrame(rng.uniform(0.002, 0.05, (8, len(methods))), index=index,
                         columns=methods)
    ref = stats.rectangles(table)["area"]
    mine = _call(ns, "rectangle_areas", table, forbidden=(stats.rectangles,))
    _entries(mine, ref, "the area of '{}' in a table you have not seen")


# --------------------------------------------------------------------------- notebook 06

def _ex06_1_gain(ns, rng):
    from sunlab.multihole import budget

    for _ in range(4):
        c, s, n = rng.uniform(0.1, 2.0), rng.uniform(0.1, 2.0), int(rng.integers(2, 150))
        # the model itself: the covariance of the n holes' errors, a common part on every pair
        cov = np.full((n, n), c * c) + np.diag(np.full(n, s * s))
        weights = np.full(n, 1.0 / n)
        exact = float(np.sqrt(cov[0, 0] / (weights @ cov @ weights)))
        mine = float(_call(ns, "averaging_gain", c, s, n, forbidden=(budget.error_budget,)))
        # a derivation is exact: a Monte Carlo estimate (0.1 % at best) does not pass
        assert abs(mine - exact) <= 1e-9 * exact, (
            f"common {c:.2f}, specific {s:.2f}, {n} holes: your gain is {mine / exact:.6f} "
            "times the exact one (the exercise asks for a derivation, exact to 1e-9)")


# --------------------------------------------------------------------------- notebook 07

def _ex07_1_x_model(ns, rng):
    x_cf, f_mm, a0 = rng.uniform(300, 900), rng.uniform(4.2, 5.8), rng.uniform(-2, 2)
    pitch = rng.uniform(0.006, 0.008)
    a = rng.uniform(-20, 20, 80)
    x = x_cf + f_mm / pitch * np.tan(np.radians(a + a0)) + rng.normal(0, 0.002, a.size)
    mine = _call(ns, "fit_x_model", a, x, pitch)
    got = np.asarray(mine, dtype=float).ravel()
    assert got.size == 3, "return (x_cf, F', alpha0)"
    # 2e-3 px of noise over 80 poses leaves errors far below these tolerances
    unseen = "on a run you have not seen"
    assert abs(got[1] - f_mm) < 1e-3, f"F' off by {got[1] - f_mm:+.4f} mm {unseen}"
    assert abs(got[2] - a0) < 0.01, f"alpha0 off by {got[2] - a0:+.3f} deg {unseen}"
    assert abs(got[0] - x_cf) < 0.2, f"x_cf off by {got[0] - x_cf:+.2f} px {unseen}"


# --------------------------------------------------------------------------- notebook 08

def _affine_rms(measured, truth):
    m, t = measured.reshape(-1, 2), truth.reshape(-1, 2)
    design = np.column_stack([m, np.ones(len(m))])
    coef, *_ = np.linalg.lstsq(design, t, rcond=None)
    return float(np.sqrt(np.mean(np.sum((design @ coef - t) ** 2, axis=1))))


def _ex08_1_import(ns, rng):
    with tempfile.TemporaryDirectory(prefix="sunlab-hidden-") as tmp:
        rec = write_recording(tmp, seed=int(rng.integers(1 << 30)))
        for name in ("train", "test"):
            cen = _call(ns, "centroids_of", rec.folder / name, rec.folder / "dark",
                        rec.folder / "flat")
            x, y = np.asarray(cen["x"], dtype=float), np.asarray(cen["y"], dtype=float)
            truth = rec.truth[name]
            assert x.shape == truth.shape[:2], (
                f"{name}: centroids of shape {x.shape}, expected (pose, shot) {truth.shape[:2]}")
            assert np.isfinite(x).all() and np.isfinite(y).all(), (
                f"{name} run you have not seen: {int((~np.isfinite(x)).sum())} frames without a "
                "centroid")
            rms = _affine_rms(np.stack([x, y], -1), truth)
            # 0.006 px with the dark and the flat applied (seeds 808, 1, 2); 0.05 px allows
            # another centroiding method
            assert rms < 0.05, (f"{name} run you have not seen: your centroids lie {rms:.3f} px "
                                "RMS from the true centres (after the best affine map)")


#: the capstone's stated accuracy on the unseen test run, deg (each angle)
CAPSTONE_MU_DEG, CAPSTONE_M_DEG = 0.002, 0.003


def _ex08_2_calibrate(ns, rng):
    from sunlab import centroid, export, io, stats

    with tempfile.TemporaryDirectory(prefix="sunlab-hidden-") as tmp:
        rec = write_recording(Path(tmp) / "run", seed=int(rng.integers(1 << 30)))
        cen = {name: centroid.locate(io.open_frames(rec.folder / name,
                                                    dark=rec.folder / "dark",
                                                    flat=rec.folder / "flat"),
                                     "projection", progress=False)
               for name in ("train", "test")}
        out = Path(tmp) / "onboard"
        cal = _call(ns, "calibrate_and_export", cen["train"], out)
        assert hasattr(cal, "predict"), "return the calibration (an object with .predict)"
        table = stats.evaluate(cal, cen["test"]).iloc[:, 0]
        for angle in ("alpha", "beta"):
            mu, m = table[(angle, "mu")], table[(angle, "M")]
            assert mu < CAPSTONE_MU_DEG and m < CAPSTONE_M_DEG, (
                f"on a test run you have not seen, {angle}: mu = {mu:.4f} deg, M = {m:.4f} deg "
                f"(the goal: mu < {CAPSTONE_MU_DEG} and M < {CAPSTONE_M_DEG} deg)")
        files = sorted(p.name for p in out.glob("*.[ch]")) if out.is_dir() else []
        assert files, f"no C export (.h and .c) in the folder {out.name} your function was given"
        if export.find_c_compiler() is not None:
            report = export.check_c(cal, out, n=200)
            assert report["max_error_double"] < 1e-9 and report["flags_agree"], (
                f"your exported C differs from Python's predict by "
                f"{report['max_error_double']:.1e} deg (domain flags agree: "
                f"{report['flags_agree']})")


# --------------------------------------------------------------------------- notebook 09

def _ex09_1_bound(ns, rng):
    from scipy import integrate

    for c, w in ((rng.uniform(-1, 1), 1.0), (rng.uniform(1.2, 3), 1.0),
                 (rng.uniform(0, 0.05), rng.uniform(0.01, 0.1)), (0.0, rng.uniform(0.5, 2))):
        # the moments of |X| from their definition, integrated to 1e-13 (split at 0)
        cut = [0.0] if c - w < 0 < c + w else None

        def moment(k, c=c, w=w, cut=cut):
            return integrate.quad(lambda x: abs(x) ** k / (2 * w), c - w, c + w, points=cut,
                                  epsabs=0, epsrel=1e-13)[0]

        m1, m2 = moment(1), moment(2)
        exact = float(np.sqrt(m2 - m1 * m1) / m1)
        mine = float(_call(ns, "abs_ratio_uniform", c, w))
        # a derivation is exact: draws (1e-3 at best) do not pass
        assert abs(mine - exact) <= 1e-9 * max(1.0, exact), (
            f"c = {c:.3f}, w = {w:.3f}: yours differs from the exact ratio by "
            f"{(mine - exact) / exact:+.2e} of it (the exercise asks for a derivation, exact "
            "to 1e-9)")


def _ex09_2_backlash(ns, rng):
    from sunlab.reproduce import fault as pf

    for truth in (0.0, rng.uniform(0.005, 0.03)):
        n = int(rng.integers(150, 400))
        d = rng.choice([-1, 1], n)
        noise = rng.uniform(0.002, 0.008)
        e = -truth * d + rng.normal(0, noise, n) + rng.uniform(-0.01, 0.01)
        e[rng.choice(n, 5, replace=False)] = np.nan
        mine = float(_call(ns, "backlash_from_errors", e, d,
                           forbidden=(pf.approach_split, pf.diagnose)))
        stderr = 0.5 * noise * np.sqrt(1 / (d > 0).sum() + 1 / (d < 0).sum())
        assert abs(mine - truth) < 5 * stderr, (
            f"on a bench you have not seen, your backlash is off by "
            f"{(mine - truth) / stderr:+.1f} standard errors")


CHECKS.update({f"{m[1]}.{m[2]}": f for n, f in list(globals().items())
               if (m := re.match(r"_ex(\d\d)_(\d+)_", n))})
