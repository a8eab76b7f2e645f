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
* ``models.csv`` and ``causes.csv``: on every scanned scene, `compare_models` (the thesis's
  logistic regressions, calibrated gradient-boosted trees on the same features, the new model
  with the context descriptors, and the baseline on the oracle object segments; all segments,
  then those of at least each of ``label_min_points`` points), per label precision and
  recall with 95 % scene-bootstrap intervals (the trees decide with the per-label thresholds
  each fold model chooses on its training scenes, ``boosting_threshold``), and the baseline's
  errors by cause (`attribute_errors`); ``labels_vs_truth.png``: the first scene's labels,
  ground truth against the baseline's and the new model's decisions;
* ``summary.md`` with the tables and the thesis's numbers (195 segments from 10 scenes,
  average precision / recall 81.8 / 81.7), and the figures of
  `probaff.experiments.point_cloud_labels.figures`.

Frames and units: every point, centroid and feature is in the robot frame of its scene (x
forward, y left, z up; metres); angles in degrees. Thresholds and their sources: the
decision threshold 0.5 and the CV's details are `cross_validate_labels`'s; the merge
thresholds are the thesis's; ``merge_pans_deg = (-10, 10, -30, 30)`` is our choice: views 20
degrees apart overlap by about two thirds of the 57-degree field of view, and ordering them
from the centre outwards makes the first V views a contiguous fan for V = 1, 2, 4. The entropy
tree figure shows the first scene's tree at the first of ``min_gains``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from probaff.experiments.base import StudyRun
from probaff.experiments.point_cloud_labels.comparison import (
    ModelComparison,
    compare_models,
    stack_records,
)
from probaff.experiments.point_cloud_labels.config import PointCloudStudyConfig
from probaff.experiments.point_cloud_labels.figures import study_figures
from probaff.experiments.point_cloud_labels.model_report import (
    cause_rows,
    model_rows,
    model_section,
)
from probaff.experiments.point_cloud_labels.report import (
    report,
    stack,
    summarise_labels,
    summarise_merge,
    summarise_refinement,
)
from probaff.experiments.point_cloud_labels.scans import merge_task, read_arrays, scan_task
from probaff.experiments.point_cloud_labels.truth_figure import plot_labels_against_truth
from probaff.perception.labels import LabelCVResult, cross_validate_labels

__all__ = ["run"]

_VERSION = 4  # 4: records keep the context descriptors and the error diagnostics
_MERGE_VERSION = 2  # 2: merge records keep their segments' points (an .npz beside each JSON)
_WORLD = ("office.yaml", "camera.yaml")
_SCAN_FIELDS = ("seed", "perception")  # the fields that shape a scene scan
_MERGE_FIELDS = ("seed", "perception", "merge_pans_deg")  # ... and a merge scan


def _merge_points(
    config: PointCloudStudyConfig, index: int, npz: Path
) -> list[tuple[np.ndarray, np.ndarray]]:
    """Per view of merge scene `index`, its segments' points (P_v, 3) and rows (P_v,).

    Reads `npz` (`merge_task`'s arrays); scans the scene again when the record survived but
    its arrays did not.
    """
    if not npz.is_file():
        merge_task(config.seed, index, config.perception, config.merge_pans_deg, str(npz))
    arrays = read_arrays(npz, ("points", "point_segments", "point_views"))
    points = arrays["points"].astype(np.float64)
    rows = arrays["point_segments"].astype(np.int64)
    views = arrays["point_views"].astype(np.int64)
    return [(points[views == v], rows[views == v]) for v in range(len(config.merge_pans_deg))]


def _cross_validate(
    config: PointCloudStudyConfig, scans: list[dict[str, Any]], min_points: int = 0
) -> tuple[dict[str, np.ndarray], LabelCVResult]:
    """The stacked segments of `scans` (of at least `min_points` points) and their CV by scene."""
    data = stack(scans)
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


