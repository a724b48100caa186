"""Studies over the paper's tables with the virtual bench: research, not part of the library.

Run from the repository's root as ``python -m studies.NAME`` (the folder is not installed with
``sunlab``; the library never imports it). They write the data files the library reads:

* :mod:`.identification` (which bench explains the tables, under the fixed protocol of
  ``studies/protocol.json``), with :mod:`.evidence` (its runs, scored and written),
  :mod:`.profiles` (the presets and each fitted parameter's profile likelihood) and
  :mod:`.ablation` (each component of the identified bench turned off); ``python -m
  studies.identify --out DIR`` (:mod:`.identify`) regenerates them: the evidence tables belong
  in ``studies/results/``, ``presets.json`` and ``intervals.csv`` in ``sunlab/data/``;
* :mod:`.sensitivity` (the verdicts' sensitivity, ``studies/results/sensitivity.csv``) and
  :mod:`.preset_sources` (each preset's source, ``sunlab/data/preset_sources.csv``);
* :mod:`.averaging` (why averaging per-hole calibrations loses to the geometric centre);
* :mod:`.surrogate_tables` (the paper's tables on the centroid-level surrogate).
"""
