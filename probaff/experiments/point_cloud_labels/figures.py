"""Figures of chapter 2's affordance labels: segments, label probabilities, Algorithm 1, views.

Every figure is a pure function of plain arrays (numpy arrays or nested lists loaded back from
JSON). Points and centroids are in the robot frame (x forward, y left, z up; metres). Label
columns follow `probaff.perception.labels.LABELS`. Probabilities, purities, completenesses and
accuracies are fractions in [0, 1]; entropies are the thesis's ``-sum_l p_l ln p_l`` in nats.

Clouds are drawn from at most ``max_points`` points (default 5 000, our choice: a 320 x 240
view returns about 75 000, and a scatter of every one is slow to draw and no clearer), taken
without replacement from a generator seeded with 0 (an even stride would alias with the image
rows), so the same cloud always gives the same picture.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from probaff._checks import (
    as_bool_array,
    check_count,
    check_finite,
    check_probability,
    check_shape,
)
from probaff._io import atomic_save_figure
from probaff.errors import InputError
from probaff.experiments.point_cloud_labels.config import PointCloudStudyConfig
from probaff.experiments.point_cloud_labels.scans import read_arrays, scan_task
from probaff.perception.labels import LABELS, LabelCVResult, label_index
from probaff.perception.refinement import SplitTree

__all__ = [
    "plot_entropy_tree",
    "plot_label_probabilities",
    "plot_merge_views",
    "plot_reliability",
    "plot_scanned_scene",
    "plot_segment_cloud",
    "study_figures",
]

_UNASSIGNED = "0.8"  # grey of points in no segment


def _cloud(
    points: object, point_segments: object, max_points: int
) -> tuple[np.ndarray, np.ndarray]:
    """Checked (n, 3) points and (n,) segment rows, strided to at most `max_points`."""
    limit = check_count("max_points", max_points)
    check_shape("points", points, (None, 3))
    pts = np.asarray(points, dtype=np.float64)
    if pts.shape[0] == 0:
        raise InputError("points is empty; give the (N, 3) cloud of at least one point.")
    check_finite("points", pts)
    check_shape("point_segments", point_segments, (pts.shape[0],))
    seg = np.asarray(point_segments)
    check_finite("point_segments", seg)
    if np.any(seg != np.round(seg)) or np.any(seg < -1):
        raise InputError("point_segments must hold segment rows >= 0, or -1 for no segment.")
    if pts.shape[0] <= limit:
        return pts, seg.astype(np.int64)
    keep = np.sort(np.random.default_rng(0).choice(pts.shape[0], size=limit, replace=False))
    return pts[keep], seg.astype(np.int64)[keep]


def _cloud_probabilities(
    points: object, point_segments: object, probabilities: object, max_points: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """`_cloud`'s points and rows, and the (S, 6) probabilities checked against those rows."""
    pts, seg = _cloud(points, point_segments, max_points)
    check_shape("probabilities", probabilities, (None, len(LABELS)))
    prob = np.asarray(probabilities, dtype=np.float64)
    check_probability("probabilities", prob)
    if seg.size and seg.max() >= prob.shape[0]:
        raise InputError(
            f"point_segments refers to row {int(seg.max())} but probabilities has "
            f"{prob.shape[0]} rows; give one row per segment."
        )
    return pts, seg, prob


def _save(fig: Figure, path: str | os.PathLike[str]) -> str:
    atomic_save_figure(fig, path, dpi=80)
    return os.fspath(path)


def _segment_colours(seg: np.ndarray) -> np.ndarray:
    """(n, 4) RGBA colour of each point by its segment row `seg` (n,), grey for -1."""
    from matplotlib import colormaps

    colour = colormaps["tab20"](seg % 20)
    colour[seg < 0] = (0.8, 0.8, 0.8, 1.0)
    return colour


def _scatter_view(ax: Axes, pts: np.ndarray, colour: np.ndarray, axes: tuple[int, int]) -> None:
    names = "xyz"
    ax.scatter(pts[:, axes[0]], pts[:, axes[1]], c=colour, s=0.5, linewidths=0)
    ax.set_xlabel(f"{names[axes[0]]} (m)")
    ax.set_ylabel(f"{names[axes[1]]} (m)")
    ax.set_aspect("equal", adjustable="datalim")


