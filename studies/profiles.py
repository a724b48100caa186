"""The identified presets and the profile likelihood of each fitted parameter.

Under protocol version 4 (docs/identification.md) the presets of :class:`sunlab.sim.Bench` are
*one* fit of the chosen hypothesis, every nuisance at its prior median and the gear period
profiled on the protocol's grid, on the protocol's preset seed (:func:`fit_presets`); each
fitted parameter's 90 % interval comes from its profile likelihood on the fit side
(:func:`profile_likelihood`, :func:`profile_intervals`):

    deviance(theta_k) = (SSR(theta_k, others refitted) - least SSR of the profile) / tau^2

where SSR is the sum over Table 4's 12 fit-side quantities of squared log residuals and tau the
hypothesis's model discrepancy from the evidence; the interval is where the deviance stays at
most chi^2_1(0.90) = 2.706 (Wilks), linear in log parameter between the grid's points.

Examples
--------
>>> p = load_presets()
>>> p["hypothesis"] in ("F5", "F17", "F5-gear", "F17-gear"), p["seed"]
(True, 4000)
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from . import identification as idn

__all__ = ["profile_intervals", "profile_likelihood"]

#: chi^2 with one degree of freedom, its 90 % quantile: a profile's interval bound (Wilks).
CHI2_1_90 = 2.705543454095404


def fit_presets(protocol: dict, name: str) -> dict:
    """The presets: one fit of ``name`` at the nuisances' prior medians on the preset seed.

    Parameters
    ----------
    protocol : dict
        :func:`studies.identification.load_protocol` (version 4 or later).
    name : str
        The chosen hypothesis.

    Returns
    -------
    dict
        ``hypothesis``, ``seed``, ``nuisances`` (the prior medians), ``fitted`` (deg, the gear
        period included for a gear hypothesis), ``fit_ssr``, ``period_ssr`` (period deg ->
        fit_ssr, empty without a gear) and ``noise_px``.
    """
    seed = int(protocol["presets"]["seed"])
    nuis = idn.draw_nuisances(protocol, None)
    fit = idn.fit_draw(protocol, name, nuis, seed=seed)
    return {"hypothesis": name, "seed": seed, "nuisances": nuis,
            "fitted": idn._parameters(fit), "fit_ssr": fit["fit_ssr"],
            "period_ssr": {str(k): v for k, v in fit.get("period_ssr", {}).items()},
            "noise_px": fit["noise_px"]}


def _profile_point(protocol: dict, presets: dict, parameter: str, value: float) -> float:
    """The fit side's SSR with ``parameter`` held at ``value`` and the others refitted."""
    fitted = presets["fitted"]
    fixed = {parameter: value}
    if "gear_period_deg" in fitted and parameter != "gear_period_deg":
        fixed["gear_period_deg"] = fitted["gear_period_deg"]
    fit = idn.fit_hypothesis(protocol, presets["hypothesis"], presets["nuisances"],
                             seed=presets["seed"], noise_px=presets["noise_px"], fixed=fixed)
    return fit["fit_ssr"]


