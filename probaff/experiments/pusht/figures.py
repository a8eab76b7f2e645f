"""Figures of the Push-T study: episodes over the goal, success and model scores against data.

`plot_episodes` draws the T's outline after every push of a few episodes of each planner
against the goal; `plot_frames` the 96 x 96 images a pixel planner planned on, with the pose
it perceived and the state's; `plot_success_curve` the learned-model planner's success (95 % Wilson
intervals) against the number of training pushes, with the diffusion policy's rate;
`plot_models` the held-out RMSE and NLPD of each model against the number of training pushes.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.figure import Figure
from matplotlib.patches import Polygon

from probaff._io import atomic_save_figure
from probaff.experiments.pusht.geometry import (
    GOAL_ORIGIN_POSE,
    OUTLINE,
    TeeGeometry,
    cog_pose,
    to_world,
)
from probaff.experiments.pusht.pixels import WORLD_SIZE, world_to_pixel
from probaff.experiments.pusht.scoring import DIFFUSION_POLICY
from probaff.experiments.pusht.template import TeeShape

__all__ = ["plot_episodes", "plot_frames", "plot_models", "plot_success_curve"]


def _finish(fig: Figure, path: str | Path) -> str:
    """Lay out, save (atomically, 110 dpi) and close `fig`; return `path` as a string."""
    fig.tight_layout()
    atomic_save_figure(fig, path, dpi=110)
    plt.close(fig)
    return str(path)


def plot_episodes(records: Sequence[dict[str, Any]], path: str | Path, per_planner: int = 3) -> str:
    """Draw the T after every push of the first kept episodes of each planner.

    Args:
        records: Episode records; those with ``poses`` are drawn.
        path: The PNG to write.
        per_planner: Episodes drawn per planner.

    Returns:
        `path` as a string.
    """
    kept: dict[str, list[dict[str, Any]]] = {}
    for r in records:
        if "poses" in r and len(kept.setdefault(r["planner"], [])) < per_planner:
            kept[r["planner"]].append(r)
    planners = list(kept) or ["(none)"]
    cols = max([len(v) for v in kept.values()] + [1])
    fig, axes = plt.subplots(
        len(planners), cols, figsize=(2.6 * cols, 2.6 * len(planners)), squeeze=False
    )
    goal = to_world(cog_pose(GOAL_ORIGIN_POSE), OUTLINE)
    for i, planner in enumerate(planners):
        for j in range(cols):
            ax = axes[i][j]
            ax.set_xlim(0, 512)
            ax.set_ylim(0, 512)
            ax.set_aspect("equal")
            ax.set_xticks([])
            ax.set_yticks([])
            ax.add_patch(Polygon(goal, closed=True, color="lightgreen", alpha=0.7))
            if j >= len(kept.get(planner, [])):
                continue
            r = kept[planner][j]
            poses = np.asarray(r["poses"], dtype=float)
            shades = plt.get_cmap("Greys")(np.linspace(0.3, 1.0, len(poses)))
            for pose, shade in zip(poses, shades, strict=True):
                ax.add_patch(Polygon(to_world(pose, OUTLINE), closed=True, fill=False, ec=shade))
            verdict = "success" if r["success"] else "failure"
            ax.set_title(
                f"{planner} ep {r['episode']}: {verdict}\n{r['pushes']} pushes, cov "
                f"{r['max_coverage']:.2f}",
                fontsize=7,
            )
    fig.suptitle("Push-T episodes: the T after every push (dark: later) and the goal (green)")
    return _finish(fig, path)


def plot_frames(records: Sequence[dict[str, Any]], path: str | Path, episodes: int = 3) -> str:
    """Draw the images pixel episodes planned on, with the perceived and the true pose.

    Each row is one episode with ``frames`` (`probaff.experiments.pusht.planner.run_episode`
    with a trajectory, from pixels): its kept images, the T's outline at the pose perceived
    from that image (the perceived shape; orange) and at the state's pose (gym-pusht's shape,
    for scoring only; dashed black). The title gives the perceived pose's error.

    Args:
        records: Episode records; those with ``frames`` are drawn, the first `episodes`.
        path: The PNG to write.
        episodes: Episodes drawn (rows).

    Returns:
        `path` as a string.
    """
    kept = [r for r in records if r.get("frames")][:episodes]
    cols = max([len(r["frames"]) for r in kept] + [1])
    fig, axes = plt.subplots(
        max(len(kept), 1), cols, figsize=(1.9 * cols, 2.1 * max(len(kept), 1)), squeeze=False
    )
    for ax in axes.ravel():
        ax.set_axis_off()
    if not kept:
        axes[0][0].text(0.5, 0.5, "no pixel episode kept its frames", ha="center", va="center")
    for i, r in enumerate(kept):
        tee = TeeGeometry.from_shape(TeeShape(*r["shape"]))
        for j, frame in enumerate(r["frames"]):
            ax = axes[i][j]
            pixels = np.asarray(frame["pixels"], dtype=np.uint8)
            n = pixels.shape[0]
            ax.imshow(pixels, extent=(-0.5, n - 0.5, n - 0.5, -0.5))
            truth = np.asarray(frame["truth"], dtype=float)
            outline = world_to_pixel(to_world(cog_pose(truth), OUTLINE), n)
            ax.add_patch(Polygon(outline, closed=True, fill=False, ec="black", ls="--", lw=0.6))
            title = "not read"
            if frame["pose"] is not None:
                pose = np.asarray(frame["pose"], dtype=float)
                seen = world_to_pixel(to_world(cog_pose(pose, tee), tee.outline), n)
                ax.add_patch(Polygon(seen, closed=True, fill=False, ec="tab:orange", lw=1.0))
                err = float(np.hypot(*(cog_pose(pose) - cog_pose(truth))[:2])) * n / WORLD_SIZE
                turn = np.degrees(np.angle(np.exp(1j * (pose[2] - truth[2]))))
                title = f"{err:.2f} px, {abs(turn):.2f} deg"
            ax.set_title(f"seed {r['seed']}: {title}" if j == 0 else title, fontsize=6)
    fig.suptitle(
        "Push-T from pixels: frames planned on, perceived pose (orange) and state (dashed)",
        fontsize=8,
    )
    return _finish(fig, path)


def plot_success_curve(
    rows: Sequence[dict[str, Any]], path: str | Path, by: str | None = None
) -> str:
    """Success of the learned-model planner against training pushes (95 % Wilson intervals).

    Args:
        rows: One row per size: ``train_pushes``, ``success_rate``, ``success_low``,
            ``success_high`` (and the column `by`).
        path: The PNG to write.
        by: A column whose values get a line each (e.g. ``"strategy"``); None for one line.

    Returns:
        `path` as a string.
    """
    fig, ax = plt.subplots(figsize=(5, 3.5))
    groups: dict[str, list[dict[str, Any]]] = {}
    for r in rows:
        groups.setdefault("beam search, mixture" if by is None else str(r[by]), []).append(r)
    for label, part in groups.items():
        part = sorted(part, key=lambda r: r["train_pushes"])
        n = np.array([r["train_pushes"] for r in part], dtype=float)
        rate = np.array([r["success_rate"] for r in part])
        lo = np.maximum(rate - np.array([r["success_low"] for r in part]), 0.0)  # rounding
        hi = np.maximum(np.array([r["success_high"] for r in part]) - rate, 0.0)
        ax.errorbar(n, rate, yerr=[lo, hi], marker="o", capsize=3, label=label)
    ax.axhline(
        DIFFUSION_POLICY.success_rate,
        color="tab:red",
        ls="--",
        label=f"diffusion policy ({DIFFUSION_POLICY.observation})",
    )
    ax.set_xscale("log")
    sizes = sorted({int(r["train_pushes"]) for r in rows})
    ax.set_xticks(sizes, [str(n) for n in sizes])
    ax.minorticks_off()
    ax.set_ylim(0, 1.02)
    ax.set_xlabel("training pushes")
    ax.set_ylabel("success rate")
    ax.legend(fontsize=8)
    ax.set_title("Push-T success against training pushes")
    return _finish(fig, path)


def plot_models(rows: Sequence[dict[str, Any]], path: str | Path) -> str:
    """Held-out RMSE (along the push) and NLPD of each model against training pushes."""
    fig, axes = plt.subplots(1, 2, figsize=(8, 3.3))
    for model in dict.fromkeys(r["model"] for r in rows):
        rs = sorted((r for r in rows if r["model"] == model), key=lambda r: r["train_pushes"])
        n = [r["train_pushes"] for r in rs]
        axes[0].plot(n, [r["rmse_z"] for r in rs], marker="o", label=model)
        axes[1].plot(n, [r["nlpd"] for r in rs], marker="o", label=model)
    for ax, label in zip(axes, ("RMSE along the push (px)", "NLPD (nats)"), strict=True):
        ax.set_xscale("log")
        ax.set_xlabel("training pushes")
        ax.set_ylabel(label)
        ax.legend(fontsize=8)
    fig.suptitle("Push-T push models on held-out pushes")
    return _finish(fig, path)
