"""Pose plans: the platform poses of an experiment and the number of frames (shots) per pose.

A plan is a flat list of commanded platform poses (alpha, beta) in degrees plus the number of
shots taken at each pose. The paper's three experiments (Table 3, docs/paper.md sec. 5) are regular
grids with the outer axis alpha as the outer loop; any other grid or a custom list of poses is a
plan too, so that every acquisition or simulation goes through one type.

Examples
--------
>>> from sunlab import plans
>>> exp3 = plans.experiment("III")
>>> len(exp3), exp3.shots
(361, 8)
>>> float(exp3.alpha[0]), float(exp3.beta[0]), float(exp3.beta[1])
(-16.5, -1.5, -0.5)
"""

from __future__ import annotations

import zlib
from dataclasses import dataclass, fields, replace

import numpy as np

from .errors import ConfigurationError

__all__ = ["experiment", "grid"]

#: The paper's Table 3: (alpha_min, alpha_max, alpha_step, beta_min, beta_max, beta_step), deg.
EXPERIMENTS: dict[str, tuple[float, float, float, float, float, float]] = {
    "I": (-17.0, 2.0, 1.0, -2.0, 17.0, 1.0), "II": (-16.25, 1.75, 1.5, -1.75, 16.25, 1.5),
    "III": (-16.5, 1.5, 1.0, -1.5, 16.5, 1.0)}

#: Orders in which the stage visits a plan's poses (:meth:`Plan.visit_order`): ``"raster"`` as
#: listed (the inner axis runs back at each row start), ``"serpentine"`` with every other row
#: reversed (the shortest path), ``"random"`` a fixed pseudo-random permutation.
SCANS = ("raster", "serpentine", "random")
#: How the inner axis reaches a pose: ``"direct"`` (the last move's direction, so a backlash
#: follows the scan) or ``"unidirectional"`` (overshoot below the target and return: every pose
#: is approached upward, so a backlash is the same at every pose and a calibration absorbs it).
APPROACHES = ("direct", "unidirectional")
#: The scan order assumed for the paper's experiments: the paper does not state it; a serpentine
#: scan is what a stage program does to save travel, and the beta statistics of Table 4 (sigma /
#: mu of 0.47, below the bound of any symmetric unimodal error) ask for an inner-axis error whose
#: sign alternates (:mod:`sunlab.reproduce.fault`). Our inference.
PAPER_SCAN = "serpentine"

#: Largest platform angle a plan may command, deg: beyond 90 deg the sun is behind the mask.
MAX_ANGLE_DEG = 90.0


def _check(ok: bool, name: str, found, expected: str, fix: str = "") -> None:
    if not ok:
        raise ConfigurationError(f"{name}: found {found}; expected {expected}." +
                                 (f" Fix: {fix}" if fix else ""))


def _check_angles(name: str, values: np.ndarray) -> None:
    _check(values.ndim == 1, name, f"an array of shape {values.shape}",
           "a flat list of angles (one per pose)", "pass np.ravel(angles).")
    _check(np.all(np.isfinite(values)), name, "non-finite angles", "finite degrees",
           "drop NaN/inf poses.")
    bad = np.abs(values) >= MAX_ANGLE_DEG
    _check(not np.any(bad), name, f"{values[bad][0] if bad.any() else 0:g} deg",
           f"|angle| < {MAX_ANGLE_DEG:g} deg (the sun must stay in front of the mask)",
           "command angles in degrees within (-90, 90).")


def _positive_int(name: str, value, expected: str, fix: str) -> int:
    _check(not isinstance(value, bool) and isinstance(value, int | np.integer) and value >= 1,
           name, repr(value), expected, fix)
    return int(value)


