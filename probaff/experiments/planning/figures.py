"""Figures of push-to-edge planning (chapter 4): episodes, success rates, pushes per trial.

The episode figures read the records of `probaff.planning.push_to_edge.episode.EdgeEpisode.to_dict`
(or the same records loaded back from JSON); the success-rate figure reads summary rows with
a rate and its 95 % interval per planner. Poses are world ``(x, y, theta)`` in metres and
radians, the table centred at the origin, its +x side the edge the book goes over.
"""

from __future__ import annotations

import math
import os
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.axes import Axes
from matplotlib.colors import to_rgba
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch, Polygon, Rectangle
from matplotlib.ticker import MaxNLocator, PercentFormatter

from probaff._checks import check_finite, check_shape
from probaff._io import atomic_save_figure
from probaff.errors import InputError
from probaff.eval.plots import check_records
from probaff.planning import EdgeTask
from probaff.planning.geometry import box_corners
from probaff.sim.inputs import floats

__all__ = [
    "edge_figures",
    "plot_edge_episodes",
    "plot_pushes_per_trial",
    "plot_success_rates",
]

_EPISODE_KEYS = (
    "planner",
    "seed",
    "success",
    "outcome",
    "pushes",
    "replans",
    "start",
    "final",
    "steps",
)
_STEP_KEYS = ("yaw", "origin", "before", "predicted", "after", "book_path")
_RATE_KEYS = ("planner", "success_rate", "success_low", "success_high", "trials")
_TRIAL_KEYS = ("success", "pushes", "replans")
_ARROW = 0.05  # drawn length (m) of a push's hand-start arrow
_SUCCESS, _FAILURE = "tab:green", "tab:red"
_EXECUTED, _PREDICTED, _HAND = "tab:blue", "tab:orange", "crimson"


def _pose(name: str, value: Any, rows: int | None = None) -> np.ndarray:
    arr = floats(name, value)
    check_shape(name, arr, (3,) if rows is None else (rows, 3))
    check_finite(name, arr)
    return arr


def _episode_steps(
    i: int, episode: Mapping[str, Any]
) -> tuple[np.ndarray, np.ndarray, list[dict[str, Any]]]:
    """The episode's (2, 3) start poses, (3,) final book pose and steps as arrays, checked."""
    start = _pose(f"episodes[{i}]['start']", episode["start"], rows=2)
    final = _pose(f"episodes[{i}]['final']", episode["final"])
    raw = episode["steps"]
    if isinstance(raw, Sequence) and not isinstance(raw, (str, bytes)) and len(raw) == 0:
        return start, final, []
    steps = check_records(f"episodes[{i}]['steps']", raw, _STEP_KEYS, "EdgeStep records")
    out = []
    for j, step in enumerate(steps):
        where = f"episodes[{i}]['steps'][{j}]"
        origin = floats(f"{where}['origin']", step["origin"])
        check_shape(f"{where}['origin']", origin, (2,))
        check_finite(f"{where}['origin']", origin)
        path = floats(f"{where}['book_path']", step["book_path"]).reshape(-1, 3)
        check_finite(f"{where}['book_path']", path)
        yaw = floats(f"{where}['yaw']", step["yaw"])
        check_shape(f"{where}['yaw']", yaw, ())
        check_finite(f"{where}['yaw']", yaw)
        out.append(
            {
                "yaw": float(yaw),
                "origin": origin,
                "before": _pose(f"{where}['before']", step["before"]),
                "predicted": _pose(f"{where}['predicted']", step["predicted"]),
                "after": _pose(f"{where}['after']", step["after"]),
                "book_path": path,
            }
        )
    return start, final, out


def _trajectory(steps: Sequence[Mapping[str, Any]]) -> np.ndarray:
    """The book's executed (T, 3) path: each step's recorded path, else its before and after."""
    parts = [
        s["book_path"] if len(s["book_path"]) else np.stack([s["before"], s["after"]])
        for s in steps
    ]
    return np.concatenate(parts) if parts else np.zeros((0, 3))