def plot_segment_cloud(
    points: object,
    point_segments: object,
    path: str | os.PathLike[str],
    *,
    max_points: int = 5_000,
) -> str:
    """The cloud coloured by segment: a top view (x, y) and a side view (x, z).

    Args:
        points: (N, 3) points (robot frame, m).
        point_segments: (N,) segment row of each point, -1 for a point in no segment (grey).
        path: Output image.
        max_points: Most points drawn (a positive integer).

    Returns:
        `path` as a string.

    Raises:
        InputError: For an empty cloud, mismatched shapes, non-finite values or bad rows.
    """
    pts, seg = _cloud(points, point_segments, max_points)
    colour = _segment_colours(seg)
    fig = Figure(figsize=(11, 4.5))
    top, side = fig.subplots(1, 2)
    _scatter_view(top, pts, colour, (0, 1))
    top.set_title("top view")
    _scatter_view(side, pts, colour, (0, 2))
    side.set_title("side view")
    n_seg = int(seg.max()) + 1 if seg.size and seg.max() >= 0 else 0
    fig.suptitle(f"segments by region growing ({n_seg} segments; grey: none)")
    return _save(fig, path)


def _camera_angles(pts: np.ndarray, eye: np.ndarray) -> np.ndarray:
    """(n, 2) azimuth (right positive) and elevation of `pts` (n, 3) seen from `eye` (degrees)."""
    d = pts - eye
    ground = np.hypot(d[:, 0], d[:, 1])
    return np.degrees(np.stack([-np.arctan2(d[:, 1], d[:, 0]), np.arctan2(d[:, 2], ground)], 1))


def plot_scanned_scene(
    points: object,
    point_segments: object,
    probabilities: object,
    path: str | os.PathLike[str],
    *,
    labels: tuple[str, ...] = ("push_forward", "liftable", "graspable"),
    viewpoint: object | None = None,
    max_points: int = 20_000,
    title: str | None = None,
) -> str:
    """One scanned scene, two panels a row: its segments, then each label's probability.

    With a `viewpoint` each panel shows the points as the camera saw them: azimuth (right
    positive) against elevation from the viewpoint, far points drawn first so that near ones
    cover them. Without one it shows the top view (x, y).

    Args:
        points: (N, 3) points (robot frame, m).
        point_segments: (N,) segment row of each point, -1 for a point in no segment (grey).
        probabilities: (S, 6) predicted probability of each label per segment row.
        path: Output image.
        labels: The labels drawn after the segments (names in `LABELS`, at least one).
        viewpoint: (3,) the camera centre (robot frame, m), or None for the top view.
        max_points: Most points drawn (a positive integer).
        title: The figure's title; None names the segment count.

    Returns:
        `path` as a string.

    Raises:
        InputError: For an empty cloud, mismatched shapes, probabilities outside [0, 1], a
            segment row beyond the probabilities' rows, no or unknown `labels`, or a bad
            `viewpoint`.
    """
    pts, seg, prob = _cloud_probabilities(points, point_segments, probabilities, max_points)
    if isinstance(labels, str) or not labels:
        raise InputError(f"labels must be a non-empty tuple of names in {LABELS}, got {labels!r}.")
    columns = [label_index(name) for name in labels]
    if viewpoint is None:
        xy, names, view = pts[:, :2], ("x (m)", "y (m)"), "top view"
    else:
        check_shape("viewpoint", viewpoint, (3,))
        eye = np.asarray(viewpoint, dtype=np.float64)
        check_finite("viewpoint", eye)
        order = np.argsort(-np.linalg.norm(pts - eye, axis=1))
        pts, seg = pts[order], seg[order]
        xy = _camera_angles(pts, eye)
        names, view = ("azimuth, right positive (deg)", "elevation (deg)"), "camera view"
    from matplotlib import colormaps

    colour = _segment_colours(seg)
    shades = colormaps["viridis"].with_extremes(bad=_UNASSIGNED)
    n_seg = int(prob.shape[0])
    lo, hi = xy.min(axis=0), xy.max(axis=0)
    pad = 0.03 * np.maximum(hi - lo, 1e-6)
    # Two panels a row, each 5 inches wide and as tall as the data's aspect asks.
    aspect = float(np.clip((hi[1] - lo[1] + 2 * pad[1]) / (hi[0] - lo[0] + 2 * pad[0]), 0.3, 2.0))
    n_rows = (len(columns) + 2) // 2
    fig = Figure(figsize=(11.5, n_rows * (5.0 * aspect + 0.9) + 0.6), layout="constrained")
    grid = fig.subplots(n_rows, 2, squeeze=False)
    axes = grid.ravel()[: 1 + len(columns)]
    for spare in grid.ravel()[1 + len(columns) :]:
        spare.set_axis_off()
    image = None
    for i, ax in enumerate(axes):
        if i == 0:
            ax.scatter(xy[:, 0], xy[:, 1], c=colour, s=1.0, linewidths=0)
            ax.set_title(f"{n_seg} segments (grey: none)")
        else:
            k = columns[i - 1]
            shade = np.full(seg.shape, np.nan)  # grey where a point is in no segment
            shade[seg >= 0] = prob[seg[seg >= 0], k]
            image = ax.scatter(
                xy[:, 0],
                xy[:, 1],
                c=shade,
                cmap=shades,
                vmin=0.0,
                vmax=1.0,
                s=1.0,
                linewidths=0,
                plotnonfinite=True,
            )
            ax.set_title(f"p({labels[i - 1]})")
        ax.set_xlabel(names[0])
        ax.set_ylabel(names[1])
        ax.set_xlim(lo[0] - pad[0], hi[0] + pad[0])
        ax.set_ylim(lo[1] - pad[1], hi[1] + pad[1])
        ax.set_aspect("equal", adjustable="box")
    if image is not None:
        fig.colorbar(image, ax=list(axes), label="predicted probability", shrink=0.6)
    fig.suptitle(title or f"scanned scene: {n_seg} segments and predicted labels, {view}")
    return _save(fig, path)