def profile_likelihood(protocol: dict, presets: dict, tau: float, *,
                       jobs: int = 1) -> pd.DataFrame:
    """Each fitted parameter's profile on the fit side, around the presets.

    Each parameter rescaled by the protocol's ``profiles.factors`` is held while the others are
    refitted (:func:`studies.identification.fit_hypothesis`; the gear period is held at
    the presets' in the others' profiles: the refit moves the rescaled parameters only); the
    gear period's profile is the presets' grid.

    Parameters
    ----------
    protocol : dict
    presets : dict
        :func:`fit_presets`.
    tau : float
        The hypothesis's model discrepancy (log units), from the evidence.
    jobs : int
        Processes that refit side by side.

    Returns
    -------
    pandas.DataFrame
        ``parameter``, ``factor`` (of the preset value), ``value`` (deg), ``fit_ssr`` and
        ``deviance`` ((SSR - the parameter's least SSR) / tau^2).
    """
    fitted = presets["fitted"]
    factors = [float(f) for f in protocol["profiles"]["factors"]]
    tasks = [(k, f, fitted[k] * f) for k in fitted if k != "gear_period_deg" for f in factors]
    args = [(protocol, presets, k, v) for k, _, v in tasks]
    ssr = dict(idn.run_all(_profile_point, args, jobs))
    ssr = [ssr[i] for i in range(len(args))]
    rows = [{"parameter": k, "factor": f, "value": v, "fit_ssr": s}
            for (k, f, v), s in zip(tasks, ssr, strict=True)]
    rows += [{"parameter": k, "factor": 1.0, "value": v, "fit_ssr": presets["fit_ssr"]}
             for k, v in fitted.items() if k != "gear_period_deg"]
    period = fitted.get("gear_period_deg")
    rows += [{"parameter": "gear_period_deg", "factor": float(p) / period, "value": float(p),
              "fit_ssr": s} for p, s in presets.get("period_ssr", {}).items()]
    df = pd.DataFrame(rows).sort_values(["parameter", "value"], ignore_index=True)
    least = df.groupby("parameter")["fit_ssr"].transform("min")
    return df.assign(deviance=(df["fit_ssr"] - least) / tau**2)


def profile_intervals(profile: pd.DataFrame, presets: dict,
                      threshold: float = CHI2_1_90) -> pd.DataFrame:
    """The 90 % profile-likelihood interval of each fitted parameter.

    Parameters
    ----------
    profile : pandas.DataFrame
        :func:`profile_likelihood`.
    presets : dict
        :func:`fit_presets`.
    threshold : float
        The deviance that bounds the interval (chi^2_1's 90 % quantile).

    Returns
    -------
    pandas.DataFrame
        ``parameter``, ``preset`` (deg), ``lo``, ``hi`` (deg; where the deviance crosses the
        threshold, linear in log parameter between grid points), ``lo_open`` / ``hi_open``
        (the deviance stays below the threshold at the grid's end: the bound is the grid's).

    Examples
    --------
    >>> prof = pd.DataFrame({"parameter": ["a"] * 3, "value": [0.5, 1.0, 2.0],
    ...                      "deviance": [5.0, 0.0, 1.0]})
    >>> r = profile_intervals(prof, {"fitted": {"a": 1.0}}).iloc[0]
    >>> round(float(r.lo), 3), round(float(r.hi), 1), bool(r.hi_open)
    (0.687, 2.0, True)
    """
    rows = []
    for k, g in profile.groupby("parameter", sort=True):
        g = g.sort_values("value")
        x = np.log(g["value"].to_numpy())
        d = g["deviance"].to_numpy()
        i0 = int(np.argmin(d))
        bound = {}
        for side, idx in (("lo", range(i0, 0, -1)), ("hi", range(i0, len(d) - 1))):
            step = -1 if side == "lo" else 1
            out = None
            for i in idx:
                j = i + step
                if d[j] > threshold >= d[i]:
                    t = (threshold - d[i]) / (d[j] - d[i])
                    out = math.exp(x[i] + t * (x[j] - x[i]))
                    break
            bound[side] = out
        rows.append({"parameter": k, "preset": float(presets["fitted"][k]),
                     "lo": bound["lo"] if bound["lo"] is not None else float(np.exp(x[0])),
                     "hi": bound["hi"] if bound["hi"] is not None else float(np.exp(x[-1])),
                     "lo_open": bound["lo"] is None, "hi_open": bound["hi"] is None})
    return pd.DataFrame(rows)


def load_presets(path=None) -> dict:
    """The shipped presets (``sunlab/data/presets.json``) or the file at ``path``.

    Returns
    -------
    dict
        As :func:`fit_presets` wrote it.
    """
    return idn.read_json(idn.LIBRARY_DATA / "presets.json" if path is None else path,
                         "run `python -m studies.identify --out DIR` again.")


def load_profiles(path=None) -> pd.DataFrame:
    """The shipped profile likelihoods (``studies/results/profiles.csv``) or those at ``path``.

    Returns
    -------
    pandas.DataFrame
        As :func:`profile_likelihood`.
    """
    from .evidence import _data

    return pd.read_csv(path) if path is not None else _data("profiles.csv")
