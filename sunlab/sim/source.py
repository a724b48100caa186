"""The solar simulator: a collimated, uniform (optionally limb-darkened) disk of 0.52 deg.

The paper's source (docs/paper.md sec. 2) is the exit port of an integrating sphere, radius
R = 6.82 mm, at the focus of a lens of focal length f = 1500 mm: every point of the port becomes a
parallel beam, so the sensor sees a disk of angular diameter 2 atan(R / f) = 0.521 deg, the Sun's
apparent size from Earth orbit. An integrating sphere's port is Lambertian, so the disk is uniform
(no limb darkening); ``limb_darkening`` > 0 gives the real Sun's linear law
I(mu) = 1 - u (1 - mu), with mu the cosine of the emergence angle on the solar disk.

Examples
--------
>>> src = Source()
>>> round(src.diameter_deg, 4)
0.521
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import ConfigurationError

__all__ = ["Source"]

def _check(ok: bool, name: str, value, expected: str, fix: str = "") -> None:
    """Raise a :class:`~sunlab.errors.ConfigurationError` naming ``name``, the value found, what
    is expected and the fix, unless ``ok`` (every part of the bench validates with it)."""
    if not ok:
        raise ConfigurationError(f"{name}: found {value!r}; expected {expected}." +
                                 (f" Fix: {fix}" if fix else ""))


#: 2 atan(6.82 mm / 1500 mm): the integrating-sphere port seen through the collimating lens, deg.
PAPER_SOURCE_DIAMETER_DEG = math.degrees(2.0 * math.atan(6.82 / 1500.0))


@dataclass(frozen=True)
class Source:
    """A collimated disk source (the paper's solar simulator).

    Parameters
    ----------
    diameter_deg : float
        Apparent angular diameter of the disk, deg. Default 2 atan(6.82 / 1500) = 0.5210 deg
        (docs/paper.md sec. 2).
    limb_darkening : float
        Coefficient u of the linear limb-darkening law I(mu) = 1 - u (1 - mu), 0 <= u <= 1.
        Default 0: the integrating sphere's port is Lambertian, i.e. a uniform disk. The real
        Sun in the visible has u of about 0.6.
    fluence_photons_per_um2 : float
        Photons per square micrometre, per exposure, on a surface normal to the beam (the whole
        disk). Default 800: our choice, so that a normally incident spot peaks near 350 DN with
        the default :class:`~sunlab.sim.Detector` (fill factor 0.5 x QE 0.7 x 49 um^2 x 800 =
        13 700 e-, at 40 e-/DN), about a third of the 10-bit range, as an operator sets the
        exposure so that no pose of the field of view saturates.

    Examples
    --------
    >>> Source(limb_darkening=0.6).profile(np.array([0.0, 1.0])).tolist()
    [1.0, 0.4]
    """

    diameter_deg: float = PAPER_SOURCE_DIAMETER_DEG
    limb_darkening: float = 0.0
    fluence_photons_per_um2: float = 800.0

    def __post_init__(self):
        d, u, f = self.diameter_deg, self.limb_darkening, self.fluence_photons_per_um2
        _check(math.isfinite(d) and 0.0 <= d < 10.0, "source.diameter_deg", d,
               "0 <= diameter < 10 deg (the paper: 0.52)", "pass diameter_deg=0.52.")
        _check(0.0 <= u <= 1.0, "source.limb_darkening", u, "0 <= u <= 1",
               "0 for the integrating sphere, about 0.6 for the real Sun.")
        _check(math.isfinite(f) and f >= 0, "source.fluence_photons_per_um2", f,
               "a non-negative photon fluence", "pass e.g. 800.")

    @property
    def radius_rad(self) -> float:
        """Angular radius of the disk, rad."""
        return math.radians(self.diameter_deg) / 2.0

    def profile(self, r):
        """Relative radiance at fractional radius r (0 = centre, 1 = limb) of the disk.

        Parameters
        ----------
        r : array_like
            Radius as a fraction of the angular radius.

        Returns
        -------
        numpy.ndarray
            I(r) = 1 - u (1 - sqrt(1 - r^2)), zero outside the disk.
        """
        r = np.asarray(r, dtype=float)
        mu = np.sqrt(np.clip(1.0 - r * r, 0.0, None))
        return np.where(r <= 1.0, 1.0 - self.limb_darkening * (1.0 - mu), 0.0)

    def second_moment(self) -> float:
        """<x^2> of the normalised radial profile over the unit disk (1/4 for a uniform disk).

        Returns
        -------
        float
            Second moment along one axis of the limb-darkened disk of unit radius.

        Examples
        --------
        >>> Source().second_moment()
        0.25
        """
        u = self.limb_darkening  # <r^2> of the profile, over 2
        return ((1 - u) / 4 + 2 * u / 15) / ((1 - u) / 2 + u / 3) / 2.0