@dataclass(frozen=True, eq=False)
class Plan:
    """A list of commanded platform poses and the number of frames taken at each.

    Parameters
    ----------
    name : str
        Name of the plan, e.g. ``"III"``; stored as the ``experiment`` attribute of a cube.
    alpha, beta : numpy.ndarray of float, shape (pose,)
        Commanded outer- and inner-axis angles of each pose, degrees. For a grid, alpha is the
        outer loop (``beta`` varies fastest).
    shots : int
        Frames per pose (the paper: 8).
    scan, approach : str
        The motion: the order of the visits (:data:`SCANS`; the poses stay listed in their own
        order) and how the inner axis reaches each pose (:data:`APPROACHES`).
    """

    name: str
    alpha: np.ndarray
    beta: np.ndarray
    shots: int = 8
    scan: str = "raster"
    approach: str = "direct"

    def __post_init__(self):
        alpha = np.atleast_1d(np.array(self.alpha, dtype=float))
        beta = np.atleast_1d(np.array(self.beta, dtype=float))
        _check_angles("alpha", alpha)
        _check_angles("beta", beta)
        _check(alpha.shape == beta.shape, "alpha, beta", f"{alpha.size} and {beta.size} angles",
               "one alpha and one beta per pose", "pass equal-length lists.")
        _check(alpha.size > 0, "alpha, beta", "an empty plan", "at least one pose",
               "widen the range or the slice.")
        alpha.setflags(write=False)
        beta.setflags(write=False)
        shots = _positive_int("shots", self.shots, "a positive integer number of frames per pose "
                              "(the paper takes 8)", "pass shots=8.")
        for name, value in (("alpha", alpha), ("beta", beta), ("shots", shots),
                            ("name", str(self.name))):
            object.__setattr__(self, name, value)
        _check(self.scan in SCANS, "scan", repr(self.scan), f"one of {SCANS}",
               "scan='serpentine'.")
        _check(self.approach in APPROACHES, "approach", repr(self.approach),
               f"one of {APPROACHES}", "approach='unidirectional' (overshoot and return).")

    def __len__(self) -> int:
        return int(self.alpha.size)

    def __getitem__(self, index) -> Plan:
        """A plan of a subset of the poses (slice, integer array or boolean mask)."""
        if isinstance(index, int | np.integer):
            index = [int(index)]
        return replace(self, alpha=self.alpha[index], beta=self.beta[index])

    def __eq__(self, other) -> bool:
        return isinstance(other, Plan) and all(
            np.array_equal(getattr(self, f.name), getattr(other, f.name)) for f in fields(self))

    __hash__ = None  # mutable-looking contents: plans are compared by value, not hashed

    def subset(self, step: int) -> Plan:
        """Every ``step``-th pose, for quick runs (``step=1`` returns an equal plan).

        Parameters
        ----------
        step : int
            Keep poses 0, step, 2 step, ... (a positive integer).

        Returns
        -------
        Plan
            Same name, shots and motion; ``ceil(len / step)`` poses.
        """
        return self[::_positive_int("step", step, "a positive integer",
                                    "pass step=2 to keep every other pose.")]

    def thin(self, step: int) -> Plan:
        """Every ``step``-th angle along each grid axis, so a thinned grid is still a grid.

        A full alpha-outer grid (:meth:`unstack_shape`) keeps every ``step``-th alpha and beta
        (maps stay maps); any other plan every ``step``-th pose (as :meth:`subset`).

        Parameters
        ----------
        step : int
            Keep every ``step``-th angle of each axis (a positive integer).

        Returns
        -------
        Plan
            Same name, shots and motion; ``ceil(n_alpha / step) * ceil(n_beta / step)`` poses for a
            full grid, ``ceil(len / step)`` otherwise.
        """
        subset, shape = self.subset(step), self.unstack_shape()  # subset checks step
        if shape is None:
            return subset
        ia, ib = np.arange(0, shape[0], step), np.arange(0, shape[1], step)
        return self[(ia[:, None] * shape[1] + ib).ravel()]

    def with_shots(self, shots: int) -> Plan:
        """The same poses with ``shots`` (a positive integer) frames per pose.

        Parameters
        ----------
        shots : int
            Frames per pose.

        Returns
        -------
        Plan
        """
        return replace(self, shots=shots)

    def with_motion(self, scan: str | None = None, approach: str | None = None) -> Plan:
        """The same poses visited in another order (:data:`SCANS`) or approached another way
        (:data:`APPROACHES`); None keeps this plan's.

        Parameters
        ----------
        scan, approach : str, optional
            The motion.

        Returns
        -------
        Plan

        Examples
        --------
        >>> p = experiment("III").with_motion(approach="unidirectional")
        >>> p.scan, p.approach
        ('serpentine', 'unidirectional')
        """
        return replace(self, scan=self.scan if scan is None else scan,
                       approach=self.approach if approach is None else approach)

    def visit_order(self) -> np.ndarray:
        """Indices of the poses in the order the stage visits them (:data:`SCANS`).

        ``"serpentine"`` reverses every other run of equal alpha, ``"random"`` is seeded by
        the plan's name and poses: a plan always replays the same way.

        Returns
        -------
        numpy.ndarray of int, shape (pose,)
            A permutation of ``0 .. len - 1``: the k-th pose visited is ``plan[order[k]]``.
        """
        n = len(self)
        if self.scan == "raster":
            return np.arange(n)
        if self.scan == "serpentine":
            starts = np.flatnonzero(np.r_[True, self.alpha[1:] != self.alpha[:-1]])
            runs = np.split(np.arange(n), starts[1:])
            return np.concatenate([r if k % 2 == 0 else r[::-1] for k, r in enumerate(runs)])
        return np.random.default_rng([self.crc32(with_shots=False), 0x5CA7]).permutation(n)

    def crc32(self, with_shots: bool = True) -> int:
        """A stable 32-bit code: CRC-32 of the name, the angles (little-endian float64) and,
        ``with_shots``, the shots (a cube mixes it into its seed, :func:`sunlab.sim.simulate`).

        Parameters
        ----------
        with_shots : bool
            Whether the shots enter the code.

        Returns
        -------
        int
        """
        h = zlib.crc32(self.name.encode())
        for a in (self.alpha, self.beta):
            h = zlib.crc32(np.ascontiguousarray(a, dtype="<f8").tobytes(), h)
        return zlib.crc32(int(self.shots).to_bytes(4, "little"), h) if with_shots else h

    def beta_approach(self, *, home_deg: float = 0.0) -> np.ndarray:
        """Direction (+1 up, -1 down) in which the inner axis arrives at each pose, by pose.

        The stage starts at ``home_deg``, last moved upward (as a homing ends). Along
        :meth:`visit_order` a pose is reached in the direction of the move from the previous
        one, or the last direction if beta did not move (the gear stays on its flank);
        ``approach="unidirectional"`` reaches every pose upward (overshoot, then return).

        Parameters
        ----------
        home_deg : float
            Inner-axis angle beta at which the stage starts, deg.

        Returns
        -------
        numpy.ndarray of int8, shape (pose,)
            +1 or -1 per pose, in the plan's (not the visit's) order.

        Examples
        --------
        >>> g = grid(0, 1, 1, 0, 2, 1, shots=1, scan="serpentine")
        >>> g.beta_approach().tolist()   # row 2 runs down; its first visit (beta 2) keeps +1
        [1, 1, 1, -1, -1, 1]
        >>> g.with_motion(approach="unidirectional").beta_approach().tolist()
        [1, 1, 1, 1, 1, 1]
        """
        out = np.ones(len(self), dtype=np.int8)
        if self.approach == "unidirectional":
            return out
        last_b, last_d = float(home_deg), 1
        for p in self.visit_order():
            b = float(self.beta[p])
            if b != last_b:
                last_d = 1 if b > last_b else -1
            out[p] = last_d
            last_b = b
        return out

    def unstack_shape(self) -> tuple[int, int] | None:
        """(n_alpha, n_beta) if the plan is a full alpha-outer grid, else None.

        Returns
        -------
        (int, int) or None
            The numbers of distinct alpha and beta when the poses are every (alpha, beta) pair,
            both ascending, alpha the outer loop; None for any other plan.
        """
        ua, ub = np.unique(self.alpha), np.unique(self.beta)
        if (ua.size * ub.size == len(self) and np.array_equal(self.alpha, np.repeat(ua, ub.size))
                and np.array_equal(self.beta, np.tile(ub, ua.size))):
            return int(ua.size), int(ub.size)
        return None

    def __repr__(self) -> str:
        return (
            f"Plan(name={self.name!r}, poses={len(self)}, shots={self.shots}, scan={self.scan}, "
            f"alpha=[{self.alpha.min():g}, {self.alpha.max():g}] deg, "
            f"beta=[{self.beta.min():g}, {self.beta.max():g}] deg)"
        )


