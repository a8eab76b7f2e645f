"""Figures of the push-model study: pushes, metrics against M, clusters, relevances, densities.

`plot_pushes` draws pushes of a dataset (object footprints before and after, the gripper's
path); the others draw the study's results: a metric against the number of experts, effect
clusters, the experts' ARD relevances and predictive densities. `study_figures` draws every
figure of a study run.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.figure import Figure
from matplotlib.patches import Circle, Polygon, Rectangle

from probaff._io import atomic_save_figure
from probaff.data.schema import PushDataset
from probaff.experiments.push_models.config import CH4_EFFECTS, CH5_EFFECTS, PushModelStudyConfig
from probaff.sim import load_catalogue
from probaff.sim.geometry import footprint_polygon

__all__ = [
    "plot_effect_clusters",
    "plot_metric_vs_experts",
    "plot_predictive_density",
    "plot_pushes",
    "plot_relevances",
    "study_figures",
]

_COLOURS = ("tab:blue", "tab:orange", "tab:green", "tab:purple")


def _footprint_patch(name: str, pose: np.ndarray, **kw: object) -> Polygon | Circle:
    obj = load_catalogue()[name]
    poly = footprint_polygon(obj)
    if poly is None:
        return Circle((pose[0], pose[1]), obj.radius, **kw)
    c, s = math.cos(pose[2]), math.sin(pose[2])
    R = np.array([[c, -s], [s, c]])
    return Polygon(poly @ R.T + pose[:2], closed=True, **kw)


def plot_pushes(
    ds: PushDataset,
    indices: Sequence[int],
    path: str | os.PathLike[str],
    reachable: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
) -> None:
    """Draw a grid of pushes, one panel each, and save it as an image.

    Each panel shows the table (world frame, metres), every object before (dashed outline) and
    after (filled), the gripper's recorded path (or the commanded segment without
    trajectories), and the push's effect on o1 in the pushing frame.

    Args:
        ds: A push dataset.
        indices: Pushes to draw.
        path: Image file to write (PNG by suffix), atomically.
        reachable: Optional ``(mask (H, W), xs (W,), ys (H,))`` from `Arm.reachable_mask`,
            shaded in the background.
    """
    n = len(indices)
    cols = min(3, n)
    rows = math.ceil(n / cols)
    fig = Figure(figsize=(4.2 * cols, 3.6 * rows))
    axes = fig.subplots(rows, cols, squeeze=False)
    tw, th = ds.meta.get("table_size", (1.0, 0.8))
    for ax, i in zip(axes.ravel(), indices, strict=False):
        ax.add_patch(Rectangle((-tw / 2, -th / 2), tw, th, fc="0.94", ec="0.4", lw=1))
        if reachable is not None:
            mask, xs, ys = reachable
            ax.contourf(
                xs, ys, mask.astype(float), levels=[0.5, 1.5], colors=["#d9f0d3"], alpha=0.6
            )
        names = ds.objects_of(i)
        for k, name in enumerate(names):
            col = _COLOURS[k % len(_COLOURS)]
            ax.add_patch(
                _footprint_patch(
                    name, ds["state_before"][i, k], fill=False, ec=col, ls="--", lw=1.2
                )
            )
            ax.add_patch(
                _footprint_patch(
                    name,
                    ds["state_after"][i, k],
                    fc=col,
                    alpha=0.45,
                    ec=col,
                    lw=1.2,
                    label=f"o{k + 1} {name}",
                )
            )
        for x0, y0, x1, y1 in ds["walls"][i]:
            ax.plot([x0, x1], [y0, y1], color="k", lw=3)
        if ds.has_trajectories:
            hand = ds["traj_hand"][i]
            ax.plot(hand[:, 0], hand[:, 1], color="crimson", lw=1.5, label="gripper path")
        else:
            o, yaw, d = ds["push_origin"][i], ds["push_yaw"][i], ds["push_distance"][i]
            ax.plot(
                [o[0], o[0] + d * math.cos(yaw)],
                [o[1], o[1] + d * math.sin(yaw)],
                color="crimson",
                lw=1.5,
                label="gripper path",
            )
        o = ds["push_origin"][i]
        ax.plot(o[0], o[1], "o", color="crimson", ms=4)
        e = ds["effect"][i, 0]
        ax.set_title(
            f"push {i}: o1 dy={100 * e[0]:.1f} cm dz={100 * e[1]:.1f} cm "
            f"dth={math.degrees(e[2]):.0f} deg",
            fontsize=8,
        )
        ax.set_xlim(-tw / 2 - 0.05, tw / 2 + 0.05)
        ax.set_ylim(-th / 2 - 0.05, th / 2 + 0.05)
        ax.set_aspect("equal")
        ax.tick_params(labelsize=7)
        ax.legend(fontsize=6, loc="upper left")
    for ax in axes.ravel()[n:]:
        ax.axis("off")
    fig.suptitle(f"{ds.meta.get('scene', '')}: before (dashed) and after (filled)", fontsize=10)
    fig.tight_layout()
    atomic_save_figure(fig, path, dpi=120)


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


def _clusters(
    results: Sequence[dict[str, Any]],
    features: Sequence[str],
    experts: Sequence[int],
    method: str,
    Y: np.ndarray,
    effects: tuple[tuple[int, int], tuple[str, str]],
    path: Path,
    title: str,
) -> dict[str, Any] | None:
    """Draw the training effects of one fold-0 fit by assignment; that fit's result row.

    The fit is of `method` with min(3, max `experts`) experts on ``"ocx"`` if it ran, else
    on the last of `features`; `effects` is the two columns of `Y` drawn and their labels;
    `title` is formatted with the fit's ``M``. None (and no figure) if there is no such row.
    """
    shown = "ocx" if "ocx" in features else features[-1]
    m = min(3, max(experts))
    key = (shown, method, 0, m)
    row = next((r for r in results if (r["features"], r["method"], r["fold"], r["M"]) == key), None)
    if row is not None:
        idx = np.asarray(row["train_index"])
        columns, labels = effects
        assignment = np.asarray(row["train_assignment"])
        plot_effect_clusters(
            Y[idx][:, list(columns)], assignment, labels, path, title=title.format(M=m)
        )
    return row


def study_figures(
    config: PushModelStudyConfig,
    summary: dict[str, Any],
    results: Sequence[dict[str, Any]],
    data: dict[str, tuple[Any, np.ndarray]],
    out: Path,
) -> list[str]:
    """Every figure of a study run, chapter 5's then chapter 4's (if it ran).

    Chapter 5: RMSE and 90 % coverage against M, and EM's assignments and ARD relevances of
    fold 0 at min(3, max M); chapter 4: RMSE against m and the clustered model's clusters.
    The clusters and relevances are drawn for ``"ocx"`` if it ran, else the last features.

    Args:
        config: The study's settings.
        summary: The summary rows by experiment (``"ch5"``, ``"ch4"``).
        results: The per-fold rows of both experiments.
        data: Experiment -> (its feature set, its effects `(N, E)`).
        out: Output folder.

    Returns:
        The written paths.
    """
    ch5 = [r for r in results if r["experiment"] == "ch5"]
    features5, Y5 = data["ch5"]
    files = []
    for metric, name, title in (
        ("rmse", "ch5_rmse_vs_M.png", "Chapter 5: RMSE vs number of experts (m, rad)"),
        ("coverage90", "ch5_coverage_vs_M.png", "Chapter 5: 90% interval coverage"),
    ):
        plot_metric_vs_experts(summary["ch5"], CH5_EFFECTS, metric, out / name, title=title)
        files.append(str(out / name))
    shown = config.ch5_features, config.ch5_experts
    effects = ((1, 4), ("o1 dz_p (m)", "o2 dz_p (m)"))
    title = "Chapter 5: EM assignments, M={M}"
    example = _clusters(ch5, *shown, "em", Y5, effects, out / "ch5_clusters.png", title)
    if example is not None:
        relevance = out / "ch5_ard_relevance.png"
        columns = example["expert_columns"]
        plot_relevances(example["lengthscales"], columns, features5.groups, relevance)
        files += [str(out / "ch5_clusters.png"), str(relevance)]
    if "ch4" in data:
        ch4 = [r for r in results if r["experiment"] == "ch4"]
        title = "Chapter 4: RMSE vs number of clusters (m, rad)"
        path = out / "ch4_rmse_vs_m.png"
        plot_metric_vs_experts(summary["ch4"], CH4_EFFECTS, "rmse", path, title=title)
        files.append(str(path))
        shown, effects = (
            (config.ch4_features, config.ch4_experts),
            ((0, 1), ("dy_p (m)", "dz_p (m)")),
        )
        path, title = out / "ch4_clusters.png", "Chapter 4: GMM clusters of the effects, m={M}"
        if _clusters(ch4, *shown, "clustered", data["ch4"][1], effects, path, title) is not None:
            files.append(str(path))
    return files
