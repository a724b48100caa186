"""The geometric models as calibrations: ideal model (1) and optimised model (3)-(4).

Both share the :class:`~sunlab.calibration.Calibration` interface so that they sit beside the
high-accuracy functions in every comparison. The equations are in :mod:`sunlab.geometry`.

Examples
--------
>>> import numpy as np
>>> from sunlab import sim
>>> a, b = np.meshgrid(np.arange(-17.0, 3.0), np.arange(-2.0, 18.0), indexing="ij")
>>> cen = sim.synthetic_centroids(a.ravel(), b.ravel(), shots=1, delta_f_mm=0.094)
>>> opt = OptimisedModel().fit(cen)
>>> round(opt.result.delta_f_mm, 6)
0.094
"""

from __future__ import annotations

import numpy as np

from .. import geometry
from ..errors import ConfigurationError, SchemaError
from .artifact import POSITIVE, check_parameters
from .base import Calibration

__all__ = ["IdealModel", "OptimisedModel"]

_SENSOR = ("mask_distance_mm", "pixel_pitch_mm", "x_cf_px", "y_cf_px")
#: The numbers of a saved optimised fit (mm, deg, px).
_FIT_NUMBERS = ("delta_f_mm", "alpha0", "beta0", "x_zp", "y_zp", "x_cf", "y_cf",
                "mask_distance_mm", "pixel_pitch_mm")


def _number_rules(keys) -> dict:
    """One finite number per key, the lengths (mm) positive."""
    return {k: (POSITIVE,) if k in ("mask_distance_mm", "pixel_pitch_mm") else () for k in keys}


def sensor_attrs(attrs: dict, *, name: str = "train") -> dict:
    """The sensor attributes a geometric model needs, read from a table's attributes.

    Parameters
    ----------
    attrs : dict
        Attributes of a centroid table (or frame cube).
    name : str
        The table's name in an error message.

    Returns
    -------
    dict
        ``{"mask_distance_mm", "pixel_pitch_mm", "x_cf_px", "y_cf_px"}`` as floats (mm, mm,
        px, px).

    Examples
    --------
    >>> sensor_attrs({"mask_distance_mm": 5, "pixel_pitch_mm": 0.007, "x_cf_px": 1, "y_cf_px": 2})
    {'mask_distance_mm': 5.0, 'pixel_pitch_mm': 0.007, 'x_cf_px': 1.0, 'y_cf_px': 2.0}
    """
    out = {}
    for key in _SENSOR:
        value = attrs.get(key)
        if value is None or not np.isfinite(float(value)):
            raise SchemaError(f"{name}.attrs[{key!r}]", value, "the sensor attribute of the frame "
                              "cube", f"a geometric model needs it: write {key} in the frames' "
                              "sensor.json (or pass it to sunlab import), carry the cube's attrs "
                              "into the centroid table (a CSV table: sunlab.io.open_centroids("
                              "path, attrs={...}), or a sensor.json beside it for the command "
                              "line), or pass the value to the model explicitly; the polynomial "
                              "and interpolation methods do not need it")
        out[key] = float(value)
    return out


#: Poses within this distance of alpha = beta = 0 (deg) count as the zero pose.
ZERO_POSE_TOL_DEG = 1e-9


class IdealModel(Calibration):
    """The ideal geometric model, eq. (1): nothing is fitted.

    ``fit`` only reads F, the pixel pitch and (x_cf, y_cf) from the training table's attributes
    (``mask_distance_mm``, ``pixel_pitch_mm``, ``x_cf_px``, ``y_cf_px``), unless given here.

    Parameters
    ----------
    mask_distance_mm, pixel_pitch_mm, x_cf_px, y_cf_px : float, optional
        Override the table's sensor attributes (mm, mm, px, px).

    Notes
    -----
    .. math:: \\tan\\alpha = \\frac{(x - x_{cf})p}{F}, \\qquad
              \\tan\\beta = \\frac{(y - y_{cf})p\\cos\\alpha}{F}  \\qquad (1)

    Examples
    --------
    >>> from sunlab import sim
    >>> cen = sim.synthetic_centroids([0.0, -10.0], [0.0, 5.0])
    >>> est = IdealModel().fit(cen).predict(cen)
    >>> [round(float(v), 9) for v in est.alpha.isel(shot=0)]
    [0.0, -10.0]
    """

    kind = "ideal"
    label = "ideal model (1)"

    def __init__(self, mask_distance_mm=None, pixel_pitch_mm=None, x_cf_px=None, y_cf_px=None):
        super().__init__()
        self._given = {"mask_distance_mm": mask_distance_mm, "pixel_pitch_mm": pixel_pitch_mm,
                       "x_cf_px": x_cf_px, "y_cf_px": y_cf_px}
        self.sensor: dict | None = None

    def _fit(self, data, validation) -> None:
        attrs = {**data.attrs, **{k: v for k, v in self._given.items() if v is not None}}
        self.sensor = sensor_attrs(attrs)

    def _predict_xy(self, x, y):
        s = self.sensor
        return geometry.ideal_angles(x, y, s["mask_distance_mm"], s["pixel_pitch_mm"],
                                     s["x_cf_px"], s["y_cf_px"])

    def _parameters(self) -> dict:
        return dict(self.sensor)

    @classmethod
    def _check_parameters(cls, p: dict) -> None:
        """Sizes, finiteness and ranges of a document's parameters, before any array is
        built (:func:`sunlab.calibration.artifact.from_dict`)."""
        check_parameters(p, _number_rules(_SENSOR))

    @classmethod
    def _from_parameters(cls, p: dict):
        obj = cls()
        obj.sensor = sensor_attrs(p, name="parameters")
        return obj


