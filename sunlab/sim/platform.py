"""The two-axis rotation platform: commanded versus true angles, and the sensor's mounting.

The outer axis sets alpha, the inner axis beta (the paper's eq. (1) convention,
``docs/nomenclature.md``). The true axis angles for a commanded pose are

.. math::

    \\alpha_t = \\alpha_c (1 + k_\\alpha) + \\delta\\alpha_{enc} + e_\\alpha + j_\\alpha, \\qquad
    \\beta_t  = \\beta_c (1 + k_\\beta) + \\delta\\beta_{enc} + w \\sin(2\\pi\\alpha_c / P + \\phi)
               + e_\\beta + j_\\beta

with encoder scale errors k, encoder zero offsets, an inner-axis wobble of amplitude w and period P
in the outer angle (a systematic, learnable error), a per-pose positioning error e drawn uniformly
in +-``*_pose_error_deg`` (bounded: the stage's positioning resolution and backlash; docs/paper.md
sec. 8 shows that sigma / mu of the paper's local errors is about 0.6, the value of a uniform, not
a normal, error) and a per-shot jitter j (normal). Three faults of the inner axis depend on the
motion history or on beta (:mod:`sunlab.reproduce.fault` tells them apart): a backlash b,
entering as :math:`-d\\,b` with the direction d = +-1 in which the axis reached the pose (the
plan's scan order and approach, :meth:`sunlab.plans.Plan.beta_approach`); a homing offset drawn
once per run; a periodic gear error :math:`g \\sin(2\\pi\\beta_c / P_g + \\phi_g)`. The sun vector
in the sensor frame is

.. math::

    \\mathbf{s} = R_z(\\gamma_0) R_y(-\\alpha_0) R_x(\\beta_0)\\;
                 R_y(-\\alpha_t)\\, R_u(\\beta_t)\\,
    \\mathbf{e}_z, \\qquad \\mathbf{u} = (\\cos\\epsilon, \\sin\\epsilon, 0),

where the inner axis u leans by the non-orthogonality epsilon toward the outer axis y and the
fixed rotation in front is the sensor's mounting on the platform (alpha0, beta0, gamma0). For
alpha0 = beta0 = 0 and epsilon = 0 this is :func:`sunlab.geometry.sun_vector`.

Defaults: a generic, imperfect platform for experiments (``Platform()``), not the paper's. The
paper's preset (:meth:`sunlab.sim.Bench.paper_single_hole`) sets every error term from the
identification of docs/identification.md and turns off what no source gives (wobble,
non-orthogonality). The defaults:

* mounting alpha0 = 1.864 deg, beta0 = 0.415 deg: the paper's fitted values (sec. 4.1).
* per-pose error, uniform in +-0.008 deg (alpha) and +-0.028 deg (beta): the size of the
  paper's common-mode error (the mean absolute value of U(-0.008, 0.008) is Table 5's 100-hole
  alpha mu, 0.004 deg).
* inner-axis wobble 0.006 deg with a 10 deg period and non-orthogonality 0.02 deg: examples of
  a systematic, learnable error (no source gives either for the paper's stage).
* jitter 0.0005 deg RMS per shot on each axis: with the centroid noise, the paper's per-shot
  scatter (M - mu of about 0.001 deg, docs/paper.md sec. 5).

Examples
--------
>>> p = Platform()
>>> p.alpha0_deg, p.beta0_deg
(1.864, 0.415)
"""

from __future__ import annotations

import math
import zlib
from dataclasses import dataclass, replace

import numpy as np

from ..geometry.model import rotation_x, rotation_y, rotation_z
from .source import _check

__all__ = ["Platform"]


