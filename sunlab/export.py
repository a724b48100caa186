"""Export a fitted calibration for on-board use: self-contained C99, or the JSON artifact.

The C (header and source; no allocation, only ``<math.h>``) declares ``sunlab_calibration_eval``
(double) and ``sunlab_calibration_evalf`` (float, own tables): centroid (px) to angles (deg),
returning :data:`FLAGS` (inside the domain of :meth:`~sunlab.calibration.Calibration.inside`,
outside and extrapolated, outside and NaN, non-finite input). Polynomials, linear
interpolation, networks and geometric models are exported; cubic interpolation (scipy's
Clough-Tocher gradients are global) and the trigonometric expansion (sin/cos) are refused.

Examples
--------
>>> import tempfile, pathlib
>>> from sunlab import sim
>>> from sunlab.calibration import Polynomial
>>> cen = sim.synthetic_centroids([0.0, 1, 2, 0, 1, 2], [0.0, 0, 0, 1, 1, 1])
>>> out = pathlib.Path(tempfile.mkdtemp())
>>> [p.name for p in export(Polynomial(order=1).fit(cen), out)]
['sunlab_calibration.h', 'sunlab_calibration.c']
"""

from __future__ import annotations

import math
import shutil
import subprocess
import tempfile
from pathlib import Path

import numpy as np

from . import __version__, atomic
from .errors import ConfigurationError

__all__ = ["export"]

#: Return values of the exported C functions; the export formats; the files' base name.
FLAGS = {"ok": 0, "outside": 1, "undefined": 2, "bad_input": 3}
FORMATS, BASENAME, _R2D = ("c", "json"), "sunlab_calibration", 180.0 / math.pi


class _Prec:
    """Spelling of one precision in C: type, literal suffix, math functions."""

    def __init__(self, double: bool):
        self.double, self.t, self.tag = double, ("float", "double")[double], "fd"[double]

    def lit(self, value: float) -> str:
        """A C literal of ``value`` in this precision (round trip exact)."""
        value = float(value)
        if not (math.isfinite(value) and (self.double or abs(value) <= 3.4028234663852886e38)):
            raise ConfigurationError(f"parameter value {value!r}: not a finite {self.t} (a float"
                                     " is at most 3.4e+38), cannot export. Fix: re-fit")
        text = repr(value if self.double else float(np.float32(value)))
        return (text if "e" in text or "." in text else text + ".0") + ("" if self.double else "f")

    def split(self, value: float, var: str | None = None) -> str:
        """``value`` as ``hi, lo`` literals, or ``((var - hi) - lo)``: exact in float too."""
        hi = float(value) if self.double else float(np.float32(value))
        hi, lo = self.lit(hi), self.lit(float(value) - hi)
        return f"{hi}, {lo}" if var is None else f"(({var} - {hi}) - {lo})"

    def fn(self, name: str) -> str:  # the math function of this precision
        return name + ("" if self.double else "f")

    def array(self, name: str, values, per_line: int = 4) -> str:
        """``static const T name_tag[n] = {...};`` from a flat sequence."""
        flat = [self.lit(v) for v in np.asarray(values, dtype=float).ravel()]
        return _c_array(f"static const {self.t} {name}_{self.tag}[{len(flat)}]", flat, per_line)


def _c_array(decl: str, items: list[str], per_line: int) -> str:
    lines = [", ".join(items[i:i + per_line]) for i in range(0, len(items), per_line)]
    return decl + " = {\n    " + ",\n    ".join(lines or ["0"]) + "\n};\n"


def _box(cal, P: _Prec) -> str:
    """Code setting ``flag`` to 1 outside the training box of the centroids."""
    (x0, x1), (y0, y1) = cal.domain["x"], cal.domain["y"]
    return (f"    int flag = (x_px < {P.lit(x0)} || x_px > {P.lit(x1)} || y_px < {P.lit(y0)} "
            f"|| y_px > {P.lit(y1)}) ? 1 : 0;\n")


