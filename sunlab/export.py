"""Export a fitted calibration for on-board use: self-contained C99, or the JSON artifact.

``export(cal, out, format="c")`` writes ``out/sunlab_calibration.h`` and
``out/sunlab_calibration.c``: the calibration as constant tables and a few lines of C that
evaluate it, with no allocation and no library beyond ``<math.h>`` (``atan``, ``sqrt``,
``tanh`` and ``isfinite``, only where the method needs them). The header declares

.. code-block:: c

    int sunlab_calibration_eval(double x_px, double y_px, double *alpha_deg, double *beta_deg);
    int sunlab_calibration_evalf(float x_px, float y_px, float *alpha_deg, float *beta_deg);

which return :data:`FLAGS` ``0`` (``SUNLAB_CALIBRATION_OK``) inside the calibrated domain,
``1`` (``SUNLAB_CALIBRATION_OUTSIDE``) outside it with the angles extrapolated, ``2``
(``SUNLAB_CALIBRATION_UNDEFINED``) outside it for a method that cannot extrapolate (angles NaN)
and ``3`` (``SUNLAB_CALIBRATION_BAD_INPUT``) for a non-finite centroid (angles NaN) — the same
domain as :meth:`sunlab.calibration.Calibration.inside`. The float variant keeps its own
single-precision tables, for processors with a single-precision FPU only.

What each method exports:

* polynomial: the coefficients on the same scaled variables (u, v) as Python, evaluated by
  Horner's rule in u of Horner polynomials in v;
* linear interpolation of the calibration table: the Delaunay triangles of the nodes (vertex
  indices and scipy's barycentric transforms, in scipy's rescaled plane) and the node angles;
  outside the convex hull NaN, or the nearest node with ``extrapolate="nearest"``;
* neural networks (strategies 1-4): input and output scaling and the weights of the tanh
  hidden layer and linear output of both nets, plus the ideal or optimised model they use;
* ideal and optimised geometric models: their constants.

Cubic interpolation is refused: scipy's Clough-Tocher interpolant builds its cubic patches from
gradients estimated globally over the table, which this exporter does not reproduce; export a
polynomial or a linear interpolation instead. Trigonometric calibrations are refused too (they
need ``sin``/``cos``, and are the paper's worst method).

Examples
--------
>>> import tempfile, pathlib
>>> from sunlab import sim
>>> from sunlab.calibration import Polynomial
>>> cen = sim.synthetic_centroids([0.0, 1, 2, 0, 1, 2], [0.0, 0, 0, 1, 1, 1])
>>> out = pathlib.Path(tempfile.mkdtemp())
>>> [p.name for p in export(Polynomial(order=1).fit(cen), out)]
['sunlab_calibration.h', 'sunlab_calibration.c']
>>> "int sunlab_calibration_evalf(float x_px" in (out / "sunlab_calibration.h").read_text()
True
"""

from __future__ import annotations

import math
import shutil
import subprocess
from pathlib import Path

import numpy as np

from .errors import ConfigurationError

__all__ = ["export", "check_c"]

#: Return values of the exported C functions.
FLAGS = {"ok": 0, "outside": 1, "undefined": 2, "bad_input": 3}
#: Export formats.
FORMATS = ("c", "json")
#: Base name of the exported C files.
BASENAME = "sunlab_calibration"

_HEADER_GUARD = "SUNLAB_CALIBRATION_H"


class _Prec:
    """Spelling of one precision in C: type, literal suffix, math functions."""

    def __init__(self, kind: str):
        self.double = kind == "d"
        self.t = "double" if self.double else "float"
        self.tag = "d" if self.double else "f"
        self.fn_suffix = "" if self.double else "f"

    def lit(self, value: float) -> str:
        """A C literal of ``value`` in this precision (round trip exact)."""
        value = float(value)
        if not math.isfinite(value):
            raise ConfigurationError(f"parameter value {value!r}: not finite, cannot export")
        if self.double:
            text = repr(value)
        else:
            text = repr(float(np.float32(value)))
        if "e" not in text and "." not in text and "inf" not in text:
            text += ".0"
        return text + ("" if self.double else "f")

    def split(self, value: float) -> tuple[str, str]:
        """``value`` as hi + lo literals: ``(x - hi) - lo`` keeps single precision exact."""
        if self.double:
            return self.lit(value), self.lit(0.0)
        hi = float(np.float32(value))
        return self.lit(hi), self.lit(value - hi)

    def fn(self, name: str) -> str:
        return name + self.fn_suffix

    def array(self, name: str, values, per_line: int = 4) -> str:
        """``static const T name[n] = {...};`` from a flat sequence."""
        flat = [self.lit(v) for v in np.asarray(values, dtype=float).ravel()]
        return _c_array(f"static const {self.t} {name}_{self.tag}[{len(flat)}]", flat, per_line)


