"""Figures of push-model studies.

Metrics against the number of experts, effect clusters, and the experts' ARD relevances.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from typing import Any

import numpy as np
from matplotlib.figure import Figure

from probaff._io import atomic_save_figure

__all__ = [
    "plot_effect_clusters",
    "plot_metric_vs_experts",
    "plot_predictive_density",
    "plot_relevances",
]

_STYLES = {"em": "-", "em-hard": "-.", "vi": "--", "clustered": ":"}


def plot_metric_vs_experts(
    rows: Sequence[dict[str, Any]],
    effects: Sequence[str],
    metric: str,
    path: str | os.PathLike[str],
    title: str = "",
) -> None:
    """One panel per effect dimension: `metric` against M, a line per (features, method).

    Args:
        rows: Summary rows with keys ``features``, ``method``, ``M`` and ``{metric}.{effect}``.
        effects: Effect dimension names.
        metric: ``"rmse"``, ``"nlpd"`` or ``"coverage90"``.
        path: PNG file to write.
        title: Figure title.
    """
    cols = min(3, len(effects))
    nrows = -(-len(effects) // cols)
    fig = Figure(figsize=(4.2 * cols, 3.2 * nrows))
    axes = np.atleast_1d(fig.subplots(nrows, cols, squeeze=False)).ravel()
    series = sorted({(r["features"], r["method"]) for r in rows})
    colours = {f: f"C{i}" for i, f in enumerate(sorted({s[0] for s in series}))}
    for ax, effect in zip(axes, effects, strict=False):
        for feat, method in series:
            pts = sorted(
                (r["M"], r[f"{metric}.{effect}"])
                for r in rows
                if (r["features"], r["method"]) == (feat, method)
            )
            ax.plot(
                [p[0] for p in pts],
                [p[1] for p in pts],
                _STYLES.get(method, "-"),
                marker="o",
                ms=3,
                color=colours[feat],
                label=f"{feat} / {method}",
            )
        if metric == "coverage90":
            ax.axhline(0.9, color="0.5", lw=0.8)
        ax.set_title(effect, fontsize=9)
        ax.set_xlabel("experts M", fontsize=8)
        ax.tick_params(labelsize=7)
    for ax in axes[len(effects) :]:
        ax.axis("off")
    axes[0].legend(fontsize=6)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    atomic_save_figure(fig, path, dpi=120)


def plot_effect_clusters(
    points: np.ndarray,
    labels: np.ndarray,
    axis_names: tuple[str, str],
    path: str | os.PathLike[str],
    title: str = "",
) -> None:
    """Effects of the pushes coloured by their expert or cluster (thesis Figs. 4.5, 5.4).

    Args:
        points: (N, 2) two effect dimensions.
        labels: (N,) expert or cluster of each push.
        axis_names: Axis labels.
        path: PNG file to write.
        title: Figure title.
    """
    fig = Figure(figsize=(5, 4.2))
    ax = fig.subplots()
    for k in np.unique(labels):
        sel = labels == k
        ax.scatter(
            points[sel, 0], points[sel, 1], s=10, alpha=0.75, label=f"expert {k} ({sel.sum()})"
        )
    ax.set_xlabel(axis_names[0])
    ax.set_ylabel(axis_names[1])
    ax.legend(fontsize=7)
    ax.set_title(title, fontsize=10)
    fig.tight_layout()
    atomic_save_figure(fig, path, dpi=120)


def plot_relevances(
    lengthscales: Sequence[Sequence[Sequence[float]]],
    columns: Sequence[int],
    groups: dict[str, slice],
    path: str | os.PathLike[str],
) -> None:
    """ARD relevance (1 / length scale, averaged over outputs) of each expert's features.

    Args:
        lengthscales: Per expert, (E, D_e) length scales in standardised units.
        columns: (D_e,) feature-matrix column of each expert input.
        groups: Feature group name -> column slice, for shading the groups.
        path: PNG file to write.
    """
    M = len(lengthscales)
    fig = Figure(figsize=(9, 1.8 * M + 0.6))
    axes = np.atleast_1d(fig.subplots(M, 1, squeeze=False)).ravel()
    cols = np.asarray(columns)
    for j, (ax, ls) in enumerate(zip(axes, lengthscales, strict=True)):
        rel = (1.0 / np.asarray(ls)).mean(0)
        ax.bar(np.arange(len(cols)), rel, color="tab:blue", width=0.9)
        for g, (name, sl) in enumerate(groups.items()):
            inside = np.flatnonzero((cols >= sl.start) & (cols < sl.stop))
            if inside.size:
                ax.axvspan(inside[0] - 0.5, inside[-1] + 0.5, color=f"C{g + 1}", alpha=0.12)
                share = rel[inside].sum() / max(rel.sum(), 1e-12)
                ax.text(
                    inside.mean(),
                    ax.get_ylim()[1] * 0.9 if rel.size else 0,
                    f"{name} {100 * share:.0f}%",
                    ha="center",
                    fontsize=7,
                )
        ax.set_ylabel(f"expert {j}", fontsize=8)
        ax.tick_params(labelsize=7)
    axes[-1].set_xlabel("feature (expert input index)", fontsize=8)
    fig.suptitle("ARD relevance 1/length scale, mean over effect dimensions", fontsize=10)
    fig.tight_layout()
    atomic_save_figure(fig, path, dpi=120)


def plot_predictive_density(
    grid: np.ndarray,
    densities: dict[str, np.ndarray],
    observed: float,
    path: str | os.PathLike[str],
    *,
    xlabel: str,
    title: str = "",
) -> None:
    """Predictive densities of one effect dimension of one push, with the observed value.

    Args:
        grid: Effect values, `(G,)`.
        densities: Model name to its density on `grid`, each `(G,)`.
        observed: The effect that was observed.
        path: PNG file to write.
        xlabel: Axis label (with units).
        title: Figure title.
    """
    fig = Figure(figsize=(5.5, 3.4))
    ax = fig.subplots()
    for i, (name, dens) in enumerate(densities.items()):
        ax.plot(grid, dens, color=f"C{i}", lw=1.8, label=name)
        ax.fill_between(grid, dens, color=f"C{i}", alpha=0.12)
    ax.axvline(observed, color="k", ls="--", lw=1.2, label="observed")
    ax.set_xlabel(xlabel)
    ax.set_ylabel("predictive density")
    ax.legend(frameon=False, fontsize=8)
    if title:
        ax.set_title(title, fontsize=10)
    fig.tight_layout()
    atomic_save_figure(fig, path)
