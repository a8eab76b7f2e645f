"""The chapter 2 study: affordance labels of office segments, Algorithm 1 and multi-view merge.

`run` samples office scenes (`probaff.sim.office.sample_office_scenes` with ``seed``), and
scans each from its robot's head with `probaff.perception.scan_labels.scan_segments` (stream
``np.random.default_rng([seed, i])`` for scene i, as `scenes_dataset` does). Every scene scan
is one resumable task (one JSON per scene under ``out/tasks/``), so a killed run rescans only
the missing scenes; the first scene's per-point arrays (points, segment rows, object ids, all
views stacked) go to an ``.npz`` next to its JSON, for the figures. The multi-view merge scans
the first ``merge_scenes`` scenes once more with the ``merge_pans_deg`` views (stream
``[seed, i, 1]``), one task each under ``out/merge_tasks/``, whose segments' points (all views
stacked) go to an ``.npz`` next to its JSON, for the point proximity of the merge.

Then, in the main process:

* ``labels.csv``: `cross_validate_labels` (``n_splits`` folds grouped by scene, seed
  ``seed``) on the first n scenes, for each n of ``scene_counts``; per label precision and
  recall of ``p >= 0.5`` (percent, beside the thesis's `THESIS_PR`), average precision and ROC
  AUC, and the mean over labels;
* ``refinement.csv``: Algorithm 1 (`refine_segments`, seed ``seed``) on the out-of-fold
  probabilities of each scene of the ``n_scenes`` CV, for each of ``min_gains``; the
  point-weighted object purity and completeness (`purity_completeness`) of the segments
  before (every segment its own group) and of the groups after, averaged over scenes with a
  95 % Student-t interval (`mean_halfwidth`);
* ``merge.csv``: for each merge scene, a classifier trained on the other scenes of the
  ``n_scenes`` set labels every view's segments; the first V views of ``merge_pans_deg`` are
  merged (`merge_views`, the thesis's 0.05 m and 0.7) for each V of ``view_counts`` and each
  proximity of ``merge_proximities`` (segments close by their nearest points, or by their
  centroids). Purity and completeness are point-weighted over the merged segments against the
  views' majority objects; label accuracy is the share of (merged segment, label) pairs whose
  ``p >= 0.5`` matches the labels of the merged segment's point-weighted majority object
  (each merged segment counts once; ``weighted_accuracy`` weights it by its points). Means
  over scenes with 95 % intervals;
* ``summary.md`` with the tables and the thesis's numbers (195 segments from 10 scenes,
  average precision / recall 81.8 / 81.7), and the figures of `probaff.eval.label_figures`.

Frames and units: every point, centroid and feature is in the robot frame of its scene (x
forward, y left, z up; metres); angles in degrees. Thresholds and their sources: the
decision threshold 0.5 and the CV's details are `cross_validate_labels`'s; the merge
thresholds are the thesis's; ``merge_pans_deg = (-10, 10, -30, 30)`` is our choice: views 20
degrees apart overlap by about two thirds of the 57-degree field of view, and ordering them
from the centre outwards makes the first V views a contiguous fan for V = 1, 2, 4. The entropy
tree figure shows the first scene's tree at the first of ``min_gains``.
"""

from __future__ import annotations

import dataclasses
import hashlib
import io
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from probaff._checks import check_count, check_output_dir
from probaff._dask import check_scheduler, check_workers
from probaff._io import atomic_write_bytes, atomic_write_text
from probaff.errors import DatasetError, InputError
from probaff.eval.fingerprint import config_fingerprint
from probaff.eval.metrics import mean_halfwidth
from probaff.eval.tables import markdown_table, write_csv
from probaff.eval.tasks import ResultStore, run_tasks
from probaff.perception.labels import (
    LABELS,
    THESIS_PR,
    LabelClassifier,
    LabelCVResult,
    cross_validate_labels,
)
from probaff.perception.merge import PROXIMITIES, MergeView, merge_views
from probaff.perception.refinement import SplitTree, purity_completeness, refine_segments
from probaff.perception.scan_labels import PerceptionConfig, head_pose, scan_segments
from probaff.sim.camera import DepthCamera, load_camera
from probaff.sim.config import worlds_dir
from probaff.sim.office import load_office, sample_office_scenes

