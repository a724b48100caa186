"""The capstone's recordings: folders of frames as a lab's camera writes them, rendered by seed.

Exercise 08.1-08.2 (notebook 08) asks the student to import a recording with its dark and flat
frames, centroid it, calibrate and export. The student works on the recording of
:data:`STUDENT_SEED`; the grader renders another with a seed of its own choosing
(:func:`write_recording`), so that an answer can only pass by processing the frames it is given.

A recording (:func:`write_recording`) is a folder with four sub-folders:

* ``train/`` and ``test/``: 10-bit PNG frames, ``manifest.csv`` (``file, alpha, beta, shot``) and
  ``sensor.json`` (pixel pitch, nominal mask distance, bit depth), like ``sunlab/data/example``;
  the test poses lie between the training poses (half-step offsets), as experiment III does;
* ``dark/`` and ``flat/``: frames of the same camera with the hole covered, and under uniform
  light at half of full scale.

The camera is drawn from the seed: a dark offset that ramps across the frame (up to a quarter of
full scale, in a random direction), a pixel response made of vignetting (4-8 % at the corners)
times a fixed flat-field ripple (3 %), read noise of 0.2 % of full scale. The spot is a pinhole's
uniform disk (a 0.2 mm hole widened by the 0.52 deg sun: about 16 px in radius at F = 2.75 mm and
7 um pixels), sub-sampled 4 x 4, at eq. (1)'s position for a mask distance (2.5-3.0 mm), a
zero-pose centroid and a sensor mounting (rotations up to 1 deg) drawn from the seed. Over the
+-6 deg field the geometry is far from linear in the centroid (a first- or second-order polynomial
leaves errors of hundredths of a degree), and the mounting makes the ideal model (1) wrong by
tenths of a degree, so the student must calibrate and choose the model. The true centre of every
frame is returned, never written.

Examples
--------
>>> import tempfile
>>> rec = write_recording(tempfile.mkdtemp(), seed=1, step=6.0)
>>> sorted(p.name for p in rec.folder.iterdir())
['dark', 'flat', 'test', 'train']
>>> rec.truth["train"].shape  # (pose, shot, x and y)
(9, 2, 2)
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import NamedTuple

import numpy as np

from .. import atomic
from ..geometry import sun_vector

__all__ = ["write_recording"]

#: the seed of the recording the student works on (notebook 08's capstone)
STUDENT_SEED = 808
PITCH_MM, BITS, SHOTS, N_CAL = 0.007, 10, 2, 6
NY, NX, SUB = 136, 152, 4
HOLE_MM, SUN_DEG, NOMINAL_F_MM = 0.2, 0.52, 2.75
HALF_FIELD_DEG = 6.0


class Recording(NamedTuple):
    """A recording written by :func:`write_recording`.

    Attributes
    ----------
    folder : Path
        Holds ``train``, ``test``, ``dark`` and ``flat``.
    truth : dict
        ``train`` and ``test``: true spot centres, px, shape (pose, shot, 2) (x, y).
    poses : dict
        ``train`` and ``test``: commanded (alpha, beta) per pose, deg, shape (pose, 2).
    camera : dict
        What the seed drew: ``mask_distance_mm``, ``x_cf_px``, ``y_cf_px``, ``mounting_deg``.
    """

    folder: Path
    truth: dict
    poses: dict
    camera: dict


def _camera(rng):
    full = 2**BITS - 1
    yy, xx = np.mgrid[0:NY, 0:NX]
    theta = rng.uniform(0, 2 * np.pi)
    u = (np.cos(theta) * (xx - NX / 2) / NX + np.sin(theta) * (yy - NY / 2) / NY)
    u = (u - u.min()) / (u.max() - u.min())
    dark = full * (0.02 + 0.23 * u)
    cx, cy = NX / 2 + rng.uniform(-15, 15), NY / 2 + rng.uniform(-15, 15)
    r2 = ((xx - cx) ** 2 + (yy - cy) ** 2) / ((NX / 2) ** 2 + (NY / 2) ** 2)
    vignetting = 1.0 - rng.uniform(0.04, 0.08) * r2
    ripple = 1.0 + 0.03 * np.sin(2 * np.pi * xx / 23.0 + rng.uniform(0, 6.3)) * np.sin(
        2 * np.pi * yy / 31.0 + rng.uniform(0, 6.3))
    return dark, vignetting * ripple


def _centre(alpha, beta, f_mm, x_cf, y_cf, mount):
    """Spot centre, px: eq. (1) for the sun vector seen through a mounting rotation (about y
    by ``mount[0]``, x by ``mount[1]``, z by ``mount[2]``, deg: Rz Ry Rx)."""
    from scipy.spatial.transform import Rotation

    s = Rotation.from_euler("xyz", [mount[1], mount[0], mount[2]], degrees=True).apply(
        sun_vector(alpha, beta))
    return x_cf - f_mm / PITCH_MM * s[0] / s[2], y_cf - f_mm / PITCH_MM * s[1] / s[2]


def _disk(xc, yc, radius_px):
    sx = (np.arange(NX * SUB) + 0.5) / SUB - 0.5
    sy = (np.arange(NY * SUB) + 0.5) / SUB - 0.5
    inside = (sx[None, :] - xc) ** 2 + (sy[:, None] - yc) ** 2 <= radius_px**2
    return inside.reshape(NY, SUB, NX, SUB).mean(axis=(1, 3))


def _expose(light, dark, response, rng):
    full = 2**BITS - 1
    dn = dark + response * light + rng.normal(0.0, 0.002 * full, light.shape)
    return np.clip(np.rint(dn), 0, full).astype(np.uint16)


def write_recording(root, seed: int = STUDENT_SEED, *, step: float = 1.5) -> Recording:
    """Render a capstone recording into ``root`` (created if missing; every file or none,
    :func:`sunlab.atomic.atomic_files`).

    Parameters
    ----------
    root : str or path-like
        Folder that receives ``train/``, ``test/``, ``dark/`` and ``flat/``.
    seed : int
        Draws the camera, the geometry and the noise.
    step : float
        Pose step of the training grid, deg (the grid spans +-6 deg in alpha and beta; the test
        grid sits half a step inside it).

    Returns
    -------
    Recording
    """
    from PIL import Image

    rng = np.random.default_rng([int(seed), 8])
    root = Path(root)
    geometry = {"mask_distance_mm": float(rng.uniform(2.5, 3.0)),
                "x_cf_px": float(NX / 2 + rng.uniform(-6, 6)),
                "y_cf_px": float(NY / 2 + rng.uniform(-6, 6)),
                "mounting_deg": [float(v) for v in rng.uniform(-1.0, 1.0, 3)]}
    dark, response = _camera(rng)
    peak = 0.5 * (2**BITS - 1)
    f_mm = geometry["mask_distance_mm"]
    radius_px = (HOLE_MM / 2 + f_mm * np.tan(np.radians(SUN_DEG / 2))) / PITCH_MM
    grid = np.arange(-HALF_FIELD_DEG, HALF_FIELD_DEG + 1e-9, step)
    mid = grid[:-1] + step / 2
    plans = {"train": [(a, b) for a in grid for b in grid],
             "test": [(a, b) for a in mid for b in mid]}
    truth, poses = {}, {}
    with atomic.atomic_files(root, overwrite=True, flag="") as tmp:  # all or nothing
        for name, plan in plans.items():
            folder = tmp / name
            folder.mkdir(parents=True, exist_ok=True)
            rows, centres = ["file,alpha,beta,shot"], []
            for p, (a, b) in enumerate(plan):
                xc, yc = _centre(a, b, geometry["mask_distance_mm"], geometry["x_cf_px"],
                                 geometry["y_cf_px"], geometry["mounting_deg"])
                centres.append([(xc, yc)] * SHOTS)
                light = peak * _disk(xc, yc, radius_px)
                for s in range(SHOTS):
                    Image.fromarray(_expose(light, dark, response, rng)).save(
                        folder / f"p{p:03d}_s{s}.png")
                    rows.append(f"p{p:03d}_s{s}.png,{a:g},{b:g},{s}")
            (folder / "manifest.csv").write_text("\n".join(rows) + "\n", encoding="utf-8")
            sensor = {"pixel_pitch_mm": PITCH_MM, "mask_distance_mm": NOMINAL_F_MM,
                      "bit_depth": BITS, "experiment": f"capstone-{name}"}
            (folder / "sensor.json").write_text(json.dumps(sensor, indent=1) + "\n",
                                                encoding="utf-8")
            truth[name], poses[name] = np.array(centres), np.array(plan, dtype=float)
        for what, level in (("dark", 0.0), ("flat", peak)):
            folder = tmp / what
            folder.mkdir(parents=True, exist_ok=True)
            for k in range(N_CAL):
                Image.fromarray(_expose(np.full((NY, NX), level), dark, response, rng)).save(
                    folder / f"{what}{k}.png")
    return Recording(root, truth, poses, geometry)
