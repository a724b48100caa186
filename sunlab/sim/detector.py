"""The detector: an Ibis4-like CMOS APS, its pixel response, noise and ADC.

Signal chain of one pixel (electrons e-, digital numbers DN):

1. Photo-electrons: the spot's irradiance integrated over the pixel's *sensitive area* (a
   rectangle of ``fill_factor`` times the pixel area, optionally off-centre), times ``qe``, times
   the pixel's gain factor ``1 + PRNU`` (a white part and a spatially correlated part).
2. Dark signal: ``dark_signal_e`` per frame, non-uniform (DSNU, relative RMS ``dsnu``), plus a
   sparse population of hot pixels.
3. Temporal noise: photon and dark shot noise (Poisson, taken as Gaussian with variance = mean:
   every pixel holds hundreds of electrons or more, where the two differ by far less than one DN)
   and read noise; drawn as one standard normal deviate per pixel in float32.
4. Saturation at ``full_well_e``; conversion at ``gain_e_per_dn``; bias plus a per-column offset
   pattern (column FPN); rounding to the nearest DN (quantisation, variance 1/12 DN^2); clipping to
   0 .. 2**bit_depth - 1 = 1023.

Defaults and their rationale (our choices where the paper is silent, docs/paper.md sec. 1, 8):

* 1280 x 1024 pixels of 7 um, 10 bits: the paper's Ibis4.
* fill factor 60 % (IBIS4-1300 datasheet) x QE 0.583 = 0.35: the paper gives the product FF x QE =
  35 % (sec. 1), so QE is that product over the datasheet's fill factor; the sensitive area (a
  centred 5.42 um square in a 7 um pixel) is smaller than the pitch, which makes the sampled
  centroid depend (slightly) on where the spot falls.
* read noise 20 e- (IBIS4-1300 datasheet); 40 e-/DN and full well 62 500 e- (ADC range 41 000 e-):
  typical of a 3-transistor APS of that generation; the ADC saturates before the pixel.
* dark signal 400 e- (10 DN) per frame with 15 % DSNU, bias 32 DN, column FPN 0.5 DN RMS: a
  background of a few tens of DN, as the task asks for an uncooled APS in a dark room.
* hot pixels: 2e-4 of the array with an exponential dark signal of mean 8000 e-.
* PRNU: 1 % white plus 4 % spatially correlated (white noise smoothed by a Gaussian of 6 px) by
  default, a generic low-cost sensor; the paper's preset
  (:meth:`sunlab.sim.Bench.paper_single_hole`) takes the identification's nuisance
  median, 0.87 % white plus 0.87 % correlated over 2.8 px
  (``sunlab/data/preset_sources.csv``). A white PRNU of RMS s moves a uniform disk's centroid
  by about 0.28 s px per axis whatever its radius (0.003 px at 1 %); a correlated pattern moves it
  more, a fixed function of where the spot falls (:func:`sunlab.sim.surrogate.spot_error_maps`:
  about 0.04 px RMS for the preset under its 35 px spot). Set ``prnu_correlated=0`` for an ideal
  sensor.
* glass lid: none by default (``lid_thickness_mm=0``); the preset has the IBIS4-1300's 0.5 mm
  D263 lid, which refracts every oblique ray toward the hole's foot (Snell's law).

Examples
--------
>>> det = Detector()
>>> det.shape, det.max_dn
((1024, 1280), 1023)
>>> round(det.fill_factor * det.qe, 2)
0.35
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, replace
from typing import NamedTuple

import numpy as np

from .source import _check

__all__ = ["Detector"]

#: Each float field's rule: (fields, test, what is expected, the fix).
_RULES = [(("pixel_pitch_mm", "fill_factor", "qe"), lambda v: 0 < v <= 1, "0 < value <= 1",
           "e.g. a 0.007 mm pitch (the Ibis4), fill factor 0.6, QE 0.58."),
          (("gain_e_per_dn", "full_well_e", "sensitive_aspect", "prnu_correlation_px"),
           lambda v: v > 0, "a positive value", "e.g. 40 e-/DN, 62500 e-, aspect 1, 6 px."),
          (("lid_index",), lambda v: v >= 1, "a refractive index >= 1", "Schott D263: 1.523."),
          (("read_noise_e", "dark_signal_e", "dsnu", "column_fpn_dn", "bias_dn", "prnu",
            "prnu_correlated", "hot_pixel_fraction", "hot_pixel_dark_e", "diffusion_px",
            "lid_thickness_mm"), lambda v: v >= 0, "a value >= 0", "0 turns it off.")]


@dataclass(frozen=True)
class Detector:
    """Parameters of the detector (an Ibis4-like APS); see the module notes for the rationale.

    Parameters
    ----------
    nx, ny : int
        Columns and rows (Ibis4: 1280 x 1024).
    pixel_pitch_mm : float
        Pixel pitch, mm (Ibis4: 0.007).
    bit_depth : int
        ADC bits (Ibis4: 10).
    fill_factor : float
        Sensitive area over pixel area, 0 < FF <= 1.
    sensitive_aspect : float
        Width over height of the sensitive rectangle.
    sensitive_offset_px : (float, float)
        Centre of the sensitive rectangle relative to the pixel centre, px (x, y).
    qe : float
        Quantum efficiency of the sensitive area.
    gain_e_per_dn : float
        Conversion gain, electrons per DN.
    full_well_e : float
        Pixel saturation, electrons.
    read_noise_e : float
        RMS read noise, electrons.
    dark_signal_e : float
        Mean dark signal per frame, electrons.
    dsnu : float
        Relative RMS dark-signal non-uniformity.
    column_fpn_dn : float
        RMS of the per-column offset pattern, DN.
    bias_dn : float
        ADC offset, DN.
    prnu : float
        Relative RMS of the white (pixel-to-pixel) response non-uniformity.
    prnu_correlated : float
        Relative RMS of the spatially correlated response non-uniformity.
    prnu_correlation_px : float
        Sigma of the Gaussian that smooths white noise into the correlated PRNU, px (its
        autocorrelation is exp(-d^2 / (4 sigma^2))).
    hot_pixel_fraction : float
        Fraction of hot pixels.
    hot_pixel_dark_e : float
        Mean extra dark signal of a hot pixel (exponentially distributed), electrons.
    diffusion_px : float
        RMS lateral charge diffusion (Gaussian blur of the signal), px. Default 0: not modelled.
    lid_thickness_mm : float
        Thickness of the glass lid over the die, mm (0: a lid-less part). The IBIS4-1300 ships
        with a Schott D263 lid (datasheet, docs/paper.md sec. 10); a plane-parallel plate shifts
        an oblique ray toward the hole's foot (:func:`sunlab.sim.render.ray_positions`).
    lid_index : float
        Refractive index of the lid (Schott D263: 1.523 at 587.6 nm).
    temporal_noise : bool
        Shot and read noise on (False: frames are the rounded expectation).
    fixed_pattern : bool
        PRNU, DSNU, column pattern and hot pixels on (False: a uniform, ideal array).
    pattern_seed : int
        Seed of the fixed patterns: the serial number of this particular sensor.
    """

    nx: int = 1280
    ny: int = 1024
    pixel_pitch_mm: float = 0.007
    bit_depth: int = 10
    fill_factor: float = 0.6
    sensitive_aspect: float = 1.0
    sensitive_offset_px: tuple[float, float] = (0.0, 0.0)
    qe: float = 0.35 / 0.6
    gain_e_per_dn: float = 40.0
    full_well_e: float = 62500.0
    read_noise_e: float = 20.0
    dark_signal_e: float = 400.0
    dsnu: float = 0.15
    column_fpn_dn: float = 0.5
    bias_dn: float = 32.0
    prnu: float = 0.01
    prnu_correlated: float = 0.04
    prnu_correlation_px: float = 6.0
    hot_pixel_fraction: float = 2e-4
    hot_pixel_dark_e: float = 8000.0
    diffusion_px: float = 0.0
    lid_thickness_mm: float = 0.0
    lid_index: float = 1.523
    temporal_noise: bool = True
    fixed_pattern: bool = True
    pattern_seed: int = 1

    def __post_init__(self):
        object.__setattr__(self, "sensitive_offset_px",
                           tuple(float(v) for v in self.sensitive_offset_px))
        for name in ("nx", "ny", "bit_depth"):
            v = getattr(self, name)
            _check(isinstance(v, int | np.integer) and 0 < v <= (16 if name == "bit_depth" else v),
                   f"detector.{name}", v, "a positive integer (bit_depth <= 16: uint16 frames)",
                   "e.g. 1280 x 1024 pixels, 10 bits.")
        for names, ok, expected, fix in _RULES:
            for name in names:
                v = getattr(self, name)
                _check(math.isfinite(v) and ok(v), f"detector.{name}", v, expected, fix)
        (ax, ay), (ox, oy) = self.sensitive_size_px, self.sensitive_offset_px
        _check(abs(ox) + ax / 2 <= 0.5 + 1e-12 and abs(oy) + ay / 2 <= 0.5 + 1e-12,
               "detector.sensitive_offset_px", self.sensitive_offset_px,
               f"the {ax:.3f} x {ay:.3f} px sensitive area inside its pixel", "reduce the offset.")

    @property
    def shape(self) -> tuple[int, int]:
        """(ny, nx): the frame's array shape."""
        return (int(self.ny), int(self.nx))

    @property
    def lid_height_loss_mm(self) -> float:
        """What the glass lid takes off the height a paraxial ray sees, mm: t (1 - 1/n) (a
        plane-parallel plate; 0 without a lid), the part of its shift that a pinhole model's F
        absorbs."""
        return self.lid_thickness_mm * (1.0 - 1.0 / self.lid_index)

    @property
    def max_dn(self) -> int:
        """Full scale of the ADC, DN."""
        return (1 << int(self.bit_depth)) - 1

    @property
    def sensitive_size_px(self) -> tuple[float, float]:
        """Width and height of the sensitive rectangle, px."""
        a, r = math.sqrt(self.fill_factor), math.sqrt(self.sensitive_aspect)
        return (a * r, a / r)

    @property
    def reference_px(self) -> tuple[float, float]:
        """The detector centre (x, y), px: the design point under the mask origin."""
        return ((self.nx - 1) / 2.0, (self.ny - 1) / 2.0)

    def replace(self, **changes) -> Detector:
        """A copy with some fields changed.

        Parameters
        ----------
        **changes
            Field names of :class:`Detector` and their new values.

        Returns
        -------
        Detector
            A new detector; this one is unchanged.
        """
        return replace(self, **changes)


