"""The one pipeline every reproduced table shares: plans, simulate, centroid, status, JSON.

Each table of :mod:`sunlab.reproduce` (Table 4, Table 5, the platform table) runs the same
steps, and this module is the one place that renders frames and centroids them:

1. :func:`experiment_plans`: the plans of Table 3 as the table runs them. *Quick* has one
   meaning for every table: :data:`QUICK`, every 2nd angle along each grid axis
   (:meth:`sunlab.plans.Plan.thin`, so maps stay maps) and 2 shots per pose; ``step`` and
   ``shots`` override it;
2. :func:`simulate_runs` and :func:`locate_runs`: the frame cubes of the virtual bench, lazy,
   and every frame of every run centroided in ONE pass of Dask (:func:`sunlab.parallel.compute`)
   with the table's centroid ``method`` on the scheduler the caller chose (``address``,
   ``scheduler``, ``workers``); :func:`simulate_and_locate` does both for experiments I-III of
   one hole (with their zero-pose checks for Table 4);
3. :func:`usable_table` and :func:`centroid_status`: which frames the calibrations use, and the
   counts of the frames removed;
4. :func:`write_json`, the one writer of every results file, and :func:`write_files`, the one
   writer of a table's files together or not at all (the identified bench's intervals are
   :mod:`sunlab.reproduce.intervals`).

Examples
--------
>>> from sunlab.reproduce.pipeline import experiment_plans
>>> {k: len(p) for k, p in experiment_plans(quick=True).items()}
{'I': 100, 'II': 49, 'III': 100}
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import xarray as xr

from .. import atomic, centroid, plans, sim
from ..centroid.estimators import PER_SPOT
from ..errors import ConfigurationError
from ..geometry import ideal_centroid
from ..schema import STATUS, STATUS_NAMES, USABLE_STATUS

__all__ = []

#: Experiments of Table 3 and their roles.
EXPERIMENTS = {"I": "calibration", "II": "validation", "III": "test"}
#: Quick mode, the same for every table: every 2nd angle along each grid axis
#: (:meth:`sunlab.plans.Plan.thin`, so maps stay maps) and 2 shots per pose.
QUICK = {"step": 2, "shots": 2}


def experiment_plans(names=tuple(EXPERIMENTS), *, quick: bool = False, step: int | None = None,
                     shots: int | None = None) -> dict:
    """The plans of Table 3 as ``sunlab reproduce`` runs them (full, quick, or thinned).

    Parameters
    ----------
    names : sequence of str
        Experiments of Table 3 (``"I"``, ``"II"``, ``"III"``).
    quick : bool
        :data:`QUICK`: every 2nd angle along each grid axis, 2 shots per pose (full: 8 shots).
    step, shots : int, optional
        Keep every ``step``-th angle along each grid axis and take ``shots`` frames per pose
        (override ``quick``).

    Returns
    -------
    dict of str to sunlab.plans.Plan

    Examples
    --------
    >>> {k: (len(p), p.shots) for k, p in experiment_plans(("I", "III"), step=4).items()}
    {'I': (25, 8), 'III': (25, 8)}
    """

    step = step or (QUICK["step"] if quick else 1)
    shots = shots or (QUICK["shots"] if quick else 8)
    return {n: plans.experiment(n).thin(step).with_shots(shots) for n in names}


def simulate_runs(runs: dict, *, seed: int = 0, chunks: str = "pose") -> dict[str, xr.Dataset]:
    """Lazy frame cubes of named runs on the virtual bench (:func:`sunlab.sim.simulate`).

    Parameters
    ----------
    runs : dict of str to (sunlab.plans.Plan, sunlab.sim.Bench)
        The plan of each run and the bench it runs on.
    seed : int
        Seed of the virtual bench; each run mixes its plan into it.
    chunks : {"pose", "frame"}
        Dask chunks of the cubes (the frames are identical either way).

    Returns
    -------
    dict of str to xarray.Dataset

    Examples
    --------
    >>> from sunlab import sim
    >>> plans_ = experiment_plans(("III",), step=7, shots=1)
    >>> cubes = simulate_runs({"III": (plans_["III"], sim.Bench.paper_single_hole())})
    >>> dict(cubes["III"].frames.sizes)["pose"]
    9
    """
    from .. import sim

    return {k: sim.simulate(plan, bench, seed=seed, chunks=chunks)
            for k, (plan, bench) in runs.items()}


def locate_runs(cubes: dict, *, method: str = "projection", hole_offset=(0.0, 0.0),
                progress: bool = True, address: str | None = None, scheduler: str = "threads",
                workers: int | None = None, pool=None) -> dict[str, xr.Dataset]:
    """Centroid every frame of every cube in one pass of Dask; centroid tables by run.

    The cubes' true centroids are left out (on the virtual bench they cost a second pass over
    each frame's spot geometry, and no table uses them).

    Parameters
    ----------
    cubes : dict of str to xarray.Dataset
        Frame cubes (lazy, e.g. of :func:`simulate_runs`).
    method : str
        Centroid method of :func:`sunlab.centroid.locate` (for a multi-hole cube, its per-spot
        estimator: ``"tight"`` or ``"fit"``).
    hole_offset : (float, float)
        Multi-hole cubes: the mounting offset (px) added to the design positions
        ``hole_x_cf``, ``hole_y_cf`` to number the spots; the tables keep the design positions.
    progress : bool
        Show a progress bar.
    address : str, optional
        A ``dask.distributed`` scheduler address (workers started separately, e.g. by ``dask
        worker``); default a local scheduler.
    scheduler : str
        Local scheduler without ``address`` (:data:`sunlab.parallel.SCHEDULERS`).
    workers : int, optional
        Threads or processes of the local scheduler (default: the CPU count). The centroids
        do not depend on the scheduler or on where a frame is rendered.
    pool : concurrent.futures.Executor, optional
        Worker processes kept between calls (:func:`sunlab.parallel.worker_pool`).

    Returns
    -------
    dict of str to xarray.Dataset
        ``centroids/1`` tables keyed as ``cubes``.

    Examples
    --------
    >>> from sunlab import sim
    >>> plans_ = experiment_plans(("III",), step=7, shots=1)
    >>> cubes = simulate_runs({"III": (plans_["III"], sim.Bench.paper_single_hole())})
    >>> cens = locate_runs(cubes, progress=False)
    >>> int((cens["III"].status == 0).sum()), "true_x" in cens["III"]
    (9, False)
    """

    moved = {}
    for name, cube in cubes.items():
        cube = cube.drop_vars(["true_x", "true_y"], errors="ignore")
        if "hole_x_cf" in cube.coords:
            cube = cube.assign_coords(hole_x_cf=cube["hole_x_cf"] + hole_offset[0],
                                      hole_y_cf=cube["hole_y_cf"] + hole_offset[1])
        moved[name] = cube
    done = centroid.locate_all(moved, method, address=address, progress=progress,
                               scheduler=scheduler, num_workers=workers, pool=pool)
    for name, cube in cubes.items():
        if "hole_x_cf" in cube.coords:  # the tables keep the design positions
            done[name] = done[name].assign_coords(
                {k: cube[k].variable for k in ("hole_x_cf", "hole_y_cf")})
    return done


def simulate_and_locate(bench=None, *, seed: int = 0, quick: bool = False,
                        method: str = "projection", progress: bool = True,
                        address: str | None = None, step: int | None = None,
                        shots: int | None = None, scheduler: str = "threads",
                        workers: int | None = None, zero_pose: bool = False) -> dict:
    """Simulate experiments I, II, III and centroid every frame; centroid tables by experiment.

    Every frame is rendered and centroided once, in one pass of Dask (:func:`locate_runs`).

    Parameters
    ----------
    bench : sunlab.sim.Bench, optional
        Default :meth:`sunlab.sim.Bench.paper_single_hole`.
    seed : int
        Seed of the virtual bench; each experiment mixes its plan into it.
    quick, step, shots
        The plans (:func:`experiment_plans`).
    method : str
        Centroid method of :func:`sunlab.centroid.locate`.
    progress : bool
        Print the experiments and show a progress bar.
    address, scheduler, workers
        Where the frames are rendered and centroided (:func:`locate_runs`).
    zero_pose : bool
        Also render and centroid each experiment's zero-pose check
        (:func:`sunlab.plans.zero_check`, one visit with the run's shots, in the same pass) and
        give each table the mean of its check's usable centroids as the attributes
        ``zero_pose_x_px``, ``zero_pose_y_px`` (px), which a network re-zeroed on each run's
        zero pose reads (Table 4's strategy 4).

    Returns
    -------
    dict of str to xarray.Dataset
        ``centroids/1`` tables keyed ``"I"``, ``"II"``, ``"III"``, every centroid status kept
        (:func:`usable_table` selects).

    Examples
    --------
    >>> cens = simulate_and_locate(seed=1, step=7, shots=1, progress=False, zero_pose=True)
    >>> {k: int(v.sizes["pose"]) for k, v in cens.items()}, "zero_pose_x_px" in cens["I"].attrs
    ({'I': 9, 'II': 4, 'III': 9}, True)
    """

    bench = sim.Bench.paper_single_hole() if bench is None else bench
    plans_ = experiment_plans(quick=quick, step=step, shots=shots)
    runs = {k: (p, bench) for k, p in plans_.items()}
    if zero_pose:
        runs.update({f"zero {k}": (plans.zero_check(p, 1), bench) for k, p in plans_.items()})
    if progress:
        for name, plan in plans_.items():
            print(f"experiment {name} ({EXPERIMENTS[name]}): {len(plan)} poses x "
                  f"{plan.shots} shots", flush=True)
        print(f"rendering and centroiding {sum(len(p) * p.shots for p in plans_.values())} "
              f"frames ({method})", flush=True)
    cens = locate_runs(simulate_runs(runs, seed=seed), method=method, progress=progress,
                       address=address, scheduler=scheduler, workers=workers)
    out = {k: cens[k] for k in plans_}
    for k in plans_ if zero_pose else ():
        zero = cens[f"zero {k}"]
        ok = usable_table(zero)["status"].values == 0
        out[k] = out[k].assign_attrs(zero_pose_x_px=float(np.mean(zero.x.values[ok])),
                                     zero_pose_y_px=float(np.mean(zero.y.values[ok])))
    return out


def spot_method(method: str) -> str:
    """The centroid estimator of the 100-hole frames for the table's ``method``: the
    single-spot algorithms (B's profiles run over the whole frame) cannot separate 100 spots,
    so there each spot gets its own tight window (:func:`sunlab.centroid.locate_spots`;
    :data:`sunlab.centroid.estimators.PER_SPOT`); an unknown method raises, naming the choices.

    Parameters
    ----------
    method : str
        The table's centroid method (:func:`sunlab.centroid.locate`).

    Returns
    -------
    str
        The per-spot estimator of :func:`sunlab.centroid.locate_spots`.

    Examples
    --------
    >>> spot_method("threshold")
    'tight'
    >>> spot_method("nearest")  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    sunlab.errors.ConfigurationError: method: found 'nearest'; expected one of [...]
    """

    if method not in PER_SPOT:
        raise ConfigurationError(f"method: found {method!r}; expected one of {sorted(PER_SPOT)}")
    return PER_SPOT[method]


def mounting_offset_px(one_hole) -> tuple[float, float]:
    """Where the one-hole spot falls relative to its design track, px (median over poses).

    The sensor's mounting on the platform (alpha0, beta0) moves every spot off its design
    place, by about 80 px at F = 17 mm, more than half the 71 px hole pitch of the 100-hole mask
    (16 px at the presets' F = 5 mm), so design positions alone can give spots to the wrong
    holes. The mounting is the platform's, common to both masks: the offset measured with the
    one hole (calibrated first, as in the paper) is the prior that
    :func:`sunlab.centroid.locate` needs to number the 100 spots.

    Parameters
    ----------
    one_hole : xarray.Dataset
        A one-hole ``centroids/1`` table with its bench's attributes ``mask_distance_mm``,
        ``pixel_pitch_mm``, ``x_cf_px``, ``y_cf_px``.

    Returns
    -------
    (float, float)
        The median of x - x0 and of y - y0 over every centroid (px), x0, y0 the ideal model's
        (1) centroid of each pose (:func:`sunlab.geometry.ideal_centroid`).

    Examples
    --------
    >>> from sunlab import sim
    >>> cen = sim.synthetic_centroids([0.0, -5.0], [0.0, 3.0], mask_distance_mm=17.0,
    ...                                    hole_offset_px=(80.0, 18.0))
    >>> [round(v, 6) for v in mounting_offset_px(cen)]
    [80.0, 18.0]
    """

    x0, y0 = ideal_centroid(one_hole["alpha"].values[:, None], one_hole["beta"].values[:, None],
                            *(float(one_hole.attrs[k]) for k in (
        "mask_distance_mm", "pixel_pitch_mm", "x_cf_px", "y_cf_px")))
    return (float(np.nanmedian(one_hole["x"].values - x0)),
            float(np.nanmedian(one_hole["y"].values - y0)))


def usable_table(cen: xr.Dataset) -> xr.Dataset:
    """The centroid table with every usable status (:data:`sunlab.schema.USABLE_STATUS`)
    marked ``ok``, as the calibrations select their training points by ``ok``: a ``repaired``
    frame (a hot pixel replaced in the window) keeps its spot and is used.

    Parameters
    ----------
    cen : xarray.Dataset
        A ``centroids/1`` table with its ``status`` codes (:data:`sunlab.schema.STATUS`).

    Returns
    -------
    xarray.Dataset
        The same table, every usable status replaced by ``ok`` (0), the others kept.

    Examples
    --------
    >>> from sunlab import schema
    >>> cen = schema.centroids_dataset([[1.0, 2.0]], [[1.0, 2.0]], alpha=[0.0], beta=[0.0],
    ...                                status=[[schema.STATUS["repaired"], 0]])
    >>> usable_table(cen).status.values.tolist()
    [[0, 0]]
    """

    st = cen["status"]
    usable = st.isin([STATUS[k] for k in USABLE_STATUS])
    return cen.assign(status=st.where(~usable, STATUS["ok"]).astype(st.dtype))


def centroid_status(cens: dict) -> dict:
    """Frames per centroid status of each table, and under ``removed`` those the calibrations
    and statistics leave out (every status but the usable ones).

    Parameters
    ----------
    cens : dict of str to xarray.Dataset
        ``centroids/1`` tables by run, as centroided (before :func:`usable_table`).

    Returns
    -------
    dict of str to dict
        Per run: frames per status name (:data:`sunlab.schema.STATUS_NAMES`), and under
        ``removed`` the counts of the statuses that are not usable.

    Examples
    --------
    >>> from sunlab import schema
    >>> cen = schema.centroids_dataset([[1.0, 2.0]], [[1.0, 2.0]], alpha=[0.0], beta=[0.0],
    ...                                status=[[schema.STATUS["saturated"], 0]])
    >>> centroid_status({"III": cen})
    {'III': {'ok': 1, 'saturated': 1, 'removed': {'saturated': 1}}}
    """

    out = {}
    for name, cen in cens.items():
        n = {STATUS_NAMES[int(c)]: int(k)
             for c, k in zip(*np.unique(cen["status"].values, return_counts=True), strict=True)}
        out[name] = {**n, "removed": {k: v for k, v in n.items() if k not in USABLE_STATUS}}
    return out


def write_json(doc: dict, path: str | Path) -> str:
    """Write a table's results file (indented JSON; NumPy scalars and arrays as numbers).

    Written atomically (:func:`sunlab.atomic.write_text`): a temporary sibling renamed into
    place, so a symbolic link planted at ``path`` is replaced, never written through, and a
    named pipe or a device there is refused.

    Parameters
    ----------
    doc : dict
        The results; NumPy scalars and arrays are written as numbers and lists, any other
        object ``float`` takes as a number (a TypeError for the rest).
    path : str or pathlib.Path
        The file to write (replaced if it exists).

    Returns
    -------
    str
        ``path``.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "t.json"
    >>> write_json({"mu": np.float64(0.5), "n": np.arange(2)}, path) == str(path)
    True
    >>> path.read_text().split()
    ['{', '"mu":', '0.5,', '"n":', '[', '0,', '1', ']', '}']
    """

    def plain(o):  # anything else that is a number (a torch scalar): float; not one: TypeError
        return o.tolist() if isinstance(o, np.generic | np.ndarray) else float(o)

    atomic.write_text(Path(path), json.dumps(doc, indent=2, default=plain), overwrite=True,
                      flag="")
    return str(path)


def write_files(out: str | Path, files: dict) -> list[str]:
    """Write a table's files under ``out`` together or not at all
    (:func:`sunlab.atomic.atomic_files`): an interrupted run leaves the previous results.

    Parameters
    ----------
    out : str or pathlib.Path
        The folder (made with its parents where missing).
    files : dict of str to callable or matplotlib.figure.Figure
        File name -> a function that writes the file at the path it is given, or a figure
        (saved at 110 dpi, then closed).

    Returns
    -------
    list of str
        The paths written, in the order of ``files``.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> out = pathlib.Path(tempfile.mkdtemp()) / "r"
    >>> [pathlib.Path(p).name for p in write_files(out, {"a.json": lambda p: write_json({}, p)})]
    ['a.json']
    """
    import matplotlib.pyplot as plt


    out = Path(out)
    out.parent.mkdir(parents=True, exist_ok=True)
    try:
        with atomic.atomic_files(out, list(files), overwrite=True, flag="") as tmp:
            for name, what in files.items():
                what.savefig(tmp / name, dpi=110) if hasattr(what, "savefig") else what(tmp / name)
    finally:
        for what in files.values():
            if hasattr(what, "savefig"):
                plt.close(what)
    return [str(out / name) for name in files]


def cells(table, name=str, value=float) -> dict:
    """``{name(column): {"angle.stat": value(v)}}`` of a statistics table.

    Parameters
    ----------
    table : pandas.DataFrame
        Index ``(angle, stat)`` as :func:`sunlab.stats.evaluate` gives it, values in deg.
    name, value : callable
        The key of each column and the conversion of each value.

    Returns
    -------
    dict
        What the results files and the interval coverage read, deg.

    Examples
    --------
    >>> import pandas as pd
    >>> cells(pd.DataFrame({"m": [0.5]}, index=pd.MultiIndex.from_tuples([("alpha", "mu")])))
    {'m': {'alpha.mu': 0.5}}
    """
    return {name(c): {f"{a}.{s}": value(v) for (a, s), v in table[c].items()}
            for c in table.columns}


def finite(v) -> float | None:
    """``float(v)``, None where it is not finite (JSON has no NaN).

    Examples
    --------
    >>> finite(0.5), finite(float("nan"))
    (0.5, None)
    """
    v = float(v)
    return v if np.isfinite(v) else None
