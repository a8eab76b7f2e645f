"""Figures of modular transition models (chapter 6): chained pushes, picks, places, errors.

Every figure is a pure function of plain records: numpy arrays or the same values as nested
lists loaded back from JSON. Tabletop poses are world ``(x, y, yaw)`` in metres and radians,
seen from above; side-view poses are ``(x, z, phi)`` in the vertical plane of the pick or
place, with the table top at ``z = 0``. Errors are in centimetres, coverages are fractions.
"""

from __future__ import annotations

import math
import os
import re
from collections.abc import Hashable, Mapping, Sequence
from typing import Any

import numpy as np
from matplotlib.axes import Axes
from matplotlib.colors import to_rgba
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.patches import Patch, Polygon
from matplotlib.ticker import MaxNLocator, NullLocator, PercentFormatter

from probaff._checks import check_count, check_finite, check_positive, check_shape
from probaff._io import atomic_save_figure
from probaff.errors import InputError
from probaff.eval.planning_figures import _check_records
from probaff.planning.edge_task import box_corners

__all__ = [
    "plot_chain_errors",
    "plot_learning_curves",
    "plot_modular_vs_monolithic",
    "plot_sideview_predictions",
    "plot_tabletop_predictions",
]

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
_CHAIN_KEYS = ("n_objects", "object", "error_cm", "error_ci", "coverage90", "coverage_ci")
_BAR_KEYS = ("model", "object", "axis", "error_cm", "error_ci")
_CURVE_KEYS = ("panel", "series", "train_size", "value", "ci")
_SKILLS = ("pick", "place")
_AXES = ("along", "off")
_Z90 = 1.645  # half-width of a central 90 % normal interval, in standard deviations
_START, _TRUE, _PRED, _MONO, _HAND = "0.45", "tab:green", "tab:blue", "tab:orange", "crimson"
_MODEL_COLOURS = {"modular": _PRED, "monolithic": _MONO}
_CYCLE = ("tab:blue", "tab:orange", "tab:purple", "tab:brown", "tab:pink", "tab:olive", "tab:cyan")
_MARGIN = 0.04  # m of empty table drawn around a scene's objects


def _check_path(path: Any) -> None:
    if isinstance(path, bytes) or not isinstance(path, (str, os.PathLike)):
        raise InputError(f"path must be a file path (str or PathLike), got {type(path).__name__}.")
    if os.fspath(path) == "":
        raise InputError("path is empty; give the image file to write (e.g. 'figure.png').")


def _array(name: str, value: Any, shape: Sequence[int | None]) -> np.ndarray:
    """`value` as a finite float array of `shape` (``None``: any size, but not zero)."""
    if value is None:
        raise InputError(f"{name} is None; give an array of shape {tuple(shape)}.")
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"{name} must be an array of numbers, got {value!r:.80}.") from None
    check_shape(name, arr, shape)
    if arr.size == 0:
        raise InputError(f"{name} is empty (shape {arr.shape}); give at least one entry.")
    check_finite(name, arr)
    return arr


def _number(name: str, value: Any) -> float:
    """`value` as a finite float."""
    if value is None or isinstance(value, (bool, np.bool_, str, bytes)):
        raise InputError(f"{name} must be a number, got {value!r}.")
    return float(_array(name, value, ()))


def _half_width(name: str, value: Any) -> float:
    """A confidence-interval half-width: a finite number >= 0."""
    check_positive(name, value, allow_zero=True)
    return _number(name, value)


def _text(name: str, value: Any) -> str:
    if not isinstance(value, str) or not value:
        raise InputError(f"{name} must be a non-empty string, got {value!r}.")
    return value


def _flag(name: str, value: Any) -> bool:
    if not isinstance(value, (bool, np.bool_)):
        raise InputError(f"{name} must be true or false, got {value!r}.")
    return bool(value)


def _unique(name: str, keys: Sequence[Hashable], what: str) -> None:
    """`InputError` naming the first record whose `key` repeats an earlier one."""
    seen: dict[Hashable, int] = {}
    for i, key in enumerate(keys):
        if key in seen:
            raise InputError(
                f"{name}[{i}] repeats {what} {key!r} of {name}[{seen[key]}]; give one row each."
            )
        seen[key] = i


