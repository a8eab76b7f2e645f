"""Evaluation: metrics, tables and figures."""

from probaff.eval.push_figures import plot_pushes

__all__ = ["plot_pushes"]