def _axis(vmin: float, vmax: float, step: float, name: str) -> np.ndarray:
    _check(np.isfinite(vmin) and np.isfinite(vmax) and np.isfinite(step), name,
           "non-finite bounds or step", "finite deg")
    _check(step > 0, f"{name}_step", repr(step), "a positive step in degrees", "pass e.g. 1.0.")
    _check(vmax >= vmin, f"{name}_min, {name}_max", f"{vmin!r} > {vmax!r}", "min <= max",
           "swap them.")
    n = int(np.floor((vmax - vmin) / step + 1e-9)) + 1
    # Built from integers so that -16.25 + 12 * 1.5 is exactly 1.75, not 1.7500000000000002.
    return np.round(vmin + step * np.arange(n), 10)


def grid(alpha_min: float, alpha_max: float, alpha_step: float, beta_min: float,
         beta_max: float, beta_step: float, shots: int = 8, name: str = "grid",
         scan: str = "raster", approach: str = "direct") -> Plan:
    """A regular grid of poses, alpha as the outer loop, bounds inclusive.

    Parameters
    ----------
    alpha_min, alpha_max, alpha_step : float
        Outer-axis range and step, degrees.
    beta_min, beta_max, beta_step : float
        Inner-axis range and step, degrees.
    shots, name : int, str
        Frames per pose and the plan's name.
    scan, approach : str
        The motion (:data:`SCANS`, :data:`APPROACHES`).

    Returns
    -------
    Plan

    Examples
    --------
    >>> p = grid(0, 2, 1, -1, 1, 1, shots=3)
    >>> len(p), p.alpha.tolist()[:4], p.beta.tolist()[:4]
    (9, [0.0, 0.0, 0.0, 1.0], [-1.0, 0.0, 1.0, -1.0])
    """
    a = _axis(float(alpha_min), float(alpha_max), float(alpha_step), "alpha")
    b = _axis(float(beta_min), float(beta_max), float(beta_step), "beta")
    return Plan(name, np.repeat(a, b.size), np.tile(b, a.size), shots, scan, approach)