__all__ = [
    "RUN_ONLY",
    "SMOKE_OVERRIDES",
    "THESIS_SEGMENTS",
    "PointCloudStudyConfig",
    "demo",
    "merge_task",
    "run",
    "scan_task",
    "smoke_config",
    "summarise_labels",
    "summarise_merge",
    "summarise_refinement",
]

THESIS_SEGMENTS = (195, 10)
"""The thesis's data set: 195 segments from 10 office scenes."""

RUN_ONLY = ("out", "workers", "scheduler", "progress")
"""Fields that decide where and how the study runs, not what it computes."""

_VERSION = 1
_MERGE_VERSION = 2  # 2: merge records keep their segments' points (an .npz beside each JSON)
_WORLD = ("office.yaml", "camera.yaml")
_SCAN_FIELDS = ("seed", "perception")  # the fields that shape a scene scan
_MERGE_FIELDS = ("seed", "perception", "merge_pans_deg")  # ... and a merge scan


@dataclass(frozen=True)
class PointCloudStudyConfig:
    """Settings of the chapter 2 study.

    Attributes:
        out: Output folder (per-scene records, tables, figures).
        seed: Seed of the scenes, the scans, the CV folds and the 2-means runs.
        n_scenes: Scenes of the headline CV, Algorithm 1 and the merge classifiers (the
            thesis's 10).
        scene_counts: Scene counts of the label CV (the first n scenes each); larger ones show
            how the classifiers improve with data.
        n_splits: Folds of the CV by scene (the thesis's 4).
        label_min_points: Further label CVs, each on the segments of at least this many
            points only (the same scenes and folds). Region growing keeps segments from
            ``perception.min_size`` (50) points, about 66 a scene; at 300 points about 24 a
            scene are left, near the thesis's 19.5.
        perception: The scan-to-segments pipeline's settings.
        min_gains: Algorithm 1's entropy drop below which a split is undone (nats; 0 is the
            thesis's rule).
        view_counts: Views merged in the merge study (each at most the merge views).
        merge_pans_deg: Pan angles of the merge scans (degrees, left positive), centre out.
        merge_scenes: How many of the first scenes the merge study scans again.
        merge_proximities: How the merge reads "segments lie close", each of `PROXIMITIES`
            (``"points"``: nearest points; ``"centroid"``: centroids); the first one is drawn
            in the figure.
        workers: 0 runs in this process; K > 0 or None uses a local Dask cluster.
        scheduler: Address of an existing Dask scheduler.
        progress: Show progress bars.
    """

    out: str = "results/point_cloud_labels"
    seed: int = 0
    n_scenes: int = 10
    scene_counts: tuple[int, ...] = (10, 30)
    n_splits: int = 4
    label_min_points: tuple[int, ...] = (300,)
    perception: PerceptionConfig = field(default_factory=PerceptionConfig)
    min_gains: tuple[float, ...] = (0.0, 0.05, 0.1, 0.2)
    view_counts: tuple[int, ...] = (1, 2, 4)
    merge_pans_deg: tuple[float, ...] = (-10.0, 10.0, -30.0, 30.0)
    merge_scenes: int = 10
    merge_proximities: tuple[str, ...] = PROXIMITIES
    workers: int | None = 0
    scheduler: str | None = None
    progress: bool = True

    def validate(self) -> None:
        """Raise `InputError` for impossible counts, gains, views or settings."""
        check_count("seed", self.seed, minimum=0)
        check_count("n_scenes", self.n_scenes, minimum=2)
        splits = check_count("n_splits", self.n_splits, minimum=2)
        if not self.scene_counts:
            raise InputError("scene_counts is empty; give at least one scene count, e.g. 10.")
        for n in self.scene_counts:
            if check_count("scene_counts", n) < splits:
                raise InputError(
                    f"scene_counts holds {n}, fewer scenes than n_splits={splits}; every CV "
                    "needs at least one scene per fold."
                )
        if self.n_scenes < splits:
            raise InputError(
                f"n_scenes={self.n_scenes} is fewer than n_splits={splits}; raise n_scenes."
            )
        for m in self.label_min_points:
            check_count("label_min_points", m)
        if not self.min_gains or any(
            not isinstance(g, (int, float)) or not math.isfinite(g) or g < 0 for g in self.min_gains
        ):
            raise InputError(
                f"min_gains must be finite numbers >= 0 (nats), got {self.min_gains!r}."
            )
        if not isinstance(self.perception, PerceptionConfig):
            raise InputError(
                f"perception must be a PerceptionConfig, got {type(self.perception).__name__}."
            )
        pans = self.merge_pans_deg
        if not pans or any(not isinstance(p, (int, float)) or not math.isfinite(p) for p in pans):
            raise InputError(f"merge_pans_deg must be finite angles (degrees), got {pans!r}.")
        if not self.view_counts:
            raise InputError("view_counts is empty; give at least one number of views, e.g. 1.")
        for v in self.view_counts:
            if check_count("view_counts", v) > len(pans):
                raise InputError(
                    f"view_counts holds {v}, more than the {len(pans)} merge_pans_deg; add "
                    "pans or lower the view count."
                )
        merged = check_count("merge_scenes", self.merge_scenes)
        if merged > self.n_scenes:
            raise InputError(
                f"merge_scenes={merged} exceeds n_scenes={self.n_scenes}; the merge scenes "
                "are among the first n_scenes."
            )
        proximities = self.merge_proximities
        if (
            not proximities
            or any(p not in PROXIMITIES for p in proximities)
            or len(set(proximities)) < len(proximities)
        ):
            raise InputError(
                f"merge_proximities must hold distinct names among {', '.join(PROXIMITIES)}, "
                f"got {proximities!r}."
            )
        check_workers(self.workers)
        check_scheduler(self.scheduler)
        check_output_dir("out", self.out)

    @property
    def scanned(self) -> int:
        """Scenes scanned: the largest of `n_scenes` and `scene_counts`."""
        return max(self.n_scenes, *self.scene_counts)