def _c_array(decl: str, items: list[str], per_line: int) -> str:
    lines = [", ".join(items[i:i + per_line]) for i in range(0, len(items), per_line)]
    return decl + " = {\n    " + ",\n    ".join(lines or ["0"]) + "\n};\n"


# --------------------------------------------------------------------------------------------
# Building blocks shared by the methods
# --------------------------------------------------------------------------------------------
def _box(cal, P: _Prec) -> str:
    """Code setting ``flag`` to 1 outside the training box of the centroids."""
    (x0, x1), (y0, y1) = cal.domain["x"], cal.domain["y"]
    return (f"    int flag = (x_px < {P.lit(x0)} || x_px > {P.lit(x1)} || y_px < {P.lit(y0)} "
            f"|| y_px > {P.lit(y1)}) ? 1 : 0;\n")


def _ideal_fn(P: _Prec) -> str:
    """Eq. (1): angles (deg) from a centroid, with cos(atan t) = 1 / sqrt(1 + t^2)."""
    T, f = P.t, P.fn
    return f"""
/* Ideal pinhole model, eq. (1): tan a = (x - x_cf) p / F, tan b = (y - y_cf) p cos a / F. */
static void ideal_{P.tag}({T} x, {T} y, {T} xc_hi, {T} xc_lo, {T} yc_hi, {T} yc_lo, {T} k,
                         {T} *a_deg, {T} *b_deg)
{{
    {T} t = ((x - xc_hi) - xc_lo) / k;
    {T} cos_a = {P.lit(1.0)} / {f("sqrt")}({P.lit(1.0)} + t * t);
    *a_deg = {f("atan")}(t) * {P.lit(180.0 / math.pi)};
    *b_deg = {f("atan")}(((y - yc_hi) - yc_lo) * cos_a / k) * {P.lit(180.0 / math.pi)};
}}
"""


def _ideal_call(P: _Prec, sensor: dict, x: str, y: str, a: str, b: str) -> str:
    k = sensor["mask_distance_mm"] / sensor["pixel_pitch_mm"]
    xh, xl = P.split(sensor["x_cf_px"])
    yh, yl = P.split(sensor["y_cf_px"])
    return f"ideal_{P.tag}({x}, {y}, {xh}, {xl}, {yh}, {yl}, {P.lit(k)}, &{a}, &{b});\n"


def _atan2_fn(P: _Prec) -> str:
    """atan2 from atan (the only inverse tangent the exported code may use)."""
    T, f, pi = P.t, P.fn, math.pi
    return f"""
static {T} atan2_{P.tag}({T} y, {T} x)
{{
    if (x > {P.lit(0.0)})
        return {f("atan")}(y / x);
    if (x < {P.lit(0.0)})
        return {f("atan")}(y / x) + (y >= {P.lit(0.0)} ? {P.lit(pi)} : {P.lit(-pi)});
    if (y > {P.lit(0.0)})
        return {P.lit(pi / 2)};
    return y < {P.lit(0.0)} ? {P.lit(-pi / 2)} : {P.lit(0.0)};
}}
"""


def _optimised_helpers(mounting: str, P: _Prec) -> str:
    return _atan2_fn(P) if mounting == "rotation" else _ideal_fn(P)


