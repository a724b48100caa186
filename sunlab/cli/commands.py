"""The ``sunlab`` command line.

Each subcommand has an ``_add_<name>(subparsers)`` function that declares its arguments and sets
``func`` to a ``_run_<name>(args)`` handler, which imports what it needs lazily (``sunlab --help``
stays fast). A user error (a wrong path, a read-only folder, a corrupt input, a bad argument)
ends in one line on stderr that names the thing and the fix, and a non-zero exit status
(:func:`main`); ``--debug`` (anywhere on the line) shows the Python traceback instead.

Examples
--------
>>> from sunlab.cli import build_parser
>>> build_parser().parse_args(["info", "cube.zarr"]).path
'cube.zarr'
"""

from __future__ import annotations

import argparse
import contextlib
import os
import signal
import sys

from ..calibration.registry import ALIASES, KINDS, OUTLIER_MADS
from ..errors import SunlabError
from . import lab as _lab
from . import study as _study
from ._signals import _ENDING, _ended_by, _signals_interrupt

__all__ = ["build_parser", "main", "run"]


def _count(low: int, high: int | None = None):
    """An argparse type: an integer >= ``low`` (and <= ``high``); its message names both."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"found {text!r}, expected an integer") from None
        if value < low or (high is not None and value > high):
            bounds = f">= {low}" if high is None else f">= {low} and <= {high}"
            raise argparse.ArgumentTypeError(f"found {value}, expected an integer {bounds}")
        return value

    parse.__name__ = f"integer >= {low}" if high is None else f"integer {low}..{high}"
    return parse


def _seconds(text: str) -> float:
    """An argparse type: a finite number of seconds >= 0."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"found {text!r}, expected seconds") from None
    if not value >= 0 or value == float("inf"):
        raise argparse.ArgumentTypeError(f"found {text!r}, expected finite seconds >= 0")
    return value


_POSITIVE = _count(1)
#: Seeds: what numpy, Dask and torch all take.
_SEED = _count(0, 2**32 - 1)
#: Frames per pose, threads or processes: bounded so a typo cannot exhaust the machine.
_SHOTS = _count(1, 10_000)
_WORKERS = _count(1, 1024)


def _check_out(path, overwrite: bool, kind: str = "file") -> None:
    """Check an output path before the work starts (folder, permissions, existing output)."""
    from pathlib import Path

    from .. import atomic, io

    if kind == "auto":
        kind = "file" if Path(path).suffix.lower() in io.NETCDF_SUFFIXES else "zarr"
    atomic.check_target(path, overwrite=overwrite, kind=kind, flag="--overwrite")


def _add_info(sub) -> None:
    p = sub.add_parser("info", help="print a summary of a frame cube, centroid table or "
                                    "calibration file")
    p.add_argument("path", help="a .zarr store, a .nc file, or a calibration .json")
    p.set_defaults(func=_run_info)


def _run_info(args) -> int:
    from ..calibration.summary import calibration_summary
    from .lab import read_calibration_json

    doc = read_calibration_json(args.path)  # standard library only: fast
    if doc is not None:
        print(_printable(calibration_summary(doc), keep="\n"))
        return 0
    from .. import io

    # Describe incomplete stores (an acquisition in progress) instead of refusing them:
    # the summary names the missing chunk files. Names and attributes come from the file:
    # a terminal escape sequence in them is shown escaped, not run.
    print(_printable(io.summary(io.open_dataset(args.path, check_chunks=False)), keep="\n"))
    return 0


def _printable(text: str, keep: str = "") -> str:
    r"""``text`` with every control character but those in ``keep`` escaped (ESC as ``\x1b``):
    what a file holds is shown to a terminal, never run by it.

    Examples
    --------
    >>> _printable("mask \x1b[2J 100 holes")
    'mask \\x1b[2J 100 holes'
    """
    if text.isprintable():
        return text
    return "".join(c if c.isprintable() or c in keep
                   else c.encode("unicode_escape").decode("ascii") for c in text)