@dataclass(frozen=True)
class Platform:
    """Errors of the two-axis platform and of the sensor's mounting on it (module notes).

    Parameters
    ----------
    alpha0_deg, beta0_deg, gamma0_deg : float
        Mounting rotation of the sensor on the inner gimbal, deg (gamma0: about the boresight).
    alpha_offset_deg, beta_offset_deg : float
        Encoder zero offsets, deg.
    alpha_scale, beta_scale : float
        Encoder scale errors (relative).
    nonorthogonality_deg : float
        Lean of the inner axis toward the outer axis, deg.
    beta_wobble_deg, beta_wobble_period_deg, beta_wobble_phase_deg : float
        Inner-axis wobble: amplitude, period in the outer angle and phase, deg.
    alpha_pose_error_deg, beta_pose_error_deg : float
        Half-width of the uniform per-pose positioning error, deg.
    alpha_jitter_deg, beta_jitter_deg : float
        RMS per-shot jitter, deg.
    beta_backlash_deg : float
        Inner-axis backlash, deg (half the dead band of the worm gear): the load lags the motor,
        so a pose reached upward ends ``beta_backlash_deg`` below its target and one reached
        downward as far above, :math:`\\beta_t = \\ldots - d\\,b` with the approach direction
        d = +-1 of :meth:`sunlab.plans.Plan.beta_approach` (the motion history: scan order and
        approach). A serpentine scan alternates d row by row, which makes beta's per-pose error
        bimodal (:mod:`sunlab.reproduce.fault` finds it from the motion record); the presets
        carry none (no hypothesis of docs/identification.md has backlash).
    beta_homing_deg : float
        Half-width of the inner axis's homing (zero) offset, deg: drawn uniformly once per run
        (each time the stage is homed), the same for every pose of the run; a calibration
        absorbs its own run's offset, so a test run is off by the difference of the two.
    beta_drift_deg : float
        Thermal drift of the inner axis's zero per run, deg: a run's zero is off by its place
        in the session (:data:`RUN_ORDER`: I 0, II 1, III 2) times this, as
        the lamp and the stage warm up between experiments I and III; like the homing offset
        it is constant within a run, and a zero-pose check taken with the run shares it.
    beta_rehoming_deg : float
        Shift of the inner axis's zero between the session of experiment I and the session of
        II and III, deg (:data:`SESSION`: I 0, II 1, III 1): the stage homed
        again between them lands its zero elsewhere by its homing repeatability. Constant
        within a run and shared by the run's zero-pose check, like the drift.
    beta_gear_deg, beta_gear_period_deg, beta_gear_phase_deg : float
        Periodic gear error of the inner axis: amplitude, period in beta and phase, deg
        (a worm's eccentricity repeats once per worm turn). With a period under two grid steps
        a calibration on a 1-degree grid only sees it aliased.
    """

    alpha0_deg: float = 1.864
    beta0_deg: float = 0.415
    gamma0_deg: float = 0.0
    alpha_offset_deg: float = 0.0
    beta_offset_deg: float = 0.0
    alpha_scale: float = 0.0
    beta_scale: float = 0.0
    nonorthogonality_deg: float = 0.02
    beta_wobble_deg: float = 0.006
    beta_wobble_period_deg: float = 10.0
    beta_wobble_phase_deg: float = 40.0
    alpha_pose_error_deg: float = 0.008
    beta_pose_error_deg: float = 0.028
    alpha_jitter_deg: float = 0.0005
    beta_jitter_deg: float = 0.0005
    beta_backlash_deg: float = 0.0
    beta_homing_deg: float = 0.0
    beta_drift_deg: float = 0.0
    beta_rehoming_deg: float = 0.0
    beta_gear_deg: float = 0.0
    beta_gear_period_deg: float = 1.6
    beta_gear_phase_deg: float = 0.0

    def __post_init__(self):
        rules = [(n, "a finite number", math.isfinite) for n in self.__dict__]
        rules += [(n, ">= 0 deg", lambda v: v >= 0) for n in (
            "alpha_pose_error_deg", "beta_pose_error_deg", "alpha_jitter_deg", "beta_jitter_deg",
            "beta_wobble_deg", "beta_backlash_deg", "beta_homing_deg", "beta_gear_deg")]
        rules += [(n, "a positive period in deg", lambda v: v > 0)
                  for n in ("beta_gear_period_deg", "beta_wobble_period_deg")]
        rules += [(n, "a small angle (|value| < 45 deg)", lambda v: abs(v) < 45)
                  for n in ("alpha0_deg", "beta0_deg", "gamma0_deg", "nonorthogonality_deg")]
        for name, expected, ok in rules:
            _check(ok(getattr(self, name)), f"platform.{name}", getattr(self, name), expected,
                   "see the defaults of sunlab.sim.Platform.")

    @classmethod
    def ideal(cls) -> Platform:
        """A perfect platform: true angles equal commanded ones, sensor aligned.

        Returns
        -------
        Platform
            Every error, offset and mounting angle zero (the periods keep their defaults).
        """
        return cls(**{k: 0.0 for k in cls.__dataclass_fields__
                      if k not in ("beta_wobble_period_deg", "beta_gear_period_deg")})

    def replace(self, **changes) -> Platform:
        """A copy with some fields changed.

        Parameters
        ----------
        **changes
            Field names of :class:`Platform` and their new values.

        Returns
        -------
        Platform
            A new platform; this one is unchanged.
        """
        return replace(self, **changes)

    def systematic(self, alpha_cmd, beta_cmd):
        """True angles without the random parts (encoder, wobble, gear error), deg.

        Parameters
        ----------
        alpha_cmd, beta_cmd : float or array_like
            Commanded outer and inner angles, deg.

        Returns
        -------
        alpha, beta : float or numpy.ndarray
            The encoder's scale and offset applied to each axis, plus on beta the wobble (a
            sinusoid of alpha) and the gear error (a sinusoid of beta), deg.
        """
        a, b = np.asarray(alpha_cmd, dtype=float), np.asarray(beta_cmd, dtype=float)
        at = a * (1 + self.alpha_scale) + self.alpha_offset_deg
        bt = b * (1 + self.beta_scale) + self.beta_offset_deg
        if self.beta_wobble_deg:
            bt = bt + self.beta_wobble_deg * np.sin(2 * np.pi * a / self.beta_wobble_period_deg
                                                    + math.radians(self.beta_wobble_phase_deg))
        if self.beta_gear_deg:
            bt = bt + self.beta_gear_deg * np.sin(2 * np.pi * b / self.beta_gear_period_deg
                                                  + math.radians(self.beta_gear_phase_deg))
        return at, bt

    def mount_matrix(self) -> np.ndarray:
        """The sensor's mounting rotation R_z(gamma0) R_y(-alpha0) R_x(beta0).

        Returns
        -------
        numpy.ndarray, shape (3, 3)
            Rotation from the platform's frame into the sensor's.
        """
        return (rotation_z(math.radians(self.gamma0_deg)) @ rotation_y(
            -math.radians(self.alpha0_deg)) @ rotation_x(math.radians(self.beta0_deg)))