def _ideal_fn(P: _Prec) -> str:
    """Eq. (1): angles (deg) from a centroid, with cos(atan t) = 1 / sqrt(1 + t^2)."""
    T, f, one = P.t, P.fn, P.lit(1.0)
    return f"""
/* Ideal pinhole model, eq. (1): tan a = (x - x_cf) p / F, tan b = (y - y_cf) p cos a / F. */
static void ideal_{P.tag}({T} x, {T} y, {T} xc_hi, {T} xc_lo, {T} yc_hi, {T} yc_lo, {T} k,
                         {T} *a_deg, {T} *b_deg)
{{
    {T} t = ((x - xc_hi) - xc_lo) / k, cos_a = {one} / {f("sqrt")}({one} + t * t);
    *a_deg = {f("atan")}(t) * {P.lit(_R2D)};
    *b_deg = {f("atan")}(((y - yc_hi) - yc_lo) * cos_a / k) * {P.lit(_R2D)};
}}
"""


def _ideal_call(P: _Prec, s: dict, a: str, b: str) -> str:
    k = P.lit(s["mask_distance_mm"] / s["pixel_pitch_mm"])
    return (f"ideal_{P.tag}(x_px, y_px, {P.split(s['x_cf_px'])}, {P.split(s['y_cf_px'])}, {k}, "
            f"{a}, {b});\n")


def _atan2_fn(P: _Prec) -> str:
    """atan2 from atan (the only inverse tangent the exported code may use)."""
    T, f, zero, pi = P.t, P.fn, P.lit(0.0), math.pi
    return f"""
static {T} atan2_{P.tag}({T} y, {T} x)
{{
    if (x > {zero}) return {f("atan")}(y / x);
    if (x < {zero}) return {f("atan")}(y / x) + (y >= {zero} ? {P.lit(pi)} : {P.lit(-pi)});
    return y > {zero} ? {P.lit(pi / 2)} : (y < {zero} ? {P.lit(-pi / 2)} : {zero});
}}
"""


def _optimised_call(P: _Prec, fit, a: str, b: str, mounting: str) -> str:
    """Code setting a, b (deg) by eqs. (3)-(4) as :func:`sunlab.geometry.model.optimised_angles`:
    rotation mounting, s = M^T ((x_cf - x) p / F', (y_cf - y) p / F', 1), alpha = atan2(-s_x,
    s_z), beta = atan(-s_y / |(s_x, s_z)|); additive, eq. (1) at F + dF minus the offsets."""
    from .geometry.model import hole_foot, mounting_matrix

    x_cf, y_cf = hole_foot(fit.mask_distance_mm, fit.pixel_pitch_mm, fit.delta_f_mm,
                           fit.alpha0, fit.beta0, fit.x_zp, fit.y_zp, mounting)
    f_eff = fit.mask_distance_mm + fit.delta_f_mm
    if mounting != "rotation":
        sensor = {"mask_distance_mm": f_eff, "pixel_pitch_mm": fit.pixel_pitch_mm,
                  "x_cf_px": float(x_cf), "y_cf_px": float(y_cf)}
        return (_ideal_call(P, sensor, "&" + a, "&" + b)
                + f"    {a} -= {P.lit(fit.alpha0)};\n    {b} -= {P.lit(fit.beta0)};\n")
    T, k, r2d = P.t, P.lit(f_eff / fit.pixel_pitch_mm), P.lit(_R2D)
    M = mounting_matrix(fit.alpha0, fit.beta0)
    (xh, xl), (yh, yl) = (P.split(float(v)).split(", ") for v in (x_cf, y_cf))
    s = [f"t0 * {P.lit(M[0, j])} + t1 * {P.lit(M[1, j])} + {P.lit(M[2, j])}" for j in range(3)]
    return f"""{{   /* optimised model (3)-(4), rigid mounting rotation */
        {T} t0 = (({xh} - x_px) + {xl}) / {k}, t1 = (({yh} - y_px) + {yl}) / {k};
        {T} s0 = {s[0]};
        {T} s1 = {s[1]}, s2 = {s[2]};
        {a} = atan2_{P.tag}(-s0, s2) * {r2d};
        {b} = {P.fn("atan")}(-s1 / {P.fn("sqrt")}(s0 * s0 + s2 * s2)) * {r2d};
    }}
"""