def _grid(fig: Figure, n: int, cols: int) -> list[Axes]:
    """`n` axes in rows of at most `cols`; the unused cells of the last row are hidden."""
    rows = math.ceil(n / cols)
    axes = list(fig.subplots(rows, cols, squeeze=False).ravel())
    for ax in axes[n:]:
        ax.axis("off")
    return axes[:n]


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


def _save(fig: Figure, path: str | os.PathLike[str], title: str | None, default: str) -> str:
    fig.suptitle(title if title is not None else default, fontsize=10)
    atomic_save_figure(fig, path, dpi=120)
    return str(path)


# --- tabletop pushes -------------------------------------------------------------------------


def _scene(i: int, scene: Mapping[str, Any]) -> dict[str, Any]:
    """Scene `i` with its arrays checked against the number of objects K of ``sizes``."""
    where = f"scenes[{i}]"
    sizes = _array(f"{where}['sizes']", scene["sizes"], (None, 3))
    if np.any(sizes <= 0):
        raise InputError(f"{where}['sizes'] must be > 0 (box length, width, height in m).")
    k = len(sizes)
    out: dict[str, Any] = {"sizes": sizes, "label": str(scene["label"])}
    for key in ("start", "true_final"):
        out[key] = _array(f"{where}[{key!r}]", scene[key], (k, 3))
    out["samples"] = _array(f"{where}['samples']", scene["samples"], (None, k, 3))
    for key in ("hand_start", "hand_end"):
        out[key] = _array(f"{where}[{key!r}]", scene[key], (2,))
    mono = scene.get("monolithic_final")
    out["monolithic_final"] = (
        None if mono is None else _array(f"{where}['monolithic_final']", mono, (k, 3))
    )
    path = scene.get("true_path")
    empty = (
        path is None
        or (isinstance(path, Sequence) and len(path) == 0)
        or (isinstance(path, np.ndarray) and path.size == 0)
    )
    out["true_path"] = None if empty else _array(f"{where}['true_path']", path, (None, k, 3))
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
    _check_path(path)
    records = _check_records("scenes", scenes, _SCENE_KEYS, "tabletop scene records")
    parsed = [_scene(i, s) for i, s in enumerate(records)]
    n = len(parsed)
    cols = min(4, n)
    fig = Figure(figsize=(3.6 * cols, 3.5 * math.ceil(n / cols) + 0.9), layout="constrained")
    for ax, scene in zip(_grid(fig, n, cols), parsed, strict=True):
        _draw_scene(ax, scene)
    monolithic = any(s["monolithic_final"] is not None for s in parsed)
    handles = _tabletop_legend(monolithic)
    fig.legend(handles=handles, loc="outside lower center", ncols=min(len(handles), 8), fontsize=7)
    return _save(fig, path, title, f"Chained push predictions, top view ({n} scenes)")


# --- side-view picks and places --------------------------------------------------------------


