"""Figures of affordance maps (chapter 3): pushability heatmaps, loop steps and step curves.

Maps are drawn as seen from above with row 0 at the top, one unit square per cell: cell
``(r, c)`` spans ``x in [c, c + 1]``, ``y in [r, r + 1]`` on an inverted y-axis, so "up" points
up the page. Pushability is coloured from blue (0, not pushable) to red (1, pushable).
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.axes import Axes
from matplotlib.cm import ScalarMappable
from matplotlib.collections import PolyCollection
from matplotlib.colors import Normalize
from matplotlib.figure import Figure
from matplotlib.ticker import MaxNLocator

from probaff._checks import as_bool_array
from probaff._io import atomic_save_figure
from probaff.grid import DIRECTION_NAMES, DIRECTION_OFFSETS
from probaff.planning import POLICIES
from probaff.planning.manipulation.loop import LoopSnapshot

__all__ = [
    "plot_auc_difference",
    "plot_fig_3_7",
    "plot_loop_steps",
    "plot_mrf_smoothing",
    "plot_step_curves",
    "study_figures",
]

_CMAP = "coolwarm"
_COLOURS = {"information_gain": "tab:red", "exhaustive": "tab:blue"}
_LABELS = {
    "information_gain": "maximum information gain (MRF)",
    "exhaustive": "exhaustive (nearest box, no MRF)",
}


def plot_step_curves(
    curves: Mapping[str, np.ndarray], ylabel: str, title: str, path: str | os.PathLike[str]
) -> None:
    """Mean of a per-step quantity over maps, with a band of one standard deviation.

    Args:
        curves: Policy name -> (n_maps, S) values at steps 0..S-1 (NaN entries are skipped).
        ylabel: Label of the quantity.
        title: Figure title.
        path: Image file to write (format from the suffix), atomically.
    """
    fig = Figure(figsize=(6.0, 4.0), layout="constrained")
    ax = fig.subplots()
    for policy, values in curves.items():
        v = np.asarray(values, dtype=float)
        steps = np.arange(v.shape[1])
        with np.errstate(invalid="ignore"):
            mean = np.nanmean(v, 0)
            std = np.nanstd(v, 0)
        colour = _COLOURS.get(policy)
        ax.plot(steps, mean, marker="o", ms=3, color=colour, label=_LABELS.get(policy, policy))
        ax.fill_between(steps, mean - std, mean + std, color=colour, alpha=0.2, lw=0)
    ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    ax.set_xlabel("manipulation step")
    ax.set_ylabel(ylabel)
    ax.set_title(title, fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    atomic_save_figure(fig, path, dpi=120)


def _band(values: Sequence[float | None], fill: float = math.nan) -> np.ndarray:
    """Floats with None as `fill`."""
    return np.array([fill if v is None else float(v) for v in values], dtype=float)


def plot_fig_3_7(fig_data: Mapping[str, Any], path: str | os.PathLike[str]) -> None:
    """Fig. 3.7 as the thesis plots it, with where each loop stopped and the paired steps.

    Top: each loop's mean map entropy at steps 1-19 with its 95 % interval over maps (a
    stopped loop's last entropy carried flat) and a triangle with a dashed line at the
    median step where that loop stopped. Middle: the maps whose loop is still pushing at
    each step (the distribution of the stop steps). Bottom: the paired difference of the
    entropy drops, information gain minus exhaustive, over the maps where both loops still
    push, with its 95 % interval and the number of such maps above each point.

    Args:
        fig_data: What `probaff.experiments.affordance_map.report.fig_3_7` returned.
        path: Image file to write (format from the suffix), atomically.
    """
    steps = np.asarray(fig_data["steps"], dtype=float)
    n_maps = len(fig_data["policies"][POLICIES[0]]["stops"]["per_map"])
    fig = Figure(figsize=(6.4, 7.2), layout="constrained")
    top, middle, bottom = fig.subplots(3, 1, sharex=True, height_ratios=(3, 1.3, 2))
    for policy in POLICIES:
        d = fig_data["policies"][policy]
        mean, ci = _band(d["mean"]), _band(d["ci"], 0.0)
        colour = _COLOURS.get(policy)
        top.plot(steps, mean, marker="o", ms=3, color=colour, label=_LABELS.get(policy, policy))
        top.fill_between(steps, mean - ci, mean + ci, color=colour, alpha=0.2, lw=0)
        median = d["stops"]["median"]
        if median is not None and steps.size and steps[0] <= median <= steps[-1]:
            at = int(np.clip(math.ceil(median), steps[0], steps[-1]) - steps[0])
            for ax in (top, middle, bottom):
                ax.axvline(median, color=colour, ls="--", lw=1)
            top.plot(median, mean[at], "v", ms=10, color=colour, mec="k", ls="none")
        middle.step(steps, d["pushing"], where="mid", color=colour, label=f"median stop {median:g}")
    top.set_ylabel("mean map entropy,\nMRF (nats)")
    top.set_title(
        f"Fig. 3.7 over {n_maps} maps: mean, band: 95 % interval; a stopped loop carried "
        "flat\n(triangle, dashed line: the loop's median stop step)",
        fontsize=9,
    )
    top.grid(alpha=0.3)
    top.legend(fontsize=7)
    middle.set_ylabel("maps still\npushing")
    middle.set_ylim(-0.5, n_maps + 0.5)
    middle.grid(alpha=0.3)
    middle.legend(fontsize=7)
    paired = fig_data["paired"]
    pm, pc = _band(paired["mean"]), _band(paired["ci"], 0.0)
    bottom.axhline(0.0, color="0.4", lw=1)
    bottom.plot(steps, pm, marker="o", ms=3, color="tab:purple")
    bottom.fill_between(steps, pm - pc, pm + pc, color="tab:purple", alpha=0.2, lw=0)
    for t, m, n in zip(steps, pm, paired["pairs"], strict=True):
        if math.isfinite(m):
            bottom.annotate(
                str(n), (t, m), textcoords="offset points", xytext=(0, 5), fontsize=6, ha="center"
            )
    bottom.set_ylabel("drop difference (nats):\ninfo gain - exhaustive")
    bottom.set_title(
        "paired over the maps where both loops push (their number above each point); "
        f"verdict: {fig_data.get('verdict')}",
        fontsize=8,
    )
    bottom.set_xlabel("manipulation step")
    bottom.xaxis.set_major_locator(MaxNLocator(integer=True))
    bottom.grid(alpha=0.3)
    atomic_save_figure(fig, path, dpi=120)


def _draw_cells(ax: Axes, occupancy: np.ndarray) -> None:
    """Outline the map and its believed boxes; free cells stay white."""
    rows, cols = occupancy.shape
    ax.set_xlim(0, cols)
    ax.set_ylim(rows, 0)
    ax.set_aspect("equal")
    ax.set_xticks(np.arange(cols) + 0.5, [str(c) for c in range(cols)], fontsize=6)
    ax.set_yticks(np.arange(rows) + 0.5, [str(r) for r in range(rows)], fontsize=6)
    ax.tick_params(length=0)
    squares = [
        [(c, r), (c + 1, r), (c + 1, r + 1), (c, r + 1)] for r, c in np.argwhere(occupancy).tolist()
    ]
    ax.add_collection(PolyCollection(squares, facecolors="none", edgecolors="k", linewidths=0.8))
    ax.plot([0, cols, cols, 0, 0], [0, 0, rows, rows, 0], color="k", lw=2.5)


def _heatmap(ax: Axes, occupancy: np.ndarray, values: np.ndarray) -> None:
    """Colour each believed box by `values` (rows, cols); free cells stay white."""
    img = np.where(occupancy, values, np.nan)
    rows, cols = occupancy.shape
    ax.imshow(
        img, cmap=_CMAP, vmin=0.0, vmax=1.0, extent=(0, cols, rows, 0), interpolation="nearest"
    )
    _draw_cells(ax, occupancy)


def plot_mrf_smoothing(
    occupancy: np.ndarray,
    unary: np.ndarray,
    smoothed: np.ndarray,
    direction: int,
    path: str | os.PathLike[str],
) -> None:
    """Predicted pushability of one direction before and after MRF smoothing (Fig. 3.5).

    Args:
        occupancy: (rows, cols) bool, the believed boxes.
        unary: (rows, cols, 4) classifier probabilities.
        smoothed: (rows, cols, 4) MRF marginals ``P(pushable)``.
        direction: Index into `DIRECTION_NAMES` of the direction shown.
        path: Image file to write, atomically.
    """
    occ = as_bool_array("occupancy", occupancy)
    fig = Figure(figsize=(9.0, 4.2), layout="constrained")
    axes = fig.subplots(1, 2)
    name = DIRECTION_NAMES[direction]
    for ax, values, title in (
        (axes[0], unary, "classifier"),
        (axes[1], smoothed, "after MRF smoothing"),
    ):
        _heatmap(ax, occ, np.asarray(values, dtype=float)[..., direction])
        ax.set_title(f"pushable {name}: {title}", fontsize=9)
    bar = fig.colorbar(ScalarMappable(Normalize(0.0, 1.0), _CMAP), ax=list(axes), shrink=0.8)
    bar.set_label("P(pushable)")
    atomic_save_figure(fig, path, dpi=120)


def _triangles(r: int, c: int) -> list[list[tuple[float, float]]]:
    """The four triangles of cell (r, c), in `DIRECTION_NAMES` order (up, down, left, right)."""
    m = (c + 0.5, r + 0.5)
    return [
        [(c, r), (c + 1, r), m],
        [(c, r + 1), (c + 1, r + 1), m],
        [(c, r), (c, r + 1), m],
        [(c + 1, r), (c + 1, r + 1), m],
    ]


def _draw_walls(ax: Axes, walls: np.ndarray) -> None:
    """Cross out the true interior wall blocks (rows, cols) bool: the robot sees boxes there."""
    for r, c in np.argwhere(walls).tolist():
        ax.plot([c + 0.1, c + 0.9], [r + 0.1, r + 0.9], color="k", lw=1.2)
        ax.plot([c + 0.1, c + 0.9], [r + 0.9, r + 0.1], color="k", lw=1.2)


def _draw_snapshot(ax: Axes, shot: LoopSnapshot, walls: np.ndarray | None = None) -> None:
    occ = np.asarray(shot.occupancy, dtype=bool)
    cells = np.argwhere(occ)
    polys, values = [], []
    for r, c in cells:
        polys.extend(_triangles(int(r), int(c)))
        values.extend(np.asarray(shot.pushability, dtype=float)[r, c])
    if polys:
        coll = PolyCollection(
            polys,
            array=np.asarray(values),
            cmap=_CMAP,
            norm=Normalize(0.0, 1.0),
            edgecolors="0.6",
            linewidths=0.3,
        )
        ax.add_collection(coll)
    _draw_cells(ax, occ)
    if walls is not None:
        _draw_walls(ax, walls)
    ax.plot(shot.robot[1] + 0.5, shot.robot[0] + 0.5, "o", color="k", ms=6)
    if shot.push is not None:
        r, c, d = shot.push
        dr, dc = (int(v) for v in DIRECTION_OFFSETS[d])
        start = (c - dc + 0.5, r - dr + 0.5)  # the access cell's centre
        end = (c + 0.5 * dc + 0.5, r + 0.5 * dr + 0.5)  # the box's far edge
        ax.annotate(
            "",
            xy=end,
            xytext=start,
            annotation_clip=False,
            arrowprops={"arrowstyle": "-|>", "color": "limegreen", "lw": 2.5},
        )


def plot_loop_steps(
    snapshots: Sequence[LoopSnapshot],
    path: str | os.PathLike[str],
    title: str = "",
    walls: np.ndarray | None = None,
) -> None:
    """A few steps of the manipulation loop (Fig. 3.6).

    Each panel shows the belief before one push: every believed box split into four triangles
    (up, down, left, right) coloured by the marginal pushability of that direction, the robot
    (black dot) and the chosen push (green arrow from the access cell across the box). With
    `walls`, the true interior wall blocks are crossed out (black X): the robot believes them
    boxes like the others, and only a push tells them apart.

    Args:
        snapshots: The states to draw, in order.
        path: Image file to write, atomically.
        title: Figure title.
        walls: (rows, cols) bool, the true interior wall blocks, or None.
    """
    n = max(1, len(snapshots))
    cols = min(n, 4)
    rows = -(-n // cols)
    fig = Figure(figsize=(3.4 * cols + 0.8, 3.6 * rows + 0.3), layout="constrained")
    axes = np.atleast_1d(fig.subplots(rows, cols, squeeze=False)).ravel()
    wall_mask = None if walls is None else as_bool_array("walls", walls)
    for k, (ax, shot) in enumerate(zip(axes, snapshots, strict=False)):
        _draw_snapshot(ax, shot, wall_mask)
        what = (
            "stop"
            if shot.push is None
            else (f"push ({shot.push[0]}, {shot.push[1]}) {DIRECTION_NAMES[shot.push[2]]}")
        )
        ax.set_title(f"step {k}: H = {shot.entropy:.2f} nats, {what}", fontsize=8)
    for ax in axes[len(snapshots) :]:
        ax.axis("off")
    bar = fig.colorbar(ScalarMappable(Normalize(0.0, 1.0), _CMAP), ax=list(axes), shrink=0.7)
    bar.set_label("P(pushable)")
    if wall_mask is not None and wall_mask.any():
        title = (title + "\n" if title else "") + "X: interior wall block (seen as a box)"
    if title:
        fig.suptitle(title, fontsize=10)
    atomic_save_figure(fig, path, dpi=120)


def plot_auc_difference(
    differences: Sequence[float], ci: float | None, path: str | os.PathLike[str]
) -> None:
    """Per-map paired differences of the entropy AUC (information gain minus exhaustive).

    The areas run to the last step with a stopped loop's last entropy carried flat, so the
    difference weighs when each loop stopped as well as how fast it fell; Fig. 3.7's verdict
    is judged on the steps where both loops push instead (`plot_fig_3_7`).

    Args:
        differences: (n_maps,) AUC of the MRF entropy, information gain minus exhaustive.
        ci: 95 % half-width of their mean, or None with fewer than two maps.
        path: Image file to write, atomically.
    """
    d = np.asarray(differences, dtype=float)
    fig = Figure(figsize=(6.0, 3.6), layout="constrained")
    ax = fig.subplots()
    ax.axhline(0.0, color="0.4", lw=1)
    ax.plot(np.arange(len(d)), d, "o", color="tab:purple", ms=4, label="one map")
    mean = float(np.mean(d)) if len(d) else math.nan
    band = ci if ci is not None else 0.0
    ax.axhline(mean, color="k", lw=1.5, label=f"mean {mean:.2f} ± {band:.2f} (95 %)")
    ax.axhspan(mean - band, mean + band, color="k", alpha=0.12, lw=0)
    ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    ax.set_xlabel("test map")
    ax.set_ylabel("AUC H (MRF): info gain - exhaustive")
    ax.set_title(
        "paired AUC difference (tail after a stop carried flat: not a rate of fall)", fontsize=10
    )
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    atomic_save_figure(fig, path, dpi=120)


def _figure_map(results: list[dict[str, Any]]) -> dict[str, Any]:
    """The map drawn in Figs. 3.5 and 3.6: the first with the most information-gain pushes."""
    pushes = [len(r["policies"]["information_gain"]["steps"]) for r in results]
    return results[int(np.argmax(pushes))]


def study_figures(
    results: list[dict[str, Any]],
    curves: dict[str, dict[str, np.ndarray]],
    out: Path,
    auc_difference: Mapping[str, Any] | None = None,
    fig_3_7: Mapping[str, Any] | None = None,
) -> dict[str, str]:
    """Every figure of a study run: the curves over steps, Figs. 3.5-3.7, the paired AUC.

    Args:
        results: The maps' results (`map_task`).
        curves: Policy -> quantity -> `(n_maps, steps + 1)` curves.
        out: Output folder.
        auc_difference: The summary's ``auc_difference`` (``per_map`` and ``ci``), drawn as
            ``auc_difference.png``; None leaves that figure out.
        fig_3_7: The summary's ``fig_3_7``, drawn as ``fig_3_7.png`` (`plot_fig_3_7`); None
            leaves that figure out.

    Returns:
        Figure name -> written path.
    """
    files = {}
    if fig_3_7 is not None:
        plot_fig_3_7(fig_3_7, out / "fig_3_7.png")
        files["fig_3_7"] = os.fspath(out / "fig_3_7.png")
    for key, ylabel, name in (
        ("entropy", "average map entropy (nats)", "entropy_vs_step.png"),
        ("entropy_mrf", "average map entropy under the MRF (nats)", "entropy_mrf_vs_step.png"),
        ("accuracy", "map accuracy (MAP estimate)", "accuracy_vs_step.png"),
        ("distance", "distance travelled (cells)", "distance_vs_step.png"),
    ):
        title = (
            f"{ylabel} over {len(results)} maps (mean, band: 1 std)\n"
            "a stopped loop's last value carried flat"
        )
        plot_step_curves({p: curves[p][key] for p in POLICIES}, ylabel, title, out / name)
        files[key] = os.fspath(out / name)
    chosen = _figure_map(results)
    fig = chosen["figure"]
    occ = np.array(fig["occupancy"], dtype=bool)
    unary = np.array(fig["unary"], dtype=float)
    mrf = np.array(fig["mrf"], dtype=float)
    direction = int(np.nanargmax(np.nansum(np.abs(mrf - unary), (0, 1))))  # most smoothed
    plot_mrf_smoothing(occ, unary, mrf, direction, out / "mrf_smoothing.png")
    files["mrf_smoothing"] = os.fspath(out / "mrf_smoothing.png")
    shots = [
        LoopSnapshot(
            occupancy=np.array(s["occupancy"], dtype=bool),
            pushability=np.array(s["pushability"], dtype=float),
            robot=(int(s["robot"][0]), int(s["robot"][1])),
            push=None if s["push"] is None else tuple(s["push"]),
            entropy=float(s["entropy"]),
        )
        for s in fig["snapshots"]
    ]
    walls = np.zeros(occ.shape, dtype=bool)
    for r, c in chosen.get("walls", []):
        walls[r, c] = True
    plot_loop_steps(
        shots,
        out / "loop_steps.png",
        title=f"information-gain loop on test map {chosen['index']}",
        walls=walls,
    )
    files["loop_steps"] = os.fspath(out / "loop_steps.png")
    if auc_difference is not None:
        plot_auc_difference(
            auc_difference["per_map"], auc_difference["ci"], out / "auc_difference.png"
        )
        files["auc_difference"] = os.fspath(out / "auc_difference.png")
    return files
