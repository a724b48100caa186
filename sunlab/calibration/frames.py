"""A calibration learned from the frames: spot windows in, platform angles out (torch).

Beyond the paper. Table 4's methods map a *centroid* to the angles; :class:`FrameNet` maps the
*pixels* around each detected spot, with the window's place on the detector, to the angles,
trained end to end on experiment I's frames against the commanded angles and stopped on
experiment II's, as Table 4's networks are.

The network (our design; its reasons):

1. **Detection** gives each spot's window: the integer pixel nearest the library's centroid
   (:func:`sunlab.centroid.locate`: algorithm B for one hole; the lattice locator for a mask of
   many holes, which also numbers the spots). Only that integer place is used: the sub-pixel
   position comes from the network.
2. **A small CNN on each window** (``window`` x ``window`` px; 5 x 5 then 3 x 3 convolutions of
   ``channels`` maps, tanh) ends in one map ``z`` that weights the window's pixels: the spot's
   place is the centre of ``relu(I) exp(z)``, a learned centre of light (a spatial soft-argmax,
   as in numerical coordinate regression with CNNs). A dense layer that regresses coordinates
   from a window must learn translation from examples, and experiment I's 3,200 frames are far
   too few to teach it to a hundredth of a pixel; the weighted centre is translation-equivariant
   by construction, so what the net learns is which pixels to trust (the blurred edge, a hot
   pixel, the shadow of dust). Its last layer starts at zero: the untrained net is the plain
   centre of light of the window, and training can only move away from it where the frames
   say so. Training crops each window anywhere within ``+-pad`` px of the detected place (the
   target does not change), which teaches the equivariance the architecture already has.
3. **A head from the spot's place to the angles**: the monomials of total degree ``order`` of
   the spot's displacement from its hole's design place (standardised), like Table 4's
   polynomial, whose coefficients are re-solved by least squares in float64 after every epoch
   (not by gradient steps: a thousandth of a degree over a 34-degree field is 3e-5 of the
   range, beyond what Adam's steps in float32 resolve).
4. **Many holes: a set network** (deep sets with attention pooling). Every spot of a frame
   goes through the same CNN; an attention MLP scores each spot from what the CNN saw (its
   features under the pixel weights, its spread and light) and its hole's design place; the
   frame's regressors are the softmax-weighted mean of its spots' (the head adds terms linear
   in the hole's place: a tilted mask puts its holes at different heights). The pooling does
   not depend on the order or the number of spots: holes missing at the field's edge or a
   dropped bad hole change the set, not the network. Not a downsampled frame: a 0.01 deg
   sensor needs the spots at full resolution, and 100 windows of 44 x 44 px are 15 % of the
   frame's pixels. The attention's output starts at zero (the plain mean of the spots).

Training: Adam (learning rate ``lr``) on the convolutions and the attention, mini-batches of
whole frames, loss the mean squared angle error (alpha and beta, in units of 0.01 deg),
float32 convolutions and a float64 head; after every epoch the head is re-solved and the loss
on experiment II's frames (centred windows) decides: the best epoch is kept, and ``patience``
epochs without improvement stop the fit. CPU by default (``threads`` torch threads),
``device="cuda"`` where a GPU exists. The weights travel as lists in the JSON artifact
(``calibration/1``, no pickle); predicting needs torch too.

Examples
--------
>>> FrameNet(channels=4).label
'learned (frames)'
"""

from __future__ import annotations

import time

import numpy as np
import xarray as xr

from ..errors import ConfigurationError, SchemaError
from ..schema import STATUS
from . import _frames_torch as T
from .artifact import POSITIVE, check_parameters
from .base import Calibration, _check_spots_move, _err_summary, _estimates
from .windows import _with_hole_uv, detect_spots, spot_windows

__all__ = ["FrameNet"]

#: The bounds (lowest, highest) of every size and setting a FrameNet takes and its model file
#: holds: a window of 512 px, 64 channels and order 12 are far beyond any useful network, and
#: an edited file cannot ask for terabytes of windows or a million threads.
_LIMITS = {"window": (8, 512), "pad": (0, 64), "channels": (1, 64), "order": (1, 12),
           "epochs": (0, 100_000), "patience": (1, 100_000), "batch": (1, 100_000),
           "threads": (1, 256), "spots": (1, 10_000), "seed": (0, 2**63 - 1)}