def _add_acquire(sub) -> None:
    p = sub.add_parser(
        "acquire",
        help="drive the bench (rotation stage + camera) through a plan into a resumable Zarr run",
        description="Move the two-axis stage through a plan, take N frames per pose and write "
        "each pose into a pre-allocated Zarr store (contract frames/1). Restart with --resume "
        "to continue at the first unfinished pose. Ctrl-C stops cleanly between poses.",
    )
    p.add_argument("--stage", required=True, metavar="URL",
                   help="fake:// (in-process fake ESP301), socket://HOST:PORT, or a serial device "
                   "path (/dev/ttyUSB0, COM3) of a Newport ESP300/ESP301")
    p.add_argument("--camera", required=True, metavar="sim|folder:PATH|module:Class|NAME",
                   help="'sim' (virtual bench), 'folder:PATH' (a camera that writes image "
                        "files), a camera class of your own as module:Class, or a name "
                        "registered in the entry point group sunlab.cameras (docs/hardware.md)")
    p.add_argument("--camera-option", action="append", default=[], metavar="KEY=VALUE",
                   help="argument of your camera class (repeat; VALUE read as JSON if it parses)")
    p.add_argument("--plan", required=True,
                   help="experiment I, II or III, or a CSV file with columns alpha,beta (deg)")
    p.add_argument("--out", required=True, help="the run's Zarr store (a directory)")
    p.add_argument("--resume", action="store_true", help="continue an existing run in --out")
    p.add_argument("--shots", type=_SHOTS, default=8, help="frames per pose (default 8)")
    p.add_argument("--step", type=_POSITIVE, default=1,
                   help="keep every STEP-th pose (quick runs)")
    p.add_argument("--settle", type=_seconds, default=0.5, help="settle time after a move, s")
    p.add_argument("--seed", type=_SEED, default=0, help="seed of the virtual bench (sim, fake)")
    p.add_argument("--bench", choices=("single", "multi"), default="single",
                   help="virtual bench preset for the sim camera and fake stage")
    p.add_argument("--binning", type=_POSITIVE, default=1, help="sim camera pixel binning")
    p.add_argument("--roi", default=None, metavar="Y0,Y1,X0,X1",
                   help="sim camera region of interest, px (half-open)")
    p.add_argument("--shape", default="1024x1280", metavar="NYxNX",
                   help="folder camera frame shape (default 1024x1280)")
    p.add_argument("--bit-depth", type=_POSITIVE, default=10, help="folder camera ADC bits")
    p.add_argument("--frame-timeout", type=_seconds, default=10.0,
                   help="folder camera: longest wait for a new image file, s")
    p.add_argument("--baudrate", type=_POSITIVE, default=19200, help="serial baud rate")
    p.add_argument("--timeout", type=_seconds, default=1.0, help="serial read timeout, s")
    p.add_argument("--no-progress", action="store_true", help="no progress bar")
    p.set_defaults(func=_run_acquire)


def _run_acquire(args) -> int:

    from .. import plans, sim
    from ..hardware.runner import run_lock

    if not args.resume:
        # The folder must exist and be writable; an existing run is the runner's to judge.
        _check_out(args.out, overwrite=True, kind="zarr")
    plan = plans.read_plan(args.plan, shots=args.shots, field="--plan").subset(args.step)
    bench = (sim.Bench.paper_single_hole() if args.bench == "single"
             else sim.Bench.paper_multi_hole())
    with run_lock(args.out):  # before the stage is opened: one session per run
        return _acquire_locked(args, plan, bench)


def _acquire_locked(args, plan, bench) -> int:
    from ..errors import ConfigurationError
    from ..hardware import FolderCamera, SimCamera, acquire, open_stage

    stage = open_stage(args.stage, bench=bench, seed=args.seed, settle_s=args.settle,
                       baudrate=args.baudrate, timeout=args.timeout)
    try:
        if args.camera == "sim":
            roi = None
            if args.roi:
                try:
                    roi = [int(v) for v in args.roi.split(",")]
                except ValueError:
                    roi = []
                if len(roi) != 4:
                    raise ConfigurationError(
                        f"--roi: found {args.roi!r}, expected four integers Y0,Y1,X0,X1"
                    )
            fake = getattr(stage, "fake", None)
            camera = SimCamera(bench, seed=args.seed, roi=roi, binning=args.binning,
                               truth=None if fake is None else fake.true_pose)
        elif args.camera.startswith("folder:"):
            try:
                shape = tuple(int(v) for v in args.shape.lower().split("x"))
            except ValueError:
                shape = ()
            if len(shape) != 2 or not all(1 <= n <= 16384 for n in shape):
                raise ConfigurationError(
                    f"--shape: found {args.shape!r}, expected NYxNX, each from 1 to 16384 px")
            camera = FolderCamera(args.camera[len("folder:"):], shape=shape,
                                  bit_depth=args.bit_depth, timeout_s=args.frame_timeout)
        else:
            from ..hardware import open_camera
            from ..hardware.cameras import parse_camera_options

            camera = open_camera(args.camera, **parse_camera_options(args.camera_option))
        result = acquire(plan, stage, camera, args.out, resume=args.resume,
                         progress=not args.no_progress)
    finally:
        stage.close()
    print(f"sunlab acquire: {result.poses_done}/{result.poses_total} poses in {result.path} "
          f"({result.exit_status}; {result.poses_this_session} this session; run {result.uid})")
    return 0 if result.exit_status == "complete" else 130


