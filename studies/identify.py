"""``python -m studies.identify --out DIR``: the identification of the bench under its protocol.

Runs every hypothesis of ``studies/protocol.json`` on its confirmation seeds
(docs/identification.md): draws the nuisances, fits Table 4's pinning cells (a gear hypothesis's
period on the protocol's grid), predicts every published cell on the centroid-level surrogate,
scores the held-out ones and writes ``evidence_cells.csv``, ``evidence.csv`` and
``intervals.csv`` into ``--out``, then the chosen hypothesis's ``presets.json`` (one fit at the
prior medians), ``profiles.csv`` (each fitted parameter's profile likelihood) and
``ablation.csv``; prints its estimate first, the evidence and the hypothesis the protocol's rule
picks last. Each (hypothesis, seed) run is kept in ``DIR/runs/`` as it ends: started again, a
stopped run resumes (the folder goes once the tables are written). The shipped
files: ``presets.json`` and ``intervals.csv`` in ``sunlab/data/`` (the library reads them), the
others in ``studies/results/``.
"""

from __future__ import annotations

import argparse
import shlex
import sys


def build_parser() -> argparse.ArgumentParser:
    """The command's arguments.

    Returns
    -------
    argparse.ArgumentParser

    Examples
    --------
    >>> build_parser().parse_args(["--out", "ev"]).jobs
    2
    """
    p = argparse.ArgumentParser(prog="python -m studies.identify",
                                description=__doc__.split("\n\n")[1].replace("\n", " "))
    p.add_argument("--out", required=True, metavar="DIR", help="folder of the tables")
    p.add_argument("--hypotheses", nargs="+", default=None, metavar="NAME",
                   help="hypotheses of the protocol (default: all)")
    p.add_argument("--seeds", nargs="+", type=int, default=None, metavar="SEED",
                   help="seeds (default: the protocol's confirmation seeds)")
    p.add_argument("--jobs", type=int, default=2, help="processes (default 2)")
    p.add_argument("--overwrite", action="store_true", help="replace tables written before")
    p.add_argument("--no-presets", dest="presets", action="store_false",
                   help="only the evidence and the intervals (no presets, profiles, ablation)")
    return p


def main(argv=None) -> int:
    """Run the identification with the command line's arguments; print its evidence.

    Parameters
    ----------
    argv : list of str, optional
        The arguments (default ``sys.argv[1:]``).

    Returns
    -------
    int
        0 on success, 1 on a refused argument or file (said in one line on stderr).
    """
    import numpy as np
    import pandas as pd

    from sunlab.errors import ConfigurationError, SunlabError

    from . import evidence
    from . import identification as idn

    args = build_parser().parse_args(argv)
    try:
        protocol = idn.load_protocol()
        unknown = sorted(set(args.hypotheses or ()) - set(protocol["hypotheses"]))
        if unknown:
            raise ConfigurationError(f"--hypotheses: {unknown} not in the protocol; expected "
                                     f"some of {sorted(protocol['hypotheses'])}.")
        if args.jobs < 1:
            raise ConfigurationError(f"--jobs: found {args.jobs}; expected 1 or more.")
        tty = sys.stderr.isatty()  # the estimate always, the progress in a terminal only

        def progress(line, always=False):
            if always or tty:
                print(line, file=sys.stderr, flush=True)

        res = evidence.regenerate(args.out, names=args.hypotheses, seeds=args.seeds,
                                  jobs=args.jobs, overwrite=args.overwrite,
                                  presets=args.presets, progress=progress,
                                  command=shlex.join(["python", "-m", "studies.identify",
                                                      *(sys.argv[1:] if argv is None else argv)]))
    except (SunlabError, OSError) as err:
        print(f"python -m studies.identify: error: {err}", file=sys.stderr)
        return 1
    g = res["evidence"].groupby("hypothesis")
    summary = pd.DataFrame({"parameters": g["parameters"].first(), "score": g["score"].mean(),
                            "se": g["score"].std(ddof=1) / np.sqrt(g["score"].count()),
                            "tau": g["tau"].first(),
                            "held_out_within_1.25": g["held_out_within_1.25"].mean()})
    print(summary.round(3).to_string())
    print(f"\nchosen by the protocol's rule: {res['chosen']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
