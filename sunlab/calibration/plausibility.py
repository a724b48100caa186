"""Is a fitted calibration physically plausible? Flags that calibrate and evaluate print.

A least-squares fit always returns numbers. A geometric model given a wrong pixel pitch or mask
distance, or a wrong sign convention, fits with errors of degrees, or "explains" the data with a
negative mask distance: the fit succeeded, the sensor it describes does not exist. These checks
say so in words, with the likely cause; they change nothing.

Examples
--------
>>> from sunlab import sim
>>> from sunlab.calibration import IdealModel
>>> cen = sim.synthetic_centroids([0.0, 8, 0, 8], [0.0, 0, 8, 8], shots=1)
>>> implausible(IdealModel().fit(cen))
[]
>>> cen.attrs["mask_distance_mm"] = 10.0  # the sensor's F is 5 mm
>>> print(implausible(IdealModel().fit(cen))[0][:55])
ideal model: its errors on its own training poses reach
"""

from __future__ import annotations

__all__ = []

#: A calibration error above this, deg, on its own training poses (or a test's mean error) is
#: not a calibration of the sensor: an input is wrong (pitch, mask distance, sign, centroids).
MAX_PLAUSIBLE_ERROR_DEG = 0.5


def implausible(cal, *, test_mu: dict | None = None) -> list[str]:
    """Reasons why a fitted calibration is physically implausible; empty when none.

    Parameters
    ----------
    cal : Calibration
        A fitted calibration (any method).
    test_mu : dict, optional
        ``{"alpha": mu, "beta": mu}``: mean local errors on a test table, deg (evaluate).

    Returns
    -------
    list of str
        One sentence per finding, each with the likely cause: training errors above
        :data:`MAX_PLAUSIBLE_ERROR_DEG`; for the optimised model a focal distance
        ``F + dF <= 0`` or a ``dF`` of more than half of ``F``, and mounting angles over 10 deg;
        a test mean error above :data:`MAX_PLAUSIBLE_ERROR_DEG`.
    """
    out = []
    limit = MAX_PLAUSIBLE_ERROR_DEG
    res = getattr(cal, "residuals", None) or {}
    worst = max((res.get(a, {}).get("max_abs") or 0.0) for a in ("alpha", "beta"))
    geometric = cal.kind in ("ideal", "optimised")
    cause = ("check sensor.json (pixel_pitch_mm, mask_distance_mm, x_cf_px, y_cf_px) and the "
             "angle signs" if geometric else "check the centroid table and the commanded angles")
    if worst > limit:
        out.append(f"{cal.kind} model: its errors on its own training poses reach {worst:.3g} "
                   f"deg (a calibration is good to ~0.01 deg); {cause}")
    if cal.kind == "optimised":
        p = cal.to_dict()["parameters"]
        f, df = float(p["mask_distance_mm"]), float(p["delta_f_mm"])
        if f + df <= 0:
            out.append(f"optimised model: F + dF = {f + df:.3g} mm, a mask below the detector; "
                       "check mask_distance_mm and the angle signs")
        elif abs(df) > 0.5 * f:
            out.append(f"optimised model: dF = {df:.3g} mm against a nominal F of {f:.3g} mm; "
                       "check mask_distance_mm in sensor.json")
        for name in ("alpha0", "beta0"):
            if abs(float(p[name])) > 10.0:
                out.append(f"optimised model: mounting angle {name} = {float(p[name]):.3g} deg; "
                           "check the zero of the platform and x_cf_px, y_cf_px")
    for angle, mu in (test_mu or {}).items():
        if mu is not None and mu > limit:
            out.append(f"mean error of {angle} on the test table {mu:.3g} deg; "
                       f"{cause}, and that the test table comes from the same sensor")
    return out