def _optimised_call(P: _Prec, fit, x: str, y: str, a: str, b: str,
                    mounting: str | None = None) -> str:
    """Eqs. (3)-(4) with the fitted dF, alpha0, beta0 and zero pose: code setting a, b (deg).

    ``mounting`` "rotation": s = M^T ((x_cf - x) p / F', (y_cf - y) p / F', 1), alpha =
    atan2(-s_x, s_z), beta = asin(-s_y / |s|) = atan(-s_y / sqrt(s_x^2 + s_z^2)), as
    :func:`sunlab.geometry.optimised_angles`; "additive": eq. (1) at F + dF minus the offsets.
    """
    from .geometry.model import hole_foot, mounting_matrix

    mounting = mounting or getattr(fit, "mounting", "additive")
    x_cf, y_cf = hole_foot(fit.mask_distance_mm, fit.pixel_pitch_mm, fit.delta_f_mm,
                               fit.alpha0, fit.beta0, fit.x_zp, fit.y_zp, mounting)
    k = (fit.mask_distance_mm + fit.delta_f_mm) / fit.pixel_pitch_mm
    if mounting != "rotation":
        sensor = {"mask_distance_mm": fit.mask_distance_mm + fit.delta_f_mm,
                  "pixel_pitch_mm": fit.pixel_pitch_mm, "x_cf_px": float(x_cf),
                  "y_cf_px": float(y_cf)}
        return (_ideal_call(P, sensor, x, y, a, b)
                + f"    {a} -= {P.lit(fit.alpha0)};\n    {b} -= {P.lit(fit.beta0)};\n")
    T, f, tag = P.t, P.fn, P.tag
    M = mounting_matrix(fit.alpha0, fit.beta0)
    xh, xl = P.split(float(x_cf))
    yh, yl = P.split(float(y_cf))
    r2d = P.lit(180.0 / math.pi)
    s_terms = [f"t0 * {P.lit(M[0, j])} + t1 * {P.lit(M[1, j])} + {P.lit(M[2, j])}"
               for j in range(3)]
    return f"""{{   /* optimised model (3)-(4), rigid mounting rotation */
        {T} t0 = (({xh} - {x}) + {xl}) / {P.lit(k)};
        {T} t1 = (({yh} - {y}) + {yl}) / {P.lit(k)};
        {T} s0 = {s_terms[0]};
        {T} s1 = {s_terms[1]};
        {T} s2 = {s_terms[2]};
        {a} = atan2_{tag}(-s0, s2) * {r2d};
        {b} = {f("atan")}(-s1 / {f("sqrt")}(s0 * s0 + s2 * s2)) * {r2d};
    }}
"""


# --------------------------------------------------------------------------------------------
# One generator per method: tables + the body of eval (sets *alpha_deg, *beta_deg, returns)
# --------------------------------------------------------------------------------------------
def _polynomial(cal, P: _Prec) -> tuple[str, str]:
    from .calibration.polynomial import monomial_exponents

    T = P.t
    tables = f"""
/* Horner's rule in u of Horner polynomials in v; c[i * (n + 1) + j] multiplies u^i v^j. */
static {T} poly_{P.tag}(const {T} *c, int n, {T} u, {T} v)
{{
    {T} acc = {P.lit(0.0)};
    int i, j;
    for (i = n; i >= 0; --i) {{
        {T} p = {P.lit(0.0)};
        for (j = n - i; j >= 0; --j)
            p = p * v + c[i * (n + 1) + j];
        acc = acc * u + p;
    }}
    return acc;
}}
"""
    body = _box(cal, P)
    for axis in ("x", "y"):
        lo, hi = cal.scaling[axis]
        ch, cl = P.split((lo + hi) / 2.0)
        body += (f"    {T} {'u' if axis == 'x' else 'v'} = (({axis}_px - {ch}) - {cl}) * "
                 f"{P.lit(2.0 / (hi - lo))};\n")
    for angle, n in zip(("alpha", "beta"), cal.orders, strict=True):
        grid = np.zeros((n + 1, n + 1))
        for (i, j), c in zip(monomial_exponents(n), cal.coefficients[angle], strict=True):
            grid[i, j] = c
        tables += P.array(f"coef_{angle}", grid, per_line=n + 1)
        body += f"    *{angle}_deg = poly_{P.tag}(coef_{angle}_{P.tag}, {n}, u, v);\n"
    return tables, body + "    return flag;\n"