def experiment(name: str, shots: int = 8, *, scan: str = PAPER_SCAN,
               approach: str = "direct") -> Plan:
    """The paper's experiment I (calibration), II (validation) or III (test), Table 3.

    Parameters
    ----------
    name : {"I", "II", "III"}
        Experiment name (case-insensitive; "1", "2", "3" also accepted).
    shots : int
        Frames per pose; the paper takes 8.
    scan, approach : str
        The motion; default :data:`PAPER_SCAN` (our inference) and a direct approach.

    Returns
    -------
    Plan
        400, 169 or 361 poses, listed alpha-outer (a grid) whatever the scan.

    Examples
    --------
    >>> [len(experiment(n)) for n in ("I", "II", "III")]
    [400, 169, 361]
    >>> p = experiment("II"); float(p.alpha.max()), float(p.beta.min())
    (1.75, -1.75)
    """
    key = {"1": "I", "2": "II", "3": "III"}.get(str(name).strip(), str(name).strip().upper())
    _check(key in EXPERIMENTS, "experiment", repr(name),
           "one of 'I', 'II', 'III' (docs/paper.md Table 3)",
           "use sunlab.plans.grid(...) for other poses.")
    return grid(*EXPERIMENTS[key], shots=shots, name=key, scan=scan, approach=approach)