SMOKE_OVERRIDES: dict[str, Any] = {
    "n_scenes": 4,
    "scene_counts": (4,),
    "n_splits": 2,
    "perception": PerceptionConfig(pans_deg=(0.0,)),
    "min_gains": (0.1,),
    "view_counts": (1, 2),
    "merge_pans_deg": (-10.0, 10.0),
    "merge_scenes": 1,
    "progress": False,
}
"""Sizes of a tiny run that checks the whole pipeline in seconds."""


def _tag(config: PointCloudStudyConfig, fields: tuple[str, ...], version: int = _VERSION) -> str:
    """Fingerprint of `fields` of `config` (code `version`) and of the world files."""
    digest = hashlib.sha256()
    for name in _WORLD:
        digest.update((worlds_dir() / name).read_bytes())
    others = tuple(f.name for f in dataclasses.fields(config) if f.name not in fields)
    tag = config_fingerprint(config, exclude=others, version=version, length=10)
    return f"{tag}{digest.hexdigest()[:6]}"


def _scan(
    seed: int, index: int, perception: PerceptionConfig, stream: tuple[int, ...]
) -> tuple[Any, Any]:
    """Scene `index` of `seed` and its scan with `perception`, drawn from `stream`."""
    scene = sample_office_scenes(load_office(), index + 1, seed)[index]
    camera = DepthCamera(load_camera())
    head = head_pose(scene, perception.head_height)
    rng = np.random.default_rng(list(stream))
    return scene, scan_segments(scene, camera, head, perception, rng)


