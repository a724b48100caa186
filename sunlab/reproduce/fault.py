"""Find the platform fault that makes beta worse than alpha, from data a lab already has.

The paper's open problem (docs/paper.md sec. 5-7): beta is worse than alpha for every method
and mask, "which points at the rotation platform (its second axis)". Three faults of a worm-gear
stage's inner axis explain it; their sign depends on the motion history differently (notebook
09): **backlash** follows the *approach direction* (a serpentine scan alternates it row by row),
a **homing offset** is *constant within a run*, a **periodic gear error** is *periodic in beta*.
The tests, on the signed beta errors of a test run: the **shape** (:func:`shape_test`: sigma /
mu of ``|X|`` below :data:`UNIMODAL_BOUND` = 1/sqrt(3) means bimodal or offset; the paper's own
tables by :func:`paper_shape`), the **approach split** (:func:`approach_split`: 2 b), the **run
offset** (:func:`run_offset`) and the **periodogram against beta** (:func:`beta_periodogram`).
:func:`diagnose` turns each into a z-score and names the candidate;
:func:`sunlab.reproduce.platform.candidate_table` sets each fault, alone on the bench, beside the
paper's beta cells. The remedy that fits the faults jointly with the calibration is
:mod:`sunlab.reproduce.remedy`.

Examples
--------
>>> ps = paper_shape()
>>> round(float(ps.loc[("polynomial", "beta"), "ratio"]), 3), bool(ps.loc[("polynomial", "beta"),
...                                                                      "below_bound"])
(0.473, True)
>>> round(UNIMODAL_BOUND, 4)
0.5774
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field

import numpy as np
import pandas as pd
import xarray as xr

from .. import stats
from ..errors import ConfigurationError
from ..plans import Plan

__all__ = ["diagnose"]

#: sigma / mu of ``|X|`` for X uniform: the least any symmetric unimodal error can give.
UNIMODAL_BOUND = 1.0 / math.sqrt(3.0)
#: The candidate faults of the inner axis, and the sign pattern of each.
FAULTS = {
    "backlash": "follows the approach direction (alternates with the scan rows)",
    "homing": "constant within a run (differs between the calibration and test runs)",
    "gear": "periodic in beta, the same in every scan row",
}


# --------------------------------------------------------------------------- shape
def shape_test(table: pd.DataFrame) -> pd.DataFrame:
    """sigma / mu of the local errors per method and angle, against :data:`UNIMODAL_BOUND`.

    Parameters
    ----------
    table : pandas.DataFrame
        Global statistics as :func:`sunlab.stats.evaluate` lays them out (index
        ``(angle, stat)``, one column per method), ours or the paper's.

    Returns
    -------
    pandas.DataFrame
        Index ``(method, angle)``; columns ``mu``, ``sigma``, ``ratio`` and ``below_bound``
        (True: the error is not symmetric unimodal, i.e. bimodal or offset).

    Examples
    --------
    >>> from sunlab import stats
    >>> t = shape_test(stats.paper_table4())
    >>> round(float(t.loc[("polynomial", "alpha"), "ratio"]), 2)
    0.6
    """
    if not isinstance(table, pd.DataFrame) or ("alpha", "mu") not in table.index:
        raise ConfigurationError(
            "table: expected a DataFrame indexed (angle, stat) as sunlab.stats.evaluate "
            "returns. Fix: pass stats.evaluate(...) or stats.paper_table4().")
    mu, sd = (table.xs(st, level=1).loc[["alpha", "beta"]].T.astype(float).stack()
              for st in ("mu", "sigma"))
    ratio = sd / mu.where(mu > 0)
    return pd.DataFrame({"mu": mu, "sigma": sd, "ratio": ratio,
                         "below_bound": ratio < UNIMODAL_BOUND}).rename_axis(["method", "angle"])


def paper_shape() -> pd.DataFrame:
    """:func:`shape_test` on the paper's Table 4 and Table 5 (docs/paper.md sec. 5-6).

    Returns
    -------
    pandas.DataFrame
        As :func:`shape_test`: Table 4's four methods, then Table 5's two 100-hole columns
        (its "1 hole" repeats Table 4's polynomial).

    Examples
    --------
    >>> t = paper_shape()
    >>> round(float(t.loc[("linear interp.", "beta"), "ratio"]), 2)
    0.48
    """

    return pd.concat([shape_test(stats.paper_table4()),
                      shape_test(stats.paper_table5().drop(columns="1 hole"))])


# --------------------------------------------------------------------------- errors
def signed_pose_errors(estimate: xr.Dataset, reference=None) -> xr.Dataset:
    """Signed error (estimate minus reference) per pose, mean over the usable shots, deg.

    Parameters
    ----------
    estimate : xarray.Dataset
        Output of :meth:`sunlab.calibration.Calibration.predict`.
    reference : mapping, optional
        As :func:`sunlab.stats.shot_errors`; default the commanded angles.

    Returns
    -------
    xarray.Dataset
        ``alpha`` and ``beta`` on ``pose``, deg (NaN for a pose without a usable shot).

    Examples
    --------
    >>> est = xr.Dataset({"alpha": (("pose", "shot"), [[0.1, 0.3]]),
    ...                   "beta": (("pose", "shot"), [[-0.2, np.nan]])},
    ...                  coords={"alpha_cmd": ("pose", [0.0]), "beta_cmd": ("pose", [0.0])})
    >>> e = signed_pose_errors(est)
    >>> [round(float(e.alpha[0]), 6), round(float(e.beta[0]), 6)]
    [0.2, -0.2]
    """


    err = stats.shot_errors(estimate, reference, absolute=False)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", category=RuntimeWarning)  # all-NaN pose -> NaN
        return err.mean("shot", skipna=True).assign_attrs(units="deg")


def approach_of(source, poses: int | None = None, name: str = "source") -> np.ndarray:
    """The inner axis's approach direction (+1 up, -1 down) per pose, from the motion record.

    Parameters
    ----------
    source : sunlab.plans.Plan or xarray.Dataset or array_like
        The plan that was run, a cube with the coordinate ``beta_approach`` (what
        :func:`sunlab.sim.simulate` and the acquisition runner record), or the directions.
    poses : int, optional
        The run's pose count, checked against the record's.
    name : str
        The argument ``source`` came in, named in the errors.

    Returns
    -------
    numpy.ndarray of int, shape (pose,)
        +1 where the inner axis reached the pose upward, -1 downward.

    Examples
    --------
    >>> from sunlab import plans
    >>> approach_of(plans.grid(0, 1, 1, 0, 1, 1, shots=1, scan="serpentine")).tolist()
    [1, 1, -1, 1]
    """

    if isinstance(source, np.ndarray | list | tuple) and np.isin(source, (-1, 1)).all():
        d = np.asarray(source, dtype=int)
    elif isinstance(source, Plan):
        d = source.beta_approach().astype(int)
    elif isinstance(source, xr.Dataset) and "beta_approach" in source.variables:
        d = np.asarray(source["beta_approach"].values, dtype=int)
    else:
        raise ConfigurationError(
            f"{name}: found {type(source).__name__} without a motion record; expected the "
            "sunlab.plans.Plan that was run or a cube with a 'beta_approach' coordinate. Fix: "
            "pass the plan (its scan and approach say how each pose was reached).")
    if poses is not None and d.size != poses:
        raise ConfigurationError(
            f"{name}: found {d.size} approach directions for {poses} poses; expected one per "
            "pose of the run. Fix: pass the plan of that run.")
    return d


def _finite(e, *arrays):
    ok = np.isfinite(e)
    return (e[ok],) + tuple(np.asarray(a)[ok] for a in arrays)


def _approach_fit(e, d):
    """The least-squares fit of the errors on [1, d]: coefficients, their standard errors (from
    the residuals' scatter: independent per-pose errors) and the residuals."""
    A = np.column_stack([np.ones_like(e), d])
    coef, *_ = np.linalg.lstsq(A, e, rcond=None)
    r = e - A @ coef
    cov = float(r @ r) / max(e.size - 2, 1) * np.linalg.pinv(A.T @ A)
    return coef, np.sqrt(np.diag(cov)), r


def approach_split(beta_error, approach) -> dict:
    """Mean signed beta error of the poses reached upward and downward; the backlash they imply.

    With the backlash b the error is -b on poses reached upward and +b on poses reached
    downward, so b = (mean_down - mean_up) / 2, minus the slope of the errors on the direction
    (:func:`run_offset`'s regression on [1, d]); its standard error is from the scatter of the
    poses about their group means (independent per-pose errors).

    Parameters
    ----------
    beta_error : array_like, shape (pose,)
        Signed beta error per pose, deg (:func:`signed_pose_errors`).
    approach : array_like of +-1, shape (pose,)
        :func:`approach_of`.

    Returns
    -------
    dict
        ``mean_up``, ``mean_down``, ``n_up``, ``n_down``, ``backlash_deg``, ``stderr_deg``, ``z``.

    Examples
    --------
    >>> d = np.array([1, -1] * 50)
    >>> r = approach_split(-0.01 * d + 0.001 * np.sin(np.arange(100)), d)
    >>> round(r["backlash_deg"], 4), r["z"] > 10
    (0.01, True)
    """
    e, d = _finite(np.asarray(beta_error, dtype=float), np.asarray(approach))
    up, down = e[d > 0], e[d < 0]
    out = {"mean_up": float(up.mean()) if up.size else float("nan"),
           "mean_down": float(down.mean()) if down.size else float("nan"),
           "n_up": int(up.size), "n_down": int(down.size)}
    if up.size < 2 or down.size < 2:
        return {**out, "backlash_deg": float("nan"), "stderr_deg": float("nan"), "z": 0.0}
    coef, se, _ = _approach_fit(e, d.astype(float))  # the slope on d is -b
    b, se = -float(coef[1]), float(se[1])
    return {**out, "backlash_deg": b, "stderr_deg": se,
            "z": abs(b) / se if se > 0 else float("inf")}


def row_split(beta_error, alpha_cmd, approach) -> pd.DataFrame:
    """Mean signed beta error per scan row (outer angle alpha) with the row's main direction.

    Parameters
    ----------
    beta_error : array_like, shape (pose,)
        Signed beta error per pose, deg (:func:`signed_pose_errors`).
    alpha_cmd : array_like, shape (pose,)
        Commanded outer angle of each pose, deg: the row it belongs to.
    approach : array_like of +-1, shape (pose,)
        :func:`approach_of`.

    Returns
    -------
    pandas.DataFrame
        Index ``alpha_cmd``; columns ``mean_error_deg``, ``approach`` (the sign of the row's
        mean direction) and ``poses``.

    Examples
    --------
    >>> r = row_split([0.01, 0.01, -0.01, -0.01], [0, 0, 1, 1], [-1, -1, 1, 1])
    >>> r["mean_error_deg"].tolist(), r["approach"].tolist()
    ([0.01, -0.01], [-1, 1])
    """
    df = pd.DataFrame({"alpha": np.asarray(alpha_cmd, dtype=float),
                       "e": np.asarray(beta_error, dtype=float),
                       "d": np.asarray(approach, dtype=float)})
    g = df.groupby("alpha")
    out = pd.DataFrame({"mean_error_deg": g["e"].mean(),
                        "approach": np.sign(g["d"].mean()).astype(int), "poses": g["e"].count()})
    out.index.name = "alpha_cmd"
    return out


def run_offset(beta_error, approach) -> dict:
    """The run's mean beta error with the approach term removed (regression on [1, d]).

    Parameters
    ----------
    beta_error : array_like, shape (pose,)
        Signed beta error per pose, deg (:func:`signed_pose_errors`).
    approach : array_like of +-1, shape (pose,)
        :func:`approach_of`.

    Returns
    -------
    dict
        ``offset_deg`` (the intercept), ``stderr_deg``, ``z``.

    Examples
    --------
    >>> d = np.array([1, -1] * 50)
    >>> r = run_offset(0.02 - 0.01 * d + 0.001 * np.cos(np.arange(100)), d)
    >>> round(r["offset_deg"], 4), r["z"] > 10
    (0.02, True)
    """
    e, d = _finite(np.asarray(beta_error, dtype=float), np.asarray(approach, dtype=float))
    coef, se, _ = _approach_fit(e, d)
    se = float(se[0])
    return {"offset_deg": float(coef[0]), "stderr_deg": se,
            "z": abs(float(coef[0])) / se if se > 0 else float("inf")}


def beta_periodogram(beta_error, beta_cmd, approach, *, detrend: int = 3,
                     frequencies=None) -> dict:
    """Periodogram against beta of the error averaged over the scan rows at each beta.

    The approach and run terms are removed (:func:`run_offset`'s regression), the residuals
    averaged per commanded beta (the mean over the rows), a polynomial of degree ``detrend`` in
    beta removed (what a smooth calibration misfit leaves), and a sinusoid of each frequency
    fitted by least squares. Under the null (no error that repeats in beta) the row means
    scatter with the within-beta variance over the number of rows, so the power of one
    frequency, in those units, is chi-square with 2 degrees of freedom; the false-alarm
    probability of the peak is ``1 - (1 - exp(-P/2))**K`` for K independent frequencies.

    Parameters
    ----------
    beta_error, beta_cmd, approach : array_like, shape (pose,)
    detrend : int
        Degree of the polynomial in beta removed before the periodogram.
    frequencies : array_like, optional
        Cycles per degree; default 0.02 to the Nyquist frequency of the beta grid.

    Returns
    -------
    dict
        ``frequency`` (cycles/deg), ``power`` (chi-square units), ``peak_frequency``,
        ``peak_period_deg``, ``peak_amplitude_deg``, ``false_alarm``, ``z``.

    Examples
    --------
    >>> b = np.tile(np.arange(19.0), 19)
    >>> rng = np.random.default_rng(0)
    >>> e = 0.02 * np.sin(2 * np.pi * b / 2.7) + rng.normal(0, 0.01, b.size)
    >>> r = beta_periodogram(e, b, np.ones(b.size))
    >>> round(r["peak_period_deg"], 1), r["z"] > 5
    (2.7, True)
    """
    from scipy import stats as sst

    e, b, d = _finite(np.asarray(beta_error, dtype=float), np.asarray(beta_cmd, dtype=float),
                      np.asarray(approach, dtype=float))
    r = _approach_fit(e, d)[2]
    ub, inv = np.unique(b, return_inverse=True)
    n_j = np.bincount(inv).astype(float)
    m_j = np.bincount(inv, weights=r) / n_j
    within = r - m_j[inv]
    dof = e.size - ub.size
    if ub.size < detrend + 4 or dof < 2:
        raise ConfigurationError(
            f"beta_cmd: found {ub.size} distinct beta values over {e.size} poses; the "
            "periodogram needs several rows at each of at least "
            f"{detrend + 4} betas. Fix: pass a full grid experiment.")
    s2_w = float(within @ within) / dof
    w = n_j / s2_w  # inverse variance of each row mean
    x = (ub - ub.mean()) / max(np.ptp(ub), 1e-12)
    V = np.vander(x, detrend + 1)
    sw = np.sqrt(w)
    c, *_ = np.linalg.lstsq(V * sw[:, None], m_j * sw, rcond=None)
    m_d = m_j - V @ c
    step = float(np.min(np.diff(ub))) if ub.size > 1 else 1.0
    if frequencies is None:
        frequencies = np.arange(0.02, 0.5 / step + 1e-9, 0.0025)
    freqs = np.asarray(frequencies, dtype=float)
    power = np.empty(freqs.size)
    amps = np.empty(freqs.size)
    for k, f in enumerate(freqs):
        S = np.column_stack([np.sin(2 * np.pi * f * ub), np.cos(2 * np.pi * f * ub), V])
        cc, *_ = np.linalg.lstsq(S * sw[:, None], m_j * sw, rcond=None)
        res = m_j - S @ cc
        power[k] = float(np.sum(w * m_d**2) - np.sum(w * res**2))
        amps[k] = math.hypot(cc[0], cc[1])
    i = int(np.argmax(power))
    k_ind = max(int(ub.size // 2), 1)
    p_one = math.exp(-0.5 * max(power[i], 0.0))
    fa = 1.0 - (1.0 - p_one) ** k_ind if p_one > 1e-12 else k_ind * p_one
    z = float(sst.norm.isf(max(fa, 1e-300)))
    return {"frequency": freqs, "power": power, "peak_frequency": float(freqs[i]),
            "peak_period_deg": float(1.0 / freqs[i]), "peak_amplitude_deg": float(amps[i]),
            "false_alarm": float(fa), "z": max(z, 0.0)}


@dataclass
class Diagnosis:
    """The result of :func:`diagnose`.

    Attributes
    ----------
    candidate : str
        One of :data:`FAULTS`, or ``"none"`` when no test passes the threshold.
    z : dict
        z-score of each candidate's test.
    evidence : dict
        The numbers behind each test (deg; JSON-ready).
    """

    candidate: str
    z: dict
    evidence: dict = field(default_factory=dict)


def diagnose(estimate: xr.Dataset, motion, *, threshold: float = 4.0) -> Diagnosis:
    """Name the inner-axis fault from a test run's estimates and its motion record.

    Parameters
    ----------
    estimate : xarray.Dataset
        A calibration's prediction on the test run (:meth:`Calibration.predict`), with the
        commanded angles.
    motion : sunlab.plans.Plan or xarray.Dataset or array_like
        The run's plan or cube (:func:`approach_of`), or the approach direction per pose.
    threshold : float
        Smallest z-score that names a candidate; the largest z wins.

    Returns
    -------
    Diagnosis

    Examples
    --------
    >>> from sunlab import plans
    >>> plan = plans.experiment("III", shots=1)
    >>> d = plan.beta_approach()
    >>> rng = np.random.default_rng(1)
    >>> est = xr.Dataset({"alpha": (("pose", "shot"), plan.alpha[:, None]),
    ...                   "beta": (("pose", "shot"), (plan.beta - 0.015 * d
    ...                            + rng.uniform(-0.01, 0.01, d.size))[:, None])},
    ...                  coords={"alpha_cmd": ("pose", plan.alpha),
    ...                          "beta_cmd": ("pose", plan.beta)})
    >>> diagnose(est, plan).candidate
    'backlash'
    """
    err = signed_pose_errors(estimate)
    e = np.asarray(err["beta"].values, dtype=float)
    d = approach_of(motion, e.size, "motion")
    b_cmd = np.asarray(estimate["beta_cmd"].values, dtype=float)
    a_cmd = np.asarray(estimate["alpha_cmd"].values, dtype=float)
    ap = approach_split(e, d)
    ro = run_offset(e, d)
    pg = beta_periodogram(e, b_cmd, d)
    z = {"backlash": float(ap["z"]), "homing": float(ro["z"]), "gear": float(pg["z"])}
    best = max(z, key=z.get)
    evidence = {
        "approach_split": {k: float(v) for k, v in ap.items()},
        "run_offset": {k: float(v) for k, v in ro.items()},
        "periodogram": {k: float(pg[k]) for k in ("peak_frequency", "peak_period_deg",
                                                   "peak_amplitude_deg", "false_alarm", "z")},
        "rows": {f"{k:g}": float(v)
                 for k, v in row_split(e, a_cmd, d)["mean_error_deg"].items()},
        "threshold_z": float(threshold),
    }
    for a in ("alpha", "beta"):
        ae = np.abs(np.asarray(err[a].values, dtype=float))
        ae = ae[np.isfinite(ae)]
        mu = float(ae.mean()) if ae.size > 1 else 0.0
        evidence[f"{a}_sigma_over_mu"] = float(ae.std(ddof=1)) / mu if mu > 0 else None
    evidence["unimodal_bound"] = UNIMODAL_BOUND
    return Diagnosis(best if z[best] >= threshold else "none", z, evidence)


def fault_bench(bench, kind: str, size_deg: float, *, period_deg: float = 1.6):
    """The bench with one inner-axis fault only (the others, and the stand-ins, set to zero).

    Parameters
    ----------
    bench : sunlab.sim.Bench
    kind : {"backlash", "homing", "gear"}
        The fault (:data:`FAULTS`): ``beta_backlash_deg``, ``beta_homing_deg`` (half-width of
        the per-run offset) or ``beta_gear_deg`` (amplitude, with ``period_deg``).
    size_deg : float
        Its size, deg.
    period_deg : float
        The gear error's period, deg (``kind="gear"`` only).

    Returns
    -------
    Bench
        ``bench`` with that fault alone on the inner axis: the other two, the thermal drift
        and the zero shift at a new homing set to zero.

    Examples
    --------
    >>> from sunlab.sim import Bench
    >>> fault_bench(Bench.paper_single_hole(), "gear", 0.02).platform.beta_gear_deg
    0.02
    """
    if kind not in FAULTS:
        raise ConfigurationError(f"kind: found {kind!r}; expected one of {tuple(FAULTS)}.")
    # the thermal drift of the zero between runs and its shift at a new homing between the
    # sessions are run offsets like the homing's: out too
    change = {f"platform__beta_{k}_deg": 0.0 for k in (*FAULTS, "drift", "rehoming")}
    change[f"platform__beta_{kind}_deg"] = float(size_deg)
    if kind == "gear":
        change["platform__beta_gear_period_deg"] = float(period_deg)
    return bench.replace(**change)
