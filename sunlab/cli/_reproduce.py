"""``sunlab reproduce``: the paper's tables on the virtual bench, ours beside the paper's
(:mod:`sunlab.reproduce`), and the tables beyond the paper (``platform``, ``learned``).

Examples
--------
>>> from sunlab.cli import build_parser
>>> build_parser().parse_args(["reproduce", "--quick"]).table
'4'
"""

from __future__ import annotations

import os

from ._args import SEED, WORKERS, verb

__all__: list[str] = []


def _add(sub) -> None:
    """Add ``reproduce``."""
    p = verb(sub, "reproduce", run_reproduce, "reproduce the paper's tables on the virtual "
             "bench (ours beside the paper's), with figures and a results file")
    p.add_argument("--table", choices=["4", "5", "all", "platform", "learned"], default="4",
                   help="Table 4 (one hole) or 5 (100 holes); beyond the paper, the platform's "
                   "fault removed, or a calibration learned from frames; default 4")
    p.add_argument("--quick", action="store_true", help="every 2nd angle along each grid axis "
                   "and 2 shots per pose (about 1/16 of the frames)")
    p.add_argument("--seed", type=SEED, default=0, help="seed of the virtual bench (default 0)")
    p.add_argument("--method", default="projection", help="centroid method (default "
                   "projection; 100-hole frames: tight, or fit)")
    p.add_argument("--no-neural", action="store_true", help="leave out the neural networks")
    p.add_argument("--out", default="results", help="output folder (default results/)")
    p.add_argument("--address", help="dask.distributed scheduler address (docs/scaling.md)")
    p.add_argument("--scheduler", choices=["threads", "processes", "synchronous", "cluster"],
                   help="local Dask scheduler (default: processes on several cores)")
    p.add_argument("--workers", type=WORKERS, help="local threads or processes")
    p.add_argument("--no-progress", action="store_true", help="no progress bars")
    p.add_argument("--benches", nargs="+", metavar="BENCH", help="--table learned: default "
                   "paper good-platform; 'all' or names of learned.BENCHES")
    p.add_argument("--full", action="store_true", help="--table learned: every bench at the "
                   "full plans, paper size (hours on 2 cores; docs/learned/README.md)")


def run_reproduce(args) -> int:
    """``sunlab reproduce``: each table asked for, printed, and the files it wrote named.

    The local scheduler is ``--scheduler``, else ``"processes"`` on several cores (a rendered
    frame holds the GIL part of its time, so threads reach about 1.6 of 2 cores; Dask's
    processes scheduler fuses rendering with centroiding, so only each frame's table crosses
    processes), ``"threads"`` on one."""
    if args.table == "learned":  # torch on its own threads: no Dask worker pool
        return _run_learned(args)
    from .. import parallel

    scheduler = args.scheduler or ("processes" if (os.cpu_count() or 1) > 1 else "threads")
    parallel.start_workers(scheduler, args.address)  # they warm up while this process imports
    from .. import reproduce

    where = {"quick": args.quick, "seed": args.seed, "method": args.method,
             "progress": not args.no_progress, "address": args.address,
             "scheduler": scheduler, "workers": args.workers}
    if args.table == "platform":
        res = reproduce.reproduce_platform(out=args.out, **where)
        print(f"\n{reproduce.platform.format_platform(res)}\n\nwrote " + ", ".join(res["files"]))
    if args.table in ("4", "all"):
        res = reproduce.reproduce_table4(neural=not args.no_neural, out=args.out, **where)
        print(f"\n{reproduce.table4.format_table(res)}\n\nwrote " + ", ".join(res.files))
    if args.table in ("5", "all"):
        res = reproduce.reproduce_table5(out=args.out, **where)
        print(f"\n{reproduce.table5.format_table5(res)}")
        print(reproduce.table4.removed_line(res["centroid_status"]))
        print(f"\n{res['runtime_s']:.0f} s; wrote " + ", ".join(map(str, res["files"])))
    return 0


def _run_learned(args) -> int:
    """``--table learned``: :func:`sunlab.reproduce.learned.reproduce_learned`."""
    from ..reproduce.learned import records_table, reproduce_learned

    res = reproduce_learned(out=args.out, quick=args.quick, full=args.full, seed=args.seed,
                            progress=not args.no_progress, threads=args.workers or 2,
                            benches=args.benches)
    print("\nmu (deg) on experiment III, unseen seeds; sunlab virtual bench")
    print(records_table(res["records"], "mu").round(5).to_string())
    print("\nwrote " + ", ".join(res["files"]))
    return 0