def custom(alpha, beta, shots: int = 8, name: str = "custom", scan: str = "raster",
           approach: str = "direct") -> Plan:
    """A plan from explicit lists of commanded angles (degrees), one (alpha, beta) per pose.

    Parameters
    ----------
    alpha, beta : array_like of float
        Commanded outer- and inner-axis angles, deg, one each per pose (same length).
    shots, name : int, str
        Frames per pose (the paper: 8) and the plan's name (a cube's ``experiment``).
    scan, approach : str
        The motion (:data:`SCANS`, :data:`APPROACHES`).

    Returns
    -------
    Plan
        The poses in the order given.

    Examples
    --------
    >>> p = custom([0.0, -5.0], [0.0, 3.0], shots=1)
    >>> p.alpha.tolist(), p.beta.tolist(), p.shots
    ([0.0, -5.0], [0.0, 3.0], 1)
    """
    return Plan(name, np.atleast_1d(np.asarray(alpha, dtype=float)),
                np.atleast_1d(np.asarray(beta, dtype=float)), shots, scan, approach)


def read_plan(spec, shots: int = 8, *, field: str = "plan") -> Plan:
    """A plan from its name (``"I"``, ``"II"``, ``"III"``, any case; Table 3) or from a CSV
    file with a header line ``alpha,beta`` and one pose (deg) per row, named after its stem.

    Parameters
    ----------
    spec : str or path
        Experiment name or CSV file.
    shots : int
        Frames per pose.
    field : str
        The caller's name for ``spec`` (e.g. ``"--plan"``), for the error messages.

    Returns
    -------
    Plan

    Examples
    --------
    >>> import pathlib, tempfile
    >>> read_plan("iii").name, len(read_plan("III"))
    ('III', 361)
    >>> path = pathlib.Path(tempfile.mkdtemp()) / "corners.csv"
    >>> _ = path.write_text("alpha,beta\\n-10,5\\n0,0\\n")
    >>> p = read_plan(path, shots=2)
    >>> p.name, p.alpha.tolist(), p.shots
    ('corners', [-10.0, 0.0], 2)
    """
    from pathlib import Path

    if str(spec).upper() in EXPERIMENTS:
        return experiment(str(spec).upper(), shots=shots)
    if not Path(spec).is_file():
        raise ConfigurationError(f"{field}: found {str(spec)!r}, expected I, II, III or an "
                                 "existing CSV file")
    import pandas as pd

    table = pd.read_csv(spec)
    missing = {"alpha", "beta"} - set(table.columns)
    if missing:
        raise ConfigurationError(
            f"{field} {spec}: columns {sorted(table.columns)}, missing {sorted(missing)}. "
            "Fix: a CSV with a header line 'alpha,beta' and one pose (deg) per row")
    return custom(table["alpha"], table["beta"], shots=shots, name=Path(spec).stem)


def zero_check(plan: Plan, checks: int = 4, *, shots: int | None = None) -> Plan:
    """The zero-pose check of a run: ``checks`` visits of the zero pose, each approached upward.

    Taken right after the stage is homed, before the run's poses, under the run's name, so that
    on the virtual bench it shares the run's homing offset: the zero-pose centroids of two runs
    measure how far their inner-axis zeros differ
    (:func:`sunlab.reproduce.remedy.fit_correction`).

    Parameters
    ----------
    plan : Plan
        The run.
    checks : int
        Visits of the zero pose (each a pose: the axis moves away and back between them).
    shots : int, optional
        Frames per visit; default the run's.

    Returns
    -------
    Plan
        ``checks`` poses at alpha = beta = 0, raster scan, unidirectional approach.

    Examples
    --------
    >>> z = zero_check(experiment("III"))
    >>> len(z), z.name, z.approach, float(z.alpha.max()), float(z.beta.max())
    (4, 'III', 'unidirectional', 0.0, 0.0)
    """
    _check(isinstance(plan, Plan), "plan", type(plan).__name__, "a sunlab.plans.Plan")
    n = _positive_int("checks", checks, "a positive number of zero-pose visits", "checks=4.")
    return Plan(plan.name, np.zeros(n), np.zeros(n), plan.shots if shots is None else shots,
                "raster", "unidirectional")
