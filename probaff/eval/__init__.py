"""Evaluation: metrics, model selection, the resumable task runner, fingerprints and tables.

Modules:
    metrics: RMSE, NLPD, interval coverage, Wilson and Student-t intervals.
    selection: choosing the number of experts by cross-validation.
    tasks: `run_tasks`, independent tasks on Dask whose results are saved as they land.
    fingerprint: short hashes of the settings that shape a stored result.
    tables: CSV and Markdown tables, written atomically.
    plots: checks of figure inputs and the atomic save shared by the studies' figures.

The studies built on them live in `probaff.experiments`.
"""

from probaff.eval.fingerprint import config_fingerprint
from probaff.eval.metrics import (
    corrected_halfwidth,
    interval_coverage,
    marginal_components,
    mean_and_halfwidth,
    mean_halfwidth,
    nlpd,
    rmse,
    wilson_interval,
)
from probaff.eval.selection import ExpertSelection, select_n_experts
from probaff.eval.tables import csv_table, markdown_table, write_csv
from probaff.eval.tasks import ResultStore, run_tasks

__all__ = [
    "ExpertSelection",
    "ResultStore",
    "config_fingerprint",
    "corrected_halfwidth",
    "csv_table",
    "interval_coverage",
    "marginal_components",
    "markdown_table",
    "mean_and_halfwidth",
    "mean_halfwidth",
    "nlpd",
    "rmse",
    "run_tasks",
    "select_n_experts",
    "wilson_interval",
    "write_csv",
]
