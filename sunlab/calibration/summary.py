"""The text of ``sunlab info CAL.json``: a saved calibration described for a person.

Standard library only, so that ``sunlab info`` starts fast (:mod:`sunlab.calibration` loads its
submodules on first use); :meth:`sunlab.calibration.Calibration.summary` gives the same text for
a fitted calibration.

Examples
--------
>>> doc = {"sunlab_schema": "calibration/1", "kind": "polynomial", "label": "polynomial(3)",
...        "sunlab_version": "0.1.0", "parameters": {"order": [3, 3]},
...        "training": {"experiment": "I", "n_poses": 400, "n_shots": 8},
...        "domain": {"alpha": [-17, 2], "beta": [-2, 17], "x": [10, 700], "y": [5, 690]},
...        "residuals": {"alpha": {"mean_abs": 0.007, "max_abs": 0.02},
...                      "beta": {"mean_abs": 0.008, "max_abs": 0.03}, "validation": None}}
>>> print(calibration_summary(doc).splitlines()[0])
calibration/1: polynomial(3) (kind 'polynomial'), order 3
"""

from __future__ import annotations

__all__ = []


def _num(v, fmt: str = ".5f") -> str:
    return "n/a" if v is None else format(float(v), fmt)


def errors_line(res) -> str:
    """``alpha mean|e| ..., rms ..., max ...; beta ...`` (deg) of a ``residuals`` entry, or
    ``n/a`` (``sunlab info`` and ``sunlab calibrate`` print it).

    Parameters
    ----------
    res : dict or None
        Per angle the statistics ``mean_abs``, ``rms``, ``max_abs`` (deg).

    Returns
    -------
    str
    """
    if not isinstance(res, dict):
        return "n/a"
    parts = []
    for a in ("alpha", "beta"):
        r = res.get(a) or {}
        parts.append(f"{a} mean|e| {_num(r.get('mean_abs'))}, rms {_num(r.get('rms'))}, "
                     f"max {_num(r.get('max_abs'))}")
    return "; ".join(parts)


def calibration_summary(doc: dict) -> str:
    """A human-readable account of a ``calibration/1`` document (``sunlab info CAL.json``).

    Method and size, domain of validity, training and validation errors, provenance. For an
    interpolation the training residuals are zero by construction (an interpolant passes
    through its nodes), so the leave-one-out error is reported in their place.

    Parameters
    ----------
    doc : dict
        The parsed JSON document.

    Returns
    -------
    str

    Examples
    --------
    >>> print(calibration_summary({"kind": "ideal", "parameters": {"mask_distance_mm": 17.0}})
    ...       .splitlines()[0])
    ?: ideal (kind 'ideal'), F 17.0 mm, pitch None mm
    """
    kind = doc.get("kind", "?")
    p = doc.get("parameters") or {}
    size = ""
    if kind == "polynomial":
        orders = p.get("order") or []
        size = (f", order {orders[0]}" if len(set(orders)) == 1
                else f", orders alpha {orders[0]}, beta {orders[1]}") if orders else ""
    elif kind == "trigonometric":
        size = f", order {p.get('order')} (period {p.get('period')})"
    elif kind.startswith("interpolation"):
        nodes = (p.get("nodes") or {}).get("x") or []
        size = (f", {len(nodes)} nodes, outside the hull: "
                f"{'nearest node' if p.get('extrapolate') == 'nearest' else 'NaN'}")
    elif kind == "neural":
        size = f", strategy {p.get('strategy')}, {p.get('hidden')} tanh neurons per net"
    elif kind == "optimised":
        size = (f", dF {_num(p.get('delta_f_mm'), '.4f')} mm, alpha0 "
                f"{_num(p.get('alpha0'), '.4f')} deg, beta0 {_num(p.get('beta0'), '.4f')} deg")
    elif kind == "ideal":
        size = f", F {p.get('mask_distance_mm')} mm, pitch {p.get('pixel_pitch_mm')} mm"
    lines = [f"{doc.get('sunlab_schema', '?')}: {doc.get('label', kind)} (kind {kind!r}){size}"]
    d = doc.get("domain") or {}

    def rng(key, unit):
        v = d.get(key) or [None, None]
        return f"[{_num(v[0], '.4g')}, {_num(v[1], '.4g')}] {unit}"

    lines.append(f"  domain: alpha {rng('alpha', 'deg')}, beta {rng('beta', 'deg')}; "
                 f"centroid x {rng('x', 'px')}, y {rng('y', 'px')}")
    t = doc.get("training") or {}
    lines.append(f"  training: experiment {t.get('experiment') or '?'!r}, {t.get('n_poses', '?')} "
                 f"poses x {t.get('n_shots', '?')} shots ({t.get('n_ok_shots', '?')} ok), "
                 f"centroid method {t.get('centroid_method') or '?'!r}, average "
                 f"{t.get('average', '?')!r}")
    res = doc.get("residuals") or {}
    if kind.startswith("interpolation"):
        lines.append("  training residuals: ~0 by construction (an interpolant passes through "
                     "its nodes)")
        loo = res.get("leave_one_out")
        lines.append("  leave-one-out errors (deg): "
                     + (errors_line(loo) if loo else "n/a (fitted by an older sunlab)"))
    else:
        lines.append(f"  training residuals (deg): {errors_line(res)}")
    val = res.get("validation")
    v = t.get("validation") or {}
    lines.append("  validation errors (deg): " + (
        f"{errors_line(val)} (experiment {v.get('experiment') or '?'!r}, "
        f"{v.get('n_poses', '?')} poses)" if val else "none (fitted without a validation table)"))
    prov = [f"sunlab {doc.get('sunlab_version', '?')}"]
    if doc.get("created"):
        prov.append(f"created {doc['created']}")
    lines.append("  written by " + ", ".join(prov))
    return "\n".join(lines)