def fit_optimised(data, sensor: dict, fit_zero_pose: bool | None = True, *,
                  n_boot: int = 0, block_deg: float = 2.0, seed: int = 0):
    """Fit the optimised model on training points; return a :class:`geometry.OptimisedFit`.

    The zero-pose centroid is fitted jointly with dF, alpha0, beta0 (``fit_zero_pose=True``,
    default); ``False`` takes the mean of the training points at alpha = beta = 0 instead, and
    ``None`` measures it when that pose exists. Standard errors come from a block bootstrap
    (``n_boot`` replicas; 0, the default here, for the Jacobian ones) whose blocks are the
    poses in squares of ``block_deg`` x ``block_deg`` degrees of the grid: every shot of a pose
    shares its platform error, and neighbouring poses share the pixel pattern under the spot,
    so the residuals are correlated within a block and the Jacobian's white-noise errors are
    too small.

    Parameters
    ----------
    data : types.SimpleNamespace
        Training points: centroids ``x``, ``y`` (px) and commanded ``alpha``, ``beta`` (deg)
        (the training points :meth:`sunlab.calibration.Calibration.fit` takes from a table).
    sensor : dict
        ``mask_distance_mm`` (nominal F, mm) and ``pixel_pitch_mm`` (p, mm), as
        :func:`sunlab.calibration.base.sensor_attrs` returns them.
    fit_zero_pose : bool or None
        Fit the zero-pose centroid (True), measure it at alpha = beta = 0 (False), or measure
        it only when that pose exists (None).
    n_boot : int
        Block-bootstrap replicas for the standard errors; 0 or 1: Jacobian errors.
    block_deg : float
        Side of the bootstrap's blocks of poses, deg.
    seed : int
        Seed of the bootstrap's resampling.

    Returns
    -------
    sunlab.geometry.OptimisedFit
        dF (mm), alpha0, beta0 (deg), the zero-pose centroid and the foot of the hole (px) of
        eqs. (3)-(4), their standard errors and the RMS residuals (deg).

    Raises
    ------
    ConfigurationError
        ``fit_zero_pose`` is False and no training point lies at alpha = beta = 0.
    """
    zero = (np.abs(data.alpha) <= ZERO_POSE_TOL_DEG) & (np.abs(data.beta) <= ZERO_POSE_TOL_DEG)
    free = (not zero.any()) if fit_zero_pose is None else bool(fit_zero_pose)
    if not free and not zero.any():
        raise ConfigurationError(
            "fit_zero_pose: found False, but the training table has no pose at alpha = beta = 0 "
            "to measure the zero-pose centroid from. Fix: add that pose to the plan, or pass "
            "fit_zero_pose=True (fit it jointly)"
        )
    zp = (None, None) if free else (float(data.x[zero].mean()), float(data.y[zero].mean()))
    blocks = (np.floor(data.alpha / block_deg) * 100003 + np.floor(data.beta / block_deg))
    return geometry.fit_optimised_model(
        data.x, data.y, data.alpha, data.beta, sensor["mask_distance_mm"],
        sensor["pixel_pitch_mm"], *zp, blocks=blocks, n_boot=n_boot, seed=seed,
    )


