"""The torch half of :class:`sunlab.calibration.FrameNet`: the network, its training, its use;
and what both torch paths (:class:`~sunlab.calibration.NeuralNet` too) share: the torch
session (:func:`session`) and the early stopping (:class:`EarlyStop`).

Private to :mod:`sunlab.calibration`; torch is imported inside the functions, so importing
this module costs nothing. The numbers that describe a fitted network (convolution weights,
attention weights, the least-squares head, scalings) travel as plain NumPy arrays in a dict
(``state``), which :mod:`sunlab.calibration.frames` writes as lists in the JSON artifact.

Shapes: ``E`` spots (elements) in ``F`` frames (sets); a window is ``W x W`` px, stored with
``pad`` px more on each side so that training can crop it anywhere within ``+-pad`` px.
"""

from __future__ import annotations

import contextlib
import math
import time

import numpy as np

from ..errors import ConfigurationError
from ..extras import require

__all__: list[str] = []

#: The loss's angle unit, deg: errors are divided by it so that the loss is of order 1.
LOSS_SCALE_DEG = 0.01
#: The attention network's hidden width.
ATTENTION_HIDDEN = 16


def _torch():
    return require("torch", purpose="the calibration learned from frames (FrameNet)")


@contextlib.contextmanager
def session(threads: int, purpose: str, *, deterministic: bool = False, device: str = "cpu"):
    """torch (imported now: its absence is an ImportError naming the extra and ``purpose``)
    with ``threads`` threads, and deterministic algorithms if asked; both restored after.
    ``device="cuda"`` without a GPU torch can see is refused first.

    Parameters
    ----------
    threads : int
        torch's threads inside the block.
    purpose : str
        What needs torch, for the message when it is missing.
    deterministic : bool
        Deterministic algorithms inside the block (NeuralNet's reproducible fits).
    device : {"cpu", "cuda"}
        Where the block will run.

    Returns
    -------
    contextlib.AbstractContextManager
        Yields the ``torch`` module.
    """
    torch = require("torch", purpose=purpose)
    if device == "cuda" and not torch.cuda.is_available():
        raise ConfigurationError("device: found 'cuda', but torch sees no GPU here. Fix: "
                                 "device='cpu'")
    before = torch.get_num_threads(), torch.are_deterministic_algorithms_enabled()
    torch.set_num_threads(threads)
    torch.use_deterministic_algorithms(deterministic or before[1])
    try:
        yield torch
    finally:
        torch.set_num_threads(before[0])
        torch.use_deterministic_algorithms(before[1])


class EarlyStop:
    """Early stopping on a validation score: :meth:`step` after every step (an epoch, an
    iteration) keeps the state of the best score so far, and says when ``patience`` steps have
    passed without a better one. ``steps`` counts the steps, ``best`` is the best one's."""

    def __init__(self, patience, score: float = math.inf, state=None):
        self.patience, self.score, self.state, self.steps, self.best = patience, score, state, 0, 0

    def step(self, score: float, state) -> bool:
        """Record one step's ``score``; ``state()`` is called (and kept) only when it is the
        best.

        Parameters
        ----------
        score : float
            The step's validation loss (smaller is better).
        state : callable
            Returns what to keep (weights) when the step is the best so far.

        Returns
        -------
        bool
            True when ``patience`` steps have passed since the best one: stop training.
        """
        self.steps += 1
        if score < self.score:
            self.score, self.best, self.state = score, self.steps, state()
        return self.steps - self.best >= self.patience


