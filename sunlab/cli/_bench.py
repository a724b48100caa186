"""The bench on the command line: ``sunlab simulate`` (an experiment rendered on the virtual
bench into a cube) and ``sunlab acquire`` (the real or fake stage and a camera through a plan
into a resumable Zarr run).

Examples
--------
>>> from sunlab.cli import build_parser
>>> build_parser().parse_args(["acquire", "--stage", "fake://", "--camera", "sim", "--plan",
...                            "I", "--out", "r.zarr", "--roi", "0,64,0,80"]).roi
[0, 64, 0, 80]
"""

from __future__ import annotations

from ..errors import ConfigurationError
from ._args import POSITIVE, SECONDS, SEED, SHOTS, WORKERS, check_out, typed, verb

__all__: list[str] = []


def _add(sub) -> None:
    """Add ``simulate`` and ``acquire``."""
    p = verb(sub, "simulate", run_simulate, "render an experiment of the virtual bench",
             progress=True, overwrite="an existing output")
    p.add_argument("--experiment", default="III", choices=["I", "II", "III"], help="Table 3")
    p.add_argument("--mask", default="single", choices=["single", "multi", "random"],
                   help="one hole, the 10 x 10 grid, or 50 random holes")
    p.add_argument("--out", required=True, help="output cube (.zarr store or .nc file)")
    p.add_argument("--seed", type=SEED, default=0, help="seed of the experiment (default 0)")
    p.add_argument("--shots", type=SHOTS, default=8, help="frames per pose (default 8)")
    p.add_argument("--subset", type=POSITIVE, default=1, metavar="STEP",
                   help="every STEP-th angle along each grid axis")
    p.add_argument("--noise-free", action="store_true", help="ideal detector: no noise, no FPN")
    p.add_argument("--ideal-platform", action="store_true", help="true angles = commanded")
    p.add_argument("--chunks", default="frame", choices=["frame", "pose"], help="per chunk")
    p.add_argument("--workers", type=WORKERS, help="threads rendering in parallel")

    p = verb(sub, "acquire", run_acquire, "drive the stage and a camera through a plan into a "
             "Zarr run (--resume continues it; Ctrl-C stops between poses)", progress=True)
    p.add_argument("--stage", required=True, help="fake://, socket://HOST:PORT, or a serial port")
    p.add_argument("--camera", required=True, metavar="sim|folder:PATH|module:Class|NAME",
                   help="the virtual bench's, a folder a camera writes images into, your "
                   "camera class, or an entry point of sunlab.cameras (docs/hardware.md)")
    p.add_argument("--camera-option", action="append", default=[], metavar="KEY=VALUE",
                   help="argument of your camera class (VALUE as JSON if it parses)")
    p.add_argument("--plan", required=True, help="experiment I, II, III, or a CSV of alpha,beta")
    p.add_argument("--out", required=True, help="the run's Zarr store (a directory)")
    p.add_argument("--resume", action="store_true", help="continue an existing run in --out")
    p.add_argument("--shots", type=SHOTS, default=8, help="frames per pose (default 8)")
    p.add_argument("--step", type=POSITIVE, default=1, help="keep every STEP-th pose")
    p.add_argument("--settle", type=SECONDS, default=0.5, help="settle time after a move, s")
    p.add_argument("--seed", type=SEED, default=0, help="seed of the virtual bench (sim, fake)")
    p.add_argument("--bench", choices=("single", "multi"), default="single", help="sim, fake")
    p.add_argument("--binning", type=POSITIVE, default=1, help="sim camera pixel binning")
    p.add_argument("--roi", metavar="Y0,Y1,X0,X1", help="sim camera region, px (half-open)",
                   type=typed(lambda t: [int(v) for v in t.split(",")], lambda v: len(v) == 4,
                              "four integers Y0,Y1,X0,X1"))
    p.add_argument("--shape", default="1024x1280", metavar="NYxNX", help="folder camera frames",
                   type=typed(lambda t: tuple(int(v) for v in t.lower().split("x")),
                              lambda v: len(v) == 2 and all(1 <= n <= 16384 for n in v),
                              "NYxNX, each from 1 to 16384 px"))
    p.add_argument("--bit-depth", type=POSITIVE, default=10, help="folder camera ADC bits")
    p.add_argument("--frame-timeout", type=SECONDS, default=10.0, help="folder camera, s")
    p.add_argument("--baudrate", type=POSITIVE, default=19200, help="serial baud rate")
    p.add_argument("--timeout", type=SECONDS, default=1.0, help="serial read timeout, s")


