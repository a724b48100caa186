"""Each ablation of the identified bench turns its component off and nothing else."""

import pytest

from studies import ablation
from studies import identification as idn


@pytest.mark.parametrize("component", sorted(ablation.ABLATIONS))
def test_each_ablation_turns_off_its_component_only(component):
    protocol = idn.load_protocol()
    fitted = {"alpha_total_deg": 0.017, "beta_zero_shift_deg": 0.02,
              "beta_pose_error_deg": 0.003, "beta_gear_deg": 0.01, "gear_period_deg": 1.26,
              "alpha_jitter_deg": 0.0007, "beta_jitter_deg": 0.0006}
    nuis = idn.draw_nuisances(protocol, None)
    benches = [idn.hypothesis_bench(protocol, "F5-gear", nuis, fitted, multi=m)
               for m in (False, True)]
    change = ablation.ABLATIONS[component]
    if change == "drift":
        assert all(b.platform.beta_rehoming_deg > 0 for b in benches)
        return
    for key, value in change.items():
        part, field = key.split("__")
        # on in the one-hole or the 100-hole bench (the ablation applies to both)
        assert any(getattr(getattr(b, part), field) != value for b in benches), key
    for bench in benches:
        off = bench.replace(**change)
        for key, value in change.items():
            part, field = key.split("__")
            assert getattr(getattr(off, part), field) == value
        # nothing else moved
        for part in ("detector", "platform", "mask"):
            changed = {k.split("__")[1] for k in change if k.startswith(part + "__")}
            before, after = vars(getattr(bench, part)), vars(getattr(off, part))
            assert {k for k in before if before[k] != after[k]} <= changed, part