def sensor_sun_vector(platform: Platform, alpha_true, beta_true) -> np.ndarray:
    """Unit vector toward the sun in the sensor frame for true axis angles (deg).

    Parameters
    ----------
    platform : Platform
        Mounting and axis geometry.
    alpha_true, beta_true : float or array_like
        True outer and inner axis angles, deg.

    Returns
    -------
    numpy.ndarray, shape (..., 3)

    Examples
    --------
    >>> from sunlab.geometry import sun_vector
    >>> s = sensor_sun_vector(Platform.ideal(), -10.0, 5.0)
    >>> bool(np.allclose(s, sun_vector(-10.0, 5.0)))
    True
    """
    a = np.deg2rad(np.asarray(alpha_true, dtype=float))
    b = np.deg2rad(np.asarray(beta_true, dtype=float))
    eps = math.radians(platform.nonorthogonality_deg)
    # R_u(beta) e_z for the inner axis u = (cos eps, sin eps, 0) (Rodrigues), then R_y(-alpha).
    v = np.stack(np.broadcast_arrays(math.sin(eps) * np.sin(b), -math.cos(eps) * np.sin(b),
                                     np.cos(b)), axis=-1)
    ca, sa = np.cos(a), np.sin(a)
    g = np.stack([ca * v[..., 0] - sa * v[..., 2], v[..., 1], sa * v[..., 0] + ca * v[..., 2]],
                 axis=-1)
    return np.einsum("...j,ij->...i", g, platform.mount_matrix())  # the same sums for any n