class FixedPattern(NamedTuple):
    """Per-pixel maps of one detector (float32, shape (ny, nx)).

    gain : relative response 1 + PRNU.
    dark_e : expected dark signal, e-.
    offset_dn : bias plus column pattern, DN.
    bg_mean_dn : expected dark frame, DN (before rounding).
    bg_sigma_dn : temporal noise of the dark frame, DN.
    """

    gain: np.ndarray
    dark_e: np.ndarray
    offset_dn: np.ndarray
    bg_mean_dn: np.ndarray
    bg_sigma_dn: np.ndarray


@functools.lru_cache(maxsize=4)
def fixed_pattern(det: Detector) -> FixedPattern:
    """The fixed-pattern maps of a detector, computed once per parameter set (cached).

    Parameters
    ----------
    det : Detector
        Its ``pattern_seed`` fixes the pattern: the same detector gets the same maps.

    Returns
    -------
    FixedPattern
        Gain (1 + PRNU), dark signal (e-), offset (DN), and the dark frame's mean and
        temporal noise (DN), each float32 of shape (ny, nx).

    Examples
    --------
    >>> fp = fixed_pattern(Detector(nx=64, ny=32))
    >>> fp.gain.shape, fp.gain.dtype.name
    ((32, 64), 'float32')
    """
    from scipy import ndimage

    shape = det.shape
    rng = np.random.default_rng(np.random.SeedSequence([int(det.pattern_seed), 0xF1C5]))
    if det.fixed_pattern:
        gain = 1.0 + det.prnu * rng.standard_normal(shape)
        if det.prnu_correlated > 0:
            field = ndimage.gaussian_filter(rng.standard_normal(shape), det.prnu_correlation_px,
                                            mode="wrap")
            field *= det.prnu_correlated / field.std()
            gain += field
        dark = det.dark_signal_e * (1.0 + det.dsnu * rng.standard_normal(shape))
        hot = rng.random(shape) < det.hot_pixel_fraction
        dark[hot] += rng.exponential(det.hot_pixel_dark_e, int(hot.sum()))
        dark = np.clip(dark, 0.0, None)
        offset = np.broadcast_to(det.bias_dn + det.column_fpn_dn * rng.standard_normal(det.nx),
                                 shape)  # a column pattern
    else:
        gain, dark, offset = (np.full(shape, v) for v in (1.0, det.dark_signal_e, det.bias_dn))
    g = det.gain_e_per_dn
    bg_mean = offset + dark / g
    bg_sigma = np.sqrt(dark + det.read_noise_e**2) / g if det.temporal_noise else np.zeros(shape)
    maps = [np.ascontiguousarray(m, dtype=np.float32)
            for m in (gain, dark, offset, bg_mean, bg_sigma)]
    for m in maps:
        m.setflags(write=False)
    return FixedPattern(*maps)
