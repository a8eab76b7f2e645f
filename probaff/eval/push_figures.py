"""Figures of pushes: object footprints before and after, and the gripper's path."""

from __future__ import annotations

import math
import os
from collections.abc import Sequence

import numpy as np
from matplotlib.figure import Figure
from matplotlib.patches import Circle, Polygon, Rectangle

from probaff._io import atomic_save_figure
from probaff.data.schema import PushDataset
from probaff.sim.config import load_catalogue
from probaff.sim.geometry import footprint_polygon

__all__ = ["plot_pushes"]

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