def _case(i: int, case: Mapping[str, Any]) -> dict[str, Any]:
    """Case `i` with its arrays checked against the number of objects K of ``sizes``."""
    where = f"cases[{i}]"
    skill = case["skill"]
    if skill not in _SKILLS:
        raise InputError(f"{where}['skill'] must be one of {list(_SKILLS)}, got {skill!r}.")
    sizes = _array(f"{where}['sizes']", case["sizes"], (None, 2))
    if np.any(sizes <= 0):
        raise InputError(f"{where}['sizes'] must be > 0 (box width and height in m).")
    k = len(sizes)
    target = check_count(f"{where}['target']", case["target"], minimum=0)
    if target >= k:
        raise InputError(
            f"{where}['target'] is {target} but the case has {k} object(s); give a 0-based "
            f"index below {k}."
        )
    sd = _array(f"{where}['pred_sd']", case["pred_sd"], (3,))
    if np.any(sd < 0):
        raise InputError(f"{where}['pred_sd'] must be >= 0 (standard deviations), got {sd}.")
    return {
        "skill": str(skill),
        "success": _flag(f"{where}['success']", case["success"]),
        "label": str(case["label"]),
        "sizes": sizes,
        "start": _array(f"{where}['start']", case["start"], (k, 3)),
        "true_final": _array(f"{where}['true_final']", case["true_final"], (k, 3)),
        "target": target,
        "pred_final": _array(f"{where}['pred_final']", case["pred_final"], (3,)),
        "pred_sd": sd,
        "tcp_commanded": _array(f"{where}['tcp_commanded']", case["tcp_commanded"], (None, 2)),
        "tcp_actual": _array(f"{where}['tcp_actual']", case["tcp_actual"], (None, 2)),
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
    _check_path(path)
    records = _check_records("cases", cases, _CASE_KEYS, "pick/place case records")
    parsed = [_case(i, c) for i, c in enumerate(records)]
    n = len(parsed)
    cols = min(5, n)
    fig = Figure(figsize=(3.0 * cols, 3.0 * math.ceil(n / cols) + 0.9), layout="constrained")
    for ax, case in zip(_grid(fig, n, cols), parsed, strict=True):
        _draw_case(ax, case)
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
    return _save(fig, path, title, default)


# --- errors along a chain --------------------------------------------------------------------


def _chain_rows(rows: Any) -> list[dict[str, Any]]:
    records = _check_records("rows", rows, _CHAIN_KEYS, "chain-error rows")
    out = []
    for i, r in enumerate(records):
        where = f"rows[{i}]"
        n = check_count(f"{where}['n_objects']", r["n_objects"])
        place = check_count(f"{where}['object']", r["object"])
        if place > n:
            raise InputError(
                f"{where}['object'] is {place} but the chain has {n} object(s) "
                "(n_objects); objects are numbered 1..n_objects from the hand."
            )
        coverage = _number(f"{where}['coverage90']", r["coverage90"])
        if not 0 <= coverage <= 1:
            raise InputError(
                f"{where}['coverage90'] must be a fraction in [0, 1] (not percent), got {coverage}."
            )
        error = _number(f"{where}['error_cm']", r["error_cm"])
        if error < 0:
            raise InputError(f"{where}['error_cm'] must be >= 0 (a distance in cm), got {error}.")
        out.append(
            {
                "n_objects": n,
                "object": place,
                "error_cm": error,
                "error_ci": _half_width(f"{where}['error_ci']", r["error_ci"]),
                "coverage90": coverage,
                "coverage_ci": _half_width(f"{where}['coverage_ci']", r["coverage_ci"]),
            }
        )
    _unique("rows", [(r["n_objects"], r["object"]) for r in out], "(n_objects, object)")
    return out


def _chain_colours(lengths: Sequence[int]) -> dict[int, Any]:
    """A colour per chain length, light to dark along the viridis map."""
    from matplotlib import colormaps

    cmap = colormaps["viridis"]
    if len(lengths) == 1:
        return {lengths[0]: cmap(0.35)}
    return {n: cmap(0.85 * j / (len(lengths) - 1)) for j, n in enumerate(lengths)}


def plot_chain_errors(
    rows: Sequence[Mapping[str, Any]],
    path: str | os.PathLike[str],
    *,
    title: str | None = None,
) -> str:
    """Error and coverage of chained predictions against each object's place in the chain.

    Two panels. Left: the mean position error (cm) of each object against its place in the
    chain (1 is the object the hand pushes), one line per chain length with 95 % error bars.
    Right: the 90 % interval coverage of each object, same layout, with the nominal 90 % as
    a dashed line. Lines of different chain lengths are set slightly apart so their bars do
    not hide one another.

    Args:
        rows: One per (chain length, object) with keys ``n_objects`` (int, the chain
            length), ``object`` (int, 1-based place in the chain), ``error_cm`` and
            ``error_ci`` (the 95 % half-width, cm), ``coverage90`` and ``coverage_ci``
            (fractions in [0, 1]).
        path: Image file to write (format from the suffix), atomically.
        title: Figure title.

    Returns:
        `path`, as a string.

    Raises:
        InputError: For no rows, a row lacking a key, a count that is not a positive
            integer, an object placed beyond its chain, a coverage outside [0, 1], a
            negative or non-finite value, or two rows of the same chain length and object.
    """
    _check_path(path)
    parsed = _chain_rows(rows)
    lengths = sorted({r["n_objects"] for r in parsed})
    colours = _chain_colours(lengths)
    fig = Figure(figsize=(9.0, 3.9), layout="constrained")
    err_ax, cov_ax = fig.subplots(1, 2)
    offsets = 0.06 * (np.arange(len(lengths)) - (len(lengths) - 1) / 2)
    for n, dx in zip(lengths, offsets, strict=True):
        mine = sorted((r for r in parsed if r["n_objects"] == n), key=lambda r: r["object"])
        x = np.array([r["object"] for r in mine], dtype=float) + dx
        style = {"color": colours[n], "marker": "o", "ms": 4, "capsize": 3, "lw": 1.5}
        label = f"{n} object{'s' if n > 1 else ''}"
        for ax, value, ci in (
            (err_ax, "error_cm", "error_ci"),
            (cov_ax, "coverage90", "coverage_ci"),
        ):
            y, yerr = [r[value] for r in mine], [r[ci] for r in mine]
            ax.errorbar(x, y, yerr=yerr, label=label, **style)
    nominal = cov_ax.axhline(0.9, color="k", ls="--", lw=1, label="nominal 90 %")
    cov_ax.set_ylim(0, 1.05)
    cov_ax.yaxis.set_major_formatter(PercentFormatter(xmax=1.0))
    cov_ax.set_ylabel("90 % interval coverage")
    err_ax.set_ylim(bottom=0)
    err_ax.set_ylabel("mean position error (cm)")
    for ax in (err_ax, cov_ax):
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))
        ax.set_xlim(0.5, max(lengths) + 0.5)
        ax.set_xlabel("place in the chain (1 = pushed by the hand)")
        ax.grid(alpha=0.3)
    err_ax.set_title("position error (bars: 95 % interval)", fontsize=9)
    cov_ax.set_title("coverage of the 90 % interval (bars: 95 % interval)", fontsize=9)
    handles = [*cov_ax.containers, nominal]
    fig.legend(handles=handles, loc="outside lower center", ncols=min(len(handles), 6), fontsize=8)
    return _save(fig, path, title, "Chained push predictions along the chain")