def scan_task(
    seed: int, index: int, perception: PerceptionConfig, npz_path: str | None
) -> dict[str, Any]:
    """One scene scan (Dask workers import it): the segments of every view, as lists.

    Args:
        seed: The study's seed (scenes and scan streams).
        index: The scene's index i (stream ``[seed, i]``).
        perception: The pipeline's settings.
        npz_path: Where to write the per-point arrays (``points`` (N, 3), ``point_segments``
            (N,) row in the record's segments or -1, ``point_object_ids`` (N,)), all views
            stacked; None writes none.

    Returns:
        ``features`` (S, 25), ``labels`` (S, 6) 0/1, ``object_ids``, ``purity``,
        ``centroids`` (S, 3), ``point_counts``, ``views`` (S,) and the counts ``n_nan``,
        ``n_points``, ``n_unassigned``, ``n_skipped``; robot frame, metres.
    """
    seed = check_count("seed", seed, minimum=0)
    index = check_count("index", index, minimum=0)
    _, scan = _scan(seed, index, perception, (seed, index))
    if npz_path is not None:
        offsets = np.cumsum([0] + [v.n_segments for v in scan.views])
        rows = [
            np.where(v.point_segments >= 0, v.point_segments + offsets[i], -1)
            for i, v in enumerate(scan.views)
        ]
        buf = io.BytesIO()
        np.savez_compressed(
            buf,
            points=np.concatenate([v.points for v in scan.views]),
            point_segments=np.concatenate(rows),
            point_object_ids=np.concatenate([v.point_object_ids for v in scan.views]),
        )
        atomic_write_bytes(npz_path, buf.getvalue())
    return {
        "index": index,
        "features": scan.features.tolist(),
        "labels": scan.labels.astype(int).tolist(),
        "object_ids": scan.object_ids.tolist(),
        "purity": scan.purity.tolist(),
        "centroids": np.concatenate([v.centroids for v in scan.views]).tolist(),
        "point_counts": scan.point_counts.tolist(),
        "views": scan.view_index.tolist(),
        "n_nan": int(scan.n_nan),
        "n_points": int(sum(len(v.points) for v in scan.views)),
        "n_unassigned": int(sum(v.n_unassigned for v in scan.views)),
        "n_skipped": int(sum(v.n_skipped for v in scan.views)),
    }


def merge_task(
    seed: int,
    index: int,
    perception: PerceptionConfig,
    pans_deg: tuple[float, ...],
    npz_path: str | None = None,
) -> dict[str, Any]:
    """One merge scan (Dask workers import it): scene `index` seen from each of `pans_deg`.

    Args:
        seed: The study's seed (scenes and scan streams).
        index: The scene's index i (stream ``[seed, i, 1]``).
        perception: The pipeline's settings; its views are replaced by `pans_deg`.
        pans_deg: Pan angles of the views (degrees).
        npz_path: Where to write the points of the views' segments: ``points`` (N, 3)
            float32 (robot frame, m), ``point_segments`` (N,) int32 each point's segment row
            in its view, ``point_views`` (N,) int8 its view; points of no segment are left
            out. None writes none.

    Returns:
        ``index`` and ``views``: per view ``features`` (S_v, 25), ``labels`` (S_v, 6) 0/1,
        ``object_ids``, ``centroids`` (S_v, 3, robot frame, m) and ``point_counts``.
    """
    seed = check_count("seed", seed, minimum=0)
    index = check_count("index", index, minimum=0)
    cfg = dataclasses.replace(perception, pans_deg=tuple(pans_deg))
    _, scan = _scan(seed, index, cfg, (seed, index, 1))
    if npz_path is not None:
        on = [v.point_segments >= 0 for v in scan.views]
        points = [v.points[m] for v, m in zip(scan.views, on, strict=True)]
        rows = [v.point_segments[m] for v, m in zip(scan.views, on, strict=True)]
        buf = io.BytesIO()
        np.savez_compressed(
            buf,
            points=np.concatenate(points).astype(np.float32),
            point_segments=np.concatenate(rows).astype(np.int32),
            point_views=np.repeat(np.arange(len(on)), [len(r) for r in rows]).astype(np.int8),
        )
        atomic_write_bytes(npz_path, buf.getvalue())
    views = [
        {
            "features": v.features.tolist(),
            "labels": v.labels.astype(int).tolist(),
            "object_ids": v.object_ids.tolist(),
            "centroids": v.centroids.tolist(),
            "point_counts": v.point_counts.tolist(),
        }
        for v in scan.views
    ]
    return {"index": index, "views": views}