class OptimisedModel(Calibration):
    """The optimised geometric model, eqs. (3)-(4): fits dF, alpha0, beta0.

    Parameters
    ----------
    fit_zero_pose : bool, optional
        True (default): fit the zero-pose centroid jointly with the other parameters from
        every pose; False: measure it (mean of the ok shots at alpha = beta = 0); None:
        measure it when the training table has that pose, else fit it.
    average : {"pose", "shot"}
        Fit on pose-mean centroids (default) or on every ok shot.
    n_boot : int
        Block-bootstrap replicas for the standard errors (0: Jacobian errors, which assume
        white residuals); see :func:`fit_optimised`.

    Attributes
    ----------
    result : sunlab.geometry.OptimisedFit
        The fitted parameters (``delta_f_mm``, ``alpha0``, ``beta0``, ...), their standard
        errors and the fit's RMS residuals.

    Notes
    -----
    Minimises :math:`\\sum_i (\\alpha_m - \\alpha_i)^2 + (\\beta_m - \\beta_i)^2` with
    :func:`sunlab.geometry.fit_optimised_model`; the paper found alpha0 = 1.864 deg,
    beta0 = 0.415 deg, dF = 0.094 mm (docs/paper.md sec. 4.1). The mounting is the rigid
    rotation R_y(-alpha0) R_x(beta0) that the virtual bench applies (our reconstruction of the
    lost eqs. (3)-(4), :mod:`sunlab.geometry`), so the fit estimates the bench's own numbers.

    Examples
    --------
    >>> OptimisedModel().label
    'optimised model (3)-(4)'
    """

    kind = "optimised"
    label = "optimised model (3)-(4)"

    def __init__(self, fit_zero_pose: bool | None = True, average: str = "pose",
                 n_boot: int = 200):
        super().__init__()
        self.fit_zero_pose = fit_zero_pose
        self.average = average
        self.n_boot = int(n_boot)
        self.result: geometry.OptimisedFit | None = None

    def min_poses(self) -> int:
        """Fewest distinct training poses: two equations per pose for dF, alpha0, beta0 and the
        zero-pose centroid (five unknowns).

        Returns
        -------
        int
            3.
        """
        return 3  # dF, alpha0, beta0 (+ the zero pose): two equations per pose

    def _fit(self, data, validation) -> None:
        self.result = fit_optimised(data, sensor_attrs(data.attrs), self.fit_zero_pose,
                                    n_boot=self.n_boot)

    def _predict_xy(self, x, y):
        return self.result.angles(x, y)

    def _parameters(self) -> dict:
        return {"fit_zero_pose": self.fit_zero_pose, **self.result.to_dict()}

    @classmethod
    def _check_parameters(cls, p: dict) -> None:
        """Sizes, finiteness and ranges of a document's parameters, before any array is
        built (:func:`sunlab.calibration.artifact.from_dict`)."""
        check_parameters(p, _number_rules(_FIT_NUMBERS))

    @classmethod
    def _from_parameters(cls, p: dict):
        obj = cls(fit_zero_pose=p.get("fit_zero_pose"))
        obj.result = optimised_fit_from_dict(p)
        return obj


def optimised_fit_from_dict(p: dict) -> geometry.OptimisedFit:
    """The fitted optimised model (3)-(4) from its dictionary
    (:meth:`sunlab.geometry.OptimisedFit.to_dict`, as saved files hold it); files written
    before the rotation mounting hold the additive form's parameters.

    Parameters
    ----------
    p : dict
        The fit's fields (:class:`sunlab.geometry.OptimisedFit`); ``mounting`` defaults to
        ``"additive"`` and ``stderr_method`` to ``"jacobian"`` when absent, a standard error
        of None reads as NaN.

    Returns
    -------
    sunlab.geometry.OptimisedFit
        The fit, its lengths in mm, angles in deg and centroids in px as saved.

    Examples
    --------
    >>> from sunlab import sim
    >>> fit = OptimisedModel().fit(sim.synthetic_centroids([0.0, -5, -10, 0, -5, -10],
    ...                                                         [0.0, 0, 0, 5, 5, 5])).result
    >>> optimised_fit_from_dict(fit.to_dict()) == fit
    True
    """
    fields = geometry.OptimisedFit.__dataclass_fields__
    defaults = {"mounting": "additive", "stderr_method": "jacobian"}
    kw = {k: p.get(k, defaults.get(k)) for k in fields}
    kw["stderr"] = {k: (np.nan if v is None else float(v)) for k, v in kw["stderr"].items()}
    return geometry.OptimisedFit(**kw | {k: float(kw[k]) for k in _FIT_NUMBERS})