def _draw_episode(
    ax: Axes,
    task: EdgeTask,
    episode: Mapping[str, Any],
    start: np.ndarray,
    final: np.ndarray,
    steps: Sequence[Mapping[str, Any]],
) -> None:
    tw, th = task.world.table_size
    ax.add_patch(Rectangle((-tw / 2, -th / 2), tw, th, fc="0.94", ec="0.4", lw=1, zorder=0))
    goal_x = task.edge_x + task.grasp_depth
    ax.add_patch(
        Rectangle((task.edge_x, -th / 2), task.grasp_depth, th, fc="#d9f0d3", ec="none", zorder=0)
    )
    ax.plot([task.edge_x] * 2, [-th / 2, th / 2], color="k", lw=1.6)
    ax.plot([goal_x] * 2, [-th / 2, th / 2], color="k", lw=1.0, ls="--")
    battery = start[1]
    ax.add_patch(
        Polygon(box_corners(battery, task.battery.size), fc="0.55", ec="0.3", lw=1, zorder=2)
    )
    book = task.book.size
    ax.add_patch(
        Polygon(box_corners(start[0], book), fill=False, ec=_EXECUTED, ls="--", lw=1.2, zorder=3)
    )
    end = _SUCCESS if bool(episode["success"]) else _FAILURE
    ax.add_patch(Polygon(box_corners(final, book), fc=to_rgba(end, 0.25), ec=end, lw=1.8, zorder=4))
    points = [np.array([[-tw / 2, -th / 2], [tw / 2, th / 2]]), box_corners(final, book)]
    if steps:
        path = _trajectory(steps)
        ax.plot(path[:, 0], path[:, 1], color=_EXECUTED, lw=1.4, zorder=5)
        ax.plot(path[-1, 0], path[-1, 1], "o", color=_EXECUTED, ms=3, zorder=5)
        points.append(path[:, :2])
        for s in steps:
            b, p = s["before"], s["predicted"]
            ax.plot([b[0], p[0]], [b[1], p[1]], color=_PREDICTED, lw=1.0, ls=":", zorder=6)
            ax.plot(p[0], p[1], "x", color=_PREDICTED, ms=5, mew=1.4, zorder=6)
            o, yaw = s["origin"], float(s["yaw"])
            ax.annotate(
                "",
                xy=(o[0] + _ARROW * math.cos(yaw), o[1] + _ARROW * math.sin(yaw)),
                xytext=(o[0], o[1]),
                annotation_clip=False,
                arrowprops={"arrowstyle": "-|>", "color": _HAND, "lw": 1.2},
                zorder=7,
            )
            points.append(np.stack([p[:2], o]))
    pts = np.concatenate(points)
    lo, hi = pts.min(0) - 0.05, pts.max(0) + 0.05
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_aspect("equal")
    ax.tick_params(labelsize=7)
    ax.set_title(
        f"{episode['planner']}, seed {episode['seed']}: {episode['outcome']}\n"
        f"{episode['pushes']} pushes, {episode['replans']} replans",
        fontsize=8,
    )


def _episode_legend() -> list[Any]:
    return [
        Patch(fc="0.55", ec="0.3", label="battery"),
        Patch(fill=False, ec=_EXECUTED, ls="--", label="book at start"),
        Patch(fc=to_rgba(_SUCCESS, 0.25), ec=_SUCCESS, label="book at end (success)"),
        Patch(fc=to_rgba(_FAILURE, 0.25), ec=_FAILURE, label="book at end (failure)"),
        Line2D([], [], color=_EXECUTED, lw=1.4, label="executed book path"),
        Line2D([], [], color=_PREDICTED, ls=":", marker="x", label="predicted pose"),
        Line2D([], [], color=_HAND, marker=r"$\rightarrow$", ls="none", ms=10, label="hand start"),
        Line2D([], [], color="k", lw=1.6, label="table edge"),
        Line2D([], [], color="k", lw=1.0, ls="--", label="edge + grasp depth"),
    ]


def plot_edge_episodes(
    episodes: Sequence[Mapping[str, Any]],
    task: EdgeTask,
    path: str | os.PathLike[str],
    *,
    title: str | None = None,
    max_panels: int = 6,
) -> str:
    """Draw push-to-edge episodes as seen from above, one panel each, and save the figure.

    Each panel shows the table with its +x edge (solid) and the goal line ``edge_x + d_g``
    (dashed, the band between them shaded), the battery (grey), the book at the start
    (dashed outline) and at the end (green for a success, red otherwise), the book's
    executed trajectory (each step's ``book_path``, or the chain of its ``before`` and
    ``after`` poses when trajectories were not kept), every push's predicted pose (a cross
    joined from the pose the push started from: planned against executed) and every push's
    hand start (an arrow along the push yaw).

    Args:
        episodes: `EdgeEpisode.to_dict` records; the first `max_panels` are drawn.
        task: The task the episodes ran (table, edge, grasp depth, book and battery sizes).
        path: Image file to write (format from the suffix), atomically.
        title: Figure title; by default the task's scene and how many episodes are shown.
        max_panels: Most panels drawn.

    Returns:
        `path`, as a string.

    Raises:
        InputError: For a task that is not an `EdgeTask`, no episodes, a record that lacks a
            key of `EdgeEpisode.to_dict`, or a malformed pose.
    """
    if not isinstance(task, EdgeTask):
        raise InputError(f"task must be an EdgeTask (load_edge_task()), got {type(task).__name__}.")
    if isinstance(max_panels, bool) or not isinstance(max_panels, int) or max_panels < 1:
        raise InputError(f"max_panels must be a positive integer, got {max_panels!r}.")
    records = check_records("episodes", episodes, _EPISODE_KEYS, "EdgeEpisode.to_dict() records")
    shown = records[:max_panels]
    parsed = [_episode_steps(i, ep) for i, ep in enumerate(shown)]
    n = len(shown)
    cols = min(3, n)
    rows = math.ceil(n / cols)
    fig = Figure(figsize=(4.2 * cols, 3.9 * rows + 0.9), layout="constrained")
    axes = fig.subplots(rows, cols, squeeze=False).ravel()
    for ax, ep, (start, final, steps) in zip(axes, shown, parsed, strict=False):
        _draw_episode(ax, task, ep, start, final, steps)
    for ax in axes[n:]:
        ax.axis("off")
    fig.legend(
        handles=_episode_legend(), loc="outside lower center", ncols=min(5, 2 + cols), fontsize=7
    )
    more = f" (first {n} of {len(records)})" if len(records) > n else ""
    fig.suptitle(
        title if title is not None else f"{task.scene.name}: {len(records)} episodes{more}",
        fontsize=10,
    )
    atomic_save_figure(fig, path, dpi=120)
    return str(path)