def _add_centroid(sub) -> None:
    p = sub.add_parser("centroid", help="centroid every frame of a cube into a centroid table")
    p.add_argument("cube", help="a frame cube (.zarr store or .nc file), or a folder of "
                                "PNG/TIFF frames with manifest.csv (as sunlab import)")
    p.add_argument("--method", default=None,
                   choices=["threshold", "projection", "tight", "fit"],
                   help="A = threshold, B = projection, tight window, disk fit (default: "
                        "projection for one spot per frame, tight for a multi-hole cube, whose "
                        "spots take tight or fit only)")
    p.add_argument("--out", required=True, help="output centroid table (.nc or .zarr)")
    p.add_argument("--background", default=None, choices=["ring", "plane"],
                   help="tight window: the background fitted around each spot, a constant "
                        "(ring, default) or a plane (for a background that slopes or drifts)")
    p.add_argument("--scheduler", default="threads",
                   choices=["threads", "processes", "synchronous", "cluster"],
                   help="local Dask scheduler ('cluster': a local dask.distributed cluster of "
                   "single-threaded processes; docs/scaling.md)")
    p.add_argument("--address", default=None, help="dask.distributed scheduler address")
    p.add_argument("--workers", type=_WORKERS, default=None,
                   help="local threads or processes")
    p.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    p.add_argument("--overwrite", action="store_true", help="replace an existing output")
    _lab.add_folder_options(p)
    p.set_defaults(func=_run_centroid)


def _run_centroid(args) -> int:
    from .. import centroid, io
    from ..errors import ConfigurationError

    _check_out(args.out, args.overwrite, kind="auto")
    from .lab import cube_from_folder, is_image_folder

    cube = (cube_from_folder(args.cube, args) if is_image_folder(args.cube)
            else io.open_frames(args.cube))
    if args.method is None:  # the library's choice (sunlab.centroid.default_method)
        args.method = centroid.default_method(cube, args.background)
    extra = {}
    if args.background is not None:
        if args.method != "tight" or centroid.is_multi_hole(cube):
            raise ConfigurationError(
                f"--background: applies to the single-spot tight window, not --method "
                f"{args.method}. Fix: pass --method tight, or drop --background")
        extra["background"] = args.background
    cen = centroid.locate(cube, args.method, scheduler=args.scheduler, address=args.address,
                          num_workers=args.workers, progress=not args.no_progress, **extra)
    io.save_centroids(cen, args.out, overwrite=args.overwrite)
    ok = int((cen.status.values == 0).sum())
    print(f"{args.out}: {cen.status.size} centroids ({ok} ok) by method {args.method!r}")
    return 0


def _add_simulate(sub) -> None:
    p = sub.add_parser("simulate", help="render an experiment on the virtual bench into a cube")
    p.add_argument("--experiment", default="III", choices=["I", "II", "III"],
                   help="the paper's experiment I, II or III (Table 3); default III")
    p.add_argument("--mask", default="single", choices=["single", "multi", "random"],
                   help="one 0.2 mm hole, the 10 x 10 grid, or 50 random holes")
    p.add_argument("--out", required=True, help="output cube (.zarr store or .nc file)")
    p.add_argument("--seed", type=_SEED, default=0, help="seed of the experiment (default 0)")
    p.add_argument("--shots", type=_SHOTS, default=8, help="frames per pose (default 8)")
    p.add_argument("--subset", type=_POSITIVE, default=1, metavar="STEP",
                   help="keep every STEP-th angle along each grid axis (about 1/STEP^2 of "
                        "the poses; maps stay maps), for quick runs")
    p.add_argument("--noise-free", action="store_true", help="ideal detector: no noise, no FPN")
    p.add_argument("--ideal-platform", action="store_true", help="true angles = commanded")
    p.add_argument("--chunks", default="frame", choices=["frame", "pose"],
                   help="store one frame or one pose per chunk")
    p.add_argument("--workers", type=_WORKERS, default=None,
                   help="threads rendering in parallel")
    p.add_argument("--no-progress", action="store_true", help="hide the progress bar")
    p.add_argument("--overwrite", action="store_true", help="replace an existing output")
    p.set_defaults(func=_run_simulate)