# One generator per method: (tables, body of eval: sets *alpha_deg, *beta_deg and returns)
def _polynomial(cal, P: _Prec) -> tuple[str, str]:
    from .calibration.polynomial import monomial_exponents

    T = P.t
    tables = f"""
/* Horner's rule in u of Horner polynomials in v; c[i * (n + 1) + j] multiplies u^i v^j. */
static {T} poly_{P.tag}(const {T} *c, int n, {T} u, {T} v)
{{
    {T} acc = {P.lit(0.0)}, p;
    int i, j;
    for (i = n; i >= 0; --i, acc = acc * u + p)
        for (p = {P.lit(0.0)}, j = n - i; j >= 0; --j) p = p * v + c[i * (n + 1) + j];
    return acc;
}}
"""
    body = _box(cal, P)
    for a, var in (("x", "u"), ("y", "v")):
        lo, hi = cal.scaling[a]
        body += f"    {T} {var} = {P.split((lo + hi) / 2, a + '_px')} * {P.lit(2 / (hi - lo))};\n"
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
            "(sunlab calibrate --method polynomial) or a linear interpolation (--method linear)")
    T, tag, interp = P.t, P.tag, cal._interp
    trans = np.concatenate([interp.tri.transform[:, :2, :].reshape(-1, 4),
                            interp.tri.transform[:, 2, :]], 1)
    keep = np.isfinite(trans).all(axis=1)  # flat triangles have no transform: never selected
    trans, simplices, n_tri = trans[keep], interp.tri.simplices[keep], int(keep.sum())
    eps = P.lit(-100 * np.finfo(float if P.double else np.float32).eps)
    tables = (P.array("tri_transform", trans, per_line=6)
              + _c_array(f"static const int tri_vertex_{tag}[{3 * n_tri}]",
                         [str(int(v)) for v in simplices.ravel()], 12)
              + P.array("node_angle", np.asarray(interp.values, dtype=float), per_line=4))
    z = [f"{P.split(interp.offset[k], c + '_px')} / {P.lit(interp.scale[k])}"
         for k, c in enumerate("xy")]
    ang = [" + ".join(f"c{k} * node_angle_{tag}[2 * v[{k}]{off}]" for k in range(3))
           for off in ("", " + 1")]
    body = f"""    /* scipy's plane: (centroid - mean of the nodes) / their span */
    {T} z0 = {z[0]}, z1 = {z[1]};
    int s;
    for (s = 0; s < {n_tri}; ++s) {{
        const {T} *t = tri_transform_{tag} + 6 * s;
        {T} c0 = t[0] * (z0 - t[4]) + t[1] * (z1 - t[5]);
        {T} c1 = t[2] * (z0 - t[4]) + t[3] * (z1 - t[5]);
        {T} c2 = {P.lit(1.0)} - c0 - c1;
        if (c0 >= {eps} && c1 >= {eps} && c2 >= {eps}) {{
            const int *v = tri_vertex_{tag} + 3 * s;
            *alpha_deg = {ang[0]};
            *beta_deg = {ang[1]};
            return 0;
        }}
    }}
"""
    if cal.extrapolate != "nearest":
        return tables, body + f"""    *alpha_deg = *beta_deg = ({T})NAN;   /* outside the hull */
    return 2;
"""
    zs = (np.column_stack([cal.nodes["x"], cal.nodes["y"]]) - interp.offset) / interp.scale
    tables += P.array("node_z", zs, per_line=4)
    return tables, body + f"""    {{   /* outside the hull: the nearest node */
        int i, best = 0;
        {T} d_best = {P.lit(0.0)};
        for (i = 0; i < {len(cal.nodes["x"])}; ++i) {{
            {T} dx = z0 - node_z_{tag}[2 * i], dy = z1 - node_z_{tag}[2 * i + 1];
            {T} d = dx * dx + dy * dy;
            if (i == 0 || d < d_best) {{ d_best = d; best = i; }}
        }}
        *alpha_deg = node_angle_{tag}[2 * best], *beta_deg = node_angle_{tag}[2 * best + 1];
        return 1;
    }}
"""