# --------------------------------------------------------------------------- random errors
#: The place of each experiment of Table 3 in the session (docs/paper.md sec. 5 runs them in
#: this order): a run named otherwise is taken at the session's start.
RUN_ORDER = {"I": 0, "II": 1, "III": 2}
#: The session of each experiment: experiment I in one, II and III in the next, after the
#: stage was homed again (``Platform.beta_rehoming_deg``); a run named otherwise is in the
#: first.
SESSION = {"I": 0, "II": 1, "III": 1}

_TAG_POSE = 0x905E
_TAG_SHOT = 0x5407
_TAG_HOME = 0x803E

def _entropy(seed) -> list[int]:
    """Seed as a list of non-negative ints (an int or a sequence of ints)."""
    items = [seed] if isinstance(seed, int | np.integer) else list(seed)
    _check(all(isinstance(v, int | np.integer) and not isinstance(v, bool) and v >= 0
               for v in items), "seed", seed, "a non-negative integer or a sequence of them",
           "pass seed=0.")
    return [int(v) for v in items]


def _pose_error(plat: Platform, key: list[int], pose: int, approach: int = 1,
                homing: float = 0.0) -> tuple[float, float]:
    """Per-pose errors (alpha, beta), deg: uniform positioning errors, plus on beta the
    backlash for the approach direction (+1 up, -1 down; :meth:`Plan.beta_approach`) and the
    run's homing offset (:func:`_homing`)."""
    eb = homing - approach * plat.beta_backlash_deg
    if not (plat.alpha_pose_error_deg or plat.beta_pose_error_deg):
        return 0.0, float(eb)
    u = np.random.default_rng(np.random.SeedSequence(key + [_TAG_POSE, int(pose)]))
    u = u.uniform(-1.0, 1.0, 3)
    return float(u[0]) * plat.alpha_pose_error_deg, float(u[1]) * plat.beta_pose_error_deg + eb


def _homing(plat: Platform, seed_key: list[int], run: str) -> float:
    """The inner axis's zero offset of one run, deg: its place in the session times the
    thermal drift per run (:data:`RUN_ORDER`, ``beta_drift_deg``), its session times the shift
    at a new homing (:data:`SESSION`, ``beta_rehoming_deg``), plus a homing offset uniform
    in +-``beta_homing_deg``, drawn from the seed and the run's name (a zero-pose check taken
    with the run, :func:`sunlab.plans.zero_check`, shares both)."""
    drift = (plat.beta_drift_deg * RUN_ORDER.get(str(run), 0)
             + plat.beta_rehoming_deg * SESSION.get(str(run), 0))
    if not plat.beta_homing_deg:
        return drift
    tag = zlib.crc32(str(run).encode())
    u = np.random.default_rng(np.random.SeedSequence(list(seed_key) + [_TAG_HOME, tag]))
    return drift + float(u.uniform(-1.0, 1.0)) * plat.beta_homing_deg


def homing_offset(bench, seed, run: str) -> float:
    """The inner axis's zero offset of one named run (one homing) on a bench, deg.

    The run's place in the session (:data:`RUN_ORDER`) times ``beta_drift_deg``, plus its
    session (:data:`SESSION`) times ``beta_rehoming_deg``, plus a homing offset uniform in
    +-``bench.platform.beta_homing_deg`` drawn from the seed and the run's name, as
    :func:`sunlab.sim.simulate` draws it for a plan of that name (a zero-pose check taken with
    the run, :func:`sunlab.plans.zero_check`, shares it): the bench's own value of what
    :func:`sunlab.reproduce.remedy.fit_correction` estimates from the zero-pose checks.

    Parameters
    ----------
    bench : Bench
    seed : int or sequence of int
        Seed of the experiment (as :func:`sunlab.sim.simulate`).
    run : str
        The run's name: a plan's name (``"I"``, ``"II"``, ``"III"``, ...).

    Returns
    -------
    float
        The zero offset of the inner axis (beta) for that run, deg.

    Examples
    --------
    >>> from sunlab.sim import Bench
    >>> b = Bench.paper_single_hole()
    >>> round(homing_offset(b, 0, "III") - homing_offset(b, 0, "I"), 4)  # the new homing
    0.0238
    >>> h = homing_offset(b.replace(platform__beta_homing_deg=0.01), 0, "I")
    >>> bool(abs(h) <= 0.01)
    True
    """
    return _homing(bench.platform, _entropy(seed), run)


