"""Reproduce the paper's tables on the virtual bench: one pipeline, one module per table.

* :mod:`sunlab.reproduce.pipeline`: what every table shares: the plans of Table 3 and the one
  meaning of *quick* (:data:`QUICK`: every 2nd angle along each grid axis, 2 shots per pose),
  simulating and centroiding every frame once, in one Dask pass with the table's ``method`` on
  the caller's ``address`` / ``scheduler`` / ``workers``, and returning the centroid tables
  (:func:`simulate_and_locate`, :func:`multi_hole_tables`), the usable frames and the counts
  of the removed ones, and the one JSON writer;
* :mod:`sunlab.reproduce.table4`: Table 4 (one hole, every calibration method),
  :func:`table4_statistics` a function of the centroid tables;
* :mod:`sunlab.reproduce.table5`: Table 5 (100 holes vs one hole) and Figs. 13-15,
  :func:`table5_statistics` a function of the centroid tables;
* :mod:`sunlab.reproduce.platform`: beyond the paper, the platform fault diagnosed and removed.

``sunlab reproduce --table 4|5|platform|all`` runs them (:mod:`sunlab.cli`).

Examples
--------
>>> from sunlab import reproduce
>>> reproduce.QUICK
{'step': 2, 'shots': 2}
>>> {k: len(p) for k, p in reproduce.experiment_plans(quick=True).items()}
{'I': 100, 'II': 49, 'III': 100}
"""

from .pipeline import (
    EXPERIMENTS,
    QUICK,
    SPOT_METHODS,
    centroid_status,
    experiment_plans,
    locate_runs,
    mounting_offset_px,
    multi_hole_tables,
    simulate_and_locate,
    simulate_experiments,
    simulate_runs,
    spot_method,
    usable_table,
    write_json,
)
from .platform import GEAR_ROW, ROWS, bench_fault_values, format_platform, reproduce_platform
from .table4 import (
    PAPER_OPTIMISED,
    Table4Result,
    bench_optimised_truth,
    format_table,
    reproduce_table4,
    table4_methods,
    table4_statistics,
)
from .table5 import COLUMNS, REJECTION_COLUMN, format_table5, reproduce_table5, table5_statistics

__all__ = [
    "EXPERIMENTS",
    "QUICK",
    "experiment_plans",
    "simulate_runs",
    "locate_runs",
    "simulate_and_locate",
    "simulate_experiments",
    "multi_hole_tables",
    "usable_table",
    "centroid_status",
    "write_json",
    "PAPER_OPTIMISED",
    "Table4Result",
    "bench_optimised_truth",
    "table4_methods",
    "reproduce_table4",
    "table4_statistics",
    "format_table",
    "COLUMNS",
    "REJECTION_COLUMN",
    "SPOT_METHODS",
    "spot_method",
    "mounting_offset_px",
    "reproduce_table5",
    "table5_statistics",
    "format_table5",
    "ROWS",
    "GEAR_ROW",
    "bench_fault_values",
    "reproduce_platform",
    "format_platform",
]