def _neural(cal, P: _Prec) -> tuple[str, str]:
    T, tag, h = P.t, P.tag, cal.hidden
    tables = {2: _ideal_fn, 3: _atan2_fn, 4: _ideal_fn}.get(cal.strategy, lambda P: "")(P)
    tables += f"""
/* One network: tanh hidden layer of {h} neurons, linear output (standardised units). */
static {T} net_{tag}(const {T} *w1, const {T} *b1, const {T} *w2, {T} b2, {T} z0, {T} z1)
{{
    {T} out = b2;
    int i;
    for (i = 0; i < {h}; ++i)
        out += w2[i] * {P.fn("tanh")}(w1[2 * i] * z0 + w1[2 * i + 1] * z1 + b1[i]);
    return out;
}}
"""
    body = _box(cal, P) + f"    {T} in0 = x_px, in1 = y_px;\n"
    if cal.strategy == 2:
        body += "    " + _ideal_call(P, cal.sensor, "&in0", "&in1")
    elif cal.strategy == 3:
        body += "    " + _optimised_call(P, cal.optimised, "in0", "in1", "rotation")
    for k, (mean, std) in enumerate(zip(*cal.input_scaling.values(), strict=True)):
        body += f"    {T} z{k} = {P.split(mean, f'in{k}')} / {P.lit(std)};\n"
    for angle in ("alpha", "beta"):
        net = cal.networks[angle]
        tables += (P.array(f"w1_{angle}", net["W1"], per_line=2) + P.array(f"b1_{angle}", net["b1"])
                   + P.array(f"w2_{angle}", net["W2"]))
        body += (f"    *{angle}_deg = net_{tag}(w1_{angle}_{tag}, b1_{angle}_{tag}, "
                 f"w2_{angle}_{tag}, {P.lit(net['b2'])}, z0, z1) * {P.lit(net['target_std'])} "
                 f"+ {P.lit(net['target_mean'])};\n")
    if cal.strategy == 4:
        body += (f"    {{\n        {T} ia, ib;\n        " + _ideal_call(P, cal.sensor, "&ia", "&ib")
                 + "        *alpha_deg += ia;\n        *beta_deg += ib;\n    }\n")
    return tables, body + "    return flag;\n"


def _geometric(cal, P: _Prec) -> tuple[str, str]:
    if cal.kind == "ideal":
        return _ideal_fn(P), _box(cal, P) + "    " + _ideal_call(
            P, cal.sensor, "alpha_deg", "beta_deg") + "    return flag;\n"
    mounting = getattr(cal.result, "mounting", "additive")
    body = (_box(cal, P) + f"    {P.t} a, b;\n    " + _optimised_call(P, cal.result, "a", "b",
                                                                      mounting)
            + "    *alpha_deg = a;\n    *beta_deg = b;\n    return flag;\n")
    return (_atan2_fn(P) if mounting == "rotation" else _ideal_fn(P)), body


_GENERATORS = {"polynomial": _polynomial, "interpolation-linear": _interpolation,
               "interpolation-cubic": _interpolation, "neural": _neural, "ideal": _geometric,
               "optimised": _geometric}


def _load(cal):
    from .calibration import Calibration, load

    return cal.check_fitted() or cal if isinstance(cal, Calibration) else load(cal)


def _comment(text, limit: int = 200) -> str:
    """``text`` safe inside a C block comment (printable ASCII but the backslash, no comment
    delimiter, no trigraph, at most ``limit`` characters): a string of a file never becomes code.
    """
    text = "".join(ch if " " <= ch <= "~" and ch != "\\" else "?" for ch in str(text))
    while "*/" in text or "/*" in text or "??" in text:
        text = text.replace("*/", "* /").replace("/*", "/ *").replace("??", "? ?")
    return text if len(text) <= limit else text[: limit - 3] + "..."