def plot_label_probabilities(
    points: object,
    point_segments: object,
    probabilities: object,
    path: str | os.PathLike[str],
    *,
    max_points: int = 5_000,
) -> str:
    """Each label's predicted probability on the cloud (top view), one panel per label.

    Args:
        points: (N, 3) points (robot frame, m).
        point_segments: (N,) segment row of each point, -1 for a point in no segment (grey).
        probabilities: (S, 6) predicted probability of each label per segment row.
        path: Output image.
        max_points: Most points drawn (a positive integer).

    Returns:
        `path` as a string.

    Raises:
        InputError: For an empty cloud, mismatched shapes, probabilities outside [0, 1], or a
            segment row beyond the probabilities' rows.
    """
    pts, seg, prob = _cloud_probabilities(points, point_segments, probabilities, max_points)
    on = seg >= 0
    fig = Figure(figsize=(13, 7.5))
    axes = fig.subplots(2, 3, gridspec_kw={"hspace": 0.35, "wspace": 0.3}).ravel()
    image = None
    for k, (ax, name) in enumerate(zip(axes, LABELS, strict=True)):
        ax.scatter(pts[~on, 0], pts[~on, 1], c=_UNASSIGNED, s=0.5, linewidths=0)
        image = ax.scatter(
            pts[on, 0],
            pts[on, 1],
            c=prob[seg[on], k],
            cmap="viridis",
            vmin=0.0,
            vmax=1.0,
            s=0.5,
            linewidths=0,
        )
        ax.set_title(name)
        ax.set_xlabel("x (m)")
        ax.set_ylabel("y (m)")
        ax.set_aspect("equal", adjustable="datalim")
    if image is not None:
        fig.colorbar(image, ax=list(axes), label="predicted probability", shrink=0.8)
    fig.suptitle("label probabilities per segment (out-of-fold), top view")
    return _save(fig, path)