# ------------------------------------------------------------------ summaries
def _stack(records: list[dict[str, Any]]) -> dict[str, np.ndarray]:
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


def _pct(x: float) -> float:
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
                "precision_pct": _pct(cv.precision[k]),
                "recall_pct": _pct(cv.recall[k]),
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
            "precision_pct": _pct(cv.mean_precision),
            "recall_pct": _pct(cv.mean_recall),
            "thesis_precision_pct": THESIS_PR["average"][0],
            "thesis_recall_pct": THESIS_PR["average"][1],
            "ap": nanmean(cv.average_precision),
            "auc": nanmean(cv.roc_auc),
        }
    )
    return rows


def _stat(values: list[float]) -> tuple[float, float]:
    return float(np.mean(values)), mean_halfwidth(values)


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
            row[name], row[f"{name}_ci"] = _stat(cols[key])
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
        train = _stack([s for s in scans if s["index"] != rec["index"]])
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
            row[name], row[f"{name}_ci"] = _stat([s[k] for s in scores])
        rows.append(row)
    return rows


def _read_arrays(npz: Path, names: tuple[str, ...]) -> dict[str, np.ndarray]:
    """The arrays `names` of a scan's ``.npz`` file (written by `scan_task` or `merge_task`).

    Raises:
        DatasetError: If the file cannot be read, is truncated or corrupt, or lacks an array.
    """
    try:
        with np.load(npz, allow_pickle=False) as arrays:
            return {name: arrays[name] for name in names}
    except Exception as exc:  # damaged archives fail in many ways (BadZipFile, zlib.error, ...)
        raise DatasetError(
            f"cannot read the scan arrays {npz} ({exc or type(exc).__name__}); delete it and "
            "rerun the study to scan the scene again."
        ) from exc


def _merge_points(
    config: PointCloudStudyConfig, index: int, npz: Path
) -> list[tuple[np.ndarray, np.ndarray]]:
    """Per view of merge scene `index`, its segments' points (P_v, 3) and rows (P_v,).

    Reads `npz` (`merge_task`'s arrays); scans the scene again when the record survived but
    its arrays did not.
    """
    if not npz.is_file():
        merge_task(config.seed, index, config.perception, config.merge_pans_deg, str(npz))
    arrays = _read_arrays(npz, ("points", "point_segments", "point_views"))
    points = arrays["points"].astype(np.float64)
    rows = arrays["point_segments"].astype(np.int64)
    views = arrays["point_views"].astype(np.int64)
    return [(points[views == v], rows[views == v]) for v in range(len(config.merge_pans_deg))]


