"""Tables and summary of the chapter 2 study: label CVs, Algorithm 1, the multi-view merge.

`summarise_labels` gives the rows of ``labels.csv`` (per label precision and recall of
``p >= 0.5`` beside the thesis's, average precision and ROC AUC, and the mean over labels),
`summarise_refinement` those of ``refinement.csv`` (Algorithm 1's purity and completeness
before and after, over scenes) and `summarise_merge` those of ``merge.csv`` (the first V
views of each merge scan merged, labelled by a classifier of the other scenes). `report`
writes the summary.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from probaff.errors import InputError
from probaff.eval.metrics import mean_and_halfwidth
from probaff.eval.tables import markdown_table
from probaff.experiments.point_cloud_labels.config import THESIS_SEGMENTS, PointCloudStudyConfig
from probaff.perception.labels import LABELS, THESIS_PR, LabelClassifier, LabelCVResult
from probaff.perception.merge import MergeView, merge_views
from probaff.perception.refinement import SplitTree, purity_completeness, refine_segments

__all__ = [
    "pct",
    "report",
    "stack",
    "summarise_labels",
    "summarise_merge",
    "summarise_refinement",
]

_LABEL_COLUMNS = [
    "n_scenes",
    "min_points",
    "label",
    "segments",
    "positives",
    "precision_pct",
    "recall_pct",
    "thesis_precision_pct",
    "thesis_recall_pct",
    "ap",
    "auc",
]

_REFINEMENT_COLUMNS = [
    "min_gain",
    "scenes",
    "segments",
    "groups",
    "depth",
    "purity_before",
    "completeness_before",
    "purity_after",
    "purity_after_ci",
    "completeness_after",
    "completeness_after_ci",
]

_MERGE_COLUMNS = [
    "proximity",
    "views",
    "scenes",
    "segments",
    "purity",
    "purity_ci",
    "completeness",
    "completeness_ci",
    "accuracy",
    "accuracy_ci",
    "weighted_accuracy",
    "weighted_accuracy_ci",
]


def stack(records: list[dict[str, Any]]) -> dict[str, np.ndarray]:
    """Segments of the scene `records`, stacked, with ``groups`` the scene index."""
    return {
        "features": np.concatenate([np.reshape(r["features"], (-1, 25)) for r in records]),
        "labels": np.concatenate(
            [np.reshape(r["labels"], (-1, len(LABELS))) for r in records]
        ).astype(bool),
        "groups": np.concatenate([np.full(len(r["object_ids"]), r["index"]) for r in records]),
        "object_ids": np.concatenate([np.asarray(r["object_ids"], np.int64) for r in records]),
        "point_counts": np.concatenate([np.asarray(r["point_counts"], np.int64) for r in records]),
    }


def pct(x: float) -> float:
    """`x` (a fraction) in percent, as a float."""
    return 100.0 * float(x)


def summarise_labels(
    n: int, data: dict[str, np.ndarray], cv: LabelCVResult, min_points: int | None = None
) -> list[dict[str, Any]]:
    """Rows of ``labels.csv`` for one scene count: one per label and the mean over labels.

    Args:
        n: The scene count.
        data: The stacked segments (`_stack`), for the segment and positive counts.
        cv: The cross-validation of those segments.
        min_points: The least points of the segments kept (None: all segments).

    Returns:
        Rows with ``n_scenes``, ``min_points``, ``label``, ``segments``, ``positives``,
        ``precision_pct``, ``recall_pct``, ``thesis_precision_pct``, ``thesis_recall_pct``,
        ``ap``, ``auc``.
    """
    rows = []
    for k, name in enumerate(LABELS):
        rows.append(
            {
                "n_scenes": n,
                "min_points": min_points,
                "label": name,
                "segments": len(data["labels"]),
                "positives": int(data["labels"][:, k].sum()),
                "precision_pct": pct(cv.precision[k]),
                "recall_pct": pct(cv.recall[k]),
                "thesis_precision_pct": THESIS_PR[name][0],
                "thesis_recall_pct": THESIS_PR[name][1],
                "ap": float(cv.average_precision[k]),
                "auc": float(cv.roc_auc[k]),
            }
        )

    def nanmean(values: np.ndarray) -> float:
        finite = values[np.isfinite(values)]
        return float(finite.mean()) if finite.size else math.nan

    rows.append(
        {
            "n_scenes": n,
            "min_points": min_points,
            "label": "average",
            "segments": len(data["labels"]),
            "positives": int(data["labels"].sum()),
            "precision_pct": pct(cv.mean_precision),
            "recall_pct": pct(cv.mean_recall),
            "thesis_precision_pct": THESIS_PR["average"][0],
            "thesis_recall_pct": THESIS_PR["average"][1],
            "ap": nanmean(cv.average_precision),
            "auc": nanmean(cv.roc_auc),
        }
    )
    return rows


def summarise_refinement(
    data: dict[str, np.ndarray],
    probabilities: np.ndarray,
    min_gains: tuple[float, ...],
    seed: int,
) -> tuple[list[dict[str, Any]], dict[tuple[int, float], SplitTree]]:
    """Algorithm 1 per scene and min_gain, scored before and after against the true objects.

    Args:
        data: The stacked segments (`_stack`) of the CV.
        probabilities: (S, 6) their out-of-fold probabilities.
        min_gains: The entropy drops below which a split is undone (nats).
        seed: Seed of the 2-means runs.

    Returns:
        Rows (one per min_gain) with ``min_gain``, ``scenes``, ``segments``, ``groups`` (mean
        per scene), ``depth`` (mean), ``purity_before`` / ``completeness_before``,
        ``purity_after`` / ``completeness_after`` and their ``*_ci`` half-widths; and the
        trees by ``(scene, min_gain)``.
    """
    rows, trees = [], {}
    scenes = np.unique(data["groups"])
    for gain in min_gains:
        cols: dict[str, list[float]] = {
            k: [] for k in ("pb", "cb", "pa", "ca", "groups", "depth", "segments")
        }
        for s in scenes:
            on = data["groups"] == s
            oids, w = data["object_ids"][on], data["point_counts"][on]
            tree = refine_segments(probabilities[on], seed=seed, min_gain=gain)
            trees[int(s), float(gain)] = tree
            pb, cb = purity_completeness(np.arange(int(on.sum())), oids, w)
            pa, ca = purity_completeness(tree.groups(), oids, w)
            for key, value in (
                ("pb", pb),
                ("cb", cb),
                ("pa", pa),
                ("ca", ca),
                ("groups", len(tree.leaves)),
                ("depth", tree.depth),
                ("segments", int(on.sum())),
            ):
                cols[key].append(float(value))
        row: dict[str, Any] = {"min_gain": float(gain), "scenes": len(scenes)}
        row["segments"] = float(np.mean(cols["segments"]))
        row["groups"] = float(np.mean(cols["groups"]))
        row["depth"] = float(np.mean(cols["depth"]))
        for key, name in (
            ("pb", "purity_before"),
            ("cb", "completeness_before"),
            ("pa", "purity_after"),
            ("ca", "completeness_after"),
        ):
            row[name], row[f"{name}_ci"] = mean_and_halfwidth(cols[key])
        rows.append(row)
    return rows, trees


def _merge_scores(
    views: list[dict[str, Any]],
    probs: list[np.ndarray],
    proximity: str,
    points: list[tuple[np.ndarray, np.ndarray]] | None,
) -> tuple[float, float, float, float, int]:
    """(purity, completeness, label accuracy, its point-weighted mean, merged segments).

    Args:
        views: The merge record's views (`merge_task`).
        probs: (S_v, 6) predicted label probabilities of each view's segments.
        proximity: `merge_views`'s proximity.
        points: Per view its segments' points (P_v, 3) and their rows (P_v,), or None (for
            the ``"centroid"`` proximity only).
    """
    given = points if points is not None else [(None, None)] * len(views)
    merged = merge_views(
        [
            MergeView(np.reshape(v["centroids"], (-1, 3)), p, np.asarray(v["point_counts"]), *pts)
            for v, p, pts in zip(views, probs, given, strict=True)
        ],
        proximity=proximity,
    )
    groups = np.concatenate(merged.membership)
    oids = np.concatenate([np.asarray(v["object_ids"], np.int64) for v in views])
    labels = np.concatenate([np.reshape(v["labels"], (-1, len(LABELS))) for v in views])
    weights = np.concatenate([np.asarray(v["point_counts"], np.float64) for v in views])
    purity, completeness = purity_completeness(groups, oids, weights)
    hits = np.zeros(len(merged.point_counts))
    for g in range(len(merged.point_counts)):
        on = groups == g
        ids, inverse = np.unique(oids[on], return_inverse=True)
        top = int(np.argmax(np.bincount(inverse, weights=weights[on])))
        truth = labels[on][np.flatnonzero(ids[inverse] == ids[top])[0]].astype(bool)
        hits[g] = np.count_nonzero((merged.label_vectors[g] >= 0.5) == truth) / len(LABELS)
    weighted = float(np.average(hits, weights=merged.point_counts))
    return purity, completeness, float(hits.mean()), weighted, len(merged.point_counts)


def summarise_merge(
    records: list[dict[str, Any]],
    scans: list[dict[str, Any]],
    view_counts: tuple[int, ...],
    proximities: tuple[str, ...] = ("centroid",),
    points: list[list[tuple[np.ndarray, np.ndarray]]] | None = None,
) -> list[dict[str, Any]]:
    """Merge the first V views of each merge scan, labelled by a classifier of the other scenes.

    Args:
        records: The merge tasks' records (`merge_task`).
        scans: The scene records (`scan_task`) of the classifiers' scenes.
        view_counts: The numbers of views merged.
        proximities: `merge_views`'s proximities to measure, each of `PROXIMITIES`.
        points: Per record, per view, its segments' points (P_v, 3) (robot frame, m) and each
            point's segment row (P_v,) (the arrays `merge_task` writes); needed for
            ``"points"``.

    Returns:
        Rows (one per proximity and view count) with ``proximity``, ``views``, ``scenes``,
        ``segments`` (merged, mean per scene), ``purity``, ``completeness``, ``accuracy``
        (mean over merged segments), ``weighted_accuracy`` (each merged segment weighted by
        its points) and their ``*_ci`` half-widths.

    Raises:
        InputError: For ``"points"`` among `proximities` without `points`, or `points` not
            one entry per record.
    """
    if "points" in proximities and points is None:
        raise InputError("summarise_merge needs points (per record and view) for 'points'.")
    if points is not None and len(points) != len(records):
        raise InputError(
            f"points holds {len(points)} entries for {len(records)} records; give one per record."
        )
    per_view: dict[tuple[str, int], list[tuple[float, float, float, float, int]]] = {
        (p, v): [] for p in proximities for v in view_counts
    }
    for r, rec in enumerate(records):
        train = stack([s for s in scans if s["index"] != rec["index"]])
        model = LabelClassifier().fit(train["features"], train["labels"])
        views = rec["views"]
        probs = [
            model.predict_proba(np.reshape(v["features"], (-1, 25)))
            if v["point_counts"]
            else np.zeros((0, len(LABELS)))
            for v in views
        ]
        for proximity in proximities:
            for n in view_counts:
                if sum(len(v["point_counts"]) for v in views[:n]):
                    pts = None if points is None else points[r][:n]
                    per_view[proximity, n].append(
                        _merge_scores(views[:n], probs[:n], proximity, pts)
                    )
    rows = []
    for proximity, n in per_view:
        scores = per_view[proximity, n]
        row: dict[str, Any] = {"proximity": proximity, "views": n, "scenes": len(scores)}
        row["segments"] = float(np.mean([s[4] for s in scores])) if scores else math.nan
        for k, name in enumerate(("purity", "completeness", "accuracy", "weighted_accuracy")):
            row[name], row[f"{name}_ci"] = mean_and_halfwidth([s[k] for s in scores])
        rows.append(row)
    return rows


def report(
    config: PointCloudStudyConfig,
    labels: list[dict[str, Any]],
    refinement: list[dict[str, Any]],
    merge: list[dict[str, Any]],
    counts: dict[str, int],
) -> str:
    """The summary's Markdown: the three tables with the thesis's numbers beside them."""
    segments, scenes = THESIS_SEGMENTS
    thesis_p, thesis_r = THESIS_PR["average"]
    md = [
        "# Chapter 2: affordance labels from a point cloud",
        "",
        f"Thesis: {segments} segments from {scenes} office scenes, 4-fold CV; average "
        f"precision / recall {thesis_p} / {thesis_r} %. Here: {counts['segments']} segments "
        f"from {counts['scenes']} scanned scenes ({counts['points']} returned points, "
        f"{counts['nan']} pixels without a return, {counts['unassigned']} points in no "
        f"segment, {counts['skipped']} segments skipped), {config.n_splits}-fold CV by scene.",
        "",
        "## Labels (out-of-fold, p >= 0.5)",
        "",
        f"`min_points`: the least points of the segments in the CV (the same scenes and "
        f"folds). Region growing keeps segments from {config.perception.min_size} points; "
        "the small ones (legs, fragments, slivers at occlusions) are the hardest to label, and "
        "at 300 points about as many segments a scene are left as the thesis had.",
        "",
        markdown_table(labels, _LABEL_COLUMNS, digits=3),
        "",
        "## Algorithm 1 (entropy-minimising 2-means)",
        "",
        f"Per scene of the {config.n_scenes}-scene CV, on its out-of-fold probabilities; "
        "point-weighted purity and completeness against the true objects, before (each "
        "segment alone) and after; `*_ci`: 95 % Student-t half-width over scenes. "
        "`min_gain` 0 is the thesis's rule, which splits every set of distinct label vectors.",
        "",
        markdown_table(refinement, _REFINEMENT_COLUMNS, digits=3),
        "",
        "## Multi-view merge (xyz < 0.05 m, label vectors < 0.7)",
        "",
        f"Views: the first V of pans {list(config.merge_pans_deg)} degrees; each scene's "
        "classifier is trained on the other scenes. `proximity`: segments of two views are "
        "close when their nearest points (`points`) or their centroids (`centroid`, the "
        "thesis's literal reading) lie closer than 0.05 m. `accuracy` counts each merged "
        "segment once, `weighted_accuracy` weights it by its points.",
        "",
        markdown_table(merge, _MERGE_COLUMNS, digits=3),
        "",
    ]
    return "\n".join(md)
