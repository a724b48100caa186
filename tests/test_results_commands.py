"""Each shipped results file names the command that wrote it (studies/results/manifest.json, and
a JSON file's own ``command`` key): the command parses with the parser it runs with, and the
settings it implies are those the manifest records and the file shows."""

import glob
import importlib
import json
import re
import shlex
from pathlib import Path

import pandas as pd
import pytest
from PIL import Image

ROOT = Path(__file__).resolve().parents[1]
ENTRIES = json.loads((ROOT / "studies" / "results" / "manifest.json").read_text("utf-8"))["files"]


def _size(png) -> list:
    with Image.open(png) as im:
        return list(im.size)


def _script(path: str):
    spec = importlib.util.spec_from_file_location(Path(path).stem, ROOT / path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _implied(command: str, tmp_path) -> dict:
    """The settings a command implies: parsed by its own parser, the defaults resolved."""
    from studies.identification import load_protocol

    protocol = load_protocol()
    words = shlex.split(command)
    if words[0] == "sunlab":
        from sunlab.cli import build_parser
        from sunlab.reproduce.learned import BENCHES, DEFAULT_BENCHES

        args = build_parser().parse_args(words[1:])
        assert args.command == "reproduce" and args.table == "learned", command
        every = args.full or args.benches == ["all"]
        return {"benches": sorted(BENCHES if every else args.benches or DEFAULT_BENCHES),
                "out": args.out}
    assert words[0] == "python", command
    if words[1] != "-m":  # a script without arguments
        assert len(words) == 2, command
        module = _script(words[1])
        if words[1] == "docs/make_readme_figure.py":
            return {"size_px": _size(module.main(tmp_path / "f.png"))}
        return {"seed": module.SEED, "shots": 2,
                **{f"poses_{k}": len(p) for k, p in module._plans().items()}}
    module = importlib.import_module(words[2])
    args = module.build_parser().parse_args(words[3:])
    if words[2] == "studies.identify":
        return {"hypotheses": sorted(args.hypotheses or protocol["hypotheses"]),
                "seeds": sorted(args.seeds or protocol["confirmation_seeds"]),
                "seed": protocol["presets"]["seed"],
                "factors": sorted([*protocol["profiles"]["factors"], 1.0]),
                "ablation_seeds": protocol["confirmation_seeds"][:2]}
    if words[2] == "studies.sensitivity":
        return {"rows": list(protocol["sensitivity"]["rows"])}
    return {"benches": sorted(set(module.preset_sources()["bench"]))}  # studies.preset_sources


def _shown(path: Path) -> dict:
    """The settings a file shows."""
    if path.match("learned/*") or path.match("learned/*/*"):
        folder = path.parent if path.parent.name == "learned" else path.parent.parent
        if path.parent.name in ("models", "benches"):  # one file per bench
            benches = [p.stem for p in path.parent.glob("*.json")]
        elif path.suffix == ".json":
            doc = json.loads(path.read_text("utf-8"))
            benches = list(doc.get("settings", doc)["benches"])
        else:
            benches = None
        return {"benches": sorted(benches) if benches else None,
                "out": folder.relative_to(ROOT).as_posix()}
    if path.parent.parent.name == "example":
        sensor = json.loads((path.parent / "sensor.json").read_text("utf-8"))
        poses = pd.read_csv(path.parent / "manifest.csv").groupby(["alpha", "beta"]).size()
        return {"seed": int(re.search(r"\(seed (\d+)\)", sensor["comment"]).group(1)),
                f"poses_{path.parent.name}": len(poses), "shots": int(poses.max())}
    if path.suffix == ".png":
        return {"size_px": _size(path)}
    if path.suffix == ".json":
        return {"seed": json.loads(path.read_text("utf-8")).get("seed")}
    t = pd.read_csv(path)
    col = {c: sorted(set(t[c])) for c in ("hypothesis", "seed", "bench") if c in t}
    out = {"hypotheses": col.get("hypothesis"), "benches": col.get("bench"),
           "rows": list(t["row"]) if "row" in t else None}
    out["ablation_seeds" if "component" in t else "seeds"] = col.get("seed")
    if "factor" in t:
        out["factors"] = sorted(set(t.loc[t["parameter"] != "gear_period_deg", "factor"]))
    return out


@pytest.mark.parametrize("pattern", sorted(ENTRIES))
def test_each_shipped_result_names_its_command_and_its_settings(pattern, tmp_path):
    entry = ENTRIES[pattern]
    paths = [Path(p) for p in sorted(glob.glob(str(ROOT / pattern)))]
    assert paths, f"{pattern}: no such file"
    if entry["command"] is None:  # a record written by hand, and said so
        assert "by hand" in entry["note"]
        return
    implied = _implied(entry["command"], tmp_path)
    assert entry["settings"], pattern
    for path in paths:
        if path.suffix == ".json" and path.parent.name not in ("models", "benches", "train",
                                                               "test"):
            # a JSON file the command writes names it inside (models and resume records: no)
            assert json.loads(path.read_text("utf-8"))["command"] == entry["command"], path
        shown = _shown(path)
        for key, value in entry["settings"].items():
            assert shown[key] == value, (path, key, shown[key])
            assert implied[key] == value, (path, key, implied[key])


def test_every_shipped_result_is_in_the_manifest():
    listed = {Path(p).resolve() for pattern in ENTRIES for p in glob.glob(str(ROOT / pattern))}
    shipped = [*ROOT.glob("studies/results/*.csv"), *ROOT.glob("sunlab/data/*.csv"),
               *ROOT.glob("sunlab/data/*.json"), *ROOT.glob("sunlab/data/example/*/*"),
               *ROOT.glob("docs/learned/**/*.json"), *ROOT.glob("docs/**/*.png")]
    assert sorted(p for p in shipped if p.resolve() not in listed) == []