def _run_simulate(args) -> int:
    import dask

    from .. import io, plans, sim

    _check_out(args.out, args.overwrite, kind="auto")
    plan = plans.experiment(args.experiment, shots=args.shots).thin(args.subset)
    bench = {
        "single": sim.Bench.paper_single_hole,
        "multi": sim.Bench.paper_multi_hole,
        "random": lambda: sim.Bench.paper_single_hole().replace(
            mask=sim.Mask.random_layout(50, seed=args.seed)),
    }[args.mask]()
    if args.noise_free:
        bench = bench.noise_free()
    if args.ideal_platform:
        bench = bench.ideal_platform()
    cube = sim.simulate(plan, bench, seed=args.seed)
    with dask.config.set(scheduler="threads", num_workers=args.workers):
        io.save_frames(cube, args.out, chunks=args.chunks, overwrite=args.overwrite,
                       progress=not args.no_progress)
    print(f"{args.out}: experiment {plan.name}, {len(plan)} poses x {plan.shots} shots, "
          f"mask {bench.mask.name} ({bench.n_holes} holes), seed {args.seed}")
    return 0


def _add_calibrate(sub) -> None:
    p = sub.add_parser("calibrate", help="fit a calibration function on a centroid table")
    p.add_argument("train", help="training centroid table (experiment I; .nc, .zarr, or .csv "
                                 "with columns alpha, beta, x, y[, shot])")
    p.add_argument("--method", default="polynomial",
                   choices=[*KINDS, *ALIASES],
                   help="calibration function (docs/paper.md sec. 4); default polynomial")
    # None defaults: an option given to a method it does not apply to is refused
    p.add_argument("--order", default=None,
                   help="polynomial / trigonometric order, or 'auto' to pick the polynomial "
                        "order on --validation (default: the method's, polynomial 5, "
                        "trigonometric 4)")
    p.add_argument("--strategy", type=int, default=None, choices=[1, 2, 3, 4],
                   help="neural-network strategy of Table 2 (default 4)")
    p.add_argument("--hidden", type=_POSITIVE, default=None,
                   help="hidden tanh neurons (default 8)")
    p.add_argument("--seed", type=_SEED, default=None, help="seed of the network weights "
                                                          "(default 0)")
    p.add_argument("--max-iter", type=_POSITIVE, default=None,
                   help="most L-BFGS iterations per network (default 3000)")
    p.add_argument("--extrapolate", action="store_true",
                   help="interpolation: nearest node outside the convex hull (default NaN)")
    p.add_argument("--validation", default=None,
                   help="validation centroid table (experiment II): early stopping, order")
    p.add_argument("--out", required=True, help="output calibration (.json)")
    p.add_argument("--outlier-mads", type=_mads, default=OUTLIER_MADS, metavar="N",
                   help="exclude shots whose centroid lies more than N median absolute "
                        "deviations from a robust fit of the table (sunlab.screening; default "
                        f"{OUTLIER_MADS:g}, as sunlab.calibration.fit; 0: keep every shot); the "
                        "excluded lines are named")
    p.add_argument("--overwrite", action="store_true", help="replace an existing output")
    p.set_defaults(func=_run_calibrate)


#: ``sunlab calibrate`` flags that set a keyword of the method's class (``--max-iter``:
#: ``max_iter``); each applies to the methods whose class takes that keyword.
_METHOD_FLAGS = ("order", "strategy", "hidden", "seed", "max_iter", "extrapolate")


def _method_options(args) -> dict:
    """The keywords of ``--method``'s class given on the command line; a flag its class does
    not take is refused, naming the methods it applies to (read from the registry)."""
    import inspect

    from ..calibration import KINDS, method_class
    from ..errors import ConfigurationError

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
    if options.get("order") not in (None, "auto"):
        try:
            options["order"] = int(options["order"])
        except ValueError:
            raise ConfigurationError(
                f"--order: found {args.order!r}, expected an integer or 'auto'") from None
    return options


