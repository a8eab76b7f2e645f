"""Precision and recall of label decisions with 95 % intervals over scenes (scene bootstrap).

`scene_intervals` pools the decisions ``p >= t`` of all segments (``t`` = 0.5 unless a model
chose its own thresholds), as the study's CVs do, and
gives each label's precision and recall (percent) and their mean over the labels, with a 95 %
percentile interval from resampling the scenes with replacement (``n_boot`` draws; our
choice of 2000, which settles the interval's ends to about 0.2 points). Resampling scenes,
not segments, keeps the segments of one scene together, as they share its layout.
A label's precision is undefined without a predicted positive and its recall without a true
positive; the mean takes the labels where each is defined, and an interval's ends skip the
draws where it is undefined. `interval_text` writes a row as ``P [lo, hi] / R [lo, hi]``.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from probaff._checks import as_bool_array, check_count, check_shape
from probaff.affordance_labels import LABELS
from probaff.errors import InputError

__all__ = ["interval_text", "scene_intervals"]


def _rates(tp: np.ndarray, pp: np.ndarray, ap: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Precision and recall (percent), (..., 6), NaN where undefined."""
    with np.errstate(invalid="ignore", divide="ignore"):
        precision = np.where(pp > 0, 100.0 * tp / np.maximum(pp, 1), np.nan)
        recall = np.where(ap > 0, 100.0 * tp / np.maximum(ap, 1), np.nan)
    return precision, recall


def _with_mean(x: np.ndarray) -> np.ndarray:
    """(..., 7): the six labels and their mean over the defined ones."""
    defined = np.isfinite(x)
    total = np.where(defined, x, 0.0).sum(axis=-1)
    count = defined.sum(axis=-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.where(count > 0, total / np.maximum(count, 1), np.nan)
    return np.concatenate([x, mean[..., None]], axis=-1)


def _ends(draws: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """2.5 and 97.5 percentiles over axis 0, skipping NaN draws."""
    lo = np.full(draws.shape[1], np.nan)
    hi = np.full(draws.shape[1], np.nan)
    for j in range(draws.shape[1]):
        finite = draws[:, j][np.isfinite(draws[:, j])]
        if finite.size:
            lo[j], hi[j] = np.percentile(finite, [2.5, 97.5])
    return lo, hi


def scene_intervals(
    truth: np.ndarray,
    probabilities: np.ndarray,
    groups: np.ndarray,
    *,
    n_boot: int = 2000,
    seed: int = 0,
    thresholds: np.ndarray | float = 0.5,
) -> list[dict[str, Any]]:
    """Pooled precision and recall of ``p >= thresholds`` per label, with 95 % scene intervals.

    Args:
        truth: (S, 6) bool ground-truth labels, `LABELS` order.
        probabilities: (S, 6) predicted probabilities.
        groups: (S,) the scene of each segment.
        n_boot: Bootstrap draws of the scenes (a positive integer).
        seed: Seed of the draws (an integer >= 0).
        thresholds: Decision thresholds: a number, or (S, 6) one per segment and label (a
            CV's thresholds, each chosen by the model of the segment's fold).

    Returns:
        One row per label and one ``"average"`` row with ``label``, ``precision_pct``,
        ``precision_lo``, ``precision_hi``, ``recall_pct``, ``recall_lo``, ``recall_hi``.

    Raises:
        InputError: For mismatched shapes, no segments, bad counts or non-finite thresholds.
    """
    t = as_bool_array("truth", truth)
    check_shape("truth", t, (None, len(LABELS)))
    if len(t) == 0:
        raise InputError("truth is empty; give at least one segment.")
    check_shape("probabilities", probabilities, t.shape)
    check_shape("groups", groups, (len(t),))
    draws = check_count("n_boot", n_boot)
    rng = np.random.default_rng(check_count("seed", seed, minimum=0))
    cut = np.asarray(thresholds, dtype=np.float64)
    if cut.ndim:
        check_shape("thresholds", cut, t.shape)
    if not np.all(np.isfinite(cut)):
        raise InputError("thresholds must be finite numbers, one or one per segment and label.")
    decided = np.asarray(probabilities, dtype=np.float64) >= cut
    _, scene = np.unique(np.asarray(groups), return_inverse=True)
    n_scenes = int(scene.max()) + 1
    per = np.zeros((3, n_scenes, len(LABELS)))
    for k, x in enumerate((t & decided, decided, t)):
        np.add.at(per[k], scene, x.astype(np.float64))
    precision, recall = (_with_mean(r) for r in _rates(*per.sum(axis=1)))
    weights = rng.multinomial(n_scenes, np.full(n_scenes, 1.0 / n_scenes), size=draws)
    boot = np.einsum("bg,kgl->kbl", weights.astype(np.float64), per)
    p_draws, r_draws = (_with_mean(r) for r in _rates(*boot))
    (p_lo, p_hi), (r_lo, r_hi) = _ends(p_draws), _ends(r_draws)
    return [
        {
            "label": name,
            "precision_pct": float(precision[j]),
            "precision_lo": float(p_lo[j]),
            "precision_hi": float(p_hi[j]),
            "recall_pct": float(recall[j]),
            "recall_lo": float(r_lo[j]),
            "recall_hi": float(r_hi[j]),
        }
        for j, name in enumerate((*LABELS, "average"))
    ]


def interval_text(row: dict[str, Any]) -> str:
    """A `scene_intervals` row as ``P [lo, hi] / R [lo, hi]`` (percent, one decimal).

    An undefined precision or recall (NaN: no predicted, or no true, positive) reads ``n/a``.
    """

    def one(name: str) -> str:
        value = row[f"{name}_pct"]
        if not np.isfinite(value):
            return "n/a"
        return f"{value:.1f} [{row[f'{name}_lo']:.1f}, {row[f'{name}_hi']:.1f}]"

    return f"{one('precision')} / {one('recall')}"