_PURPOSE = "the calibration learned from frames (FrameNet)"
#: The training settings a model file keeps (``settings``).
_SETTINGS = ("epochs", "patience", "batch", "lr", "seed", "threads", "spots")


class FrameNet(Calibration):
    """A calibration learned from the frames (module docstring): one hole or a set of spots.

    Parameters
    ----------
    window : int
        Side of each spot's window, px (the one-hole spot is about 35 px across).
    pad : int
        Training crops move the window by up to ``pad`` px about the detected place.
    channels : int
        Feature maps of the two convolutions.
    order : int
        Total degree of the head's monomials of the spot's displacement.
    epochs, patience : int
        Most epochs; epochs without a better validation loss before stopping.
    batch : int, optional
        Frames per mini-batch (default 32 for one hole, 8 for a mask of many).
    lr : float
        Adam's learning rate.
    seed : int
        Seed of the initial weights, the batches and the crops.
    threads : int
        torch threads (and poses cropped at once).
    device : {"cpu", "cuda"}
        Where torch trains and predicts.
    hole_offset : (float, float)
        Many holes: the mounting's offset of the spots from their design places, px, used to
        number them (:func:`detect_spots`).
    spots : int
        Many holes: spots of each frame drawn at random for each training step (spot dropout;
        prediction uses every spot).

    Attributes
    ----------
    history : dict
        Epochs run, the epoch kept, losses per epoch (units of 0.01 deg squared), seconds.
    timings : dict
        Seconds of the last fit or prediction by stage (detection, windows, network).

    Examples
    --------
    >>> FrameNet(order=3).min_poses()
    10
    """

    kind = "learned-frames"
    label = "learned (frames)"

    def __init__(self, window: int = 44, pad: int = 3, channels: int = 6, order: int = 5, *,
                 epochs: int = 40, patience: int = 6, batch: int | None = None,
                 lr: float = 3e-3, seed: int = 0, threads: int = 2, device: str = "cpu",
                 hole_offset=(0.0, 0.0), spots: int = 16):
        super().__init__()
        given = {"window": window, "pad": pad, "channels": channels, "order": order,
                 "epochs": epochs, "patience": patience, "threads": threads, "spots": spots,
                 "seed": seed, **({} if batch is None else {"batch": batch})}
        for name, v in given.items():
            low, high = _LIMITS[name]
            if isinstance(v, bool) or not isinstance(v, int | float | np.integer) or \
                    int(v) != v or not low <= v <= high:
                raise ConfigurationError(
                    f"{name}: found {v!r}, expected an integer from {low} to {high}")
        if not (np.isfinite(lr) and lr > 0):
            raise ConfigurationError(f"lr: found {lr!r}, expected a positive learning rate")
        if device not in ("cpu", "cuda"):
            raise ConfigurationError(f"device: found {device!r}, expected 'cpu' or 'cuda'")
        self.batch, self.lr, self.device = None, float(lr), device
        vars(self).update({k: int(v) for k, v in given.items()})  # batch too, when given
        self.hole_offset = (float(hole_offset[0]), float(hole_offset[1]))
        self.multi: bool | None = None
        self.scaling: dict | None = None
        self.arrays: dict | None = None
        self.coef: np.ndarray | None = None
        self.history: dict | None = None
        self.timings: dict = {}

    def min_poses(self) -> int:
        """Fewest distinct training poses: one per coefficient of the head's polynomial.

        Returns
        -------
        int
            ``(order + 1)(order + 2) / 2``, the monomials of total degree ``order`` per angle.
        """
        return (self.order + 1) * (self.order + 2) // 2

    # --- data --------------------------------------------------------------------------------
    def _data(self, cube, detections, name: str) -> dict:
        if not isinstance(cube, xr.Dataset) or "frames" not in cube:
            raise SchemaError(name, type(cube).__name__, "a frames/1 cube (sunlab simulate, "
                              "sunlab import, or sunlab.io.open_frames)",
                              "pass the frames, not a centroid table")
        t = time.perf_counter()
        if detections is None:
            detections = detect_spots(cube, self.hole_offset, workers=self.threads)
        self.timings[f"{name} detection"] = time.perf_counter() - t
        t = time.perf_counter()
        data = spot_windows(cube, detections, window=self.window, pad=self.pad,
                            threads=self.threads)
        self.timings[f"{name} windows"] = time.perf_counter() - t
        if data["n_frames"] == 0:
            raise SchemaError(f"{name}.frames", "no usable spot in any frame",
                              "frames with a spot inside the detector",
                              "check the cube (sunlab info) and its detection")
        return data

    def _state(self) -> dict:
        return {**self.scaling, "order": self.order, "multi": self.multi}

    # --- fit ---------------------------------------------------------------------------------
    def fit(self, train: xr.Dataset, validation: xr.Dataset | None = None, *,
            detections: xr.Dataset | None = None, val_detections: xr.Dataset | None = None):
        """Train on the frames of ``train`` (experiment I), stopping on ``validation`` (II).

        Parameters
        ----------
        train, validation : xarray.Dataset
            ``frames/1`` cubes with the commanded angles ``alpha``, ``beta`` on ``pose``.
        detections, val_detections : xarray.Dataset, optional
            Their spots (:func:`detect_spots`), when already located.

        Returns
        -------
        FrameNet
            ``self``, fitted.
        """
        with T.session(self.threads, _PURPOSE, device=self.device):  # checked first
            self.timings = {}
            data = self._data(train, detections, "train")
            self.multi = bool(data["multi"])
            distinct = len({(a, b) for a, b in data["target"].tolist()})
            if distinct < self.min_poses():
                raise ConfigurationError(
                    f"train: {distinct} distinct poses, but a head of order {self.order} needs at "
                    f"least {self.min_poses()}. Fix: train on more poses or lower order")
            d, hole = data["corner"] + data["window"] / 2 + data["pad"] - data["hole"], data["hole"]
            _check_spots_move(d[:, 0], d[:, 1], "train")
            hstd = hole.std(axis=0)
            self.scaling = {"d_mean": d.mean(axis=0), "d_std": d.std(axis=0), "hole_mean":
                            hole.mean(axis=0), "hole_std": np.where(hstd > 0, hstd, 1.0)}
            data = _with_hole_uv(data, self.scaling)
            val = None if validation is None else _with_hole_uv(
                self._data(validation, val_detections, "validation"), self.scaling)
            net = T.build(self.channels, self.seed)
            st = self._state()
            self.history = T.train(net, data, val, st, {
                "device": self.device, "seed": self.seed, "lr": self.lr, "epochs": self.epochs,
                "patience": self.patience, "batch": self.batch or (8 if self.multi else 32),
                "spots": self.spots})
        self.timings["train network"] = self.history["seconds"]
        self.arrays, self.coef = T.to_arrays(net), np.asarray(st["coef"], dtype=float)
        self._record(train, validation, data, val)
        return self

    def _record(self, train, validation, data: dict, val: dict | None) -> None:
        """The artifact's training summary, domain and residuals (per-shot errors, deg)."""
        def summary(cube, d):
            return {"experiment": str(cube.attrs.get("experiment", "")),
                    "n_frames": int(d["n_frames"]), "n_spots": int(d["corner"].shape[0]),
                    "n_poses": int(np.unique(d["pose"]).size), "n_shots": int(d["shape"][1])}

        pred, pos = self._predict_data(data)
        self.training = {**summary(train, data), **_frames_kind(train),
                         "n_samples": int(data["n_frames"]),
                         "n_ok_shots": int(data["n_frames"]), "average": "shot",
                         "centroid_method": "learned from frames",
                         "validation": None if val is None else summary(validation, val)}
        self.domain = {a: [float(v.min()), float(v.max())] for a, v in
                       zip(("alpha", "beta", "x", "y"), [*data["target"].T, *pos.T], strict=True)}

        def errors(d, p):
            return {a: _err_summary(p[:, k], d["target"][:, k])
                    for k, a in enumerate(("alpha", "beta"))}

        self.residuals = {**errors(data, pred), "validation": None if val is None
                          else errors(val, self._predict_data(val)[0])}

    # --- predict -----------------------------------------------------------------------------
    def _predict_data(self, data: dict):
        with T.session(self.threads, _PURPOSE, device=self.device) as torch:
            net = T.from_arrays(self.arrays, self.channels, self.device)
            phi, pos = T.forward_all(net, data, self._state(), torch.device(self.device))
        return phi @ self.coef, pos

    def predict_frames(self, cube: xr.Dataset, *, detections: xr.Dataset | None = None
                       ) -> xr.Dataset:
        """Estimated platform angles of every frame of ``cube``.

        Parameters
        ----------
        cube : xarray.Dataset
            A ``frames/1`` cube, as ``sunlab simulate`` or ``sunlab import`` writes it (a
            mask of the kind trained on).
        detections : xarray.Dataset, optional
            Its spots (:func:`detect_spots`), when already located.

        Returns
        -------
        xarray.Dataset
            ``alpha``, ``beta`` (deg) on (pose, shot), NaN for a frame without a usable spot;
            ``status`` (``ok``, or ``no_spot``), ``n_spots``; ``in_domain`` (bool): False where
            the estimate lies outside the training poses' range widened by the largest training
            error (an extrapolation), attribute ``n_out_of_domain`` counting them; coordinates
            ``alpha_cmd``, ``beta_cmd`` (the commanded angles): what
            :func:`sunlab.stats.evaluate` reads. Attribute ``timings`` (str) gives the seconds
            of each stage.

        Raises
        ------
        SchemaError
            Frames of another shape, bit depth or number of holes than the training frames.
        """
        self.check_fitted()
        self.timings = {}
        multi = "hole_x_cf" in cube.coords and "hole" in cube.dims
        if multi != self.multi:
            raise SchemaError("cube", f"a {'multi' if multi else 'one'}-hole cube",
                              f"a {'multi' if self.multi else 'one'}-hole cube, as trained",
                              "predict with a model trained on frames of this mask")
        for key, found in _frames_kind(cube).items():  # recorded since issue 47
            if key in self.training and found != self.training[key]:
                raise SchemaError(f"cube {key}", found, f"{self.training[key]}, the frames the "
                                  "model was trained on", "predict with a model trained on "
                                  "frames of this detector and mask, or train one on these")
        data = _with_hole_uv(self._data(cube, detections, "cube"), self.scaling)
        t = time.perf_counter()
        pred, _ = self._predict_data(data)
        self.timings["cube network"] = time.perf_counter() - t
        shape = data["shape"]
        out = np.full(shape + (2,), np.nan)
        out[data["pose"], data["shot"]] = pred
        n = np.zeros(shape, dtype=np.int32)
        n[data["pose"], data["shot"]] = np.diff(data["start"])
        status = np.where(n > 0, STATUS["ok"], STATUS["no_spot"]).astype(np.int8)
        inside = np.ones(shape, dtype=bool)  # the estimate within the training poses' range,
        for k, a in enumerate(("alpha", "beta")):  # widened by the largest training error
            tol = ((self.residuals or {}).get(a) or {}).get("max_abs") or 0.0
            lo, hi = self.domain[a]
            inside &= (out[..., k] >= lo - tol) & (out[..., k] <= hi + tol)
        est = _estimates(self, cube, ("pose", "shot"), out[..., 0], out[..., 1],
                         np.isfinite(out[..., 0]), inside, status=(("pose", "shot"), status),
                         n_spots=(("pose", "shot"), n))
        est.attrs["timings"] = repr({k: round(v, 3) for k, v in self.timings.items()})
        return est

    def predict(self, cube: xr.Dataset) -> xr.Dataset:
        """:meth:`predict_frames`: a frame calibration reads frames, not centroids.

        Parameters
        ----------
        cube : xarray.Dataset
            A ``frames/1`` cube, as ``sunlab simulate`` or ``sunlab import`` writes it, of the kind
            of mask (one hole or many) the network was trained on.

        Returns
        -------
        xarray.Dataset
            As :meth:`predict_frames`: ``alpha``, ``beta`` (deg) on ``(pose, shot)``, NaN for a
            frame without a usable spot; ``status``, ``n_spots``; coordinates ``alpha_cmd``,
            ``beta_cmd`` (deg).
        """
        return self.predict_frames(cube)

    def predict_xy(self, x, y):
        """Not available: a frame calibration has no map from a centroid.

        Parameters
        ----------
        x, y : array_like
            Centroids, px (refused).

        Raises
        ------
        ConfigurationError
            Always; the message names :meth:`predict_frames`.
        """
        raise ConfigurationError(
            "FrameNet: learned from frames, it has no map from a centroid (x, y). Fix: call "
            "predict_frames(cube) with the frames")

    # --- artifact ----------------------------------------------------------------------------
    def _parameters(self) -> dict:
        return {
            "window": self.window, "pad": self.pad, "channels": self.channels,
            "order": self.order, "multi": self.multi,
            "hole_offset_px": list(self.hole_offset),
            "settings": {k: getattr(self, k) for k in _SETTINGS},
            "scaling": {k: np.asarray(v, dtype=float).tolist() for k, v in self.scaling.items()},
            "network": {k: np.asarray(v).tolist() for k, v in self.arrays.items()},
            "head": np.asarray(self.coef).tolist(),
            "history": self.history,
            "design": "CNN pixel weights (learned centre of light) + least-squares polynomial "
                      "head" + ("; attention pooling over the spots" if self.multi else ""),
        }

    @classmethod
    def _check_parameters(cls, p: dict) -> None:
        limits = {k: range(low, high + 1) for k, (low, high) in _LIMITS.items()}
        check_parameters(p, {k: limits[k] for k in ("window", "pad", "channels", "order")}
                         | {"multi": bool})
        s = p.get("settings") if isinstance(p.get("settings"), dict) else {}
        check_parameters(p, {
            "hole_offset_px": (2,),
            "scaling": {k: (POSITIVE, 2) if k.endswith("std") else (2,)
                        for k in ("d_mean", "d_std", "hole_mean", "hole_std")},
            "head": ((p["order"] + 1) * (p["order"] + 2) // 2 + 6 * p["multi"], 2),
            "network": _shapes(p["channels"]),  # a layer more is refused, not left unused
            "settings": {"lr": (POSITIVE,)} | {  # batch and spots: None is the default
                k: None if k in ("batch", "spots") and s.get(k) is None else limits[k]
                for k in ("epochs", "patience", "threads", "seed", "spots", "batch")}})

    @classmethod
    def _from_parameters(cls, p: dict):
        s = p["settings"]
        obj = cls(**{k: p[k] for k in ("window", "pad", "channels", "order")},
                  hole_offset=p["hole_offset_px"], **{k: s[k] for k in _SETTINGS if k in s})
        obj.multi = bool(p["multi"])
        obj.scaling = {k: np.asarray(v, dtype=float) for k, v in p["scaling"].items()}
        obj.arrays = {k: np.asarray(v, dtype=float) for k, v in p["network"].items()}
        obj.coef = np.asarray(p["head"], dtype=float)
        obj.history = p.get("history")
        return obj


def _frames_kind(cube: xr.Dataset) -> dict:
    """What a model is trained for: the frames' shape (px), bit depth and number of holes."""
    return {"frame_shape": [int(n) for n in cube["frames"].shape[-2:]],
            "bit_depth": int(cube.attrs.get("bit_depth", 0)),
            "n_holes": int(cube.sizes.get("hole", 1))}


def _shapes(c: int) -> dict:
    """The shape of each weight array of a network of ``c`` channels (no torch needed)."""
    nf = T.n_features(c)
    h = T.ATTENTION_HIDDEN
    return {"conv1.weight": (c, 1, 5, 5), "conv1.bias": (c,), "conv2.weight": (c, c, 3, 3),
            "conv2.bias": (c,), "conv3.weight": (1, c, 1, 1), "conv3.bias": (1,),
            "att1.weight": (h, nf), "att1.bias": (h,), "att2.weight": (1, h), "att2.bias": (1,)}
