"""Calibrations on the command line: ``sunlab calibrate`` (:func:`sunlab.calibration.fit` on a
centroid table), ``sunlab evaluate`` (:func:`sunlab.stats.evaluate`, printed as the paper's
Table 4, and its report) and ``sunlab export`` (:func:`sunlab.export.export`, on-board C).

The methods offered are read from the registry :data:`sunlab.calibration.registry.KINDS`; a method's
option given to a method whose class does not take it is refused, naming the methods it applies
to.

Examples
--------
>>> from sunlab.cli import build_parser
>>> build_parser().parse_args(["calibrate", "t.nc", "--order", "auto", "--out", "c.json"]).order
'auto'
"""

from __future__ import annotations

import math

from ..calibration.registry import ALIASES, KINDS, OUTLIER_MADS
from ..errors import ConfigurationError
from ._args import POSITIVE, SEED, check_out, typed, verb
from ._files import open_centroid_table

__all__: list[str] = []

#: ``calibrate`` flags that set a keyword of the method's class (``--max-iter``: ``max_iter``).
_METHOD_FLAGS = ("order", "strategy", "hidden", "seed", "max_iter", "extrapolate")


def _add(sub) -> None:
    """Add ``calibrate``, ``evaluate`` and ``export``."""
    p = verb(sub, "calibrate", run_calibrate, "fit a calibration function on a centroid table",
             overwrite="an existing output")
    p.add_argument("train", help="training centroid table (.nc, .zarr, or .csv of alpha, beta, "
                   "x, y[, shot])")
    p.add_argument("--method", default="polynomial", choices=[*KINDS, *ALIASES],
                   help="calibration function (docs/paper.md sec. 4); default polynomial")
    # None defaults: an option given to a method it does not apply to is refused
    p.add_argument("--order", help="order (default: the method's), or 'auto' on --validation",
                   type=typed(lambda t: t if t == "auto" else int(t), lambda v: True,
                              "an integer or 'auto'"))
    p.add_argument("--strategy", type=int, choices=[1, 2, 3, 4],
                   help="neural-network strategy of Table 2 (default 4)")
    p.add_argument("--hidden", type=POSITIVE, help="hidden tanh neurons (default 8)")
    p.add_argument("--seed", type=SEED, help="seed of the network weights (default 0)")
    p.add_argument("--max-iter", type=POSITIVE, help="most L-BFGS iterations (default 3000)")
    p.add_argument("--extrapolate", action="store_true",
                   help="interpolation: nearest node outside the convex hull (default NaN)")
    p.add_argument("--validation", help="validation table: early stopping, order 'auto'")
    p.add_argument("--out", required=True, help="output calibration (.json)")
    p.add_argument("--outlier-mads", metavar="N", default=OUTLIER_MADS,
                   type=typed(float, lambda v: v == 0 or 3 < v < math.inf,
                              "0 (off) or a number of MADs above 3"),
                   help="exclude (and name) shots more than N MADs from a robust fit "
                        f"(default {OUTLIER_MADS:g}; 0: keep every shot)")

    p = verb(sub, "evaluate", run_evaluate, "the paper's statistics (Table 4) of a calibration "
             "on a test table; with --out its per-pose errors and Figs. 10-11",
             overwrite="existing outputs in DIR")
    p.add_argument("calibration", help="calibration file (.json, from sunlab calibrate)")
    p.add_argument("test", help="test centroid table (.nc, .zarr, or .csv)")
    p.add_argument("--out", metavar="DIR", help="write evaluation.json, errors.csv and figures")
    p.add_argument("--paper", action="store_true", help="print the paper's Table 4 beside")

    p = verb(sub, "export", run_export, "export a calibration for on-board use: self-contained "
             "C99 (sunlab_calibration.h/.c), or JSON", overwrite="existing files in DIR")
    p.add_argument("calibration", help="calibration file (.json, from sunlab calibrate)")
    p.add_argument("--format", default="c", choices=["c", "json"], help="default c")
    p.add_argument("--out", required=True, metavar="DIR", help="output folder (created)")
    p.add_argument("--check", action="store_true",
                   help="compile it and compare with Python on 1,000 points of the domain")


def run_calibrate(args) -> int:
    """``sunlab calibrate``: :func:`sunlab.calibration.fit` (screening, order 'auto') saved."""
    import time

    from .. import calibration
    options = _method_options(args)
    check_out(args.out, args.overwrite, kind="file")
    train = open_centroid_table(args.train, "train")
    val = None if args.validation is None else open_centroid_table(args.validation,
                                                                   "validation")
    if options.get("order") == "auto" and val is None:
        raise ConfigurationError(
            "--order: found 'auto' without --validation. Fix: pass --validation VAL.nc")
    t0 = time.perf_counter()
    try:
        cal = calibration.fit(train, args.method, val, outlier_mads=args.outlier_mads,
                              **options)
    except ConfigurationError as err:
        raise ConfigurationError(f"--{err}" if str(err).startswith("order:") else str(err)
                                 ) from err
    elapsed = time.perf_counter() - t0
    _print_excluded(cal.training.get("excluded", []), args.train, "train", args.outlier_mads)
    _print_excluded(cal.training.get("validation_excluded", []), args.validation,
                    "validation", args.outlier_mads)
    if getattr(cal, "order_scores", None) is not None:
        print(cal.order_scores.to_string(float_format=lambda v: f"{v:.5f}"))
    cal.save(args.out, overwrite=args.overwrite)
    _print_fit(cal, args.out, elapsed)
    return 0