def plot_success_rates(
    rows: Sequence[Mapping[str, Any]],
    path: str | os.PathLike[str],
    *,
    title: str | None = None,
    reference: tuple[str, float] | None = None,
) -> str:
    """Success rate per planner with its 95 % interval, one row each, and save the figure.

    Args:
        rows: One per planner, top to bottom, with keys ``planner``, ``success_rate``,
            ``success_low`` and ``success_high`` (fractions in [0, 1]) and ``trials``.
        path: Image file to write (format from the suffix), atomically.
        title: Figure title.
        reference: Optional ``(label, rate)``, a rate in [0, 1] drawn as a dashed vertical
            line (e.g. ``("thesis, 14/15", 14 / 15)``).

    Returns:
        `path`, as a string.

    Raises:
        InputError: For no rows, a row lacking a key, a rate outside [0, 1] or an interval
            that does not contain its rate.
    """
    records = check_records("rows", rows, _RATE_KEYS, "success-rate rows")
    rates = np.empty((len(records), 3))
    for i, r in enumerate(records):
        try:
            rates[i] = [float(r["success_low"]), float(r["success_rate"]), float(r["success_high"])]
        except (TypeError, ValueError):
            raise InputError(f"rows[{i}] holds a success rate that is not a number.") from None
        lo, rate, hi = rates[i]
        if not (0 <= lo <= rate <= hi <= 1):
            raise InputError(
                f"rows[{i}] ({r['planner']}): need 0 <= success_low <= success_rate <= "
                f"success_high <= 1 (fractions, not percent), got {lo}, {rate}, {hi}."
            )
    if reference is not None:
        if not (isinstance(reference, (tuple, list)) and len(reference) == 2):
            raise InputError(f"reference must be (label, rate), got {reference!r}.")
        ref_rate = float(reference[1])
        if not 0 <= ref_rate <= 1:
            raise InputError(f"reference rate must lie in [0, 1], got {ref_rate}.")
    fig = Figure(figsize=(6.4, 1.5 + 0.45 * len(records)), layout="constrained")
    ax = fig.subplots()
    y = np.arange(len(records))
    pct = 100 * rates
    ax.errorbar(
        pct[:, 1],
        y,
        xerr=[pct[:, 1] - pct[:, 0], pct[:, 2] - pct[:, 1]],
        fmt="o",
        color="tab:blue",
        ecolor="tab:blue",
        capsize=4,
        label="success rate, 95 % interval",
    )
    for yi, r, p in zip(y, records, pct, strict=True):
        k = round(p[1] * float(r["trials"]) / 100)
        ax.annotate(
            f"{k}/{r['trials']}",
            (p[1], yi),
            xytext=(0, 6),
            textcoords="offset points",
            ha="center",
            fontsize=7,
        )
    if reference is not None:
        ax.axvline(100 * ref_rate, color="k", ls="--", lw=1, label=str(reference[0]))
    ax.set_yticks(y, [str(r["planner"]) for r in records], fontsize=8)
    ax.set_ylim(len(records) - 0.4, -0.6)
    ax.set_xlim(-2, 102)
    ax.xaxis.set_major_formatter(PercentFormatter())
    ax.set_xlabel("success rate")
    ax.grid(axis="x", alpha=0.3)
    fig.legend(loc="outside lower center", ncols=2, fontsize=7)
    if title:
        ax.set_title(title, fontsize=10)
    atomic_save_figure(fig, path, dpi=120)
    return str(path)


