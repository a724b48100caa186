"""Neural-network calibration functions, the four strategies of the paper's Table 2.

One network per angle: a feed-forward net with one hidden layer of ``hidden`` tanh neurons and
one linear output neuron (docs/paper.md sec. 4.2). The strategies differ in what the net sees and
learns:

=====  ===============================================  =====================================
#      input                                            output
=====  ===============================================  =====================================
1      centroid (x, y)                                  platform angles (alpha, beta)
2      angles from the ideal model (1)                  platform angles
3      angles from the optimised model (3)-(4)          platform angles
4      centroid (x, y)                                  error of model (1): the estimate is
                                                        model (1) + the learned error
=====  ===============================================  =====================================

Training (our choices; the paper gives none): inputs and outputs standardised with the training
means and standard deviations; the mean squared error and its gradient computed by torch
autograd in float64 on the CPU (one thread), minimised full-batch by L-BFGS
(:func:`scipy.optimize.minimize`, ``L-BFGS-B``: torch's own ``LBFGS`` is an order of magnitude
slower on problems this small). With a validation table (experiment II) training stops when the
validation loss has not improved for ``patience`` iterations and the best weights are kept
(early stopping); without one it runs to convergence or ``max_iter``. Weights are initialised
from a ``torch.Generator`` seeded with ``seed`` (the beta net with ``seed + 1``) and
deterministic algorithms are on during the fit, so a fit is reproducible on a given machine.

torch is imported inside :meth:`NeuralNet.fit` only: predicting with a fitted or loaded network
is plain NumPy (the weights are stored as lists in the JSON artifact).

Examples
--------
>>> import numpy as np
>>> from sunlab import sim
>>> a, b = np.meshgrid(np.arange(-17.0, 3.0, 2), np.arange(-2.0, 18.0, 2), indexing="ij")
>>> cen = sim.synthetic_centroids(a.ravel(), b.ravel(), shots=1, delta_f_mm=0.094,
...                                    mounting_deg=(1.864, 0.415, 0.0))
>>> net = NeuralNet(strategy=4, hidden=6, max_iter=300).fit(cen)
>>> net.residuals["alpha"]["mean_abs"] < 0.01
True
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import minimize

from .. import geometry, parallel
from ..errors import ConfigurationError
from ..extras import require
from ._frames_torch import EarlyStop, session
from .artifact import POSITIVE, check_parameters
from .base import Calibration
from .model import IdealModel, fit_optimised, optimised_fit_from_dict, sensor_attrs

__all__ = ["NeuralNet"]

#: Table 2 of the paper: strategy -> (input, output).
STRATEGIES = {
    1: ("centroid (x, y)", "platform angles"),
    2: ("angles from the ideal model (1)", "platform angles"),
    3: ("angles from the optimised model (3)-(4)", "platform angles"),
    4: ("centroid (x, y)", "error of model (1)"),
}


_PURPOSE = "the neural-network calibration (NeuralNet)"
_SETTINGS = ("strategy", "hidden", "seed", "max_iter", "patience", "weight_decay")


def _forward(z: np.ndarray, net: dict) -> np.ndarray:
    """NumPy forward pass of one standardised network: tanh hidden layer, linear output."""
    h = np.tanh(z @ net["W1"].T + net["b1"])
    return h @ net["W2"] + net["b2"]


class NeuralNet(Calibration):
    """Neural-network calibration (one net per angle), strategies 1-4 of Table 2.

    Parameters
    ----------
    strategy : {1, 2, 3, 4}
        Training strategy (module docstring).
    hidden : int
        Number n of tanh neurons of the hidden layer.
    seed : int
        Seed of the weight initialisation.
    max_iter : int
        Most L-BFGS iterations per network.
    patience : int
        Iterations without validation improvement before early stopping.
    weight_decay : float
        L2 penalty on the weights (standardised units); 0 by default.
    average : {"pose", "shot"}
        Train on pose-mean centroids (default) or on every ok shot.
    reference : {"design", "zero_pose"}
        Where model (1) of strategies 2 and 4 puts (x_cf, y_cf): the design projection of the
        hole (the table's ``x_cf_px``, ``y_cf_px``, fixed at the fit), or the zero-pose
        centroid measured with each run (the table's ``zero_pose_x_px``, ``zero_pose_y_px``,
        read at the fit from the training run and at every prediction from the run predicted):
        the sensor re-zeroed on each run's zero-pose frames. That removes an offset of a whole
        run (the inner axis's homing) and adds the zero-pose frames' own error as a constant.

    Attributes
    ----------
    history : dict
        Per angle: iterations run, the iteration kept, final training and validation losses
        (mean squared error in standardised units).

    Examples
    --------
    >>> NeuralNet(strategy=4, hidden=8).label
    'NN strategy 4'
    """

    kind = "neural"

    def __init__(self, strategy: int = 4, hidden: int = 8, seed: int = 0, *,
                 max_iter: int = 3000, patience: int = 200, weight_decay: float = 0.0,
                 average: str = "pose", reference: str = "design"):
        super().__init__()
        if reference not in ("design", "zero_pose"):
            raise ConfigurationError(f"reference: found {reference!r}, expected 'design' or "
                                     "'zero_pose'")
        if strategy not in STRATEGIES:
            raise ConfigurationError(f"strategy: found {strategy!r}, expected one of "
                                     f"{sorted(STRATEGIES)} (Table 2)")
        for name, v in (("hidden", hidden), ("max_iter", max_iter), ("patience", patience)):
            if int(v) != v or v < 1:
                raise ConfigurationError(f"{name}: found {v!r}, expected a positive integer")
        self.strategy, self.hidden, self.seed = int(strategy), int(hidden), int(seed)
        self.max_iter, self.patience, self.weight_decay = int(max_iter), int(patience), \
            float(weight_decay)
        self.reference, self.average = reference, average
        self.sensor: dict | None = None
        self.optimised: geometry.OptimisedFit | None = None
        self.input_scaling: dict | None = None
        self.networks: dict | None = None
        self.history: dict | None = None

    @property
    def label(self) -> str:
        return f"NN strategy {self.strategy}"

    # --- inputs and targets of each strategy -----------------------------------------------
    _ideal = IdealModel._predict_xy  # model (1) of ``sensor``

    def _inputs(self, x, y) -> np.ndarray:
        if self.strategy in (1, 4):
            return np.column_stack([x, y])
        if self.strategy == 2:
            return np.column_stack(self._ideal(x, y))
        return np.column_stack(geometry.model.optimised_angles(x, y, *self.optimised.params))

    def _targets(self, d) -> np.ndarray:
        if self.strategy == 4:
            ia, ib = self._ideal(d.x, d.y)
            return np.column_stack([d.alpha - ia, d.beta - ib])
        return np.column_stack([d.alpha, d.beta])

    def min_poses(self) -> int:
        """Fewest distinct training poses: one per weight of one network.

        Returns
        -------
        int
            ``4 * hidden + 1``: ``2 hidden`` input weights, ``hidden`` hidden biases, ``hidden``
            output weights and one output bias.
        """
        # weights of one net: hidden x 2 inputs, hidden biases, hidden outputs, output bias
        return 4 * self.hidden + 1

    # --- training ----------------------------------------------------------------------------
    def _zeroed(self, attrs) -> dict:
        """The sensor with model (1) referenced to the run's zero pose (``reference``)."""
        try:
            x0, y0 = float(attrs["zero_pose_x_px"]), float(attrs["zero_pose_y_px"])
        except (KeyError, TypeError, ValueError):
            raise ConfigurationError(
                "centroids: reference='zero_pose' needs the run's zero-pose centroid in the "
                "table's attributes zero_pose_x_px and zero_pose_y_px (px). Fix: measure the "
                "zero pose with the run (sunlab.plans.zero_check) or use reference='design'."
            ) from None
        return dict(self.sensor, x_cf_px=x0, y_cf_px=y0)

    def predict(self, centroids):
        """Estimated platform angles for every centroid of a ``centroids/1`` table.

        As :meth:`Calibration.predict`; with ``reference="zero_pose"`` (strategies 2 and 4)
        model (1) is first re-zeroed on the zero-pose centroid of the table's own run.

        Parameters
        ----------
        centroids : xarray.Dataset
            A ``centroids/1`` table (``x``, ``y`` px, ``status``; commanded ``alpha``, ``beta``
            as coordinates when known); with ``reference="zero_pose"``, attributes
            ``zero_pose_x_px``, ``zero_pose_y_px`` (px).

        Returns
        -------
        xarray.Dataset
            ``alpha``, ``beta`` (deg) on the dims of ``x``, ``status``, ``in_domain`` and the
            commanded ``alpha_cmd``, ``beta_cmd`` (deg), as :meth:`Calibration.predict`.
        """
        if self.reference != "zero_pose" or self.strategy not in (2, 4):
            return super().predict(centroids)
        fitted = self.sensor
        self.sensor = self._zeroed(centroids.attrs)
        try:
            return super().predict(centroids)
        finally:
            self.sensor = fitted

    def _fit_tables(self, train, validation) -> None:
        require("torch", purpose=_PURPOSE)  # checked first
        super()._fit_tables(train, validation)

    def _fit(self, data, validation) -> None:
        self.sensor = sensor_attrs(data.attrs) if self.strategy != 1 else None
        if self.reference == "zero_pose" and self.strategy in (2, 4):
            self.sensor = self._zeroed(data.attrs)
        self.optimised = fit_optimised(data, self.sensor) if self.strategy == 3 else None
        X = self._inputs(data.x, data.y)
        T = self._targets(data)
        mean, std = X.mean(axis=0), X.std(axis=0)
        std = np.where(std > 0, std, 1.0)
        self.input_scaling = {"mean": mean, "std": std}
        Z = (X - mean) / std
        v = validation
        Zv = None if v is None else (self._inputs(v.x, v.y) - mean) / std
        self.networks, self.history = {}, {}
        for k, angle in enumerate(("alpha", "beta")):
            t_mean, t_std = float(T[:, k].mean()), float(T[:, k].std()) or 1.0
            tv = None if v is None else (self._targets(v)[:, k] - t_mean) / t_std
            net, hist = self._train_one(Z, (T[:, k] - t_mean) / t_std, Zv, tv, self.seed + k)
            net.update(target_mean=t_mean, target_std=t_std)
            self.networks[angle] = net
            self.history[angle] = hist

    def _train_one(self, Z, t, Zv, tv, seed):
        n_in, h = Z.shape[1], self.hidden
        sizes = [h * n_in, h, h, 1]
        cuts = np.cumsum(sizes)[:-1]

        def unpack(theta):
            W1, b1, W2, b2 = np.split(theta, cuts)
            return {"W1": W1.reshape(h, n_in), "b1": b1, "W2": W2, "b2": float(b2[0])}

        # tiny full-batch problems: threads only add overhead
        with session(1, _PURPOSE, deterministic=True) as torch:
            gen = torch.Generator().manual_seed(seed)
            bounds = (1.0 / np.sqrt(n_in),) * 2 + (1.0 / np.sqrt(h),) * 2
            theta0 = np.concatenate([
                ((torch.rand(n, generator=gen, dtype=torch.float64) * 2 - 1) * bnd).numpy()
                for n, bnd in zip(sizes, bounds, strict=True)
            ])
            Zt = torch.as_tensor(Z, dtype=torch.float64)
            tt = torch.as_tensor(t, dtype=torch.float64)

            def loss_and_grad(theta):
                p = torch.from_numpy(theta.copy()).requires_grad_(True)
                W1, b1, W2, b2 = torch.split(p, sizes)
                out = torch.tanh(Zt @ W1.view(h, n_in).T + b1) @ W2 + b2
                loss = torch.mean((out - tt) ** 2)
                if self.weight_decay:
                    loss = loss + self.weight_decay * (W1.pow(2).sum() + W2.pow(2).sum())
                loss.backward()
                return float(loss.detach()), p.grad.numpy().astype(float)

            # early stopping on the validation loss; without one every iteration is the best
            stop = EarlyStop(self.patience, state=theta0.copy())

            def callback(intermediate_result):
                x = intermediate_result.x
                score = -stop.steps if Zv is None else float(
                    np.mean((_forward(Zv, unpack(x)) - tv) ** 2))
                if stop.step(score, x.copy):
                    raise StopIteration

            with parallel.single_threaded_blas():
                res = minimize(loss_and_grad, theta0, jac=True, method="L-BFGS-B",
                               callback=callback,
                               options={"maxiter": self.max_iter, "maxcor": 20,
                                        "ftol": 1e-15, "gtol": 1e-12})
        net = unpack(res.x if Zv is None else stop.state)
        train_loss = float(np.mean((_forward(Z, net) - t) ** 2))
        val_loss = None if Zv is None else float(np.mean((_forward(Zv, net) - tv) ** 2))
        return net, {"iterations": stop.steps, "best_iteration": stop.best,
                     "train_loss": train_loss, "val_loss": val_loss}

    # --- prediction (NumPy) ------------------------------------------------------------------
    def _predict_xy(self, x, y):
        Z = (self._inputs(x, y) - self.input_scaling["mean"]) / self.input_scaling["std"]
        out = [_forward(Z, self.networks[a]) * self.networks[a]["target_std"]
               + self.networks[a]["target_mean"] for a in ("alpha", "beta")]
        zero = self._ideal(x, y) if self.strategy == 4 else (0.0, 0.0)  # model (1) + error
        return out[0] + zero[0], out[1] + zero[1]

    # --- artifact ----------------------------------------------------------------------------
    def _parameters(self) -> dict:
        return {
            **{k: getattr(self, k) for k in _SETTINGS}, "reference": self.reference,
            "strategy_io": list(STRATEGIES[self.strategy]),
            "activation": "tanh hidden layer, linear output",
            "sensor": self.sensor,
            "optimised": None if self.optimised is None else self.optimised.to_dict(),
            "input_scaling": {k: np.asarray(v).tolist() for k, v in self.input_scaling.items()},
            "networks": {a: {k: np.asarray(v).tolist() for k, v in net.items()}
                         for a, net in self.networks.items()},
            "history": self.history,
        }

    @classmethod
    def _check_parameters(cls, p: dict) -> None:
        """Sizes, finiteness and ranges of a document's parameters, before any array is
        built (:func:`sunlab.calibration.artifact.from_dict`)."""
        check_parameters(p, {"hidden": range(1, 2**63)})
        h = p["hidden"]
        net = {"W1": (h, 2), "b1": (h,), "W2": (h,), "b2": (), "target_mean": (),
               "target_std": (POSITIVE,)}  # two inputs per strategy
        check_parameters(p, {"input_scaling": {"mean": (2,), "std": (POSITIVE, 2)},
                             "networks": {"alpha": net, "beta": net}})

    @classmethod
    def _from_parameters(cls, p: dict):
        obj = cls(**{k: p[k] for k in _SETTINGS}, reference=str(p.get("reference", "design")))
        obj.sensor = None if p["sensor"] is None else sensor_attrs(p["sensor"], name="sensor")
        if obj.strategy == 3:
            obj.optimised = optimised_fit_from_dict(p["optimised"])
        obj.input_scaling = {k: np.asarray(p["input_scaling"][k], dtype=float)
                             for k in ("mean", "std")}
        nets = p["networks"]  # sizes checked by _check_parameters
        obj.networks = {a: {k: np.asarray(nets[a][k], dtype=float) for k in ("W1", "b1", "W2")}
                        | {k: float(nets[a][k]) for k in ("b2", "target_mean", "target_std")}
                        for a in ("alpha", "beta")}
        obj.history = p.get("history")
        return obj
