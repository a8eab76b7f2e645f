"""A figure of one scanned scene's labels: the ground truth against two models' decisions.

`plot_labels_against_truth` draws the cloud from above once per (row, label): the first row
the ground truth of each segment, then one row per model its decision ``p >= 0.5``. Points of
a positive segment are dark, of a negative segment light, of no segment grey; a wrong
decision is drawn in red, so the errors stand out against the truth above. Robot frame (x
forward, y left, z up), metres; at most ``max_points`` points are drawn (seeded draw, as the
other figures of the study).
"""

from __future__ import annotations

import os
from collections.abc import Mapping

import numpy as np
from matplotlib.figure import Figure

from probaff._checks import (
    as_bool_array,
    check_count,
    check_finite,
    check_probability,
    check_shape,
)
from probaff._io import atomic_save_figure
from probaff.affordance_labels import LABELS
from probaff.errors import InputError

__all__ = ["plot_labels_against_truth"]

_COLOURS = {"none": "0.85", "negative": "#9ecae1", "positive": "#08306b", "wrong": "#e31a1c"}


def plot_labels_against_truth(
    points: np.ndarray,
    point_segments: np.ndarray,
    truth: np.ndarray,
    models: Mapping[str, np.ndarray],
    path: str | os.PathLike[str],
    *,
    max_points: int = 8_000,
    title: str | None = None,
) -> str:
    """The scene's ground-truth labels and each model's decisions, top view.

    Args:
        points: (N, 3) the scene's points (robot frame, m), finite.
        point_segments: (N,) each point's segment row, -1 for none.
        truth: (S, 6) bool ground-truth labels per segment row, `LABELS` order.
        models: Model name -> (S, 6) predicted probabilities (at least one model).
        path: Output image.
        max_points: Most points drawn (a positive integer).
        title: The figure's title; a default one when None.

    Returns:
        `path` as a string.

    Raises:
        InputError: For mismatched shapes, non-finite points, probabilities outside [0, 1],
            segment rows out of range, or no model.
    """
    limit = check_count("max_points", max_points)
    check_shape("points", points, (None, 3))
    pts = np.asarray(points, dtype=np.float64)
    check_finite("points", pts)
    check_shape("point_segments", point_segments, (len(pts),))
    seg = np.asarray(point_segments).astype(np.int64)
    t = as_bool_array("truth", truth)
    check_shape("truth", t, (None, len(LABELS)))
    if not models:
        raise InputError("models is empty; give at least one model's (S, 6) probabilities.")
    if seg.size and (seg.min() < -1 or seg.max() >= len(t)):
        raise InputError(
            f"point_segments must hold rows in [-1, {len(t) - 1}] (one truth row per segment)."
        )
    decisions = {}
    for name, prob in models.items():
        check_shape(f"models[{name!r}]", prob, t.shape)
        p = np.asarray(prob, dtype=np.float64)
        check_probability(f"models[{name!r}]", p)
        decisions[name] = p >= 0.5
    if len(pts) > limit:
        keep = np.sort(np.random.default_rng(0).choice(len(pts), size=limit, replace=False))
        pts, seg = pts[keep], seg[keep]
    on = seg >= 0
    rows = [("ground truth", t), *decisions.items()]
    fig = Figure(figsize=(3.0 * len(LABELS), 3.0 * len(rows)))
    axes = fig.subplots(len(rows), len(LABELS), squeeze=False)
    for i, (name, decided) in enumerate(rows):
        for k, label in enumerate(LABELS):
            ax = axes[i, k]
            colour = np.full(len(pts), _COLOURS["none"], dtype=object)
            value = decided[seg[on], k]
            right = value == t[seg[on], k]
            colour[on] = np.where(
                right,
                np.where(value, _COLOURS["positive"], _COLOURS["negative"]),
                _COLOURS["wrong"],
            )
            ax.scatter(pts[:, 0], pts[:, 1], c=list(colour), s=0.6, linewidths=0)
            ax.set_aspect("equal", adjustable="datalim")
            ax.set_xticks([])
            ax.set_yticks([])
            if i == 0:
                ax.set_title(label)
            if k == 0:
                ax.set_ylabel(name)
    fig.suptitle(
        title
        or "labels per segment, top view (x right, y up): dark positive, light negative, red wrong"
    )
    atomic_save_figure(fig, path, dpi=70)
    return os.fspath(path)