def _interpolation(cal, P: _Prec) -> tuple[str, str]:
    if cal.method != "linear":
        raise ConfigurationError(
            f"calibration kind {cal.kind!r}: cubic interpolation is not exported to C. scipy's "
            "Clough-Tocher interpolant builds its cubic patches from gradients estimated over "
            "the whole table, which this exporter does not reproduce. Fix: export a polynomial "
            "(sunlab calibrate --method polynomial) or a linear interpolation (--method linear)"
        )
    T, tag = P.t, P.tag
    interp = cal._interp
    tri = interp.tri
    trans = np.concatenate([tri.transform[:, :2, :].reshape(-1, 4),
                            tri.transform[:, 2, :]], axis=1)  # inverse matrix, then r
    # degenerate (flat) triangles have no transform (NaN); scipy never selects them either
    keep = np.isfinite(trans).all(axis=1)
    trans, simplices = trans[keep], tri.simplices[keep]
    n_tri, n_nodes = len(simplices), len(cal.nodes["x"])
    z = (np.column_stack([cal.nodes["x"], cal.nodes["y"]]) - interp.offset) / interp.scale
    eps = 100 * (np.finfo(float).eps if P.double else np.finfo(np.float32).eps)
    tables = P.array("tri_transform", trans, per_line=6)
    tables += _c_array(f"static const int tri_vertex_{tag}[{3 * n_tri}]",
                       [str(int(v)) for v in simplices.ravel()], 12)
    tables += P.array("node_angle", np.asarray(interp.values, dtype=float), per_line=4)
    if cal.extrapolate == "nearest":
        tables += P.array("node_z", z, per_line=4)
    oxh, oxl = P.split(interp.offset[0])
    oyh, oyl = P.split(interp.offset[1])
    body = f"""    /* scipy's plane: (centroid - mean of the nodes) / their span */
    {T} z0 = ((x_px - {oxh}) - {oxl}) / {P.lit(interp.scale[0])};
    {T} z1 = ((y_px - {oyh}) - {oyl}) / {P.lit(interp.scale[1])};
    int s;
    for (s = 0; s < {n_tri}; ++s) {{
        const {T} *t = tri_transform_{tag} + 6 * s;
        {T} c0 = t[0] * (z0 - t[4]) + t[1] * (z1 - t[5]);
        {T} c1 = t[2] * (z0 - t[4]) + t[3] * (z1 - t[5]);
        {T} c2 = {P.lit(1.0)} - c0 - c1;
        if (c0 >= {P.lit(-eps)} && c1 >= {P.lit(-eps)} && c2 >= {P.lit(-eps)}) {{
            const int *v = tri_vertex_{tag} + 3 * s;
            *alpha_deg = c0 * node_angle_{tag}[2 * v[0]] + c1 * node_angle_{tag}[2 * v[1]]
                         + c2 * node_angle_{tag}[2 * v[2]];
            *beta_deg = c0 * node_angle_{tag}[2 * v[0] + 1] + c1 * node_angle_{tag}[2 * v[1] + 1]
                        + c2 * node_angle_{tag}[2 * v[2] + 1];
            return 0;
        }}
    }}
"""
    if cal.extrapolate == "nearest":
        body += f"""    {{   /* outside the convex hull: the nearest node (extrapolate="nearest") */
        int i, best = 0;
        {T} d_best = {P.lit(0.0)};
        for (i = 0; i < {n_nodes}; ++i) {{
            {T} dx = z0 - node_z_{tag}[2 * i], dy = z1 - node_z_{tag}[2 * i + 1];
            {T} d = dx * dx + dy * dy;
            if (i == 0 || d < d_best) {{ d_best = d; best = i; }}
        }}
        *alpha_deg = node_angle_{tag}[2 * best];
        *beta_deg = node_angle_{tag}[2 * best + 1];
        return 1;
    }}
"""
    else:
        body += f"""    *alpha_deg = ({T})NAN;   /* outside the convex hull: no extrapolation */
    *beta_deg = ({T})NAN;
    return 2;
"""
    return tables, body


