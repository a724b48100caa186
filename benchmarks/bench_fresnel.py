"""Fresnel diffraction of the paper's pinhole (mask.diffraction): its effect at F = 5 and 17 mm.

Prints, for the paper's 0.2 mm hole on ``Bench.paper_single_hole()`` (F = 5 mm) and the same bench
with ``mask__distance_mm=17.0``: the Fresnel number at 550 nm; the spot's full width at 10 % of
its peak (the row through the peak of the expected image at normal incidence, px) without and
with diffraction, and the region of interest's 130 px over it (the paper: "about 2.5x the spot");
and, on noise-free frames (``noise_free()``: bias and 10-bit quantisation stay; the mask's play
held at zero) at poses
(alpha, beta) in {0, 10, -15}^2, algorithm B's centroid (``sunlab.centroid.projection_window``)
with diffraction minus without, px, and each one's error against its own ``spot_truth`` (NaN:
the spot is clipped by the frame's edge).

Run:  python benchmarks/bench_fresnel.py
"""

from __future__ import annotations

import itertools

import numpy as np

from sunlab.centroid import projection_window
from sunlab.sim import Bench, diffraction, render_frame
from sunlab.sim.spots import spot_image, spot_truth

POSES = list(itertools.product((0.0, 10.0, -15.0), repeat=2))


def width_at(img, level=0.1):
    """Full width (px) of the row through the peak at ``level`` of the peak, crossings
    interpolated linearly."""
    i, j = np.unravel_index(np.argmax(img), img.shape)
    row = img[i] / img[i, j]
    right = j + int(np.argmax(row[j:] < level))
    left = j - int(np.argmax(row[j::-1] < level))
    xr = right - 1 + (row[right - 1] - level) / (row[right - 1] - row[right])
    xl = left + 1 - (row[left + 1] - level) / (row[left + 1] - row[left])
    return xr - xl


def main():
    for f_mm in (5.0, 17.0):
        base = Bench.paper_single_hole().replace(mask__distance_mm=f_mm).noise_free()
        benches = {on: base.replace(mask__diffraction=on) for on in (False, True)}
        w = {on: width_at(spot_image(b, 0.0, 0.0)[0]) for on, b in benches.items()}
        print(f"F = {f_mm:g} mm: N(550 nm) = {diffraction.fresnel_number(0.1, f_mm):.2f}; "
              f"spot width at 10 % of peak {w[False]:.1f} px geometric, {w[True]:.1f} px Fresnel; "
              f"ROI 130 px = {130 / w[False]:.2f}x / {130 / w[True]:.2f}x the spot")
        diffs = []
        for a, b in POSES:
            c, err = {}, {}
            for on, bench in benches.items():
                r = projection_window(render_frame(bench, a, b, seed=0, play_mm=(0.0, 0.0)))
                c[on] = np.array([r.x, r.y])
                err[on] = c[on] - np.concatenate(spot_truth(bench, a, b))  # one hole
            d = c[True] - c[False]
            diffs.append(d)
            (gx, gy), (fx, fy) = err[False], err[True]
            print(f"  alpha {a:+5.1f} beta {b:+5.1f}: B(Fresnel) - B(geometric) = "
                  f"({d[0]:+.4f}, {d[1]:+.4f}) px; B - truth geometric ({gx:+.4f}, {gy:+.4f}), "
                  f"Fresnel ({fx:+.4f}, {fy:+.4f})")
        d = np.array(diffs)[np.all(np.isfinite(diffs), axis=1)]
        rms = np.sqrt(np.mean(d**2, axis=0))
        print(f"  RMS of the difference over the {len(d)} poses on the frame: x {rms[0]:.4f} px, "
              f"y {rms[1]:.4f} px")


if __name__ == "__main__":
    main()