def _method_options(args) -> dict:
    """The keywords of ``--method``'s class given on the command line; a flag its class does
    not take is refused, naming the methods it applies to (read from the registry)."""
    import inspect

    from ..calibration.registry import method_class
    def takes(method, name):
        return name in inspect.signature(method_class(method).__init__).parameters

    options = {}
    for name in _METHOD_FLAGS:
        value = getattr(args, name)
        if value in (None, False):
            continue
        if not takes(args.method, name):
            flag = "--" + name.replace("_", "-")
            methods = [k for k in KINDS if takes(k, name)]
            raise ConfigurationError(
                f"{flag}: does not apply to --method {args.method} (only to "
                f"{', '.join(methods)}). Fix: leave {flag} out, or choose one of those methods")
        options[name] = "nearest" if name == "extrapolate" else value
    return options


def _print_excluded(found, path, name: str, n_mad: float) -> None:
    """Name each shot the library's screening excluded, by its line for a CSV table."""
    from ..io.csvtable import csv_line_of

    for o in found:
        line = csv_line_of(path, o) if str(path).lower().endswith((".csv", ".txt")) else None
        where = (f"line {line}" if line else f"pose {o['pose']} shot {o['shot']}"
                 + (f" hole {o['hole']}" if "hole" in o else ""))
        print(f"{path} {where} ({name}): excluded as an outlier: alpha {o['alpha']:g}, beta "
              f"{o['beta']:g} deg, x {o['x']:.6g}, y {o['y']:.6g} px, {o['residual_px']:.3g} px "
              f"= {o['mads']:.3g} MADs from a robust fit (threshold {n_mad:g}; --outlier-mads)")


def _print_fit(cal, out, elapsed: float) -> None:
    """The fit's residuals (leave-one-out for an interpolant), repaired shots, warnings."""
    from ..calibration.plausibility import implausible
    from ..calibration.summary import errors_line

    res = cal.residuals
    if res.get("leave_one_out"):  # an interpolant passes through its nodes: ~0 residuals
        line = ("leave-one-out errors (deg): " + errors_line(res["leave_one_out"])
                + " (training residuals ~0 by construction)")
    else:
        line = "training residuals (deg): " + errors_line(res)
    print(f"{out}: {cal.label} fitted on {cal.training['n_poses']} poses in {elapsed:.2f} s; "
          f"{line}")
    if res.get("validation"):
        print("  validation residuals (deg): " + errors_line(res["validation"]))
    if cal.training.get("n_repaired_shots"):
        print(f"  {cal.training['n_repaired_shots']} of the {cal.training['n_ok_shots']} shots "
              "used are 'repaired' (an isolated hot pixel in the centroid window, replaced by "
              "the median of its neighbours): kept, as their spot is intact")
    for finding in implausible(cal):
        print(f"warning: implausible fit: {finding}")


def run_evaluate(args) -> int:
    """``sunlab evaluate``: :func:`sunlab.stats.evaluate` printed as the paper's Table 4, and
    with ``--out`` the files of :func:`sunlab.report.write_report`."""
    from .. import atomic, calibration, report, stats

    if args.out is not None:  # checked now, before any work; made once every file is written
        atomic.check_folder(args.out, report.REPORT_FILES, overwrite=args.overwrite,
                            flag="--overwrite")
    cal = calibration.load(args.calibration)
    test = open_centroid_table(args.test, "test")
    evaluation = stats.evaluate(cal, test, return_errors=True)
    sources = {"calibration": args.calibration, "test": args.test}
    doc = report.evaluation_document(cal, test, evaluation, paper=args.paper, sources=sources)
    print(f"{cal.label} on {args.test}: {doc['n_poses']} poses x {doc['n_shots']} shots "
          f"({doc['n_ok_shots']} ok); global statistics (deg), as the paper's Table 4:")
    _print_table(cal, evaluation[0], args.paper)
    if doc["n_out_of_domain"]:
        print(f"warning: {doc['n_out_of_domain']} centroid(s) outside the calibrated domain "
              f"(extrapolated{' or NaN' if cal.kind.startswith('interpolation') else ''}); see "
              "in_domain in errors.csv")
    if args.out is not None:
        written = report.write_report(args.out, cal, test, evaluation, paper=args.paper,
                                      sources=sources, overwrite=args.overwrite,
                                      flag="--overwrite")
        print("\n".join([*written["notes"], f"wrote {', '.join(map(str, written['files']))}"]))
    return 0


def _print_table(cal, table, paper: bool) -> None:
    """Our global statistics (with the paper's column beside), and what looks implausible."""
    import pandas as pd

    from .. import stats
    from ..calibration.plausibility import implausible

    shown = table.rename(columns={cal.label: f"{cal.label} (sunlab)"})
    if paper:
        published = stats.paper_table4()
        want = stats.PAPER_COLUMNS.get(cal.kind)
        keep = [want] if want in published.columns else list(published.columns)
        shown = pd.concat([shown, published[keep].add_suffix(" (paper)")], axis=1)
    print(shown.to_string(float_format=lambda v: f"{v:.5f}"))
    col = table[cal.label]
    for finding in implausible(cal, test_mu={a: col[(a, "mu")] for a in ("alpha", "beta")}):
        print(f"warning: implausible: {finding}")


def run_export(args) -> int:
    """``sunlab export``: :func:`sunlab.export.export`, with ``--check`` compiled and compared."""
    from .. import calibration, export

    cal = calibration.load(args.calibration)
    files = export.export(cal, args.out, format=args.format, overwrite=args.overwrite)
    print(f"{cal.label}: wrote {', '.join(map(str, files))}")
    if args.check and args.format == "c":
        r = export.check_c(cal, args.out)
        print(f"compiled with {r['compiler']}; max |C - Python| on {r['n']} points: double "
              f"{r['max_error_double']:.2e} deg, float {r['max_error_float']:.2e} deg; domain "
              f"flags agree: {r['flags_agree']}")
    return 0