# --- modular against monolithic --------------------------------------------------------------


def _bar_rows(rows: Any) -> list[dict[str, Any]]:
    records = _check_records("rows", rows, _BAR_KEYS, "model-error rows")
    out = []
    for i, r in enumerate(records):
        where = f"rows[{i}]"
        axis = r["axis"]
        if axis not in _AXES:
            raise InputError(f"{where}['axis'] must be one of {list(_AXES)}, got {axis!r}.")
        error = _number(f"{where}['error_cm']", r["error_cm"])
        if error < 0:
            raise InputError(f"{where}['error_cm'] must be >= 0 (an absolute error), got {error}.")
        out.append(
            {
                "model": _text(f"{where}['model']", r["model"]),
                "object": check_count(f"{where}['object']", r["object"]),
                "axis": str(axis),
                "error_cm": error,
                "error_ci": _half_width(f"{where}['error_ci']", r["error_ci"]),
            }
        )
    _unique("rows", [(r["model"], r["object"], r["axis"]) for r in out], "(model, object, axis)")
    return out


def _thesis_values(
    thesis: Any, bars: Mapping[tuple[str, int, str], Any]
) -> dict[tuple[str, int, str], float]:
    """The thesis's values keyed like `bars`; every key must name a drawn bar."""
    if not isinstance(thesis, Mapping):
        raise InputError(
            f"thesis must map (model, object, axis) to a value in cm, got {type(thesis).__name__}."
        )
    out = {}
    for key, value in thesis.items():
        name = f"thesis[{key!r}]"
        if not (isinstance(key, tuple) and len(key) == 3):
            raise InputError(f"{name}: keys must be (model, object, axis) tuples.")
        norm = (key[0], check_count(f"{name} object", key[1]), key[2])
        if norm not in bars:
            raise InputError(
                f"{name} matches no bar; the rows give (model, object, axis) in {sorted(bars)}."
            )
        check_positive(name, value, allow_zero=True)
        out[norm] = float(value)
    return out


def _model_colours(models: Sequence[str]) -> dict[str, str]:
    """The modular and monolithic models keep their colours; the others take free ones."""
    free = [c for c in _CYCLE if c not in {_MODEL_COLOURS.get(m) for m in models}]
    out = {}
    for m in models:
        out[m] = _MODEL_COLOURS[m] if m in _MODEL_COLOURS else free.pop(0) if free else "0.5"
    return out