def _bench(name: str, seed: int):
    """The virtual bench of ``--mask``/``--bench``: one hole, the 10 x 10 grid, 50 random."""
    from .. import sim

    if name == "random":
        return sim.Bench.paper_single_hole().replace(mask=sim.Mask.random_layout(50, seed=seed))
    return sim.Bench.paper_single_hole() if name == "single" else sim.Bench.paper_multi_hole()


def run_simulate(args) -> int:
    """``sunlab simulate``: :func:`sunlab.sim.simulate` saved as a cube."""
    import dask

    from .. import io, plans, sim

    plan = plans.experiment(args.experiment, shots=args.shots).thin(args.subset)
    bench = _bench(args.mask, args.seed)
    ny, nx = bench.detector.shape  # uint16 frames: refused before any work if they cannot fit
    check_out(args.out, args.overwrite, nbytes=2 * ny * nx * len(plan) * plan.shots)
    bench = bench.noise_free() if args.noise_free else bench
    bench = bench.ideal_platform() if args.ideal_platform else bench
    cube = sim.simulate(plan, bench, seed=args.seed)
    with dask.config.set(scheduler="threads", num_workers=args.workers):
        io.save_frames(cube, args.out, chunks=args.chunks, overwrite=args.overwrite,
                       progress=not args.no_progress)
    print(f"{args.out}: experiment {plan.name}, {len(plan)} poses x {plan.shots} shots, "
          f"mask {bench.mask.name} ({bench.n_holes} holes), seed {args.seed}")
    return 0


def run_acquire(args) -> int:
    """``sunlab acquire``: :func:`sunlab.hardware.acquire`, one session per run (its lock
    taken before the stage is opened); exit 130 when the run stopped before its end."""
    from .. import plans
    from ..hardware import acquire, open_stage
    from ..hardware.runner import call, run_lock

    if not args.resume:  # the folder must be writable; an existing run is the runner's
        check_out(args.out, overwrite=True, kind="zarr")
    plan = plans.read_plan(args.plan, shots=args.shots, field="--plan").subset(args.step)
    bench = _bench(args.bench, args.seed)
    with run_lock(args.out):
        stage = open_stage(args.stage, bench=bench, seed=args.seed, settle_s=args.settle,
                           baudrate=args.baudrate, timeout=args.timeout)
        try:
            result = acquire(plan, stage, _camera(args, bench, stage), args.out,
                             resume=args.resume, progress=not args.no_progress)
        finally:
            call("stage", stage, "close")
    print(f"sunlab acquire: {result.poses_done}/{result.poses_total} poses in {result.path} "
          f"({result.exit_status}; {result.poses_this_session} this session; run {result.uid})")
    return 0 if result.exit_status == "complete" else 130


def _camera(args, bench, stage):
    """The camera of ``--camera``: the virtual bench's (told the fake stage's true pose), a
    folder that a camera writes images into, or one opened by name or ``module:Class``."""
    from ..hardware import FolderCamera, SimCamera, open_camera
    from ..hardware.cameras import parse_camera_options

    builtin = "sim" if args.camera == "sim" else "folder" if args.camera.startswith("folder:") \
        else None
    if builtin and args.camera_option:  # taken silently, the lab's setting would be lost
        raise ConfigurationError(
            f"--camera-option {args.camera_option[0]!r}: the built-in camera {builtin!r} takes "
            "no options. Fix: set it with --roi, --binning, --shape, --bit-depth or "
            "--frame-timeout, or give --camera-option to a plug-in camera")
    if args.camera == "sim":
        fake = getattr(stage, "fake", None)
        return SimCamera(bench, seed=args.seed, roi=args.roi, binning=args.binning,
                         truth=None if fake is None else fake.true_pose)
    if args.camera.startswith("folder:"):
        return FolderCamera(args.camera[len("folder:"):], shape=args.shape,
                            bit_depth=args.bit_depth, timeout_s=args.frame_timeout)
    return open_camera(args.camera, **parse_camera_options(args.camera_option))
