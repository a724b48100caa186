"""Where each preset value comes from (``sunlab/data/preset_sources.csv``, from the presets).

``python -m studies.preset_sources`` walks the dataclass fields of
:meth:`sunlab.sim.Bench.paper_single_hole` and :meth:`sunlab.sim.Bench.paper_multi_hole` (public
names only) and writes one row per numeric field: ``bench``, ``parameter`` (the dotted field path,
such as ``detector.gain_e_per_dn``; a tuple's items and each hole numbered), ``value``, ``source``
(``paper``, ``datasheet``, ``physics``, ``identified`` or ``assumed``) and ``reference``. The
source of each path is :data:`SOURCES`, the first pattern that matches; a field no pattern names
is ``assumed``, "no source recorded". A one-at-a-time sensitivity of the assumed values (each at
half and twice its value, scored on the held-out cells) needs a surrogate run per value, and it
has not been run.

Examples
--------
>>> t = preset_sources()
>>> sorted(set(t["source"])) <= ["assumed", "datasheet", "identified", "paper", "physics"]
True
>>> t.set_index(["bench", "parameter"]).loc[("paper_single_hole", "detector.read_noise_e"),
...                                         "source"]
'datasheet'
"""

from __future__ import annotations

import argparse
import dataclasses
import re
import sys
from pathlib import Path

import pandas as pd

__all__ = ["SOURCES", "preset_sources"]

_FILE = Path(__file__).resolve().parent.parent / "sunlab" / "data" / "preset_sources.csv"
_ID = "docs/identification.md; studies/protocol.json cells.pinning"
_NUISANCE = "a nuisance at its prior median (studies/protocol.json priors): a choice"

#: (pattern on the dotted path, source, reference): the first match names a field's source.
SOURCES: tuple[tuple[str, str, str], ...] = (
    (r"source\.diameter_deg", "paper",
     "sec. 2: the sphere port R = 6.82 mm through the f = 1500 mm lens, 2 atan(R / f)"),
    (r"source\.limb_darkening", "physics", "a uniform disk: the sphere's port, not the Sun"),
    (r"source\.fluence_photons_per_um2", "assumed", "no source recorded: sets the signal level"),
    (r"mask\.holes\.\d+\.diameter_mm", "paper", "sec. 2: 0.2 mm holes"),
    (r"mask\.holes\.\d+\.[xy]_mm", "assumed",
     "the pattern's place on the detector (sunlab.sim.mask PAPER_GRID_CENTRE_MM) and, for 100 "
     "holes, its 0.5 mm pitch: our choice (docs/paper.md sec. 8)"),
    (r"mask\.distance_mm", "assumed",
     "F: the protocol's pick is F5, but F is not identified (studies/results/sensitivity.csv): "
     "a choice"),
    (r"mask\.delta_f_mm", "paper",
     "sec. 4.1: dF = 0.094 mm, plus the lid's paraxial height loss t (1 - 1/n) (physics)"),
    (r"mask\.(tilt_[xy]_deg|offset_[xy]_mm|rotation_deg)", "assumed",
     "no source recorded: a mounting tolerance of our choosing"),
    (r"mask\.play_x_mm", "identified",
     "alpha_total (Table 4 polynomial alpha mu) times the rest of alpha_platform_share; "
     + _ID),
    (r"mask\.play_y_mm", "assumed",
     "the 100-hole mask's play: " + _NUISANCE + " (0.5-10 um, log-uniform)"),
    (r"mask\.size_mm\.\d", "assumed", "no source recorded: the mask plate's size"),
    (r"detector\.(nx|ny)", "paper", "sec. 2: 1280 x 1024 pixels"),
    (r"detector\.pixel_pitch_mm", "paper", "sec. 2: 7 um pitch"),
    (r"detector\.bit_depth", "paper", "sec. 2: 10-bit ADC"),
    (r"detector\.(read_noise_e|fill_factor)", "datasheet",
     "IBIS4-1300 datasheet (FillFactory/Cypress 38-05707)"),
    (r"detector\.qe", "paper",
     "sec. 1: FF x QE = 35 %, divided by the datasheet's fill factor 0.6"),
    (r"detector\.(sensitive_aspect|sensitive_offset_px\.\d)", "assumed",
     "no source recorded: a square sensitive area centred in the pixel"),
    (r"detector\.(gain_e_per_dn|full_well_e|dark_signal_e|dsnu|column_fpn_dn|bias_dn"
     r"|hot_pixel_fraction|hot_pixel_dark_e)", "assumed",
     "no source recorded: a generic uncooled APS (sunlab.sim.detector)"),
    (r"detector\.(prnu|prnu_correlated|prnu_correlation_px)", "assumed",
     "the pixel response: " + _NUISANCE + " (0.5-3 % RMS, 1-8 px)"),
    (r"detector\.diffusion_px", "assumed", "off: no source recorded"),
    (r"detector\.lid_thickness_mm", "assumed",
     "datasheet: monochrome parts ship with a D263 lid; its 0.5 mm thickness our choice"),
    (r"detector\.lid_index", "physics", "D263 glass, n = 1.523 (Schott)"),
    (r"detector\.pattern_seed", "assumed", "the fixed pattern's seed: a choice"),
    (r"platform\.(alpha0_deg|beta0_deg)", "identified",
     "so that the optimised model fitted on I returns the paper's alpha0 = 1.864, beta0 = 0.415 "
     "deg (sec. 4.1)"),
    (r"platform\.gamma0_deg", "assumed",
     "boresight rotation: no published number pins it; its ablation scores slightly better "
     "without it (docs/identification.md)"),
    (r"platform\.alpha_pose_error_deg", "identified",
     "alpha_total (Table 4 polynomial alpha mu) times alpha_platform_share (" + _NUISANCE
     + "); " + _ID),
    (r"platform\.beta_pose_error_deg", "identified", "Table 4 polynomial beta sigma; " + _ID),
    (r"platform\.beta_rehoming_deg", "identified", "Table 4 polynomial beta mu; " + _ID),
    (r"platform\.(alpha|beta)_jitter_deg", "identified",
     "Table 4 polynomial M - mu of its angle; " + _ID),
    (r"platform\.beta_gear_deg", "assumed",
     "0, no gear error: not identified (studies/results/sensitivity.csv): a choice"),
    (r"platform\.beta_gear_(period|phase)_deg", "assumed",
     "inert while the gear amplitude is 0: a choice"),
    (r"platform\.(nonorthogonality_deg|beta_wobble_deg|alpha_offset_deg|beta_offset_deg"
     r"|alpha_scale|beta_scale|beta_backlash_deg|beta_homing_deg|beta_drift_deg)", "assumed",
     "0: off, no source gives it (studies/protocol.json common)"),
    (r"platform\.beta_wobble_(period|phase)_deg", "assumed", "inert while the wobble is 0"),
)


