"""Drawings of chapter 6's predictions: chained pushes on the table, picks and places.

Every figure is a pure function of plain records: numpy arrays or the same values as nested
lists loaded back from JSON. Tabletop poses are world ``(x, y, yaw)`` in metres and radians,
seen from above; side-view poses are ``(x, z, phi)`` in the vertical plane of the pick or
place, with the table top at ``z = 0``.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import numpy as np
from matplotlib.axes import Axes
from matplotlib.colors import to_rgba
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch, Polygon

from probaff._checks import check_count
from probaff.errors import InputError
from probaff.eval.plots import (
    axes_grid,
    check_figure_path,
    check_flag,
    check_records,
    finite_array,
    save_titled,
)
from probaff.planning.geometry import box_corners

__all__ = ["plot_sideview_predictions", "plot_tabletop_predictions"]

_SCENE_KEYS = (
    "sizes",
    "start",
    "true_final",
    "samples",
    "hand_start",
    "hand_end",
    "label",
)
_CASE_KEYS = (
    "skill",
    "success",
    "label",
    "sizes",
    "start",
    "true_final",
    "target",
    "pred_final",
    "pred_sd",
    "tcp_commanded",
    "tcp_actual",
)
_SKILLS = ("pick", "place")
_Z90 = 1.645  # half-width of a central 90 % normal interval, in standard deviations
_START, _TRUE, _PRED, _MONO, _HAND = "0.45", "tab:green", "tab:blue", "tab:orange", "crimson"
_MARGIN = 0.04  # m of empty table drawn around a scene's objects


def _frame(ax: Axes, points: Sequence[np.ndarray], ylabel: str, floor: float | None = None) -> None:
    """A square window, metres on both axes, around `points` (each (N, 2)) with a margin.

    With a `floor` (the table top of a side view) the window starts just below it and grows
    upwards, so that the table takes a thin band at the bottom.
    """
    pts = np.concatenate([np.reshape(p, (-1, 2)) for p in points])
    centre = 0.5 * (pts.min(0) + pts.max(0))
    half = 0.5 * float(np.max(pts.max(0) - pts.min(0))) + _MARGIN
    lo, hi = centre - half, centre + half
    if floor is not None:
        lo[1] = min(float(pts[:, 1].min()), floor) - _MARGIN
        hi[1] = max(lo[1] + 2 * half, float(pts[:, 1].max()) + _MARGIN)
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)", fontsize=7)
    ax.set_ylabel(ylabel, fontsize=7)
    ax.tick_params(labelsize=6)
    ax.grid(alpha=0.2, lw=0.5)


def _panels(
    parsed: list[dict[str, Any]],
    draw: Callable[[Axes, dict[str, Any]], None],
    max_cols: int,
) -> tuple[Figure, list[dict[str, Any]]]:
    """A figure of one panel per parsed record, in rows of at most `max_cols`, each drawn.

    Panels are 3.6 x 3.5 inches in rows of 4 (tabletop scenes), 3 x 3 in rows of 5 (side
    views).
    """
    n = len(parsed)
    cols = min(max_cols, n)
    width, height = (3.6, 3.5) if max_cols == 4 else (3.0, 3.0)
    fig = Figure(figsize=(width * cols, height * math.ceil(n / cols) + 0.9), layout="constrained")
    for ax, record in zip(axes_grid(fig, n, cols), parsed, strict=True):
        draw(ax, record)
    return fig, parsed


def _box(pose: np.ndarray, size: np.ndarray, **style: Any) -> Polygon:
    return Polygon(box_corners(pose, (float(size[0]), float(size[1]))), closed=True, **style)


def _arrow(ax: Axes, start: np.ndarray, end: np.ndarray, colour: str) -> None:
    ax.annotate(
        "",
        xy=(float(end[0]), float(end[1])),
        xytext=(float(start[0]), float(start[1])),
        annotation_clip=False,
        arrowprops={"arrowstyle": "-|>", "color": colour, "lw": 1.6, "shrinkA": 0, "shrinkB": 0},
        zorder=8,
    )


# --- tabletop pushes -------------------------------------------------------------------------


def _scene(i: int, scene: Mapping[str, Any]) -> dict[str, Any]:
    """Scene `i` with its arrays checked against the number of objects K of ``sizes``."""
    where = f"scenes[{i}]"
    sizes = finite_array(f"{where}['sizes']", scene["sizes"], (None, 3))
    if np.any(sizes <= 0):
        raise InputError(f"{where}['sizes'] must be > 0 (box length, width, height in m).")
    k = len(sizes)
    out: dict[str, Any] = {"sizes": sizes, "label": str(scene["label"])}
    for key in ("start", "true_final"):
        out[key] = finite_array(f"{where}[{key!r}]", scene[key], (k, 3))
    out["samples"] = finite_array(f"{where}['samples']", scene["samples"], (None, k, 3))
    for key in ("hand_start", "hand_end"):
        out[key] = finite_array(f"{where}[{key!r}]", scene[key], (2,))
    mono = scene.get("monolithic_final")
    out["monolithic_final"] = (
        None if mono is None else finite_array(f"{where}['monolithic_final']", mono, (k, 3))
    )
    path = scene.get("true_path")
    empty = (
        path is None
        or (isinstance(path, Sequence) and len(path) == 0)
        or (isinstance(path, np.ndarray) and path.size == 0)
    )
    out["true_path"] = None if empty else finite_array(f"{where}['true_path']", path, (None, k, 3))
    return out


def _mean_pose(samples: np.ndarray) -> np.ndarray:
    """(K, 3) mean of (S, K, 3) sampled poses; the yaw is the circular mean."""
    yaw = np.arctan2(np.sin(samples[..., 2]).mean(0), np.cos(samples[..., 2]).mean(0))
    return np.concatenate([samples[..., :2].mean(0), yaw[:, None]], axis=1)


def _errors_cm(pred: np.ndarray, true: np.ndarray) -> str:
    """Centre errors of (K, 3) predictions, per object for up to 3, else mean and max."""
    err = 100 * np.linalg.norm(pred[:, :2] - true[:, :2], axis=1)
    if len(err) <= 3:
        return ", ".join(f"o{j + 1} {e:.1f}" for j, e in enumerate(err)) + " cm"
    return f"mean {err.mean():.1f}, max {err.max():.1f} cm over {len(err)} objects"


def _draw_scene(ax: Axes, s: Mapping[str, Any]) -> None:
    sizes, start, true, samples = s["sizes"], s["start"], s["true_final"], s["samples"]
    mean, mono, path = _mean_pose(samples), s["monolithic_final"], s["true_path"]
    points = [box_corners(start[j], tuple(sizes[j, :2])) for j in range(len(sizes))]
    for j, size in enumerate(sizes):
        ax.add_patch(_box(start[j], size, fill=False, ec=_START, lw=1.2, zorder=2))
        ax.add_patch(_box(true[j], size, fc=to_rgba(_TRUE, 0.25), ec=_TRUE, lw=1.5, zorder=3))
        ax.add_patch(_box(mean[j], size, fill=False, ec=_PRED, ls="--", lw=1.5, zorder=5))
        if mono is not None:
            ax.add_patch(_box(mono[j], size, fill=False, ec=_MONO, ls=":", lw=1.8, zorder=5))
            points.append(box_corners(mono[j], tuple(size[:2])))
        x, y = float(start[j, 0]), float(start[j, 1])
        ax.text(x, y, f"o{j + 1}", fontsize=6, color="0.3", ha="center", va="center", zorder=7)
        points += [box_corners(true[j], tuple(size[:2])), box_corners(mean[j], tuple(size[:2]))]
    if path is not None:
        for j in range(len(sizes)):
            ax.plot(path[:, j, 0], path[:, j, 1], color=_TRUE, lw=1.2, zorder=4)
        points.append(path[..., :2])
    dots = samples[..., :2].reshape(-1, 2)
    ax.plot(dots[:, 0], dots[:, 1], "o", color=_PRED, ms=2, alpha=0.25, mew=0, zorder=6)
    for j in range(len(sizes)):
        line = np.stack([start[j, :2], mean[j, :2]])
        ax.plot(line[:, 0], line[:, 1], color=_PRED, lw=1.0, zorder=6)
    _arrow(ax, s["hand_start"], s["hand_end"], _HAND)
    points += [dots, np.stack([s["hand_start"], s["hand_end"]])]
    _frame(ax, points, "y (m)")
    errors = f"modular: {_errors_cm(mean, true)}"
    if mono is not None:
        errors += f"\nmonolithic: {_errors_cm(mono, true)}"
    ax.set_title(f"{s['label']}\n{errors}", fontsize=7)


def _tabletop_legend(monolithic: bool) -> list[Any]:
    handles: list[Any] = [
        Patch(fill=False, ec=_START, lw=1.2, label="start"),
        Patch(fc=to_rgba(_TRUE, 0.25), ec=_TRUE, label="observed final"),
        Line2D([], [], color=_TRUE, lw=1.2, label="observed path"),
        Line2D([], [], color=_PRED, marker="o", ms=3, alpha=0.5, ls="none", label="samples"),
        Patch(fill=False, ec=_PRED, ls="--", lw=1.5, label="modular mean"),
        Line2D([], [], color=_PRED, lw=1.0, label="predicted path"),
    ]
    if monolithic:
        handles.append(Patch(fill=False, ec=_MONO, ls=":", lw=1.8, label="monolithic"))
    handles.append(
        Line2D([], [], color=_HAND, marker=r"$\rightarrow$", ls="none", ms=10, label="hand push")
    )
    return handles


def plot_tabletop_predictions(
    scenes: Sequence[Mapping[str, Any]],
    path: str | os.PathLike[str],
    *,
    title: str | None = None,
) -> str:
    """Chained push predictions seen from above, one panel per scene, and save the figure.

    Each panel shows every box at the start (grey outline), where it ended (green, its
    observed trajectory a green line), the modular chain's sampled final centres (blue dots),
    the box at the circular mean of those samples (blue dashed) joined to its start centre
    (the predicted trajectory), the monolithic model's final box when given (orange dotted)
    and the hand's commanded push (red arrow). The panel title gives the centre error of each
    prediction. Panels come four to a row.

    Args:
        scenes: One mapping per scene with keys ``sizes`` (K, 3) box length (along the box's
            own x), width and height in m; ``start`` and ``true_final`` (K, 3) world
            ``(x, y, yaw)`` poses in m and rad; ``samples`` (S, K, 3) sampled final poses of
            the chained prediction; ``hand_start`` and ``hand_end`` (2,) world ``(x, y)``;
            ``label`` a short panel title; optionally ``true_path`` (T, K, 3) observed poses
            and ``monolithic_final`` (K, 3), either ``None`` or absent when not available.
        path: Image file to write (format from the suffix), atomically.
        title: Figure title; by default how many scenes are drawn.

    Returns:
        `path`, as a string.

    Raises:
        InputError: For no scenes, a scene lacking a key, an array of the wrong shape (the
            number of objects K is that of ``sizes``), a non-finite value or a size <= 0.
    """
    check_figure_path(path)
    records = check_records("scenes", scenes, _SCENE_KEYS, "tabletop scene records")
    fig, parsed = _panels([_scene(i, s) for i, s in enumerate(records)], _draw_scene, 4)
    n = len(parsed)
    monolithic = any(s["monolithic_final"] is not None for s in parsed)
    handles = _tabletop_legend(monolithic)
    fig.legend(handles=handles, loc="outside lower center", ncols=min(len(handles), 8), fontsize=7)
    return save_titled(fig, path, title, f"Chained push predictions, top view ({n} scenes)")


# --- side-view picks and places --------------------------------------------------------------


def _case(i: int, case: Mapping[str, Any]) -> dict[str, Any]:
    """Case `i` with its arrays checked against the number of objects K of ``sizes``."""
    where = f"cases[{i}]"
    skill = case["skill"]
    if skill not in _SKILLS:
        raise InputError(f"{where}['skill'] must be one of {list(_SKILLS)}, got {skill!r}.")
    sizes = finite_array(f"{where}['sizes']", case["sizes"], (None, 2))
    if np.any(sizes <= 0):
        raise InputError(f"{where}['sizes'] must be > 0 (box width and height in m).")
    k = len(sizes)
    target = check_count(f"{where}['target']", case["target"], minimum=0)
    if target >= k:
        raise InputError(
            f"{where}['target'] is {target} but the case has {k} object(s); give a 0-based "
            f"index below {k}."
        )
    sd = finite_array(f"{where}['pred_sd']", case["pred_sd"], (3,))
    if np.any(sd < 0):
        raise InputError(f"{where}['pred_sd'] must be >= 0 (standard deviations), got {sd}.")
    return {
        "skill": str(skill),
        "success": check_flag(f"{where}['success']", case["success"]),
        "label": str(case["label"]),
        "sizes": sizes,
        "start": finite_array(f"{where}['start']", case["start"], (k, 3)),
        "true_final": finite_array(f"{where}['true_final']", case["true_final"], (k, 3)),
        "target": target,
        "pred_final": finite_array(f"{where}['pred_final']", case["pred_final"], (3,)),
        "pred_sd": sd,
        "tcp_commanded": finite_array(
            f"{where}['tcp_commanded']", case["tcp_commanded"], (None, 2)
        ),
        "tcp_actual": finite_array(f"{where}['tcp_actual']", case["tcp_actual"], (None, 2)),
    }


def _draw_case(ax: Axes, c: Mapping[str, Any]) -> None:
    sizes, start, true, t = c["sizes"], c["start"], c["true_final"], c["target"]
    pred, sd = c["pred_final"], c["pred_sd"]
    points = [c["tcp_commanded"], c["tcp_actual"], np.array([[pred[0], 0.0]])]
    for j, size in enumerate(sizes):
        ax.add_patch(_box(start[j], size, fill=False, ec=_START, lw=1.2, zorder=2))
        ax.add_patch(_box(true[j], size, fc=to_rgba(_TRUE, 0.25), ec=_TRUE, lw=1.5, zorder=3))
        points += [box_corners(p, tuple(size)) for p in (start[j], true[j])]
    ax.add_patch(_box(pred, sizes[t], fill=False, ec=_PRED, ls="--", lw=1.6, zorder=5))
    ax.errorbar(
        pred[0],
        pred[1],
        xerr=_Z90 * sd[0],
        yerr=_Z90 * sd[1],
        fmt="o",
        ms=3,
        color=_PRED,
        capsize=3,
        lw=1.2,
        zorder=6,
    )
    points.append(box_corners(pred, tuple(sizes[t])))
    points.append(pred[:2] + _Z90 * np.array([[-sd[0], -sd[1]], [sd[0], sd[1]]]))
    for key, ls in (("tcp_commanded", "--"), ("tcp_actual", "-")):
        tcp = c[key]
        ax.plot(tcp[:, 0], tcp[:, 1], color=_HAND, ls=ls, lw=1.2, marker=".", ms=3, zorder=7)
    _frame(ax, points, "z (m)", floor=0.0)
    ax.axhspan(ax.get_ylim()[0] - 1.0, 0.0, color="0.9", zorder=0)
    ax.axhline(0.0, color="0.25", lw=3, zorder=1)
    done = {"pick": ("lifted", "not lifted"), "place": ("placed", "not placed")}[c["skill"]]
    outcome = done[0] if c["success"] else done[1]
    colour = _TRUE if c["success"] else "tab:red"
    ax.set_title(f"{c['label']}\n{c['skill']}: {outcome}", fontsize=7, color=colour)


def plot_sideview_predictions(
    cases: Sequence[Mapping[str, Any]],
    path: str | os.PathLike[str],
    *,
    title: str | None = None,
) -> str:
    """Pick and place predictions seen from the side, one panel per case, and save the figure.

    Each panel shows the table top (``z = 0``, a thick line over a grey band), every box at
    the start (grey outline) and where it ended (green), the predicted final box of the
    target object (blue dashed) with a 90 % error bar (1.645 standard deviations) on x and z
    at its centre, and the tool centre point's commanded (dashed) and actual (solid) paths.
    The title gives the case's label, skill and whether the box was lifted or placed. Panels
    come five to a row.

    Args:
        cases: One mapping per case with keys ``skill`` (``"pick"`` or ``"place"``),
            ``success`` (bool), ``label`` (str), ``sizes`` (K, 2) box width along x and
            height along z in m, ``start`` and ``true_final`` (K, 3) poses ``(x, z, phi)``
            in m and rad, ``target`` the 0-based index of the predicted object,
            ``pred_final`` and ``pred_sd`` (3,) the target's predicted final pose and its
            standard deviations, ``tcp_commanded`` and ``tcp_actual`` (T, 2) ``(x, z)``.
        path: Image file to write (format from the suffix), atomically.
        title: Figure title; by default how many picks and places are drawn.

    Returns:
        `path`, as a string.

    Raises:
        InputError: For no cases, a case lacking a key, an unknown skill, a target that is
            not an object's index, an array of the wrong shape, a non-finite value, a size
            <= 0 or a negative standard deviation.
    """
    check_figure_path(path)
    records = check_records("cases", cases, _CASE_KEYS, "pick/place case records")
    fig, parsed = _panels([_case(i, c) for i, c in enumerate(records)], _draw_case, 5)
    n = len(parsed)
    handles = [
        Patch(fill=False, ec=_START, lw=1.2, label="start"),
        Patch(fc=to_rgba(_TRUE, 0.25), ec=_TRUE, label="observed final"),
        Patch(fill=False, ec=_PRED, ls="--", lw=1.6, label="predicted target, 90 % bars"),
        Line2D([], [], color=_HAND, ls="--", lw=1.2, label="tcp commanded"),
        Line2D([], [], color=_HAND, ls="-", lw=1.2, label="tcp actual"),
        Line2D([], [], color="0.25", lw=3, label="table top"),
    ]
    fig.legend(handles=handles, loc="outside lower center", ncols=len(handles), fontsize=7)
    picks = sum(c["skill"] == "pick" for c in parsed)
    default = f"Pick and place predictions, side view ({picks} picks, {n - picks} places)"
    return save_titled(fig, path, title, default)