def build(channels: int, seed: int):
    """The network: a small CNN whose last layer weights the window's pixels (a learned
    centre of light) and an attention MLP that scores each spot of a set. Weights drawn from a
    ``torch.Generator`` seeded with ``seed``; the pixel-weight layer and the attention's output
    start at zero, so an untrained net is the centre of light of the window's positive pixels
    and the plain mean of the spots."""
    torch = _torch()
    nn = torch.nn
    torch.manual_seed(seed)
    net = nn.ModuleDict({
        "conv1": nn.Conv2d(1, channels, 5, padding=2),
        "conv2": nn.Conv2d(channels, channels, 3, padding=1),
        "conv3": nn.Conv2d(channels, 1, 1),
        "att1": nn.Linear(n_features(channels), ATTENTION_HIDDEN),
        "att2": nn.Linear(ATTENTION_HIDDEN, 1),
    })
    with torch.no_grad():
        for name in ("conv3", "att2"):
            net[name].weight.zero_()
            net[name].bias.zero_()
    return net


def _spots(net, win, corner):
    """Position (px, float64) and per-spot features of each window ``win`` (E, W, W)."""
    torch = _torch()
    w = win[:, None]
    h = torch.tanh(net["conv1"](w))
    h = torch.tanh(net["conv2"](h))
    z = net["conv3"](h).clamp(-30.0, 30.0)
    q = torch.relu(w) * torch.exp(z)
    s = q.sum(dim=(1, 2, 3)).clamp_min(1e-12)
    n = win.shape[-1]
    grid = torch.arange(n, dtype=win.dtype, device=win.device)
    mx = (q.sum(dim=2)[:, 0] * grid).sum(dim=1) / s
    my = (q.sum(dim=3)[:, 0] * grid).sum(dim=1) / s
    pos = corner + torch.stack([mx, my], dim=1).to(corner.dtype)
    # what a spot looks like to the attention: the conv features under its weights, its
    # spread (second moments, px^2 / 100) and its weight in light
    feats = (q * h).sum(dim=(2, 3)) / s[:, None]
    dx, dy = grid[None, :] - mx[:, None], grid[None, :] - my[:, None]
    sxx = (q.sum(dim=2)[:, 0] * dx**2).sum(dim=1) / s / 100.0
    syy = (q.sum(dim=3)[:, 0] * dy**2).sum(dim=1) / s / 100.0
    return pos, torch.cat([feats, sxx[:, None], syy[:, None], torch.log(s)[:, None] / 10.0],
                          dim=1)


def n_features(channels: int) -> int:
    """Inputs of the attention MLP: conv features, two second moments, log weight, and the
    hole's design place (2)."""
    return channels + 3 + 2


def design(d_uv, hole_uv, order: int, multi: bool):
    """The head's regressors of each spot: the monomials ``u^a v^b`` (``a + b <= order``) of
    its standardised displacement from its hole's design place, and for a mask of many holes
    ``(1, u, v) x (hole u, hole v)``: the small changes of the map from hole to hole (a tilted
    mask puts holes at different heights)."""
    torch = _torch()
    u, v = d_uv[:, 0], d_uv[:, 1]
    cols = [u**a * v**(k - a) for k in range(order + 1) for a in range(k, -1, -1)]
    if multi:
        hu, hv = hole_uv[:, 0], hole_uv[:, 1]
        cols += [hu, hv, u * hu, u * hv, v * hu, v * hv]
    return torch.stack(cols, dim=1)


def _segment_softmax(logit, frame, n_frames):
    torch = _torch()
    m = torch.full((n_frames,), -math.inf, dtype=logit.dtype, device=logit.device)
    m = m.scatter_reduce(0, frame, logit, reduce="amax", include_self=True)
    e = torch.exp(logit - m[frame])
    den = torch.zeros(n_frames, dtype=logit.dtype, device=logit.device).index_add(0, frame, e)
    return e / den[frame]