def plot_entropy_tree(
    depth: object,
    entropy: object,
    parent: object,
    path: str | os.PathLike[str],
    *,
    leaves: object | None = None,
) -> str:
    """Algorithm 1's split tree: each node's entropy against its depth, linked to its parent.

    Args:
        depth: (M,) depth of each node (0 for the root).
        entropy: (M,) entropy of each node's centroid (nats).
        parent: (M,) parent node of each node, -1 for the root; parents come first.
        path: Output image.
        leaves: (M,) bool, which nodes are leaves (objects, drawn filled); None marks nodes
            with no child.

    Returns:
        `path` as a string.

    Raises:
        InputError: For no nodes, mismatched shapes, non-finite values, or a parent that is
            not an earlier node one level up.
    """
    check_shape("depth", depth, (None,))
    d = np.asarray(depth)
    if d.size == 0:
        raise InputError("depth is empty; give the tree's nodes (at least the root).")
    check_finite("depth", d)
    check_shape("entropy", entropy, (d.size,))
    h = np.asarray(entropy, dtype=np.float64)
    check_finite("entropy", h)
    check_shape("parent", parent, (d.size,))
    par = np.asarray(parent)
    check_finite("parent", par)
    par = par.astype(np.int64)
    d = d.astype(np.int64)
    index = np.arange(d.size)
    child = par >= 0
    if (
        par[0] != -1
        or np.any(par[1:] < 0)
        or np.any(par >= index)
        or np.any(d[child] != d[par[child]] + 1)
    ):
        raise InputError(
            "parent must be -1 for the root (node 0) and an earlier node one level up for "
            "every other node."
        )
    if leaves is None:
        leaf = ~np.isin(index, par[child])
    else:
        leaf = as_bool_array("leaves", leaves)
        check_shape("leaves", leaf, (d.size,))
    fig = Figure(figsize=(7, 4.5))
    ax = fig.subplots()
    # Spread the nodes of each depth over a small horizontal offset so siblings separate.
    offset = np.zeros(d.size)
    for level in np.unique(d):
        at = np.flatnonzero(d == level)
        if len(at) > 1:
            offset[at] = np.linspace(-0.3, 0.3, len(at))
    x = d + offset
    for i in index[child]:
        ax.plot([x[par[i]], x[i]], [h[par[i]], h[i]], color="0.6", lw=0.8)
    ax.scatter(x[~leaf], h[~leaf], facecolors="none", edgecolors="C0", label="split set")
    ax.scatter(x[leaf], h[leaf], color="C1", label="leaf (object)")
    ax.set_xlabel("depth")
    ax.set_ylabel("entropy of the set centroid (nats)")
    ax.set_title("Algorithm 1: split tree")
    ax.legend(loc="best")
    return _save(fig, path)


def plot_merge_views(
    n_views: object,
    purity: object,
    completeness: object,
    accuracy: object,
    path: str | os.PathLike[str],
) -> str:
    """Purity, completeness and label accuracy of the merged segments against the views.

    Args:
        n_views: (K,) number of merged views of each point, positive integers.
        purity: (K,) object purity of the merged segments.
        completeness: (K,) object completeness.
        accuracy: (K,) label accuracy of the merged label vectors.
        path: Output image.

    Returns:
        `path` as a string.

    Raises:
        InputError: For empty or mismatched inputs, non-integer view counts, or values outside
            [0, 1].
    """
    check_shape("n_views", n_views, (None,))
    v = np.asarray(n_views)
    if v.size == 0:
        raise InputError("n_views is empty; give at least one view count.")
    check_finite("n_views", v)
    if np.any(v < 1) or np.any(v != np.round(v)):
        raise InputError("n_views must hold positive integers (views merged).")
    fig = Figure(figsize=(6, 4))
    ax = fig.subplots()
    for name, values, marker in (
        ("purity", purity, "o"),
        ("completeness", completeness, "s"),
        ("label accuracy", accuracy, "^"),
    ):
        check_shape(name, values, (v.size,))
        arr = np.asarray(values, dtype=np.float64)
        check_probability(name, arr)
        ax.plot(v, arr, marker=marker, label=name)
    ax.set_xticks(np.unique(v))
    ax.set_xlabel("views merged")
    ax.set_ylabel("fraction")
    ax.set_ylim(0.0, 1.02)
    ax.legend(loc="lower right")
    ax.set_title("multi-view merge")
    return _save(fig, path)