def _neural(cal, P: _Prec) -> tuple[str, str]:
    T, tag, f = P.t, P.tag, P.fn
    h = cal.hidden
    tables = ""
    if cal.strategy in (2, 4):
        tables += _ideal_fn(P)
    if cal.strategy == 3:  # as NeuralNet._inputs: geometry.optimised_angles' default mounting
        tables += _optimised_helpers("rotation", P)
    tables += f"""
/* One network: tanh hidden layer of {h} neurons, linear output (standardised units). */
static {T} net_{tag}(const {T} *w1, const {T} *b1, const {T} *w2, {T} b2, {T} z0, {T} z1)
{{
    {T} out = b2;
    int i;
    for (i = 0; i < {h}; ++i)
        out += w2[i] * {f("tanh")}(w1[2 * i] * z0 + w1[2 * i + 1] * z1 + b1[i]);
    return out;
}}
"""
    body = _box(cal, P)
    if cal.strategy in (1, 4):
        body += f"    {T} in0 = x_px, in1 = y_px;\n"
    elif cal.strategy == 2:
        body += f"    {T} in0, in1;\n    " + _ideal_call(P, cal.sensor, "x_px", "y_px", "in0",
                                                         "in1")
    else:
        body += f"    {T} in0, in1;\n    " + _optimised_call(P, cal.optimised, "x_px", "y_px",
                                                             "in0", "in1", mounting="rotation")
    mean, std = cal.input_scaling["mean"], cal.input_scaling["std"]
    for k in range(2):
        mh, ml = P.split(mean[k])
        body += f"    {T} z{k} = ((in{k} - {mh}) - {ml}) / {P.lit(std[k])};\n"
    for angle in ("alpha", "beta"):
        net = cal.networks[angle]
        tables += P.array(f"w1_{angle}", net["W1"], per_line=2)
        tables += P.array(f"b1_{angle}", net["b1"])
        tables += P.array(f"w2_{angle}", net["W2"])
        body += (f"    *{angle}_deg = net_{tag}(w1_{angle}_{tag}, b1_{angle}_{tag}, "
                 f"w2_{angle}_{tag}, {P.lit(net['b2'])}, z0, z1) * {P.lit(net['target_std'])} "
                 f"+ {P.lit(net['target_mean'])};\n")
    if cal.strategy == 4:
        body += (f"    {{\n        {T} ia, ib;\n        "
                 + _ideal_call(P, cal.sensor, "x_px", "y_px", "ia", "ib")
                 + "        *alpha_deg += ia;\n        *beta_deg += ib;\n    }\n")
    return tables, body + "    return flag;\n"


def _ideal(cal, P: _Prec) -> tuple[str, str]:
    body = _box(cal, P) + "    " + _ideal_call(P, cal.sensor, "x_px", "y_px", "*alpha_deg",
                                               "*beta_deg").replace("&*", "")
    return _ideal_fn(P), body + "    return flag;\n"


def _optimised(cal, P: _Prec) -> tuple[str, str]:
    T = P.t
    body = _box(cal, P) + f"    {T} a, b;\n    " + _optimised_call(P, cal.result, "x_px",
                                                                     "y_px", "a", "b")
    body += "    *alpha_deg = a;\n    *beta_deg = b;\n"
    mounting = getattr(cal.result, "mounting", "additive")
    return _optimised_helpers(mounting, P), body + "    return flag;\n"


_GENERATORS = {
    "polynomial": _polynomial,
    "interpolation-linear": _interpolation,
    "interpolation-cubic": _interpolation,
    "neural": _neural,
    "ideal": _ideal,
    "optimised": _optimised,
}


def _load(cal):
    from .calibration import Calibration, load

    if isinstance(cal, Calibration):
        cal.check_fitted()
        return cal
    return load(cal)


def c_sources(cal) -> tuple[str, str]:
    """The text of ``sunlab_calibration.h`` and ``sunlab_calibration.c`` for a calibration.

    Parameters
    ----------
    cal : sunlab.calibration.Calibration or path-like
        A fitted calibration, or the path of its JSON file.

    Returns
    -------
    header, source : str

    Raises
    ------
    ConfigurationError
        For a method that is not exported (cubic interpolation, trigonometric), with the reason.
    """
    from . import __version__

    cal = _load(cal)
    if cal.kind not in _GENERATORS:
        raise ConfigurationError(
            f"calibration kind {cal.kind!r}: not exported to C (a trigonometric calibration "
            "needs sin/cos, and is the paper's least accurate method). Fix: export a "
            "polynomial, a linear interpolation, a neural network or a geometric model"
        )
    about = _about(cal)
    header = f"""/* {BASENAME}.h - generated by sunlab {__version__} (sunlab export --format c).
 *
{about} *
 * Centroid (x_px = column, y_px = row, pixels, centre of the first pixel = 0) -> platform
 * angles (alpha_deg, beta_deg, degrees). Self-contained C99: constant tables, no allocation,
 * only <math.h>. The return value is 0 inside the calibrated domain, non-zero outside it:
 */
#ifndef {_HEADER_GUARD}
#define {_HEADER_GUARD}

#define SUNLAB_CALIBRATION_OK 0        /* inside the calibrated domain */
#define SUNLAB_CALIBRATION_OUTSIDE 1   /* outside the domain: angles extrapolated */
#define SUNLAB_CALIBRATION_UNDEFINED 2 /* outside the domain, no extrapolation: angles NaN */
#define SUNLAB_CALIBRATION_BAD_INPUT 3 /* non-finite centroid: angles NaN */

#ifdef __cplusplus
extern "C" {{
#endif

/* Double precision (matches sunlab's Python predict to ~1e-12 deg). */
int sunlab_calibration_eval(double x_px, double y_px, double *alpha_deg, double *beta_deg);

/* Single precision, for a single-precision FPU (its own float tables). */
int sunlab_calibration_evalf(float x_px, float y_px, float *alpha_deg, float *beta_deg);

#ifdef __cplusplus
}}
#endif

#endif /* {_HEADER_GUARD} */
"""
    return header, _c_source(cal, about)