def _numeric(value) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def _walk(obj, prefix: str = ""):
    """(dotted path, value) of every numeric leaf of a dataclass (tuples' items numbered)."""
    if dataclasses.is_dataclass(obj):
        for f in dataclasses.fields(obj):
            yield from _walk(getattr(obj, f.name), f"{prefix}{f.name}.")
    elif isinstance(obj, tuple | list):
        for i, item in enumerate(obj):
            yield from _walk(item, f"{prefix}{i}.")
    elif _numeric(obj):
        yield prefix.rstrip("."), obj


def _source(bench: str, path: str, value) -> tuple[str, str]:
    if bench == "paper_multi_hole" and path == "mask.delta_f_mm":
        return "assumed", "the 100-hole mask's height error: no source recorded (a choice)"
    if re.fullmatch(r"mask\.play_[xy]_mm", path) and value == 0:
        return "assumed", ("0: this mask's play is along the other axis (studies/protocol.json "
                           "common.mask_play_axes)")
    for pattern, source, reference in SOURCES:
        if re.fullmatch(pattern, path):
            return source, reference
    return "assumed", "no source recorded"


def preset_sources() -> pd.DataFrame:
    """Every numeric field of both presets with its source.

    Returns
    -------
    pandas.DataFrame
        Columns ``bench``, ``parameter``, ``value``, ``source``, ``reference``.
    """
    from sunlab.sim import Bench

    rows = []
    for bench in ("paper_single_hole", "paper_multi_hole"):
        for path, value in _walk(getattr(Bench, bench)()):
            rows.append({"bench": bench, "parameter": path, "value": value,
                         **dict(zip(("source", "reference"), _source(bench, path, value),
                                  strict=True))})
    return pd.DataFrame(rows)


def build_parser() -> argparse.ArgumentParser:
    """The arguments of ``python -m studies.preset_sources``."""
    p = argparse.ArgumentParser(prog="python -m studies.preset_sources")
    p.add_argument("--out", default=str(_FILE), metavar="CSV")
    return p


def main(argv=None) -> int:
    """Write ``sunlab/data/preset_sources.csv`` (or ``--out``) and print the count by source.

    Returns
    -------
    int
        0.
    """
    args = build_parser().parse_args(argv)
    t = preset_sources()
    t.to_csv(args.out, index=False)
    print(t.groupby(["bench", "source"]).size().to_string())
    print(f"written to {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