def _scan_all(
    study: StudyRun[PointCloudStudyConfig],
) -> tuple[list[dict[str, Any]], Path, list[dict[str, Any]], list[Any]]:
    """The scene scans, the first scene's arrays, the merge scans and their points."""
    config = study.config
    tag = config.tag(only=_SCAN_FIELDS, world=_WORLD, version=_VERSION)
    npz = study.out / "tasks" / f"scene_000.{tag}.npz"
    tasks = [
        (f"scene_{i:03d}.{tag}", (config.seed, i, config.perception, str(npz) if i == 0 else None))
        for i in range(config.scanned)
    ]
    scans = study.tasks(scan_task, tasks, desc="chapter 2 scans")
    mtag = config.tag(only=_MERGE_FIELDS, world=_WORLD, version=_MERGE_VERSION)
    folder = study.out / "merge_tasks"
    mnpz = [folder / f"merge_{i:03d}.{mtag}.npz" for i in range(config.merge_scenes)]
    merge_tasks = [
        (
            f"merge_{i:03d}.{mtag}",
            (config.seed, i, config.perception, config.merge_pans_deg, str(mnpz[i])),
        )
        for i in range(config.merge_scenes)
    ]
    merges = study.tasks(merge_task, merge_tasks, desc="chapter 2 merge scans", folder=folder.name)
    points = [_merge_points(config, i, path) for i, path in enumerate(mnpz)]
    return scans, npz, merges, points


def _truth_figure(
    config: PointCloudStudyConfig, out: Path, npz: Path, head: ModelComparison
) -> str:
    """The first scene's labels against the truth (``labels_vs_truth.png``)."""
    if not npz.is_file():  # the record survived but its arrays did not: rescan them
        scan_task(config.seed, 0, config.perception, str(npz))
    arrays = read_arrays(npz, ("points", "point_segments"))
    first = head.groups == head.groups.min()
    return plot_labels_against_truth(
        arrays["points"],
        arrays["point_segments"],
        head.labels[first],
        {name: head.decisions(name)[first].astype(np.float64) for name in ("thesis", "new")},
        out / "labels_vs_truth.png",
        title="first scene, all views: ground truth, thesis baseline and new model (top "
        "view, x right, y up; dark positive, light negative, red wrong)",
    )


def run(config: PointCloudStudyConfig) -> dict[str, Any]:
    """Run (or resume) the study and write its tables and figures.

    Args:
        config: Study settings.

    Returns:
        ``{"labels", "refinement", "merge", "models", "causes": summary rows, "files":
        paths}``.

    Raises:
        InputError: For an invalid config.
    """
    study = StudyRun(config, PointCloudStudyConfig)
    config = study.config
    scans, npz, merge_records, merge_points = _scan_all(study)
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
    head_scans = scans[: config.n_scenes]
    merge = summarise_merge(
        merge_records, head_scans, config.view_counts, config.merge_proximities, merge_points
    )
    stacked = stack_records(scans)
    comparisons = [
        compare_models(
            stacked,
            n_splits=config.n_splits,
            seed=config.seed,
            min_points=m,
            options=config.boosting,
        )
        for m in (0, *config.label_min_points)
    ]
    study.table("models.csv", model_rows(comparisons))
    study.table("causes.csv", cause_rows(comparisons))
    study.figure(_truth_figure(config, study.out, npz, comparisons[0]))
    study.table("labels.csv", label_rows)
    study.table("refinement.csv", refinement)
    study.table("merge.csv", merge)
    first = head.probabilities[head_data["groups"] == 0]
    tree = trees[0, float(config.min_gains[0])]
    for path in study_figures(config, study.out, npz, first, head, tree, merge):
        study.figure(path)
    counts = {
        "segments": len(head_data["labels"]),
        "scenes": config.n_scenes,
        **{
            name: sum(r[key] for r in head_scans)
            for name, key in (
                ("points", "n_points"),
                ("nan", "n_nan"),
                ("unassigned", "n_unassigned"),
                ("skipped", "n_skipped"),
            )
        },
    }
    study.summary(
        report(config, label_rows, refinement, merge, counts)
        + "\n"
        + model_section(comparisons, len(scans))
    )
    return {
        "labels": label_rows,
        "refinement": refinement,
        "merge": merge,
        "models": model_rows(comparisons),
        "causes": cause_rows(comparisons),
        "files": study.files,
    }