def _comment(text, limit: int = 200) -> str:
    """``text`` made safe inside a C block comment: printable ASCII but the backslash, no
    comment delimiter, no trigraph, at most ``limit`` characters (strings read from a file must
    never close the comment and become code).

    Examples
    --------
    >>> _comment("I */ int evil(void) { return 1; } /* ??/")
    'I * / int evil(void) { return 1; } / * ? ?/'
    """
    text = "".join(ch if " " <= ch <= "~" and ch != "\\" else "?" for ch in str(text))
    while "*/" in text or "/*" in text or "??" in text:
        text = text.replace("*/", "* /").replace("/*", "/ *").replace("??", "? ?")
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _about(cal) -> str:
    """The comment lines that describe the calibration: method, training, domain."""
    (x0, x1), (y0, y1) = cal.domain["x"], cal.domain["y"]
    domain = ("the convex hull of the calibration table's nodes"
              if cal.kind.startswith("interpolation") else
              f"x in [{x0:.6g}, {x1:.6g}] px, y in [{y0:.6g}, {y1:.6g}] px")
    training = cal.training or {}
    about = (f" * Calibration: {_comment(cal.label)} (kind {_comment(repr(cal.kind))}), fitted "
             f"on {_comment(training.get('n_poses', '?'))} poses of experiment "
             f"{_comment(repr(training.get('experiment') or '?'))}.\n"
             f" * Domain: {domain}\n"
             f" *   (alpha in [{cal.domain['alpha'][0]:.6g}, {cal.domain['alpha'][1]:.6g}] deg, "
             f"beta in [{cal.domain['beta'][0]:.6g}, {cal.domain['beta'][1]:.6g}] deg).\n")
    return about


def _c_source(cal, about: str) -> str:
    """The text of ``sunlab_calibration.c``: the evaluation function in double and in
    single precision, each with its own tables."""
    from . import __version__

    parts = [f"""/* {BASENAME}.c - generated by sunlab {__version__}; see {BASENAME}.h.
 *
{about} */
#include <math.h>
#include "{BASENAME}.h"
"""]
    for kind in ("d", "f"):
        P = _Prec(kind)
        tables, body = _GENERATORS[cal.kind](cal, P)
        name = "sunlab_calibration_eval" + ("" if P.double else "f")
        parts.append(f"""
/* ===================== {P.t} precision ===================== */
{tables}
int {name}({P.t} x_px, {P.t} y_px, {P.t} *alpha_deg, {P.t} *beta_deg)
{{
    if (!isfinite(x_px) || !isfinite(y_px)) {{
        *alpha_deg = ({P.t})NAN;
        *beta_deg = ({P.t})NAN;
        return SUNLAB_CALIBRATION_BAD_INPUT;
    }}
    {{
{body}    }}
}}
""")
    return "".join(parts)