def plot_modular_vs_monolithic(
    rows: Sequence[Mapping[str, Any]],
    path: str | os.PathLike[str],
    *,
    thesis: Mapping[tuple[str, int, str], float] | None = None,
    title: str | None = None,
) -> str:
    """Mean absolute error per object and axis, one bar per model, and save the figure.

    Groups are the objects (o1 is the one the hand pushes) and the axis of the error,
    ``along`` or ``off`` the push; each model has a bar in each group with its 95 % error
    bar and value written above. The modular model is blue and the monolithic orange, as in
    `plot_tabletop_predictions`. Values reported in the thesis are black ticks across the
    matching bars.

    Args:
        rows: One per (model, object, axis) with keys ``model`` (str), ``object`` (int,
            1-based), ``axis`` (``"along"`` or ``"off"``), ``error_cm`` and ``error_ci``
            (the 95 % half-width, cm).
        path: Image file to write (format from the suffix), atomically.
        thesis: Optional ``{(model, object, axis): value_cm}``, e.g.
            ``{("modular", 1, "along"): 1.89, ("monolithic", 1, "along"): 4.83}``.
        title: Figure title.

    Returns:
        `path`, as a string.

    Raises:
        InputError: For no rows, a row lacking a key, an unknown axis, an object that is
            not a positive integer, a negative or non-finite value, two rows of the same
            model, object and axis, or a thesis entry that matches no bar.
    """
    _check_path(path)
    parsed = _bar_rows(rows)
    bars = {(r["model"], r["object"], r["axis"]): r for r in parsed}
    marks = {} if thesis is None else _thesis_values(thesis, bars)
    models = list(dict.fromkeys(r["model"] for r in parsed))
    groups = sorted(
        {(r["object"], r["axis"]) for r in parsed}, key=lambda g: (g[0], _AXES.index(g[1]))
    )
    colours = _model_colours(models)
    width = 0.8 / len(models)
    wide = 1.4 + 1.25 * len(groups) * max(1.0, len(models) / 2)
    fig = Figure(figsize=(max(5.0, wide), 4.0), layout="constrained")
    ax = fig.subplots()
    top = 0.0
    handles: list[Any] = []
    for m, model in enumerate(models):
        xs, heights, cis = [], [], []
        for g, (obj, axis) in enumerate(groups):
            row = bars.get((model, obj, axis))
            if row is not None:
                xs.append(g + (m - (len(models) - 1) / 2) * width)
                heights.append(row["error_cm"])
                cis.append(row["error_ci"])
        drawn = ax.bar(xs, heights, width * 0.92, yerr=cis, color=colours[model], capsize=3)
        drawn.set_label(model)
        handles.append(drawn)
        for x, h, ci in zip(xs, heights, cis, strict=True):
            ax.annotate(
                f"{h:.2f}",
                (x, h + ci),
                xytext=(0, 2),
                textcoords="offset points",
                ha="center",
                va="bottom",
                fontsize=6,
            )
            top = max(top, h + ci)
    if marks:
        centres = np.array(
            [
                groups.index((obj, axis)) + (models.index(model) - (len(models) - 1) / 2) * width
                for model, obj, axis in marks
            ]
        )
        values = np.array(list(marks.values()))
        ticks = ax.hlines(
            values,
            centres - 0.45 * width,
            centres + 0.45 * width,
            color="k",
            lw=2.5,
            zorder=5,
            label="thesis",
        )
        handles.append(ticks)
        top = max(top, float(values.max()))
    ax.set_xticks(
        range(len(groups)), [f"o{obj}\n{axis} the push" for obj, axis in groups], fontsize=8
    )
    ax.set_xlim(-0.6, len(groups) - 0.4)
    ax.set_ylim(0, 1.15 * top if top > 0 else 1.0)
    ax.set_ylabel("mean absolute error (cm)")
    ax.grid(axis="y", alpha=0.3)
    ax.set_axisbelow(True)
    fig.legend(handles=handles, loc="outside lower center", ncols=min(len(handles), 6), fontsize=8)
    return _save(fig, path, title, "Push prediction error, 95 % interval")


# --- learning curves -------------------------------------------------------------------------