def _jitter(plat: Platform, key: list[int], pose: int, shot: int) -> tuple[float, float]:
    if not (plat.alpha_jitter_deg or plat.beta_jitter_deg):
        return 0.0, 0.0
    j = np.random.default_rng(np.random.SeedSequence(key + [_TAG_SHOT, int(pose), int(shot)]))
    j = j.standard_normal(2)
    return float(j[0]) * plat.alpha_jitter_deg, float(j[1]) * plat.beta_jitter_deg


def platform_pose(bench, alpha_cmd: float, beta_cmd: float, *, seed, pose: int, shot: int,
                  approach: int = 1, run: str | None = None) -> tuple[float, float]:
    """True platform angles (deg) for commanded ones, deterministic in (seed, pose, shot).

    The per-pose error (uniform, bounded) depends on (seed, pose), the jitter (normal) on
    (seed, pose, shot); the systematic errors (encoder, wobble, gear) on the commanded angles
    only; the inner axis's backlash on the direction ``approach`` (+1 up, -1 down) in which it
    reached the pose, and its homing offset on (seed, ``run``) (none when ``run`` is None).
    See :mod:`sunlab.sim.platform` for the model and its defaults.

    Parameters
    ----------
    bench : Bench
    alpha_cmd, beta_cmd : float
        Commanded outer and inner angles, deg, each within +-90 (exclusive).
    seed : int or sequence of int
        Seed of the experiment (as :func:`sunlab.sim.simulate`).
    pose, shot : int
        Index of the pose in its plan and of the shot at that pose.
    approach : {1, -1}
        Direction in which the inner axis reached the pose (up, down).
    run : str, optional
        The run's name, for its homing offset (:func:`homing_offset`).

    Returns
    -------
    alpha, beta : float
        True platform angles, deg.

    Examples
    --------
    >>> from sunlab.sim import Bench
    >>> b = Bench.paper_single_hole()
    >>> a, _ = platform_pose(b, -10.0, 5.0, seed=0, pose=3, shot=0)
    >>> bool(abs(a + 10.0) < 0.008 + 5 * 0.0005)
    True
    >>> platform_pose(b.ideal_platform(), -10.0, 5.0, seed=0, pose=3, shot=0)
    (-10.0, 5.0)
    """
    for name, v in (("alpha_cmd", alpha_cmd), ("beta_cmd", beta_cmd)):
        v = np.asarray(v, dtype=float)
        _check(bool(np.all(np.isfinite(v)) and np.all(np.abs(v) < 90.0)), name, v,
               "finite angles with |angle| < 90 deg", "command platform angles in degrees.")
    plat = bench.platform
    at, bt = plat.systematic(float(alpha_cmd), float(beta_cmd))
    key = _entropy(seed)
    _check(approach in (1, -1), "approach", approach, "+1 (reached upward) or -1 (downward)")
    home = 0.0 if run is None else _homing(plat, key, run)
    ea, eb = _pose_error(plat, key, pose, approach, home)
    ja, jb = _jitter(plat, key, pose, shot)
    return float(at) + ea + ja, float(bt) + eb + jb


def _platform_table(bench, plan, key: list[int]):
    """True angles (pose, shot) of a whole plan; identical to :func:`platform_pose` per frame
    (with each pose's approach direction from the plan's motion and the plan's name as run)."""
    plat = bench.platform
    ta, tb = np.empty((2, len(plan), plan.shots))
    approach, home = plan.beta_approach(), _homing(plat, key[:-1], plan.name)
    for p in range(len(plan)):
        # scalar arithmetic, as in platform_pose, so that both agree to the last bit
        at, bt = plat.systematic(float(plan.alpha[p]), float(plan.beta[p]))
        ea, eb = _pose_error(plat, key, p, int(approach[p]), home)
        for s in range(plan.shots):
            ja, jb = _jitter(plat, key, p, s)
            ta[p, s] = float(at) + ea + ja
            tb[p, s] = float(bt) + eb + jb
    return ta, tb