def export_c(cal, out, *, overwrite: bool = False) -> tuple[Path, Path]:
    """Write ``out/sunlab_calibration.h`` and ``out/sunlab_calibration.c``; return the paths.

    See the module docstring for what each method exports and :func:`c_sources`. Existing
    files are replaced only with ``overwrite=True``.

    Parameters
    ----------
    cal : sunlab.calibration.Calibration or path-like
        A fitted calibration, or the path of its JSON file.
    out : str or path-like
        The output folder (created if missing); both files are moved in together.
    overwrite : bool
        Replace existing files of the same names.

    Returns
    -------
    header : pathlib.Path
        ``out/sunlab_calibration.h``.
    source : pathlib.Path
        ``out/sunlab_calibration.c``.

    Raises
    ------
    ConfigurationError
        For a method that is not exported (:func:`c_sources`).
    OutputExistsError
        A file exists and ``overwrite`` is False (checked before anything is written).
    """
    from . import atomic

    header, source = c_sources(cal)
    out = Path(out)
    h, c = out / f"{BASENAME}.h", out / f"{BASENAME}.c"
    # both files or neither: a header never lands beside another export's source
    with atomic.atomic_files(out, [h.name, c.name], overwrite=overwrite,
                             flag="--overwrite") as tmp:
        (tmp / h.name).write_text(header, encoding="utf-8")
        (tmp / c.name).write_text(source, encoding="utf-8")
    return h, c


def export(cal, out, format: str = "c", *, overwrite: bool = False) -> list[Path]:
    """Export a calibration: ``"c"`` (header + source, :func:`export_c`) or ``"json"``.

    Parameters
    ----------
    cal : sunlab.calibration.Calibration or path-like
        A fitted calibration or its JSON file.
    out : path-like
        Output folder (created); ``"json"`` writes ``out/sunlab_calibration.json``, the
        interchange format (contract ``calibration/1``).
    format : {"c", "json"}
    overwrite : bool
        Replace existing files.

    Returns
    -------
    list of pathlib.Path
        The files written.
    """
    if format not in FORMATS:
        raise ConfigurationError(f"format: found {format!r}, expected one of {FORMATS}")
    cal = _load(cal)
    if format == "c":
        return list(export_c(cal, out, overwrite=overwrite))
    from . import atomic

    name = f"{BASENAME}.json"
    with atomic.atomic_files(out, [name], overwrite=overwrite, flag="--overwrite") as tmp:
        cal.save(tmp / name)
    return [Path(out) / name]


def find_c_compiler() -> str | None:
    """The system C compiler (``cc``, ``gcc`` or ``clang`` on the PATH), or None.

    Returns
    -------
    str or None
        The full path of the first of ``cc``, ``gcc``, ``clang`` found; None when none is.
    """
    for name in ("cc", "gcc", "clang"):
        path = shutil.which(name)
        if path:
            return path
    return None


_DRIVER = """#include <stdio.h>
#include "sunlab_calibration.h"
int main(void)
{
    double x, y, a, b;
    while (scanf("%lf %lf", &x, &y) == 2) {
        float af, bf;
        int flag = sunlab_calibration_eval(x, y, &a, &b);
        int flagf = sunlab_calibration_evalf((float)x, (float)y, &af, &bf);
        printf("%d %.17g %.17g %d %.9g %.9g\\n", flag, a, b, flagf, (double)af, (double)bf);
    }
    return 0;
}
"""


def run_c(folder, x, y, *, cc: str | None = None, timeout: float = 60.0) -> dict:
    """Compile the exported C in ``folder`` with a small driver and evaluate it at points.

    A check of an export against :meth:`Calibration.predict_xy`: compiles with
    ``-std=c99 -O2 -Wall -Wextra -Werror`` and links only ``-lm``.

    Parameters
    ----------
    folder : path-like
        Folder holding ``sunlab_calibration.h`` and ``sunlab_calibration.c``.
    x, y : array_like
        Centroids, px.
    cc : str, optional
        The compiler; default :func:`find_c_compiler`.

    Returns
    -------
    dict
        ``alpha``, ``beta``, ``flag`` from the double function; ``alpha_f``, ``beta_f``,
        ``flag_f`` from the float one (called with ``x``, ``y`` rounded to float).
    """
    cc = cc or find_c_compiler()
    if cc is None:
        raise ConfigurationError(
            "cc: no C compiler found on the PATH (cc, gcc, clang). Fix: install one "
            "(e.g. apt-get install gcc) or compile the exported files on the target"
        )
    import tempfile

    folder = Path(folder)
    # the driver (with its main()) and the executable are built in a folder of their own,
    # never among the deliverables
    build = Path(tempfile.mkdtemp(prefix="sunlab-check-"))
    try:
        return _compile_and_run(cc, folder, build, x, y, timeout)
    finally:
        shutil.rmtree(build, ignore_errors=True)