def pooled(net, batch: dict, st: dict):
    """Per frame: the attention-weighted mean of its spots' regressors (F, T), float64."""
    torch = _torch()
    pos, feats = _spots(net, batch["win"], batch["corner"])
    mean = torch.as_tensor(st["d_mean"], dtype=torch.float64, device=pos.device)
    std = torch.as_tensor(st["d_std"], dtype=torch.float64, device=pos.device)
    d_uv = (pos - batch["hole"] - mean) / std
    phi = design(d_uv, batch["hole_uv"].to(d_uv.dtype), st["order"], st["multi"])
    if st["multi"]:
        logit = net["att2"](torch.tanh(net["att1"](
            torch.cat([feats, batch["hole_uv"].to(feats.dtype)], dim=1))))[:, 0]
        w = _segment_softmax(logit.to(phi.dtype), batch["frame"], batch["n_frames"])
    else:
        w = torch.ones(phi.shape[0], dtype=phi.dtype, device=phi.device)
    out = torch.zeros((batch["n_frames"], phi.shape[1]), dtype=phi.dtype, device=phi.device)
    return out.index_add(0, batch["frame"], w[:, None] * phi), pos


def _elements(data: dict, frames: np.ndarray, rng=None, most: int | None = None):
    """The element indices of ``frames`` and the position of each one's frame in ``frames``;
    with ``rng``, at most ``most`` spots of each frame drawn at random (training's spot
    dropout: a frame's set changes from epoch to epoch, as spots come and go at the field's
    edge, and an epoch costs ``most`` windows a frame, not a hundred)."""
    sel, remap = [], []
    for k, f in enumerate(frames):
        idx = np.arange(data["start"][f], data["start"][f + 1])
        if rng is not None and most is not None and idx.size > most:
            idx = np.sort(rng.choice(idx, most, replace=False))
        sel.append(idx)
        remap.append(np.full(idx.size, k))
    return np.concatenate(sel), np.concatenate(remap)


def _batch(data: dict, frames: np.ndarray, offsets, device, elements=None) -> dict:
    """The elements of ``frames`` (indices into ``data``'s frames; ``elements``: a chosen
    subset, :func:`_elements`), cropped at ``offsets`` (E, 2) px within the stored padding,
    as tensors on ``device``."""
    torch = _torch()
    sel, remap = _elements(data, frames) if elements is None else elements
    n = data["window"]
    ox, oy = offsets[:, 0], offsets[:, 1]
    rows = oy[:, None] + np.arange(n)[None, :]
    cols = ox[:, None] + np.arange(n)[None, :]
    win = data["win"][sel[:, None, None], rows[:, :, None], cols[:, None, :]]
    corner = data["corner"][sel] + offsets.astype(float)
    return {"win": torch.as_tensor(win, device=device),
            "corner": torch.as_tensor(corner, dtype=torch.float64, device=device),
            "hole": torch.as_tensor(data["hole"][sel], dtype=torch.float64, device=device),
            "hole_uv": torch.as_tensor(data["hole_uv"][sel], dtype=torch.float32,
                                       device=device),
            "frame": torch.as_tensor(remap, device=device), "n_frames": int(frames.size)}


def forward_all(net, data: dict, st: dict, device, chunk: int = 256) -> tuple:
    """Pooled regressors (F, T) and spot positions (E, 2) of every frame, centred windows."""
    torch = _torch()
    phis, poss = [], []
    with torch.no_grad():
        for lo in range(0, data["n_frames"], chunk):
            frames = np.arange(lo, min(lo + chunk, data["n_frames"]))
            centred = np.full((int(np.diff(data["start"])[frames].sum()), 2), data["pad"])
            phi, pos = pooled(net, _batch(data, frames, centred, device), st)
            phis.append(phi.cpu().numpy())
            poss.append(pos.cpu().numpy())
    return np.concatenate(phis), np.concatenate(poss)


def _solve_head(net, data: dict, st: dict, device) -> None:
    """``st["coef"]``: the head's least-squares coefficients (T, 2), float64, on the pooled
    regressors of every frame of ``data`` (centred windows)."""
    phi, _ = forward_all(net, data, st, device)
    st["coef"] = np.linalg.lstsq(phi, data["target"], rcond=None)[0]