# ------------------------------------------------------------------ report
def _report(
    config: PointCloudStudyConfig,
    labels: list[dict[str, Any]],
    refinement: list[dict[str, Any]],
    merge: list[dict[str, Any]],
    counts: dict[str, int],
) -> str:
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
        markdown_table(
            labels,
            [
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
            ],
            digits=3,
        ),
        "",
        "## Algorithm 1 (entropy-minimising 2-means)",
        "",
        f"Per scene of the {config.n_scenes}-scene CV, on its out-of-fold probabilities; "
        "point-weighted purity and completeness against the true objects, before (each "
        "segment alone) and after; `*_ci`: 95 % Student-t half-width over scenes. "
        "`min_gain` 0 is the thesis's rule, which splits every set of distinct label vectors.",
        "",
        markdown_table(
            refinement,
            [
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
            ],
            digits=3,
        ),
        "",
        "## Multi-view merge (xyz < 0.05 m, label vectors < 0.7)",
        "",
        f"Views: the first V of pans {list(config.merge_pans_deg)} degrees; each scene's "
        "classifier is trained on the other scenes. `proximity`: segments of two views are "
        "close when their nearest points (`points`) or their centroids (`centroid`, the "
        "thesis's literal reading) lie closer than 0.05 m. `accuracy` counts each merged "
        "segment once, `weighted_accuracy` weights it by its points.",
        "",
        markdown_table(
            merge,
            [
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
            ],
            digits=3,
        ),
        "",
    ]
    return "\n".join(md)


def _figures(
    config: PointCloudStudyConfig,
    out: Path,
    npz: Path,
    first: np.ndarray,
    cv: LabelCVResult,
    tree: SplitTree,
    merge: list[dict[str, Any]],
) -> list[str]:
    """Every figure of the study; `first` (S0, 6) holds the first scene's probabilities."""
    from probaff.eval import label_figures as lf

    if not npz.is_file():  # the record survived but its arrays did not: rescan them
        scan_task(config.seed, 0, config.perception, str(npz))
    arrays = _read_arrays(npz, ("points", "point_segments"))
    points, rows = arrays["points"], arrays["point_segments"]
    files = [
        lf.plot_segment_cloud(points, rows, out / "segments.png"),
        lf.plot_label_probabilities(points, rows, first, out / "label_probabilities.png"),
        lf.plot_entropy_tree(
            [n.depth for n in tree.nodes],
            [n.entropy for n in tree.nodes],
            [-1 if n.parent is None else n.parent for n in tree.nodes],
            out / "entropy_tree.png",
        ),
        lf.plot_reliability(
            cv.reliability[0].centres,
            [r.frequency for r in cv.reliability],
            [r.counts for r in cv.reliability],
            out / "reliability.png",
        ),
    ]
    done = [r for r in merge if r["scenes"] and r["proximity"] == config.merge_proximities[0]]
    if done:
        files.append(
            lf.plot_merge_views(
                [r["views"] for r in done],
                [r["purity"] for r in done],
                [r["completeness"] for r in done],
                [r["accuracy"] for r in done],
                out / "merge_views.png",
            )
        )
    return files


def _cross_validate(
    config: PointCloudStudyConfig, scans: list[dict[str, Any]], min_points: int = 0
) -> tuple[dict[str, np.ndarray], LabelCVResult]:
    """The stacked segments of `scans` (of at least `min_points` points) and their CV by scene."""
    data = _stack(scans)
    if min_points:
        keep = data["point_counts"] >= min_points
        data = {k: v[keep] for k, v in data.items()}
    cv = cross_validate_labels(
        data["features"],
        data["labels"],
        data["groups"],
        n_splits=config.n_splits,
        seed=config.seed,
    )
    return data, cv