def _curve_rows(rows: Any) -> list[dict[str, Any]]:
    records = _check_records("rows", rows, _CURVE_KEYS, "learning-curve rows")
    out = [
        {
            "panel": _text(f"rows[{i}]['panel']", r["panel"]),
            "series": _text(f"rows[{i}]['series']", r["series"]),
            "train_size": check_count(f"rows[{i}]['train_size']", r["train_size"]),
            "value": _number(f"rows[{i}]['value']", r["value"]),
            "ci": _half_width(f"rows[{i}]['ci']", r["ci"]),
        }
        for i, r in enumerate(records)
    ]
    _unique(
        "rows", [(r["panel"], r["series"], r["train_size"]) for r in out], "(panel, series, size)"
    )
    return out


def _unit(panel: str) -> str:
    """The y label of a panel: "error" with the unit the panel name ends in, if any."""
    found = re.search(r"\(([^()]+)\)\s*$", panel)
    return f"error ({found.group(1)})" if found else "error"


def plot_learning_curves(
    rows: Sequence[Mapping[str, Any]],
    path: str | os.PathLike[str],
    *,
    title: str | None = None,
) -> str:
    """Error against training-set size, one panel per quantity, and save the figure.

    Each panel (e.g. ``"push o1 along (cm)"``) has a line per series with its 95 % band; a
    series keeps its colour in every panel. The x axis is logarithmic when a panel's sizes
    span more than a factor of 4, its ticks at the sizes measured. Panels come three to a
    row; the y label takes the unit the panel name ends in, in parentheses.

    Args:
        rows: One per (panel, series, training-set size) with keys ``panel`` and
            ``series`` (str), ``train_size`` (int), ``value`` and ``ci`` (its 95 %
            half-width, in the panel's unit).
        path: Image file to write (format from the suffix), atomically.
        title: Figure title.

    Returns:
        `path`, as a string.

    Raises:
        InputError: For no rows, a row lacking a key, a non-string panel or series, a size
            that is not a positive integer, a non-finite value, a negative half-width or two
            rows of the same panel, series and size.
    """
    _check_path(path)
    parsed = _curve_rows(rows)
    panels = list(dict.fromkeys(r["panel"] for r in parsed))
    series = list(dict.fromkeys(r["series"] for r in parsed))
    colours = {s: _CYCLE[j % len(_CYCLE)] for j, s in enumerate(series)}
    n = len(panels)
    cols = min(3, n)
    fig = Figure(figsize=(4.0 * cols, 3.3 * math.ceil(n / cols) + 0.7), layout="constrained")
    for ax, panel in zip(_grid(fig, n, cols), panels, strict=True):
        mine = [r for r in parsed if r["panel"] == panel]
        for s in series:
            pts = sorted((r for r in mine if r["series"] == s), key=lambda r: r["train_size"])
            if not pts:
                continue
            x = np.array([r["train_size"] for r in pts], dtype=float)
            y = np.array([r["value"] for r in pts])
            ci = np.array([r["ci"] for r in pts])
            ax.fill_between(x, y - ci, y + ci, color=colours[s], alpha=0.18, lw=0)
            ax.plot(x, y, color=colours[s], marker="o", ms=4, lw=1.5, label=s)
            if len(x) == 1:  # a band of one point does not show; draw its interval as a bar
                ax.errorbar(x, y, yerr=ci, color=colours[s], capsize=3, lw=1.5)
        sizes = sorted({r["train_size"] for r in mine})
        if sizes[-1] > 4 * sizes[0]:
            ax.set_xscale("log")
            ax.xaxis.set_minor_locator(NullLocator())
        ax.set_xticks(sizes, [str(s) for s in sizes], fontsize=7)
        ax.tick_params(axis="y", labelsize=7)
        ax.set_xlabel("training-set size (samples)", fontsize=8)
        ax.set_ylabel(_unit(panel), fontsize=8)
        ax.set_title(panel, fontsize=9)
        ax.grid(alpha=0.3)
    handles: list[Any] = [
        Line2D([], [], color=colours[s], marker="o", ms=4, lw=1.5, label=s) for s in series
    ]
    handles.append(Patch(fc="0.5", alpha=0.3, label="95 % interval"))
    fig.legend(handles=handles, loc="outside lower center", ncols=min(len(handles), 5), fontsize=8)
    return _save(fig, path, title, "Learning curves, 95 % intervals")
