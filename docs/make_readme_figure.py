"""Render the README's picture from the virtual bench: `python docs/make_readme_figure.py`."""

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from sunlab import centroid, sim


def main(path: Path = Path(__file__).parent / "images" / "bench.png") -> Path:
    a, b = -8.0, 7.0
    f1 = sim.render_frame(sim.Bench.paper_single_hole(), a, b, seed=0)
    f100 = sim.render_frame(sim.Bench.paper_multi_hole(), a, b, seed=0)
    c = centroid.projection_window(f1)
    fig = Figure(figsize=(13, 3.6))
    ax = fig.subplots(1, 3, gridspec_kw={"width_ratios": [1.25, 1.25, 1]})
    ax[0].imshow(f1, cmap="gray", vmax=np.percentile(f1, 99.99))
    ax[0].set_title(f"one 0.2 mm hole, alpha={a} deg, beta={b} deg")
    ax[1].imshow(f100, cmap="gray", vmax=np.percentile(f100, 99.9))
    ax[1].set_title("10 x 10 mask, same pose (some holes defective)")
    x0, x1, y0, y1 = (int(v) for v in c.window)
    stamp = f1[y0:y1, x0:x1]
    ax[2].imshow(stamp, cmap="magma", extent=(x0 - 0.5, x1 - 0.5, y1 - 0.5, y0 - 0.5))
    ax[2].plot(c.x, c.y, "c+", ms=14, mew=1.5)
    ax[2].set_title(f"algorithm B window\ncentroid ({c.x:.2f}, {c.y:.2f}) px")
    for a_ in ax[:2]:
        a_.set(xlabel="x (column)", ylabel="y (row)")
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=80)
    return path


if __name__ == "__main__":
    print(main())