def run(config: PointCloudStudyConfig) -> dict[str, Any]:
    """Run (or resume) the study and write its tables and figures.

    Args:
        config: Study settings.

    Returns:
        ``{"labels", "refinement", "merge": summary rows, "files": paths}``.

    Raises:
        InputError: For an invalid config.
    """
    config.validate()
    out = Path(config.out)
    tag = _tag(config, _SCAN_FIELDS)
    npz = out / "tasks" / f"scene_000.{tag}.npz"
    tasks = [
        (
            f"scene_{i:03d}.{tag}",
            (config.seed, i, config.perception, str(npz) if i == 0 else None),
        )
        for i in range(config.scanned)
    ]
    common: dict[str, Any] = {"workers": config.workers, "scheduler": config.scheduler}
    scans = run_tasks(
        scan_task,
        tasks,
        ResultStore(out / "tasks"),
        progress=config.progress,
        desc="chapter 2 scans",
        **common,
    )
    mtag = _tag(config, _MERGE_FIELDS, version=_MERGE_VERSION)
    mnpz = [out / "merge_tasks" / f"merge_{i:03d}.{mtag}.npz" for i in range(config.merge_scenes)]
    merge_records = run_tasks(
        merge_task,
        [
            (
                f"merge_{i:03d}.{mtag}",
                (config.seed, i, config.perception, config.merge_pans_deg, str(mnpz[i])),
            )
            for i in range(config.merge_scenes)
        ],
        ResultStore(out / "merge_tasks"),
        progress=config.progress,
        desc="chapter 2 merge scans",
        **common,
    )
    merge_points = [_merge_points(config, i, path) for i, path in enumerate(mnpz)]
    cvs = {n: _cross_validate(config, scans[:n]) for n in sorted({*config.scene_counts})}
    if config.n_scenes not in cvs:
        cvs[config.n_scenes] = _cross_validate(config, scans[: config.n_scenes])
    label_rows = [
        row
        for n in config.scene_counts
        for row in summarise_labels(n, *cvs[n], min_points=config.perception.min_size)
    ]
    for m in config.label_min_points:
        for n in config.scene_counts:
            label_rows += summarise_labels(n, *_cross_validate(config, scans[:n], m), min_points=m)
    head_data, head = cvs[config.n_scenes]
    refinement, trees = summarise_refinement(
        head_data, head.probabilities, config.min_gains, config.seed
    )
    merge = summarise_merge(
        merge_records,
        scans[: config.n_scenes],
        config.view_counts,
        config.merge_proximities,
        merge_points,
    )
    files = [
        write_csv(out / "labels.csv", label_rows),
        write_csv(out / "refinement.csv", refinement),
        write_csv(out / "merge.csv", merge),
    ]
    first = head.probabilities[head_data["groups"] == 0]
    files += _figures(config, out, npz, first, head, trees[0, float(config.min_gains[0])], merge)
    counts = {
        "segments": len(head_data["labels"]),
        "scenes": config.n_scenes,
        "points": sum(r["n_points"] for r in scans[: config.n_scenes]),
        "nan": sum(r["n_nan"] for r in scans[: config.n_scenes]),
        "unassigned": sum(r["n_unassigned"] for r in scans[: config.n_scenes]),
        "skipped": sum(r["n_skipped"] for r in scans[: config.n_scenes]),
    }
    atomic_write_text(out / "summary.md", _report(config, label_rows, refinement, merge, counts))
    files.append(str(out / "summary.md"))
    return {"labels": label_rows, "refinement": refinement, "merge": merge, "files": files}


def smoke_config(out: str) -> PointCloudStudyConfig:
    """The smoke-sized config writing to `out`."""
    return dataclasses.replace(PointCloudStudyConfig(out=out), **SMOKE_OVERRIDES)


_DEMO_SCENES = 4  # scene 0 is held out, scenes 1-3 train the classifier
_DEMO_PERCEPTION = PerceptionConfig(pans_deg=(0.0,))  # the head's centre view only, as smoke


def _mean_precision_recall(truth: np.ndarray, probabilities: np.ndarray) -> tuple[float, float]:
    """Mean over labels of the precision and recall of ``p >= 0.5`` (fractions).

    Args:
        truth: (S, 6) bool ground-truth labels.
        probabilities: (S, 6) predicted probabilities.

    Returns:
        ``(precision, recall)``, each averaged over the labels where it is defined (a
        predicted positive for precision, a true positive for recall); NaN where none is.
    """
    predicted = probabilities >= 0.5
    hits = np.count_nonzero(truth & predicted, axis=0).astype(np.float64)
    n_pred = np.count_nonzero(predicted, axis=0)
    n_true = np.count_nonzero(truth, axis=0)
    precision = hits[n_pred > 0] / n_pred[n_pred > 0]
    recall = hits[n_true > 0] / n_true[n_true > 0]
    return (
        float(precision.mean()) if precision.size else math.nan,
        float(recall.mean()) if recall.size else math.nan,
    )


