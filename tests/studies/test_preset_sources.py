"""sunlab/data/preset_sources.csv: every numeric preset field, its value and its source."""

import dataclasses

import pandas as pd
import pytest

from studies import preset_sources as ps
from sunlab.sim import Bench

SHIPPED = pd.read_csv(ps._FILE)
SOURCES = {"paper", "datasheet", "physics", "identified", "assumed"}


def _get(obj, path: str):
    for part in path.split("."):
        obj = obj[int(part)] if part.isdigit() else getattr(obj, part)
    return obj


@pytest.mark.parametrize("bench", ["paper_single_hole", "paper_multi_hole"])
def test_every_numeric_field_is_listed_with_the_presets_value(bench):
    preset = getattr(Bench, bench)()
    rows = SHIPPED[SHIPPED["bench"] == bench].set_index("parameter")
    assert list(SHIPPED.columns) == ["bench", "parameter", "value", "source", "reference"]
    assert set(rows["source"]) <= SOURCES and rows.index.is_unique
    # the file is what the code generates now, and each value is the preset's own
    fresh = ps.preset_sources()
    assert list(fresh[fresh["bench"] == bench]["parameter"]) == list(rows.index)
    for path, r in rows.iterrows():
        assert _get(preset, path) == pytest.approx(r["value"], rel=1e-12, abs=0), path
    # every numeric leaf is covered: the detector, the platform, the source and the mask
    n_fields = sum(1 for f in dataclasses.fields(preset.detector)
                   if isinstance(getattr(preset.detector, f.name), int | float)
                   and not isinstance(getattr(preset.detector, f.name), bool))
    assert rows.index.str.startswith("detector.").sum() >= n_fields
    assert rows.index.str.match(r"mask\.holes\.\d+\.x_mm").sum() == len(preset.mask.holes)


def test_the_choices_are_labelled_assumed():
    single = SHIPPED[SHIPPED["bench"] == "paper_single_hole"].set_index("parameter")
    for path in ("mask.distance_mm", "platform.beta_gear_deg", "detector.gain_e_per_dn",
                 "detector.full_well_e", "platform.gamma0_deg", "detector.prnu"):
        assert single.loc[path, "source"] == "assumed", path
    assert single.loc["detector.read_noise_e", "source"] == "datasheet"
    assert single.loc["platform.beta_pose_error_deg", "source"] == "identified"