def c_sources(cal) -> tuple[str, str]:
    """The texts of ``sunlab_calibration.h`` and ``.c`` for a calibration (or its JSON file).

    Parameters
    ----------
    cal : sunlab.calibration.Calibration or path-like

    Returns
    -------
    header, source : str
    """
    cal = _load(cal)
    if cal.kind not in _GENERATORS:
        raise ConfigurationError(
            f"calibration kind {cal.kind!r}: not exported to C (a trigonometric calibration "
            "needs sin/cos, and is the paper's least accurate method). Fix: export a "
            "polynomial, a linear interpolation, a neural network or a geometric model")
    (x0, x1), (y0, y1), d, t = cal.domain["x"], cal.domain["y"], cal.domain, cal.training or {}
    domain = ("the convex hull of the calibration table's nodes" if cal.kind.startswith(
        "interpolation") else f"x in [{x0:.6g}, {x1:.6g}] px, y in [{y0:.6g}, {y1:.6g}] px")
    about = (f" * Calibration: {_comment(cal.label)} (kind {_comment(repr(cal.kind))}), fitted "
             f"on {_comment(t.get('n_poses', '?'))} poses of experiment "
             f"{_comment(repr(t.get('experiment') or '?'))}.\n * Domain: {domain}\n"
             f" *   (alpha in [{d['alpha'][0]:.6g}, {d['alpha'][1]:.6g}] deg, "
             f"beta in [{d['beta'][0]:.6g}, {d['beta'][1]:.6g}] deg).\n")
    flags = "".join(f"#define SUNLAB_CALIBRATION_{k.upper()} {v}\n" for k, v in FLAGS.items())
    header = f"""/* {BASENAME}.h - generated by sunlab {__version__} (sunlab export --format c).
 *
{about} *
 * Centroid (x_px = column, y_px = row, px; first pixel's centre 0) -> angles (deg), C99.
 */
#ifndef {BASENAME.upper()}_H
#define {BASENAME.upper()}_H
{flags}
#ifdef __cplusplus
extern "C" {{
#endif
int sunlab_calibration_eval(double x_px, double y_px, double *alpha_deg, double *beta_deg);
int sunlab_calibration_evalf(float x_px, float y_px, float *alpha_deg, float *beta_deg);
#ifdef __cplusplus
}}
#endif
#endif
"""
    source = f"/* {BASENAME}.c - generated by sunlab {__version__}; see {BASENAME}.h.\n *\n" \
             f"{about} */\n#include <math.h>\n#include \"{BASENAME}.h\"\n"
    for P in (_Prec(True), _Prec(False)):
        tables, body = _GENERATORS[cal.kind](cal, P)
        source += f"""
/* ===================== {P.t} precision ===================== */
{tables}
int sunlab_calibration_eval{"" if P.double else "f"}({P.t} x_px, {P.t} y_px, {P.t} *alpha_deg, \
{P.t} *beta_deg)
{{
    if (!isfinite(x_px) || !isfinite(y_px)) {{
        *alpha_deg = *beta_deg = ({P.t})NAN;
        return SUNLAB_CALIBRATION_BAD_INPUT;
    }}
    {{
{body}    }}
}}
"""
    return header, source


def export(cal, out, format: str = "c", *, overwrite: bool = False) -> list[Path]:
    """Export a calibration (or its JSON file) into the folder ``out``: ``"c"`` (header and
    source, :func:`c_sources`) or ``"json"`` (``sunlab_calibration.json``, ``calibration/1``),
    their files written together or not at all (existing ones only with ``overwrite``).

    Parameters
    ----------
    cal : sunlab.calibration.Calibration or path-like
    out : path-like
    format : {"c", "json"}
    overwrite : bool

    Returns
    -------
    list of pathlib.Path
    """
    if format not in FORMATS:
        raise ConfigurationError(f"format: found {format!r}, expected one of {FORMATS}")
    cal = _load(cal)
    texts = dict(zip((f"{BASENAME}.h", f"{BASENAME}.c"), c_sources(cal), strict=True)) \
        if format == "c" else {f"{BASENAME}.json": None}
    with atomic.atomic_files(out, list(texts), overwrite=overwrite, flag="--overwrite") as tmp:
        for name, text in texts.items():
            if text is None:
                cal.save(tmp / name)
            else:
                (tmp / name).write_text(text, encoding="utf-8")
    return [Path(out) / name for name in texts]


def find_c_compiler() -> str | None:
    """The system C compiler: the path of ``cc``, ``gcc`` or ``clang``, or None.

    Returns
    -------
    str or None
    """
    return next(filter(None, map(shutil.which, ("cc", "gcc", "clang"))), None)


_DRIVER = r"""#include <stdio.h>
#include "sunlab_calibration.h"
int main(void) { double x, y, a, b; float af, bf; int flag, flagf;
    while (scanf("%lf %lf", &x, &y) == 2) { flag = sunlab_calibration_eval(x, y, &a, &b);
        flagf = sunlab_calibration_evalf((float)x, (float)y, &af, &bf);
        printf("%d %.17g %.17g %d %.9g %.9g\n", flag, a, b, flagf, (double)af, (double)bf); }
    return 0; }
"""


