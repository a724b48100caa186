"""The pinhole mask: its holes (:mod:`sunlab.sim.holes`), layouts and placement errors.

Frames and units. The mask frame has its origin above the centre of the detector (the design
point, pixel ((nx - 1) / 2, (ny - 1) / 2)), x along the detector columns and y along the rows, in
millimetres; a hole's ``x_mm, y_mm`` is the design position of its centre in that frame, so its
design projection with the sun at zenith is pixel (x_ref + x_mm / p, y_ref + y_mm / p). The mask
plane sits at height ``distance_mm + delta_f_mm`` above the focal plane; it may be tilted
(``tilt_x_deg`` about x, ``tilt_y_deg`` about y), rotated in its plane (``rotation_deg``) about its
origin and offset (``offset_x_mm, offset_y_mm``). ``play_x_mm, play_y_mm`` model a loosely held
mask: at every pose it sits at a new offset within +-play, uniformly distributed.

Examples
--------
>>> m = Mask.grid()
>>> len(m.holes), m.holes[0].i, m.holes[11].j
(100, 0, 1)
>>> Mask.single_hole().holes[0].diameter_mm
0.2
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from .holes import _DEFECT_TYPES, Burred, Dust, Elliptical, Hole, Undersized, _positive
from .source import _check

__all__ = ["Mask"]


#: Centre of the paper-like 10 x 10 grid relative to the detector centre, mm (our choice): the
#: spots sweep -16.5..1.5 deg in alpha and -1.5..16.5 deg in beta (plus the 1.864 / 0.415 deg
#: mounting errors), i.e. about -200..+50 px in x and -20..+240 px in y, so the array sits left
#: of and above the centre to keep every spot on the 1280 x 1024 detector (docs/paper.md sec. 8).
PAPER_GRID_CENTRE_MM = (0.52, -0.78)

#: Mask-to-focal-plane distance F of the paper's bench, mm: a choice, not identified (the
#: sensitivity table's rows disagree; docs/identification.md, Results). The paper never gives F;
#: the primary clues split: the ROI sentence ("130 px, about 2.5 times the spot", sec. 1) gives
#: 3.67 at 5 mm and 2.55 at 17 mm; at 5 mm the 10 x 10 pattern stays whole on the detector over
#: the test range, at 17 mm part of it leaves the frame (docs/paper.md sec. 10).
PAPER_DISTANCE_MM = 5.0

#: Where the presets put the one hole, mm from the detector centre: under the centre of the
#: 10 x 10 grid (:data:`PAPER_GRID_CENTRE_MM`), so that the one spot's track over the test
#: range (about 250 x 260 px at F = 5 mm) sits where the grid's central spots go.
PAPER_TRACK_CENTRE_MM = PAPER_GRID_CENTRE_MM


@dataclass(frozen=True)
class Mask:
    """An opaque mask with pinholes, at distance F above the focal plane.

    Parameters
    ----------
    holes : tuple of Hole
        The holes, design positions in the mask frame (see the module notes).
    distance_mm : float
        Nominal (design) mask-to-focal-plane distance F, mm. Default 5.0 (0.08 deg per pixel,
        a 35 px spot): the presets' choice for the paper's bench, not identified
        (:data:`PAPER_DISTANCE_MM`; docs/identification.md, Results).
    delta_f_mm : float
        Error of the mask distance: the true distance is F + dF, mm (the paper fitted 0.094).
    tilt_x_deg, tilt_y_deg : float
        Tilt of the mask plane about the detector x and y axes, deg.
    rotation_deg : float
        In-plane rotation of the mask about its origin, deg.
    offset_x_mm, offset_y_mm : float
        In-plane offset of the mask from its design position, mm.
    play_x_mm, play_y_mm : float
        Half-width of a per-pose extra offset: a mask held with play that settles differently
        at each platform pose, mm (common to all holes).
    size_mm : tuple of float
        Width (x) and height (y) of the mask plate, mm; every hole must lie on it.
    name : str
        Label stored in a cube's ``mask`` attribute.
    diffraction : bool
        Render each dust-free circular or elliptical hole's broadband Fresnel pattern
        (:mod:`sunlab.sim.diffraction`) instead of its geometric shadow. Default False: geometric
        optics, as every preset and the identification's evidence use. Polygonal holes (burrs,
        undersized outlines) and holes with dust stay geometric either way. The transform's
        table takes about 2 s per hole height (cached); a 100-hole frame then renders in about
        2 s instead of 0.2 s.
    """

    holes: tuple = ()
    distance_mm: float = 5.0
    delta_f_mm: float = 0.0
    tilt_x_deg: float = 0.0
    tilt_y_deg: float = 0.0
    rotation_deg: float = 0.0
    offset_x_mm: float = 0.0
    offset_y_mm: float = 0.0
    play_x_mm: float = 0.0
    play_y_mm: float = 0.0
    size_mm: tuple[float, float] = (11.0, 9.0)
    name: str = "custom"
    diffraction: bool = False

    def __post_init__(self):
        _check(isinstance(self.diffraction, bool | np.bool_), "mask.diffraction", self.diffraction,
               "True or False", "True for the Fresnel spot, False for the geometric shadow.")
        for name, v in (("holes", tuple(self.holes)), ("diffraction", bool(self.diffraction)),
                        ("size_mm", tuple(float(v) for v in self.size_mm))):
            object.__setattr__(self, name, v)
        _check(bool(self.holes) and all(isinstance(h, Hole) for h in self.holes), "mask.holes",
               self.holes, "at least one Hole", "use Mask.single_hole() or Mask.grid().")
        f, df = self.distance_mm, self.delta_f_mm
        _check(math.isfinite(f) and f > 0, "mask.distance_mm", f,
               "a positive mask-to-focal-plane distance F in mm", "pass distance_mm=5.0.")
        _check(math.isfinite(df) and f + df > 0, "mask.delta_f_mm", df,
               f"a true distance F + dF = {f + df!r} mm > 0", "keep |dF| < F.")
        for name in ("tilt_x_deg", "tilt_y_deg", "play_x_mm", "play_y_mm"):
            v, tilt = getattr(self, name), name.startswith("tilt")
            _check(math.isfinite(v) and (abs(v) < 30.0 if tilt else v >= 0), f"mask.{name}", v,
                   "|tilt| < 30 deg" if tilt else "a half-width >= 0 mm", "0 for none.")
        w, h = self.size_mm
        for k, hole in enumerate(self.holes):
            r = hole.max_radius_mm()
            _check(abs(hole.x_mm) + r <= w / 2 and abs(hole.y_mm) + r <= h / 2,
                   f"mask.holes[{k}]", (hole.x_mm, hole.y_mm),
                   f"a hole on the {w:g} x {h:g} mm mask centred on the detector",
                   f"move the hole within +-{w / 2:g}, +-{h / 2:g} mm or enlarge size_mm.")

    @property
    def true_distance_mm(self) -> float:
        """True mask-to-focal-plane distance F + dF, mm."""
        return self.distance_mm + self.delta_f_mm

    @property
    def n_holes(self) -> int:
        return len(self.holes)

    def rotation_matrix(self) -> np.ndarray:
        """3 x 3 rotation of the mask frame into the detector frame: R_z(rot) R_y(ty) R_x(tx).

        Returns
        -------
        numpy.ndarray, shape (3, 3)
            From ``tilt_x_deg``, ``tilt_y_deg`` and ``rotation_deg``.
        """
        cx, sx, cy, sy, cz, sz = (f(math.radians(v)) for v in (self.tilt_x_deg, self.tilt_y_deg,
                                  self.rotation_deg) for f in (math.cos, math.sin))
        return (np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
                @ np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
                @ np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]]))

    def replace(self, **changes) -> Mask:
        """A copy with some fields changed (``dataclasses.replace``).

        Parameters
        ----------
        **changes
            Field names of :class:`Mask` and their new values.

        Returns
        -------
        Mask
            A new mask; this one is unchanged.
        """
        return replace(self, **changes)

    def with_defects(self, defects: dict) -> Mask:
        """A copy where hole ``k`` gets ``defects[k]`` (a defect or a tuple) added to its own.

        Parameters
        ----------
        defects : dict of int to defect or tuple of defects
            Hole index -> :class:`Dust`, :class:`Burred`, :class:`Elliptical` or
            :class:`Undersized` (or several).

        Returns
        -------
        Mask

        Examples
        --------
        >>> m = Mask.grid(2, 2).with_defects({3: Undersized(0.7)})
        >>> [h.defect_flags for h in m.holes]
        [0, 0, 0, 8]
        """
        holes = list(self.holes)
        for k, d in defects.items():
            d = (d,) if isinstance(d, _DEFECT_TYPES) else tuple(d)
            holes[k] = replace(holes[k], defect=holes[k].defect + d)
        return replace(self, holes=tuple(holes))

    # ------------------------------------------------------------------ constructors
    @classmethod
    def single_hole(cls, diameter_mm: float = 0.2, x_mm: float = 0.0, y_mm: float = 0.0,
                    **kwargs) -> Mask:
        """The paper's one-hole mask: a 0.2 mm pinhole above the detector centre.

        Parameters
        ----------
        diameter_mm : float
            Hole diameter, mm.
        x_mm, y_mm : float
            Hole centre in the mask frame, mm.
        **kwargs
            Other fields of :class:`Mask` (``distance_mm``, ``delta_f_mm``, tilts, play, ...).

        Returns
        -------
        Mask
        """
        kwargs.setdefault("name", "single")
        return cls(holes=(Hole(x_mm, y_mm, diameter_mm),), **kwargs)

    @classmethod
    def grid(cls, rows: int = 10, cols: int = 10, pitch_mm: float = 0.5, diameter_mm: float = 0.2,
             centre_mm: tuple[float, float] = (0.0, 0.0), **kwargs) -> Mask:
        """A rows x cols grid of identical holes at ``pitch_mm`` (the paper: 10 x 10, 0.5 mm).

        Hole ``k = i * cols + j`` is at grid row ``i`` (along y) and column ``j`` (along x).

        Parameters
        ----------
        rows, cols : int
            Holes along y and along x.
        pitch_mm, diameter_mm : float
            Centre-to-centre spacing and hole diameter, mm.
        centre_mm : (float, float)
            Centre of the grid in the mask frame, mm.
        **kwargs
            Other fields of :class:`Mask` (``distance_mm``, ``delta_f_mm``, tilts, play, ...).

        Returns
        -------
        Mask
        """
        _check(rows >= 1 and cols >= 1, "grid", f"{rows} x {cols} holes", ">= 1 x 1")
        _positive("grid.pitch_mm", pitch_mm, "pass the hole spacing in mm, e.g. 0.5")
        holes = [Hole(centre_mm[0] + (j - (cols - 1) / 2) * pitch_mm,
                      centre_mm[1] + (i - (rows - 1) / 2) * pitch_mm, diameter_mm, i=i, j=j)
                 for i in range(rows) for j in range(cols)]
        kwargs.setdefault("name", f"grid{rows}x{cols}")
        return cls(holes=tuple(holes), **kwargs)

    @classmethod
    def random_layout(cls, n: int = 50, *, seed: int = 0,
                      diameter_mm: tuple[float, float] = (0.12, 0.3),
                      region_mm: tuple[float, float, float, float] = (-1.8, 2.8, -3.0, 1.4),
                      min_separation_mm: float = 0.45, **kwargs) -> Mask:
        """Randomly placed holes of random diameters (the paper's open problem, docs/paper.md
        sec. 6).

        Parameters
        ----------
        n : int
            Number of holes.
        seed : int
            Seed of the layout.
        diameter_mm : (float, float)
            Diameters are uniform in this range, mm.
        region_mm : (x0, x1, y0, y1)
            Region of the mask frame where hole centres lie, mm.
        min_separation_mm : float
            Smallest centre-to-centre distance, mm (so spots do not overlap).
        **kwargs
            Other fields of :class:`Mask`.

        Returns
        -------
        Mask
            Named ``"random<n>"`` unless ``name`` is given.

        Examples
        --------
        >>> m = Mask.random_layout(20, seed=1)
        >>> len(m.holes), m.name
        (20, 'random20')
        """
        rng = np.random.default_rng(np.random.SeedSequence([int(seed), 0x5EED]))
        pts: list[tuple[float, float]] = []
        for _ in range(200 * n):
            if len(pts) == n:
                break
            p = (rng.uniform(region_mm[0], region_mm[1]), rng.uniform(region_mm[2], region_mm[3]))
            if all(math.hypot(p[0] - q[0], p[1] - q[1]) >= min_separation_mm for q in pts):
                pts.append(p)
        _check(len(pts) == n, "random_layout", f"{len(pts)} of {n} holes placed",
               f"{n} holes {min_separation_mm} mm apart in {region_mm}",
               "fewer holes, a smaller separation or a larger region.")
        d = rng.uniform(diameter_mm[0], diameter_mm[1], n)
        kwargs.setdefault("name", f"random{n}")
        return cls(holes=tuple(Hole(x, y, float(dk)) for (x, y), dk in zip(pts, d, strict=True)),
                   **kwargs)

    def with_random_defects(self, n_bad: int, *, seed: int = 0) -> Mask:
        """A copy with ``n_bad`` randomly chosen holes given random defects (dust standing above
        the mask, burrs, elliptical outlines or undersized holes), reproducible from ``seed``.

        Parameters
        ----------
        n_bad : int
            Number of holes to spoil (at most all of them); the kinds take turns.
        seed : int
            Seed of the choice of holes and of the defects' sizes.

        Returns
        -------
        Mask
        """
        rng = np.random.default_rng(np.random.SeedSequence([int(seed), 0xBAD]))
        idx = rng.choice(len(self.holes), size=min(n_bad, len(self.holes)), replace=False)
        out = {}
        for n, k in enumerate(sorted(idx.tolist())):
            r = self.holes[k].diameter_mm / 2
            kind = n % 4
            if kind == 0:
                ang = rng.uniform(0, 2 * np.pi)
                dist = rng.uniform(0.6, 0.9) * r
                out[k] = Dust(dist * math.cos(ang), dist * math.sin(ang),
                              rng.uniform(0.5, 0.8) * r, rng.uniform(0.02, 0.05))
            elif kind == 1:
                out[k] = Burred(rng.uniform(0.04, 0.08), seed=int(rng.integers(1 << 30)))
            elif kind == 2:
                out[k] = Elliptical(rng.uniform(0.75, 0.92), rng.uniform(0, 180))
            else:
                out[k] = Undersized(rng.uniform(0.6, 0.85))
        return self.with_defects(out)
