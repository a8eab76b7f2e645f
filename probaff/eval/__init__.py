"""Evaluation: metrics, resumable batch tasks, tables and figures."""

from probaff.eval.metrics import (
    interval_coverage,
    marginal_components,
    mean_halfwidth,
    nlpd,
    rmse,
    wilson_interval,
)
from probaff.eval.push_figures import plot_pushes
from probaff.eval.selection import ExpertSelection, select_n_experts
from probaff.eval.tasks import ResultStore, run_tasks

__all__ = [
    "ExpertSelection",
    "ResultStore",
    "interval_coverage",
    "marginal_components",
    "mean_halfwidth",
    "nlpd",
    "plot_pushes",
    "rmse",
    "run_tasks",
    "select_n_experts",
    "wilson_interval",
]
