"""The holes of a pinhole mask: position, diameter, shape and defects, and each hole's aperture
(its outline, its affine map of the unit disk, its dust) in the mask frame, mm.

Defects (per hole, any combination):

* :class:`Dust` -- an opaque particle over part of the hole, optionally standing ``height_mm``
  above the mask plane, so that its shadow slides over the aperture with the sun angle (a
  pose-dependent centroid error: a "bad hole" of docs/paper.md Fig. 14);
* :class:`Elliptical` -- an elliptical outline (a drill that wandered, an etch that ran);
* :class:`Burred` -- an irregular, burred rim (random low-order harmonics of the radius);
* :class:`Undersized` -- a smaller diameter (a partly closed hole).

Examples
--------
>>> Hole(0.0, 0.0, 0.2, defect=Elliptical(0.5, 0.0)).affine().round(3).tolist()
[[0.1, 0.0], [0.0, 0.05]]
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..schema import DEFECT_FLAGS
from .source import _check

__all__ = []


def _positive(name: str, value: float, fix: str) -> None:
    _check(isinstance(value, int | float | np.floating | np.integer) and math.isfinite(value)
           and value > 0, name, value, "a positive number", fix)


@dataclass(frozen=True)
class Dust:
    """An opaque dust particle partly covering a hole.

    Parameters
    ----------
    dx_mm, dy_mm : float
        Centre of the particle relative to the hole centre, mask frame, mm.
    diameter_mm : float
        Particle diameter, mm.
    height_mm : float
        Height of the particle above the mask plane (toward the sun), mm. 0: it lies in the hole's
        plane and only removes a fixed part of the aperture (a constant centroid offset). > 0: its
        shadow moves by ``height * tan(theta)`` with the sun angle, so the occluded part of the
        aperture and the centroid error change from pose to pose.
    """

    dx_mm: float = 0.07
    dy_mm: float = 0.0
    diameter_mm: float = 0.06
    height_mm: float = 0.03

    def __post_init__(self):
        _positive("dust.diameter_mm", self.diameter_mm, "pass the particle size in mm, e.g. 0.05")
        _check(math.isfinite(self.height_mm) and self.height_mm >= 0, "dust.height_mm",
               self.height_mm, ">= 0 mm", "0 for a particle in the hole plane.")


@dataclass(frozen=True)
class Elliptical:
    """An elliptical outline: the hole's diameter is the major axis, ``axis_ratio`` = minor/major.

    Parameters
    ----------
    axis_ratio : float
        Minor over major axis, 0 < ratio <= 1.
    angle_deg : float
        Angle of the major axis from the mask x axis, deg.
    """

    axis_ratio: float = 0.85
    angle_deg: float = 30.0

    def __post_init__(self):
        _check(0.0 < self.axis_ratio <= 1.0, "elliptical.axis_ratio", self.axis_ratio,
               "0 < ratio <= 1", "pass minor/major, e.g. 0.85.")

    def stretch(self) -> np.ndarray:
        """The map of a circle onto this ellipse (mask frame).

        Returns
        -------
        numpy.ndarray, shape (2, 2)
            R diag(1, ratio) R^T, R the rotation by ``angle_deg``.
        """
        c, s = math.cos(math.radians(self.angle_deg)), math.sin(math.radians(self.angle_deg))
        rot = np.array([[c, -s], [s, c]])
        return rot @ np.diag([1.0, self.axis_ratio]) @ rot.T


@dataclass(frozen=True)
class Burred:
    """An irregular (burred) rim: r(phi) = r0 (1 + sum_k a_k cos(k phi + phi_k)).

    Parameters
    ----------
    amplitude : float
        RMS relative perturbation of the radius (0.05 = 5 % of the radius).
    seed : int
        Seed of the random harmonic amplitudes and phases (the hole's own shape).
    harmonics : tuple of int
        Lowest and highest harmonic k.
    """

    amplitude: float = 0.05
    seed: int = 0
    harmonics: tuple[int, int] = (2, 12)

    def __post_init__(self):
        _check(0.0 <= self.amplitude < 0.3, "burred.amplitude", self.amplitude,
               "0 <= amplitude < 0.3 (relative RMS radius error)", "pass e.g. 0.05.")

    def radius_factor(self, phi: np.ndarray) -> np.ndarray:
        """1 + sum_k a_k cos(k phi + phi_k), the relative radius at polar angles ``phi`` (rad).

        Parameters
        ----------
        phi : numpy.ndarray, shape (n,)
            Polar angles about the hole centre, rad.

        Returns
        -------
        numpy.ndarray, shape (n,)
            Radius at each angle over the design radius; the harmonics' amplitudes and phases
            come from ``seed``, scaled to an RMS of ``amplitude``.
        """
        k = np.arange(self.harmonics[0], self.harmonics[1] + 1)
        rng = np.random.default_rng(np.random.SeedSequence([int(self.seed), 0xB0B]))
        a = rng.standard_normal(k.size) / np.sqrt(k)
        a *= self.amplitude * np.sqrt(2.0) / np.sqrt(np.sum(a * a))
        ph = rng.uniform(0.0, 2 * np.pi, k.size)
        return 1.0 + np.sum(a[:, None] * np.cos(k[:, None] * phi[None, :] + ph[:, None]), axis=0)


@dataclass(frozen=True)
class Undersized:
    """A hole smaller than designed: diameter multiplied by ``factor`` (0 < factor <= 1)."""

    factor: float = 0.8

    def __post_init__(self):
        _check(0.0 < self.factor <= 1.0, "undersized.factor", self.factor, "0 < factor <= 1",
               "pass e.g. 0.8 for a hole 20 % too small.")


_DEFECT_TYPES = (Dust, Elliptical, Burred, Undersized)


@dataclass(frozen=True)
class Hole:
    """One pinhole of the mask.

    Parameters
    ----------
    x_mm, y_mm : float
        Design position of the hole centre in the mask frame, mm (x along columns, y along rows).
    diameter_mm : float
        Design diameter, mm (the paper: 0.2).
    shape : {"circle", "square"}
        Design outline; a square's side equals ``diameter_mm``.
    defect : Dust, Elliptical, Burred, Undersized or a tuple of them, optional
        Manufacturing defects or contamination; stored as a tuple.
    i, j : int
        Grid row and column of the hole (-1 when the mask is not a grid).

    Examples
    --------
    >>> h = Hole(0.0, 0.0, 0.2, defect=Undersized(0.5))
    >>> round(h.area_mm2(), 6)  # pi (0.05 mm)^2
    0.007854
    """

    x_mm: float
    y_mm: float
    diameter_mm: float = 0.2
    shape: str = "circle"
    defect: tuple = field(default=())
    i: int = -1
    j: int = -1

    def __post_init__(self):
        for name in ("x_mm", "y_mm"):
            _check(math.isfinite(getattr(self, name)), f"hole.{name}", getattr(self, name),
                   "a finite position")
        _positive("hole.diameter_mm", self.diameter_mm, "pass the hole diameter in mm, e.g. 0.2")
        _check(self.shape in ("circle", "square"), "hole.shape", self.shape,
               "'circle' or 'square'", "describe irregular outlines with a Burred or Elliptical "
               "defect.")
        d = self.defect
        d = () if d is None else (d,) if isinstance(d, _DEFECT_TYPES) else tuple(d)
        _check(all(isinstance(item, _DEFECT_TYPES) for item in d), "hole.defect", d,
               "Dust, Elliptical, Burred or Undersized (or a tuple of them)")
        object.__setattr__(self, "defect", d)

    def _find(self, kind):
        return [d for d in self.defect if isinstance(d, kind)]

    @property
    def defect_flags(self) -> int:
        """Bit flags of the defects (:data:`DEFECT_FLAGS`); 0 for a good hole."""
        return sum(DEFECT_FLAGS[name] for name, kind in zip(DEFECT_FLAGS, _DEFECT_TYPES,
                                                          strict=True) if self._find(kind))

    @property
    def effective_diameter_mm(self) -> float:
        """Design diameter times the :class:`Undersized` factors, mm."""
        return math.prod((u.factor for u in self._find(Undersized)), start=self.diameter_mm)

    def affine(self) -> np.ndarray | None:
        """2 x 2 matrix mapping the unit disk onto the (elliptical) aperture, mask frame, mm.

        None when the outline is not an affine image of a circle (square or burred holes).

        Returns
        -------
        numpy.ndarray, shape (2, 2), or None
            The effective radius (undersizing included) times the ellipses' stretches, mm.
        """
        if self.shape != "circle" or self._find(Burred):
            return None
        r = self.effective_diameter_mm / 2.0
        a = np.diag([r, r])
        for e in self._find(Elliptical):
            a = e.stretch() @ a
        return a

    def outline(self, n: int = 72) -> np.ndarray:
        """The aperture outline as a counter-clockwise polygon, (n, 2) mm relative to the centre.

        Parameters
        ----------
        n : int
            Number of vertices.

        Returns
        -------
        numpy.ndarray, shape (n, 2)
            Vertices (x, y), mm, in the mask frame; a circle's vertices sit slightly outside it
            so that the polygon keeps its area.
        """
        phi = np.linspace(0.0, 2 * np.pi, n, endpoint=False)
        r = self.effective_diameter_mm / 2.0
        if self.shape == "square":
            # Polar radius of a square of side 2 r, sampled at the same angles plus its corners.
            rho = r / np.maximum(np.abs(np.cos(phi)), np.abs(np.sin(phi)))
        else:
            # vertices slightly outside the circle so that the polygon keeps the circle's area
            rho = np.full(n, r * math.sqrt((2 * math.pi / n) / math.sin(2 * math.pi / n)))
        for b in self._find(Burred):
            rho = rho * b.radius_factor(phi)
        pts = np.stack([rho * np.cos(phi), rho * np.sin(phi)], axis=-1)
        for e in self._find(Elliptical):
            pts = pts @ e.stretch().T
        return pts

    def occluders(self, n: int = 36) -> list[tuple[np.ndarray, float]]:
        """Dust particles as (convex polygon (n, 2) mm relative to the hole centre, height mm).

        Parameters
        ----------
        n : int
            Vertices of each particle's polygon.

        Returns
        -------
        list of (numpy.ndarray, float)
            One entry per :class:`Dust` defect: its outline (n, 2) mm and its height above the
            mask, mm; empty for a clean hole.
        """
        phi = np.linspace(0.0, 2 * np.pi, n, endpoint=False)
        return [(np.stack([d.dx_mm + d.diameter_mm / 2.0 * np.cos(phi),
                           d.dy_mm + d.diameter_mm / 2.0 * np.sin(phi)], axis=-1),
                 float(d.height_mm)) for d in self._find(Dust)]

    def area_mm2(self) -> float:
        """Open area of the aperture at normal incidence, mm^2 (dust in the hole plane removed
        only approximately: use the renderer for exact areas).

        Returns
        -------
        float
            pi abs(det A) for an affine outline (:meth:`affine`), else the area of a 512-vertex
            polygon of the outline, mm^2.
        """
        a = self.affine()
        if a is not None:
            return float(math.pi * abs(np.linalg.det(a)))
        x, y = self.outline(512).T
        return float(0.5 * np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))

    def max_radius_mm(self) -> float:
        """Largest distance of the outline from the hole centre, mm.

        Returns
        -------
        float
            The largest semi-axis of an affine outline, else the outline's largest vertex
            radius, mm.
        """
        a = self.affine()
        if a is not None:
            return float(np.linalg.norm(a, 2))
        return float(np.max(np.hypot(*self.outline(256).T)))