def _compile_and_run(cc: str, folder: Path, build: Path, x, y, timeout: float) -> dict:
    (build / "sunlab_driver.c").write_text(_DRIVER, encoding="utf-8")
    exe = build / "sunlab_driver"
    cmd = [cc, "-std=c99", "-O2", "-Wall", "-Wextra", "-Werror", "-pedantic", "-I", str(folder),
           "-o", str(exe), str(build / "sunlab_driver.c"), str(folder / f"{BASENAME}.c"), "-lm"]
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, check=False)
    if done.returncode:
        raise ConfigurationError(f"{' '.join(cmd)} failed:\n{done.stderr}")
    x = np.asarray(x, dtype=float).ravel()
    y = np.asarray(y, dtype=float).ravel()
    stdin = "".join(f"{a!r} {b!r}\n" for a, b in zip(x.tolist(), y.tolist(), strict=True))
    run = subprocess.run([str(exe)], input=stdin, capture_output=True, text=True,
                         timeout=timeout, check=True)
    rows = np.array([line.split() for line in run.stdout.splitlines()], dtype=float)
    rows = rows.reshape(-1, 6)
    return {"flag": rows[:, 0].astype(int), "alpha": rows[:, 1], "beta": rows[:, 2],
            "flag_f": rows[:, 3].astype(int), "alpha_f": rows[:, 4], "beta_f": rows[:, 5]}


def check_c(cal, folder, n: int = 1000, *, seed: int = 0, cc: str | None = None) -> dict:
    """Compile an export and compare it with Python ``predict_xy`` on ``n`` points.

    The points are drawn uniformly in the box of the training centroids (``domain['x']`` x
    ``domain['y']``) widened by 10 % on each side, so that some fall outside the domain; the
    float function is compared with Python at the float-rounded centroids (the rounding of the
    input is the caller's, not the export's).

    Parameters
    ----------
    cal : sunlab.calibration.Calibration or path-like
        The fitted calibration that was exported, or the path of its JSON file.
    folder : str or path-like
        The folder :func:`export_c` wrote.
    n : int
        Number of test centroids.
    seed : int
        Seed of the points' draw.
    cc : str, optional
        The compiler; default :func:`find_c_compiler`.

    Returns
    -------
    dict
        ``max_error_double``, ``max_error_float`` (deg, over the points where Python gives a
        finite angle), ``flags_agree`` (the C flag is 0 exactly where
        :meth:`~sunlab.calibration.Calibration.inside` is True,
        for both precisions), ``nan_agree`` (NaN where Python gives NaN), ``n``,
        ``n_outside``, ``compiler``.
    """
    cal = _load(cal)
    rng = np.random.default_rng(seed)
    (x0, x1), (y0, y1) = cal.domain["x"], cal.domain["y"]
    x = rng.uniform(x0 - 0.1 * (x1 - x0), x1 + 0.1 * (x1 - x0), n)
    y = rng.uniform(y0 - 0.1 * (y1 - y0), y1 + 0.1 * (y1 - y0), n)
    compiler = cc or find_c_compiler()
    got = run_c(folder, x, y, cc=compiler)
    a, b = cal.predict_xy(x, y)
    xf, yf = (v.astype(np.float32).astype(float) for v in (x, y))
    af, bf = cal.predict_xy(xf, yf)
    fin, finf = np.isfinite(a), np.isfinite(af)
    inside, insidef = cal.inside(x, y), cal.inside(xf, yf)
    err64 = np.abs(np.concatenate([got["alpha"] - a, got["beta"] - b])[np.r_[fin, fin]])
    err32 = np.abs(np.concatenate([got["alpha_f"] - af, got["beta_f"] - bf])[np.r_[finf, finf]])
    return {
        "n": int(n), "n_outside": int((~inside).sum()), "compiler": compiler,
        "max_error_double": float(err64.max()) if err64.size else float("nan"),
        "max_error_float": float(err32.max()) if err32.size else float("nan"),
        "flags_agree": bool(np.array_equal(got["flag"] == 0, inside)
                            and np.array_equal(got["flag_f"] == 0, insidef)),
        "nan_agree": bool(np.array_equal(np.isnan(got["alpha"]), ~fin)
                          and np.array_equal(np.isnan(got["alpha_f"]), ~finf)),
    }