def train(net, data: dict, val: dict | None, st: dict, opts: dict) -> dict:
    """Adam on the convolutions and the attention, the head re-solved by least squares after
    every epoch; early stopping on ``val`` (the best epoch's weights kept). Returns the
    history (epochs, best epoch, losses, wall-clock seconds and the process's CPU seconds,
    all threads: on a shared machine the wall clock counts the others' work too)."""
    torch = _torch()
    device = torch.device(opts["device"])
    net.to(device)
    rng = np.random.default_rng(opts["seed"])
    params = [p for name, p in net.named_parameters()
              if st["multi"] or not name.startswith("att")]
    optim = torch.optim.Adam(params, lr=opts["lr"])
    t0, c0 = time.perf_counter(), time.process_time()
    _solve_head(net, data, st, device)
    stop = EarlyStop(opts["patience"], _score(net, val or data, st, device),
                     (_snapshot(net), st["coef"].copy()))
    hist = {"train_loss": [], "val_loss": [stop.score]}
    target = torch.as_tensor(data["target"], dtype=torch.float64, device=device)
    for _ in range(opts["epochs"]):
        order = rng.permutation(data["n_frames"])
        coef_t = torch.as_tensor(st["coef"], dtype=torch.float64, device=device)
        phis, seen, total = [], [], 0.0
        for lo in range(0, order.size, opts["batch"]):
            frames = np.sort(order[lo:lo + opts["batch"]])
            els = _elements(data, frames, rng, opts.get("spots"))
            b = _batch(data, frames, rng.integers(0, 2 * data["pad"] + 1, (els[0].size, 2)),
                       device, els)
            phi_b, _ = pooled(net, b, st)
            loss = (((phi_b @ coef_t - target[frames]) / LOSS_SCALE_DEG) ** 2).sum(dim=1).mean()
            optim.zero_grad()
            loss.backward()
            optim.step()
            total += float(loss.detach()) * frames.size
            phis.append(phi_b.detach().cpu().numpy())
            seen.append(frames)
        seen = np.concatenate(seen)
        st["coef"] = np.linalg.lstsq(np.concatenate(phis), data["target"][seen], rcond=None)[0]
        score = _score(net, val or data, st, device)
        hist["train_loss"].append(total / order.size)
        hist["val_loss"].append(score)
        if stop.step(score, lambda: (_snapshot(net), st["coef"].copy())):
            break
    net.load_state_dict(stop.state[0])
    st["coef"] = stop.state[1]
    _solve_head(net, data, st, device)  # the head for the kept weights
    return {"epochs": len(hist["train_loss"]), "best_epoch": stop.best,
            "train_loss": hist["train_loss"], "val_loss": hist["val_loss"],
            "loss_unit_deg": LOSS_SCALE_DEG, "seconds": time.perf_counter() - t0,
            "cpu_seconds": time.process_time() - c0}


def _snapshot(net) -> dict:
    return {k: v.detach().clone() for k, v in net.state_dict().items()}


def _score(net, data: dict, st: dict, device) -> float:
    """Mean squared angle error of ``data``'s frames in :data:`LOSS_SCALE_DEG` units."""
    phi, _ = forward_all(net, data, st, device)
    err = (phi @ st["coef"] - data["target"]) / LOSS_SCALE_DEG
    return float(np.mean(np.sum(err**2, axis=1)))


def to_arrays(net) -> dict:
    """The network's weights as float64 NumPy arrays, by parameter name."""
    return {k: v.detach().cpu().double().numpy() for k, v in net.state_dict().items()}


def from_arrays(arrays: dict, channels: int, device: str = "cpu"):
    """A network of ``channels`` rebuilt from :func:`to_arrays`' output (of the layers and
    shapes a model file was checked for: ``FrameNet._check_parameters``)."""
    torch = _torch()
    net = build(channels, 0)
    net.load_state_dict({k: torch.as_tensor(np.asarray(arrays[k]), dtype=torch.float32)
                         for k in net.state_dict()})
    return net.to(torch.device(device))