def demo(out: str | Path, *, seed: int = 0, progress: bool = True) -> dict[str, Any]:
    """One scanned office scene, segmented and labelled by a classifier of other scenes.

    ``probaff demo`` calls it. It samples 4 office scenes with `seed` and scans each from its
    robot's head (the centre view only; stream ``[seed, i]`` for scene i, as `run` does, so
    scene 0 is the study's first scene scanned with the smoke perception), trains a
    `LabelClassifier` on the segments of scenes 1-3 and predicts the labels of the segments of
    scene 0, held out. It writes ``scanned_scene.png`` (the held-out cloud as the camera saw
    it, coloured by segment and by the predicted probability of three labels) and prints two
    lines: the segments found, and the held-out precision and recall of ``p >= 0.5`` averaged
    over the labels, beside the thesis's.

    Args:
        out: Output folder (created).
        seed: Seed of the scenes and the scans (an integer >= 0).
        progress: Show a progress bar over the scans.

    Returns:
        ``{"scenes", "train_segments", "segments", "points", "unassigned", "precision_pct",
        "recall_pct", "file"}``: scenes sampled, segments of the training scenes, segments
        and returned points of the held-out scene, its points in no segment, the mean
        held-out precision and recall (percent) and the figure's path.

    Raises:
        InputError: For a bad `seed` or an `out` that cannot be a folder.
    """
    from tqdm.auto import tqdm

    from probaff.eval.label_figures import plot_scanned_scene

    seed = check_count("seed", seed, minimum=0)
    folder = check_output_dir("out", out)
    folder.mkdir(parents=True, exist_ok=True)
    cfg = _DEMO_PERCEPTION
    camera = DepthCamera(load_camera())
    scenes = sample_office_scenes(load_office(), _DEMO_SCENES, seed)
    scans = [
        scan_segments(
            scene, camera, head_pose(scene, cfg.head_height), cfg, np.random.default_rng([seed, i])
        )
        for i, scene in enumerate(
            tqdm(scenes, desc="chapter 2 demo scans", disable=not progress, leave=False)
        )
    ]
    held, train = scans[0], scans[1:]
    model = LabelClassifier().fit(
        np.concatenate([s.features for s in train]), np.concatenate([s.labels for s in train])
    )
    view = held.views[0]
    probabilities = model.predict_proba(view.features)
    precision, recall = _mean_precision_recall(view.labels, probabilities)
    file = plot_scanned_scene(
        view.points,
        view.point_segments,
        probabilities,
        folder / "scanned_scene.png",
        viewpoint=view.viewpoint,
        title=f"held-out office scene (seed {seed}): segments and predicted labels, camera view",
    )
    summary: dict[str, Any] = {
        "scenes": len(scenes),
        "train_segments": int(sum(len(s.labels) for s in train)),
        "segments": view.n_segments,
        "points": len(view.points),
        "unassigned": view.n_unassigned,
        "precision_pct": _pct(precision),
        "recall_pct": _pct(recall),
        "file": file,
    }
    print(
        f"held-out office scene: {summary['segments']} segments from {summary['points']} "
        f"points ({summary['unassigned']} in no segment); classifier trained on "
        f"{summary['train_segments']} segments of {len(train)} other scenes"
    )
    thesis_p, thesis_r = THESIS_PR["average"]
    print(
        f"held-out precision / recall (p >= 0.5, mean over labels): "
        f"{summary['precision_pct']:.1f} / {summary['recall_pct']:.1f} % "
        f"(thesis: {thesis_p} / {thesis_r} %); figure: {file}"
    )
    return summary