def plot_reliability(
    centres: object,
    frequency: object,
    counts: object,
    path: str | os.PathLike[str],
) -> str:
    """One reliability diagram per label: observed frequency against predicted probability.

    Args:
        centres: (B,) bin centres in [0, 1].
        frequency: (6, B) observed share of positives per bin and label, NaN in an empty bin.
        counts: (6, B) predictions per bin and label.
        path: Output image.

    Returns:
        `path` as a string.

    Raises:
        InputError: For empty or mismatched inputs, centres or frequencies outside [0, 1], or
            negative counts.
    """
    check_shape("centres", centres, (None,))
    c = np.asarray(centres, dtype=np.float64)
    if c.size == 0:
        raise InputError("centres is empty; give the bins' centres.")
    check_probability("centres", c)
    check_shape("frequency", frequency, (len(LABELS), c.size))
    f = np.asarray(frequency, dtype=np.float64)
    seen = np.isfinite(f)
    check_probability("frequency", f[seen])
    check_shape("counts", counts, (len(LABELS), c.size))
    n = np.asarray(counts, dtype=np.float64)
    check_finite("counts", n)
    if np.any(n < 0):
        raise InputError("counts must be >= 0 (predictions per bin).")
    fig = Figure(figsize=(12, 7))
    axes = fig.subplots(2, 3, gridspec_kw={"hspace": 0.4, "wspace": 0.3}).ravel()
    for k, (ax, name) in enumerate(zip(axes, LABELS, strict=True)):
        ax.plot([0, 1], [0, 1], color="0.6", ls="--", lw=0.8)
        ok = seen[k]
        ax.plot(c[ok], f[k, ok], color="C0", lw=1.0)
        size = 200.0 * n[k, ok] / max(float(n[k].max()), 1.0)
        ax.scatter(c[ok], f[k, ok], s=np.maximum(size, 8.0), color="C0", zorder=3)
        ax.set_xlim(0, 1)
        ax.set_ylim(0, 1)
        ax.set_title(name)
        ax.set_xlabel("predicted probability")
        ax.set_ylabel("observed frequency")
    fig.suptitle("reliability of the out-of-fold probabilities (marker area: predictions per bin)")
    return _save(fig, path)


def study_figures(
    config: PointCloudStudyConfig,
    out: Path,
    npz: Path,
    first: np.ndarray,
    cv: LabelCVResult,
    tree: SplitTree,
    merge: list[dict[str, Any]],
) -> list[str]:
    """Every figure of a study run.

    Args:
        config: The study's settings.
        out: Output folder.
        npz: The first scene's per-point arrays (`scan_task`'s; rescanned if missing).
        first: (S0, 6) the first scene's out-of-fold label probabilities.
        cv: The headline cross-validation (its reliability curves).
        tree: The first scene's Algorithm 1 tree at the first of ``min_gains``.
        merge: The merge table's rows.

    Returns:
        The written paths.
    """
    if not npz.is_file():  # the record survived but its arrays did not: rescan them
        scan_task(config.seed, 0, config.perception, str(npz))
    arrays = read_arrays(npz, ("points", "point_segments"))
    points, rows = arrays["points"], arrays["point_segments"]
    files = [
        plot_segment_cloud(points, rows, out / "segments.png"),
        plot_label_probabilities(points, rows, first, out / "label_probabilities.png"),
        plot_entropy_tree(
            [n.depth for n in tree.nodes],
            [n.entropy for n in tree.nodes],
            [-1 if n.parent is None else n.parent for n in tree.nodes],
            out / "entropy_tree.png",
        ),
        plot_reliability(
            cv.reliability[0].centres,
            [r.frequency for r in cv.reliability],
            [r.counts for r in cv.reliability],
            out / "reliability.png",
        ),
    ]
    done = [r for r in merge if r["scenes"] and r["proximity"] == config.merge_proximities[0]]
    if done:
        files.append(
            plot_merge_views(
                [r["views"] for r in done],
                [r["purity"] for r in done],
                [r["completeness"] for r in done],
                [r["accuracy"] for r in done],
                out / "merge_views.png",
            )
        )
    return files