def plot_pushes_per_trial(
    episodes_by_planner: Mapping[str, Sequence[Mapping[str, Any]]],
    path: str | os.PathLike[str],
    *,
    title: str | None = None,
) -> str:
    """Pushes and replans per trial, by planner, and save the figure.

    Two panels, pushes and replans per trial. For each planner a box spans its successful
    trials; every trial is a jittered point, green for a success and a red cross for a
    failure. The tick labels give the successes out of the trials.

    Args:
        episodes_by_planner: Planner label -> its `EdgeEpisode.to_dict` records (keys
            ``success``, ``pushes`` and ``replans`` are read).
        path: Image file to write (format from the suffix), atomically.
        title: Figure title.

    Returns:
        `path`, as a string.

    Raises:
        InputError: For no planners, a planner without episodes, or a record lacking a key.
    """
    if not isinstance(episodes_by_planner, Mapping):
        raise InputError(
            "episodes_by_planner must map planner labels to episode records, got "
            f"{type(episodes_by_planner).__name__}."
        )
    if not episodes_by_planner:
        raise InputError("episodes_by_planner is empty; give at least one planner's episodes.")
    data: dict[str, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
    for planner, eps in episodes_by_planner.items():
        records = check_records(
            f"episodes_by_planner[{planner!r}]", eps, _TRIAL_KEYS, "EdgeEpisode.to_dict() records"
        )
        data[str(planner)] = (
            np.array([bool(e["success"]) for e in records]),
            np.array([float(e["pushes"]) for e in records]),
            np.array([float(e["replans"]) for e in records]),
        )
    names = list(data)
    fig = Figure(figsize=(max(6.4, 1.6 + 1.3 * len(names)), 4.2), layout="constrained")
    axes = fig.subplots(1, 2)
    rng = np.random.default_rng(0)
    positions = np.arange(len(names))
    for ax, column, label in ((axes[0], 1, "pushes per trial"), (axes[1], 2, "replans per trial")):
        for x, name in zip(positions, names, strict=True):
            ok, values = data[name][0], data[name][column]
            if ok.any():
                ax.boxplot(
                    values[ok],
                    positions=[x],
                    widths=0.5,
                    showfliers=False,
                    patch_artist=True,
                    boxprops={"facecolor": "#d9f0d3", "edgecolor": _SUCCESS},
                    medianprops={"color": _SUCCESS, "lw": 2},
                    whiskerprops={"color": _SUCCESS},
                    capprops={"color": _SUCCESS},
                )
            jitter = x + rng.uniform(-0.18, 0.18, len(values))
            ax.plot(jitter[ok], values[ok], "o", color=_SUCCESS, ms=4, alpha=0.7, ls="none")
            ax.plot(jitter[~ok], values[~ok], "x", color=_FAILURE, ms=5, mew=1.5, ls="none")
        ax.set_xticks(
            positions,
            [f"{n}\n{int(data[n][0].sum())}/{len(data[n][0])} succeeded" for n in names],
            fontsize=7,
            rotation=30,
            ha="right",
            rotation_mode="anchor",
        )
        ax.set_xlim(-0.6, len(names) - 0.4)
        ax.yaxis.set_major_locator(MaxNLocator(integer=True))
        ax.set_ylim(bottom=-0.5)
        ax.set_ylabel(label)
        ax.grid(axis="y", alpha=0.3)
    fig.legend(
        handles=[
            Patch(fc="#d9f0d3", ec=_SUCCESS, label="successful trials"),
            Line2D([], [], color=_SUCCESS, marker="o", ls="none", label="success"),
            Line2D([], [], color=_FAILURE, marker="x", ls="none", label="failure"),
        ],
        fontsize=7,
        loc="outside lower center",
        ncols=3,
    )
    if title:
        fig.suptitle(title, fontsize=10)
    atomic_save_figure(fig, path, dpi=120)
    return str(path)


def edge_figures(
    rows: Sequence[Mapping[str, Any]],
    records: Sequence[Mapping[str, Any]],
    planners: Sequence[str],
    task: EdgeTask,
    out: Path,
) -> list[str]:
    """The push-to-edge figures of a study run: success rates, pushes per trial, episodes.

    Args:
        rows: The planners' summary rows.
        records: The episode records of every planner.
        planners: The planners, in the order drawn; the episodes figure shows the first two
            episodes of the first three.
        task: The task.
        out: Output folder.

    Returns:
        The written paths.
    """
    files = [
        plot_success_rates(
            rows,
            out / "edge_success.png",
            title="Push to the edge: success rate (95 % Wilson intervals)",
            reference=("thesis 14/15", 14 / 15),
        )
    ]
    by_planner = {p: [r for r in records if r["planner"] == p] for p in planners}
    files.append(plot_pushes_per_trial(by_planner, out / "edge_pushes.png"))
    shown = [r for p in planners[:3] for r in by_planner[p][:2]]
    files.append(plot_edge_episodes(shown, task, out / "edge_episodes.png"))
    return files
