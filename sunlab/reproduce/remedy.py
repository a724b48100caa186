"""Remove the platform fault: fit it jointly with the polynomial calibration (remedy (b)).

The diagnosis (:mod:`sunlab.reproduce.fault`) names the inner axis's fault from a test run and
its motion record; :func:`fit_correction` fits the backlash (and, given zero-pose checks, the
homing offset, and given a period, the gear error) jointly with the polynomial calibration, with
standard errors, and :meth:`JointCorrection.reference` corrects the test run's reference angles
from its recorded motion (``sunlab reproduce --table platform``, notebook 09).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field

import numpy as np
import xarray as xr

from ..calibration import Polynomial
from ..errors import ConfigurationError
from ..schema import STATUS, USABLE_STATUS
from .fault import approach_of

__all__ = []


def _pose_means(cen: xr.Dataset):
    """Pose-mean centroids of the usable shots, px (NaN for a pose without one)."""


    ok = np.asarray(cen["status"].isin([STATUS[k] for k in USABLE_STATUS]).values)
    x = np.where(ok, np.asarray(cen["x"].values, dtype=float), np.nan)
    y = np.where(ok, np.asarray(cen["y"].values, dtype=float), np.nan)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", category=RuntimeWarning)
        return np.nanmean(x, axis=1), np.nanmean(y, axis=1)


@dataclass
class JointCorrection:
    """A polynomial calibration whose beta part was fitted jointly with fault terms.

    Attributes
    ----------
    calibration : sunlab.calibration.Polynomial
        alpha as fitted alone; beta the polynomial part of the joint fit (it estimates the
        true inner-axis angle, not the commanded one).
    parameters : dict
        ``name -> {"fitted": value, "stderr": value}`` (deg): ``beta_backlash_deg``, and when
        fitted ``beta_homing_difference_deg`` (test run minus calibration run) and
        ``beta_gear_amplitude_deg``.
    gear_frequency : float or None
        Frequency of the gear term, cycles/deg.
    """

    calibration: object
    parameters: dict
    gear_frequency: float | None = None
    _coef: dict = field(default_factory=dict, repr=False)

    def predict(self, centroids: xr.Dataset) -> xr.Dataset:
        """The calibration's estimate (:meth:`sunlab.calibration.Calibration.predict`).

        Parameters
        ----------
        centroids : xarray.Dataset
            A ``centroids/1`` table (the test run).

        Returns
        -------
        xarray.Dataset
            Estimated ``alpha`` and ``beta``, deg; compare them with :meth:`reference`.
        """
        return self.calibration.predict(centroids)

    def reference(self, estimate: xr.Dataset, motion) -> dict:
        """The test run's reference angles corrected from its motion record, deg.

        beta: commanded - b d + g(beta) + h, with the fitted backlash b, approach d, gear
        error g and homing difference h; alpha: commanded. Pass as ``reference`` to
        :func:`sunlab.stats.evaluate`.

        Parameters
        ----------
        estimate : xarray.Dataset
            :meth:`predict` on the test run, with its commanded angles.
        motion : sunlab.plans.Plan or xarray.Dataset or array_like
            The test run's plan or cube (:func:`approach_of`), or its approach per pose.

        Returns
        -------
        dict
            ``alpha`` and ``beta`` (xarray.DataArray on pose), deg.
        """
        d = approach_of(motion, estimate.sizes["pose"], "motion").astype(float)
        b_cmd = estimate["beta_cmd"]
        beta = b_cmd - self._coef.get("backlash", 0.0) * xr.DataArray(d, dims=b_cmd.dims)
        if self.gear_frequency is not None:
            ph = 2 * np.pi * self.gear_frequency * b_cmd
            beta = beta - (self._coef["sin"] * np.sin(ph) + self._coef["cos"] * np.cos(ph))
        beta = beta + self.parameters.get("beta_homing_difference_deg", {}).get("fitted", 0.0)
        return {"alpha": estimate["alpha_cmd"], "beta": beta}


def fit_correction(train: xr.Dataset, train_motion, validation: xr.Dataset | None = None, *,
                   order=None, gear_frequency: float | None = None, zero_train=None,
                   zero_test=None, backlash: bool = True) -> JointCorrection:
    """Fit the polynomial calibration jointly with the inner axis's fault terms.

    The beta polynomial P of the centroid estimates the true inner-axis angle; the commanded
    angle of each calibration pose is

    .. math:: \\beta_{cmd} = P(x, y) + b\\,d - g(\\beta_{cmd}),
              \\quad g(\\beta) = s \\sin 2\\pi f\\beta + c \\cos 2\\pi f\\beta

    with the approach direction d of the pose (the motion record), the backlash b and, when
    ``gear_frequency`` f is given, the gear error g (at the grid, a period under two steps is
    only seen aliased, so f is the alias the periodogram finds; the amplitude is the same).
    All coefficients come from one least-squares fit over the pose means, the standard errors
    from its covariance (residuals independent between poses: the per-pose errors are). The
    homing offset of the test run relative to the calibration run comes from their zero-pose
    checks (:func:`sunlab.plans.zero_check`): the mean of P over the test run's checks minus
    that over the calibration run's, its standard error from the checks' scatter.

    Parameters
    ----------
    train : xarray.Dataset
        Centroid table of the calibration run (experiment I).
    train_motion : sunlab.plans.Plan or xarray.Dataset or array_like
        Its motion record (:func:`approach_of`).
    validation : xarray.Dataset, optional
        Experiment II: picks the polynomial order (:meth:`Polynomial.select_order`).
    order : int or (int, int), optional
        The order, when no validation table is given (default 5).
    gear_frequency : float, optional
        Fit a gear term at this frequency, cycles/deg.
    zero_train, zero_test : xarray.Dataset, optional
        Centroid tables of the zero-pose checks of the calibration and test runs.
    backlash : bool
        Fit the backlash term (leave it out for a unidirectional plan, where every pose is
        reached upward and the term cannot be told from the polynomial's constant).

    Returns
    -------
    JointCorrection

    Examples
    --------
    >>> from sunlab import plans
    >>> from sunlab.sim import Bench
    >>> from sunlab.sim.surrogate import surrogate_centroids
    >>> from sunlab.reproduce.fault import fault_bench
    >>> bench = fault_bench(Bench.paper_single_hole(), "backlash", 0.02)
    >>> plan = plans.experiment("I", shots=1)
    >>> jc = fit_correction(surrogate_centroids(bench, plan, 0), plan, order=5)
    >>> p = jc.parameters["beta_backlash_deg"]
    >>> abs(p["fitted"] - 0.02) < 3 * p["stderr"] < 0.002
    True
    """

    if validation is not None:
        cal, _ = Polynomial.select_order(train, validation)
    else:
        cal = Polynomial(5 if order is None else order).fit(train)
    xm, ym = _pose_means(train)
    b_cmd = np.asarray(train["beta"].values, dtype=float)
    d = approach_of(train_motion, b_cmd.size, "train_motion").astype(float)
    params, extra = _joint_beta_fit(cal, xm, ym, d, b_cmd, backlash=backlash,
                                    gear_frequency=gear_frequency)
    if (zero_train is None) != (zero_test is None):
        raise ConfigurationError(
            "zero_train, zero_test: found one of them; expected both zero-pose checks (the "
            "calibration run's and the test run's) or neither. Fix: plans.zero_check(plan) "
            "for each run.")
    if zero_train is not None:
        params["beta_homing_difference_deg"] = _homing_difference(cal, zero_train, zero_test)
    return JointCorrection(cal, params, None if gear_frequency is None else float(gear_frequency),
                           extra)


def _joint_beta_fit(cal, xm, ym, d, b_cmd, *, backlash: bool, gear_frequency):
    """Refit beta's polynomial jointly with the backlash term (``d``: approach directions) and
    a gear term; the polynomial's coefficients go into ``cal``. The fitted fault parameters
    with standard errors, and the terms :class:`JointCorrection` applies."""
    ok = np.isfinite(xm) & np.isfinite(ym)
    P = cal.basis(xm[ok], ym[ok], "beta")
    cols = [P, d[ok, None]] if backlash else [P]
    if gear_frequency is not None:
        ph = 2 * np.pi * float(gear_frequency) * b_cmd[ok]
        cols.append(np.column_stack([np.sin(ph), np.cos(ph)]))
    A = np.hstack(cols)
    coef, *_ = np.linalg.lstsq(A, b_cmd[ok], rcond=None)
    r = b_cmd[ok] - A @ coef
    s2 = float(r @ r) / (A.shape[0] - A.shape[1])
    cov = s2 * np.linalg.pinv(A.T @ A)
    k = P.shape[1]
    cal.coefficients["beta"] = coef[:k]
    params, extra = {}, {}
    if backlash:
        params["beta_backlash_deg"] = {"fitted": float(coef[k]),
                                       "stderr": math.sqrt(float(cov[k, k]))}
        extra["backlash"] = float(coef[k])
        k += 1
    if gear_frequency is not None:
        s, c = float(coef[k]), float(coef[k + 1])
        amp = math.hypot(s, c)
        g = np.array([s, c]) / max(amp, 1e-300)
        se = math.sqrt(float(g @ cov[k:k + 2, k:k + 2] @ g))
        params["beta_gear_amplitude_deg"] = {"fitted": amp, "stderr": se}
        extra.update({"sin": -s, "cos": -c})
    return params, extra


def _homing_difference(cal, zero_train, zero_test) -> dict:
    """The test run's homing offset minus the calibration run's, from the beta ``cal`` reads
    at the zero-pose checks of each run, with its standard error."""
    vals = []
    for z in (zero_train, zero_test):
        zx, zy = _pose_means(z)
        _, bz = cal.predict_xy(zx, zy)
        bz = bz[np.isfinite(bz)]
        if bz.size < 2:
            raise ConfigurationError(
                "zero check: found fewer than 2 usable zero-pose visits; expected several. "
                "Fix: plans.zero_check(plan, checks=4).")
        vals.append(bz)
    h = float(vals[1].mean() - vals[0].mean())
    se = math.sqrt(vals[0].var(ddof=1) / vals[0].size + vals[1].var(ddof=1) / vals[1].size)
    return {"fitted": h, "stderr": se}