def run_c(folder, x, y, *, cc: str | None = None, timeout: float = 60.0) -> dict:
    """Compile the export in ``folder`` with a driver (``-std=c99 -Wall -Wextra -Werror
    -pedantic``, ``-lm``; compiler ``cc``, limit ``timeout`` s) and evaluate it at centroids
    ``x``, ``y`` (px). The header and source are copied into a private build folder and compiled
    there by their own names: no path of the user's reaches the compiler (a folder named like
    an option, ``-o...``, stays a folder).

    Returns
    -------
    dict
        ``alpha``, ``beta``, ``flag`` of the double function, ``alpha_f``, ``beta_f``,
        ``flag_f`` of the float one (at ``x``, ``y`` rounded to float).
    """
    if (cc := cc or find_c_compiler()) is None:
        raise ConfigurationError("cc: no C compiler found on the PATH (cc, gcc, clang). Fix: "
                                 "install one (e.g. apt-get install gcc) or compile on the target")
    x, y = (np.asarray(v, dtype=float).ravel().tolist() for v in (x, y))
    with tempfile.TemporaryDirectory(prefix="sunlab-check-") as build:
        build = Path(build)
        for name in (f"{BASENAME}.h", f"{BASENAME}.c"):
            shutil.copyfile(Path(folder) / name, build / name)
        (build / "sunlab_driver.c").write_text(_DRIVER, encoding="utf-8")
        cmd = [cc, "-std=c99", "-O2", "-Wall", "-Wextra", "-Werror", "-pedantic", "-o",
               "sunlab_driver", "sunlab_driver.c", f"{BASENAME}.c", "-lm"]
        done = subprocess.run(cmd, cwd=build, capture_output=True, text=True, timeout=timeout,
                              check=False)
        if done.returncode:
            raise ConfigurationError(f"{' '.join(cmd)} failed:\n{done.stderr}")
        stdin = "".join(f"{a!r} {b!r}\n" for a, b in zip(x, y, strict=True))
        run = subprocess.run([str(build / "sunlab_driver")], input=stdin, capture_output=True,
                             text=True,
                             timeout=timeout, check=True)
    rows = np.array([line.split() for line in run.stdout.splitlines()], float).reshape(-1, 6)
    return {"flag": rows[:, 0].astype(int), "alpha": rows[:, 1], "beta": rows[:, 2],
            "flag_f": rows[:, 3].astype(int), "alpha_f": rows[:, 4], "beta_f": rows[:, 5]}


def check_c(cal, folder, n: int = 1000, *, seed: int = 0, cc: str | None = None) -> dict:
    """Compile an export and compare it with ``cal.predict_xy`` at ``n`` points drawn in the
    training box widened by 10 % a side (the float function at the float-rounded points).

    Parameters
    ----------
    cal : sunlab.calibration.Calibration or path-like
    folder : str or path-like
    n, seed : int
    cc : str, optional

    Returns
    -------
    dict
        ``max_error_double``, ``max_error_float`` (deg, where Python is finite),
        ``flags_agree`` (flag 0 exactly where ``cal.inside``), ``nan_agree``, ``n``,
        ``n_outside``, ``compiler``.
    """
    cal, rng = _load(cal), np.random.default_rng(seed)
    x, y = (rng.uniform(lo - 0.1 * (hi - lo), hi + 0.1 * (hi - lo), n)
            for lo, hi in (cal.domain["x"], cal.domain["y"]))
    got = run_c(folder, x, y, cc=(compiler := cc or find_c_compiler()))
    out = {"n": int(n), "n_outside": int((~cal.inside(x, y)).sum()), "compiler": compiler,
           "flags_agree": True, "nan_agree": True}
    for tag, xs, ys in (("", x, y), ("_f", *(v.astype(np.float32).astype(float) for v in (x, y)))):
        a, b = cal.predict_xy(xs, ys)
        fin = np.isfinite(a)
        err = np.abs(np.r_[got["alpha" + tag] - a, got["beta" + tag] - b][np.r_[fin, fin]])
        key = "max_error_" + ("float" if tag else "double")
        out[key] = float(err.max()) if err.size else float("nan")
        out["flags_agree"] &= bool(np.array_equal(got["flag" + tag] == 0, cal.inside(xs, ys)))
        out["nan_agree"] &= bool(np.array_equal(np.isnan(got["alpha" + tag]), ~fin))
    return out