def _mads(text: str) -> float:
    """An argparse type: a number of MADs above 3, or 0 (no screening)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"found {text!r}, expected a number") from None
    if not (value == 0 or 3 < value < float("inf")):
        raise argparse.ArgumentTypeError(f"found {text!r}, expected 0 (off) or a number of "
                                         "MADs above 3")
    return value


def _print_excluded(found, path, name: str, n_mad: float) -> None:
    """Name each shot the library's screening excluded (``training["excluded"]``), by its
    line for a CSV table."""
    from ..io.csvtable import csv_line_of

    for o in found:
        line = csv_line_of(path, o) if str(path).lower().endswith((".csv", ".txt")) else None
        where = (f"line {line}" if line else f"pose {o['pose']} shot {o['shot']}"
                 + (f" hole {o['hole']}" if "hole" in o else ""))
        print(f"{path} {where} ({name}): excluded as an outlier: alpha {o['alpha']:g}, beta "
              f"{o['beta']:g} deg, x {o['x']:.6g}, y {o['y']:.6g} px, {o['residual_px']:.3g} px "
              f"= {o['mads']:.3g} MADs from a robust fit (threshold {n_mad:g}; --outlier-mads)")


def _run_calibrate(args) -> int:
    import time

    from .. import calibration
    from ..errors import ConfigurationError
    from .lab import open_centroid_table

    options = _method_options(args)
    _check_out(args.out, args.overwrite)
    train = open_centroid_table(args.train, "train")
    val = None if args.validation is None else open_centroid_table(args.validation,
                                                                   "validation")
    if options.get("order") == "auto" and val is None:
        raise ConfigurationError(
            "--order: found 'auto' without --validation. Fix: pass --validation VAL.nc")
    t0 = time.perf_counter()
    try:  # the library decides: screening, order 'auto' (sunlab.calibration.fit)
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
    res = cal.residuals

    def fmt(r):
        return ", ".join(f"{a} mean|e| {r[a]['mean_abs'] or float('nan'):.5f} "
                         f"max {r[a]['max_abs'] or float('nan'):.5f}" for a in ("alpha", "beta"))

    if res.get("leave_one_out"):  # an interpolant passes through its nodes: ~0 residuals
        line = ("leave-one-out errors (deg): " + fmt(res["leave_one_out"])
                + " (training residuals ~0 by construction)")
    else:
        line = "training residuals (deg): " + fmt(res)
    print(f"{args.out}: {cal.label} fitted on {cal.training['n_poses']} poses in "
          f"{elapsed:.2f} s; {line}")
    if res.get("validation"):
        print("  validation residuals (deg): " + fmt(res["validation"]))
    if cal.training.get("n_repaired_shots"):
        print(f"  {cal.training['n_repaired_shots']} of the {cal.training['n_ok_shots']} shots "
              "used are 'repaired' (an isolated hot pixel in the centroid window, replaced by "
              "the median of its neighbours): kept, as their spot is intact")
    from ..calibration.plausibility import implausible

    for finding in implausible(cal):
        print(f"warning: implausible fit: {finding}")
    return 0


def _add_reproduce(sub) -> None:
    p = sub.add_parser(
        "reproduce",
        help="reproduce the paper's tables on the virtual bench (ours beside the paper's)",
        description="Simulate experiments I-III on the virtual bench, centroid every frame, fit "
        "every calibration method and print the paper's table with our value beside each of its "
        "values; write figures and a machine-readable results file.",
    )
    p.add_argument("--table", choices=["4", "5", "all", "platform", "learned"], default="4",
                   help="Table 4 (one hole, every method) or Table 5 (100 holes); default 4; "
                   "'platform': beyond the paper, the inner axis's fault diagnosed and removed; "
                   "'learned': beyond the paper, a calibration learned from the frames beside "
                   "the classical one on several benches (learned.json, models/, learned.png)")
    p.add_argument("--quick", action="store_true",
                   help="quick mode, the same for every table: every 2nd angle along each grid "
                   "axis of the experiments (Table 4: 100 + 49 + 100 poses of 930; Table 5: "
                   "100 + 100 of 761; platform: as Table 4) and 2 shots per pose instead of 8 "
                   "(about 1/16 of the frames)")
    p.add_argument("--seed", type=_SEED, default=0, help="seed of the virtual bench (default 0)")
    p.add_argument("--method", default="projection",
                   help="centroid method of every table (default projection: the paper's "
                   "algorithm B; on 100-hole frames each spot gets a tight window, or fit "
                   "with --method fit)")
    p.add_argument("--no-neural", action="store_true", help="leave out the neural networks")
    p.add_argument("--out", default="results", help="output folder (default results/)")
    p.add_argument("--address", default=None,
                   help="dask.distributed scheduler address (every table; docs/scaling.md)")
    p.add_argument("--scheduler", default=None,
                   choices=["threads", "processes", "synchronous", "cluster"],
                   help="local Dask scheduler when no --address is given (default: processes "
                   "on a machine with several cores, as rendering holds the GIL part of each "
                   "frame; threads on one core; 'cluster': a local cluster of single-threaded "
                   "processes)")
    p.add_argument("--workers", type=_WORKERS, default=None,
                   help="local threads or processes (default: one per core)")
    p.add_argument("--no-progress", action="store_true", help="no progress bars")
    p.add_argument("--benches", nargs="+", default=None, metavar="BENCH",
                   help="--table learned: the benches to run (default all; "
                   "sunlab.reproduce.learned.BENCHES)")
    p.set_defaults(func=_run_reproduce)


def _reproduce_scheduler(scheduler: str | None) -> str:
    """The local scheduler of ``sunlab reproduce``: as given, else ``"processes"`` on a machine
    with several cores (a rendered frame holds the GIL part of its time, so threads reach about
    1.6 of 2 cores; Dask's processes scheduler fuses rendering with centroiding, so only each
    frame's table crosses processes) and ``"threads"`` on one core.

    Examples
    --------
    >>> _reproduce_scheduler("threads")
    'threads'
    >>> import os
    >>> _reproduce_scheduler(None) == ("processes" if (os.cpu_count() or 1) > 1 else "threads")
    True
    """
    import os

    if scheduler is not None:
        return scheduler
    return "processes" if (os.cpu_count() or 1) > 1 else "threads"


def _run_reproduce(args) -> int:
    if args.table == "learned":  # torch on its own threads: no Dask worker pool
        return _run_learned(args)
    from .. import parallel

    scheduler = _reproduce_scheduler(args.scheduler)
    parallel.start_workers(scheduler, args.address)  # they warm up while this process imports
    from .. import reproduce

    where = {"quick": args.quick, "seed": args.seed, "method": args.method,
             "progress": not args.no_progress, "address": args.address,
             "scheduler": scheduler, "workers": args.workers}
    if args.table == "platform":
        resp = reproduce.reproduce_platform(out=args.out, **where)
        print()
        print(reproduce.format_platform(resp))
        print("\nwrote " + ", ".join(resp["files"]))
        return 0
    if args.table in ("4", "all"):
        res = reproduce.reproduce_table4(neural=not args.no_neural, out=args.out, **where)
        print()
        print(reproduce.format_table(res))
        print("\nwrote " + ", ".join(res.files))
    if args.table in ("5", "all"):
        res5 = reproduce.reproduce_table5(out=args.out, **where)
        print()
        print(reproduce.format_table5(res5))
        print("Frames removed (status: count): " + "; ".join(
            f"{k}: " + (", ".join(f"{n} {s}" for s, n in v["removed"].items()) or "none")
            for k, v in res5["centroid_status"].items()))
        print(f"\n{res5['runtime_s']:.0f} s; wrote " + ", ".join(map(str, res5["files"])))
    return 0


def _run_learned(args) -> int:
    from ..reproduce.learned import records_table, reproduce_learned

    res = reproduce_learned(out=args.out, quick=args.quick, seed=args.seed,
                            progress=not args.no_progress, threads=args.workers or 2,
                            benches=args.benches)
    print("\nmu (deg) on experiment III, unseen seeds; sunlab virtual bench")
    print(records_table(res["records"], "mu").round(5).to_string())
    print("\nwrote " + ", ".join(res["files"]))
    return 0


def _add_course(sub) -> None:
    p = sub.add_parser(
        "course", help="write the course's student and teacher editions, or grade notebooks",
        description="--out DIR writes DIR/student (each exercise's answer replaced by a stub "
        "that raises NotImplementedError with a hint; no hidden check, no model answer) and "
        "DIR/teacher (answers kept, nbgrader metadata), all or nothing. --grade runs students' "
        "notebooks against the teacher edition (their check cells restored, hidden checks on "
        "fresh inputs), prints each exercise's points and, with --gradebook DIR, writes "
        "DIR/gradebook.csv and DIR/gradebook.json; it exits 1 when a check fails. "
        "docs/course.md is the student syllabus, docs/teacher-notes.md the teacher's.")
    what = p.add_mutually_exclusive_group(required=True)
    what.add_argument("--out", metavar="DIR", help="folder of the two editions")
    what.add_argument("--grade", nargs="+", metavar="NOTEBOOK",
                      help="students' notebooks (STUDENT/NN-title.ipynb) to run and grade")
    p.add_argument("--gradebook", metavar="DIR", default=None,
                   help="with --grade: write DIR/gradebook.csv and DIR/gradebook.json")
    p.add_argument("--seed", type=int, default=None,
                   help="with --grade: seed of the hidden checks' fresh inputs (default: drawn "
                   "at random and printed)")
    p.add_argument("--notebooks", default=None, metavar="DIR",
                   help="folder of the numbered notebooks (default: the checkout's notebooks/)")
    p.add_argument("--full", action="store_true",
                   help="leave out the first cell that selects the small settings")
    p.add_argument("--timeout", type=_seconds, default=180.0,
                   help="with --grade: limit per cell, s (a notebook's budget is 10 limits); "
                   "past it the notebook's open exercises score 0 (default: 180)")
    p.add_argument("--overwrite", action="store_true",
                   help="replace editions (or a gradebook) written before")
    p.set_defaults(func=_run_course)


def _run_course(args) -> int:
    from pathlib import Path

    from .. import atomic
    from ..course import batch, grading, write_course

    if args.grade:
        if args.gradebook is not None:  # refused before hours of grading, not after
            atomic.check_folder(args.gradebook, grading.GRADEBOOK_FILES,
                                overwrite=args.overwrite, flag="--overwrite")
        seed = args.seed if args.seed is not None else int.from_bytes(os.urandom(3), "big")
        print(f"hidden checks on fresh inputs drawn from seed {seed}")
        _, status = batch.grade_batch(args.grade, notebooks=args.notebooks, seed=seed,
                                      quick=not args.full, timeout=args.timeout,
                                      gradebook=args.gradebook, overwrite=args.overwrite)
        if args.gradebook is not None:
            print(f"wrote {Path(args.gradebook) / 'gradebook.csv'}, "
                  f"{Path(args.gradebook) / 'gradebook.json'}")
        return status
    res = write_course(args.out, notebooks=args.notebooks, quick=not args.full,
                       overwrite=args.overwrite)
    books = {ex.notebook for ex in res["exercises"]}
    print(f"{len(res['exercises'])} exercises in {len(books)} notebooks, "
          f"{len(res['written'])} written answers; wrote "
          f"{len(res['student'])} student notebooks to {res['student'][0].parent} and "
          f"{len(res['teacher'])} teacher notebooks to {res['teacher'][0].parent}")
    return 0


def _add_lab(name: str):
    """The adder of a lab subcommand (import, evaluate, export) from :mod:`sunlab.cli.lab`."""
    return getattr(_lab, f"_add_{name}")


# One adder per subcommand, in the order `sunlab --help` lists them.
_ADDERS = [
    _add_reproduce, _add_simulate, _add_lab("import"), _add_centroid, _add_calibrate,
    _add_lab("evaluate"), _add_lab("export"), _add_acquire, _add_info, _add_course,
    _study._add_identify,
]


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of the ``sunlab`` command.

    Returns
    -------
    argparse.ArgumentParser
        One subcommand per command, each with ``func`` set to its ``_run_<name>`` handler."""
    from .. import __version__

    parser = argparse.ArgumentParser(
        prog="sunlab",
        description="Reproduce, teach and extend the lab calibration of a pinhole APS sun sensor.",
    )
    parser.add_argument("--version", action="version", version=f"sunlab {__version__}")
    parser.add_argument("--debug", action="store_true",
                        help="show the Python traceback of an error (also after the command)")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for adder in _ADDERS:
        adder(sub)
    return parser


def _one_line(err: BaseException) -> str:
    """The message of an error on one line; OS errors name the file and say what to check."""
    if isinstance(err, OSError) and not isinstance(err, SunlabError):
        where = err.filename if err.filename is not None else ""
        what = err.strerror or str(err) or type(err).__name__
        fix = {
            PermissionError: "check the permissions of the file or folder, or choose a path "
                             "you can write to",
            FileNotFoundError: "check the path (relative paths start at the current folder)",
            IsADirectoryError: "give a file, not a folder",
            NotADirectoryError: "check the path: a part of it is a file, not a folder",
        }.get(type(err), "check the path, the free disk space and the permissions")
        text = f"{where}: {what}. Fix: {fix}" if where else f"{what}. Fix: {fix}"
    else:
        text = str(err) or type(err).__name__
    return _printable(" ".join(text.split()))


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``sunlab`` console script.

    Parameters
    ----------
    argv : list of str, optional
        Arguments after ``sunlab`` (default ``sys.argv[1:]``); ``--debug`` re-raises errors.

    Returns
    -------
    int
        Exit status: 0 success, 1 an error in the inputs, files or settings (one stderr line
        naming it and the fix), 2 a bad command line, 3 an internal error, 130, 143, 129 on
        SIGINT, SIGTERM, SIGHUP (one line, temporary outputs removed, workers stopped)."""
    argv = list(sys.argv[1:] if argv is None else argv)
    debug = "--debug" in argv
    argv = [a for a in argv if a != "--debug"]
    parser = build_parser()
    args = parser.parse_args(argv)
    if getattr(args, "func", None) is None:
        parser.print_help()
        return 2
    try:
        with _signals_interrupt(quiet=not debug) as received:
            status = int(args.func(args) or 0)
            sys.stdout.flush()  # a closed pipe is reported here, not at the interpreter's exit
        if not received:
            return status
        # the command returned although a signal came: a library swallowed the interrupt
        raise _ENDING.get(received[0], _ENDING[signal.SIGINT])[1]
    except KeyboardInterrupt as err:
        if debug:
            raise
        name, status = _ended_by(err)
        with contextlib.suppress(OSError):  # the terminal may be gone (SIGHUP)
            print(f"sunlab {args.command}: interrupted by {name}", file=sys.stderr)
        return status
    except BrokenPipeError as err:  # the reader of stdout went away (`sunlab info X | head`)
        if debug:
            raise
        global _PIPE_CLOSED
        _PIPE_CLOSED = True
        if err.filename is not None:  # a pipe the command opened itself
            print(f"sunlab {args.command}: error: {_one_line(err)}", file=sys.stderr)
            return 1
        with contextlib.suppress(OSError):
            print(f"sunlab {args.command}: error: the output pipe was closed before the "
                  "command finished (its reader stopped). Fix: read the whole output, or "
                  "redirect it to a file", file=sys.stderr)
        return 1
    except (SunlabError, OSError) as err:
        if debug:
            raise
        print(f"sunlab {args.command}: error: {_one_line(err)}", file=sys.stderr)
        return 1
    except MemoryError as err:  # a size the user asked for, not a bug
        if debug:
            raise
        print(f"sunlab {args.command}: error: not enough memory ({_one_line(err)}). Fix: ask "
              "for less (a smaller frame shape or region, fewer poses or shots) or run on a "
              "machine with more memory", file=sys.stderr)
        return 1
    except Exception as err:  # noqa: BLE001 - never a traceback without --debug
        if debug:
            raise
        print(f"sunlab {args.command}: internal error: {type(err).__name__}: {_one_line(err)}. "
              "Fix: this is probably a bug in sunlab; run again with --debug and report the "
              "traceback", file=sys.stderr)
        return 3


#: Set when a command met a closed stdout pipe: :func:`run` then silences stdout.
_PIPE_CLOSED = False


def _quiet_stdout() -> None:
    """Point stdout at the null device, so that the interpreter's last flush of a closed pipe
    cannot print a second error (Python's documented remedy for SIGPIPE)."""
    with contextlib.suppress(OSError, ValueError, AttributeError):
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        os.close(devnull)


def run() -> None:
    """The ``sunlab`` console script and ``python -m sunlab.cli``: :func:`main`, then exit with
    its status. Library code calls :func:`main`, which returns the status instead."""
    status = main()
    if _PIPE_CLOSED:
        _quiet_stdout()
    sys.exit(status)
