"""``sunlab identify``: the identification of the bench under its fixed protocol."""

from __future__ import annotations

import sys


def _add_identify(sub) -> None:
    p = sub.add_parser(
        "identify", help="regenerate the bench's identification under its fixed protocol",
        description="Runs every hypothesis of sunlab/data/protocol.json on its confirmation "
        "seeds (docs/identification.md): draws the nuisances, fits Table 4's pinning cells "
        "(a gear hypothesis's period on the protocol's grid), predicts every published cell "
        "on the centroid-level surrogate, scores the held-out ones and writes "
        "evidence_cells.csv, evidence.csv and intervals.csv into --out, then the chosen "
        "hypothesis's presets.json (one fit at the prior medians), profiles.csv (each fitted "
        "parameter's profile likelihood) and ablation.csv; prints the evidence and the "
        "hypothesis the protocol's rule picks.")
    p.add_argument("--out", required=True, metavar="DIR",
                   help="folder of the three tables (sunlab/data to refresh the shipped ones)")
    p.add_argument("--hypotheses", nargs="+", default=None, metavar="NAME",
                   help="hypotheses of the protocol (default: all)")
    p.add_argument("--seeds", nargs="+", type=int, default=None, metavar="SEED",
                   help="seeds (default: the protocol's confirmation seeds)")
    p.add_argument("--jobs", type=int, default=2, help="processes (default 2)")
    p.add_argument("--overwrite", action="store_true", help="replace tables written before")
    p.add_argument("--no-presets", dest="presets", action="store_false",
                   help="only the evidence and the intervals (no presets, profiles, ablation)")
    p.set_defaults(func=_run_identify)


def _run_identify(args) -> int:
    import numpy as np
    import pandas as pd

    from ..errors import ConfigurationError
    from ..studies import evidence
    from ..studies import identification as idn

    protocol = idn.load_protocol()
    unknown = sorted(set(args.hypotheses or ()) - set(protocol["hypotheses"]))
    if unknown:
        raise ConfigurationError(f"--hypotheses: {unknown} not in the protocol; expected some of "
                                 f"{sorted(protocol['hypotheses'])}.")
    if args.jobs < 1:
        raise ConfigurationError(f"--jobs: found {args.jobs}; expected 1 or more.")
    quiet = not sys.stderr.isatty()
    res = evidence.regenerate(args.out, names=args.hypotheses, seeds=args.seeds, jobs=args.jobs,
                         overwrite=args.overwrite, presets=args.presets,
                         progress=None if quiet else (lambda m: print("  done " + m,
                                                                      file=sys.stderr)))
    ev = res["evidence"]
    g = ev.groupby("hypothesis")
    summary = pd.DataFrame({"parameters": g["parameters"].first(), "score": g["score"].mean(),
                            "se": g["score"].std(ddof=1) / np.sqrt(g["score"].count()),
                            "tau": g["tau"].first(),
                            "held_out_within_1.25": g["held_out_within_1.25"].mean()})
    print(summary.round(3).to_string())
    print(f"\nchosen by the protocol's rule: {res['chosen']}")
    return 0
