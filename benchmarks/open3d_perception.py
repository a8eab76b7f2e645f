"""Open3D against the hand-written perception on the same office scans, piece by piece.

For each of ``--scenes`` office scenes (`worlds/office.yaml`, sampled with ``--seed``), the
robot's head scans the centre view (pan 0, the study's tilt and height, with the sensor
model), and each piece runs both ways on one thread:

* ray casting: `DepthCamera.cast` against `o3d_cast` (the primitives tessellated, cylinders
  with 64 sides); agreement: share of pixels whose hit object is the same, and the median
  absolute depth difference where both hit;
* neighbour search: scipy's ``cKDTree.query`` (k = 30) against `o3d_knn`; agreement: share of
  points whose k neighbours are the same set;
* normals: `estimate_normals` against `o3d_normals` (k = 30, towards the camera); agreement:
  median angle between them (degrees);
* segmentation: region growing (`grow_regions`, the study's settings) against Open3D's
  DBSCAN (``--eps``, 10 points, then clusters of fewer than 50 points dropped as region
  growing drops them); quality: point-weighted purity and completeness against the objects,
  the share of points left in no segment, and the label precision and recall of a 4-fold CV
  by scene of the thesis's logistic regressions on each segmentation's 25 features.

Times are wall-clock seconds per scan (mean over scenes). Writes ``results/open3d_perception/``
(``pieces.csv``, ``summary.md``) and prints the summary. Without Open3D it prints one line
saying how to install it and exits with status 2, as for a bad flag.

Usage: python benchmarks/open3d_perception.py [--scenes 30] [--seed 0] [--eps 0.03]
    [--out results/open3d_perception]
"""

import os

os.environ.setdefault("OMP_NUM_THREADS", "1")  # Open3D's OpenMP pool: one thread, as ours

import argparse
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np
from scipy.spatial import cKDTree
from threadpoolctl import threadpool_limits

from probaff._checks import check_count, check_number
from probaff.errors import ProbaffError
from probaff.eval.tables import markdown_table, write_csv
from probaff.perception.labels import cross_validate_labels
from probaff.perception.normals import estimate_normals
from probaff.perception.open3d_backend import (
    o3d_cast,
    o3d_dbscan,
    o3d_knn,
    o3d_normals,
    require_open3d,
)
from probaff.perception.refinement import purity_completeness
from probaff.perception.scan_labels import PerceptionConfig, grow_regions, head_pose
from probaff.perception.segment_features import segment_features
from probaff.sim import load_office, sample_office_scenes
from probaff.sim.camera import DepthCamera, head_views, load_camera

_K = 30
_MIN_SIZE = 50


def _timed(fn: Any, *args: Any, **kwargs: Any) -> tuple[Any, float]:
    start = time.perf_counter()
    out = fn(*args, **kwargs)
    return out, time.perf_counter() - start


def _segments(
    points: np.ndarray, rows: np.ndarray, oids: np.ndarray, labels_of: Any, eye: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Features (S, 25), labels (S, 6) and point counts (S,) of the segments `rows` (N,)."""
    ids, counts = np.unique(rows[rows >= 0], return_counts=True)
    small = np.isin(rows, ids[counts < _MIN_SIZE])
    rows = np.where(small, -1, rows)
    feats = segment_features(points, rows, viewpoint=eye)
    labels = []
    for s in feats.segment_ids:
        member = oids[rows == s]
        values, n = np.unique(member, return_counts=True)
        labels.append(labels_of(int(values[np.argmax(n)])))
    return feats.features, np.array(labels, dtype=bool).reshape(-1, 6), counts


def _quality(rows: np.ndarray, oids: np.ndarray) -> tuple[float, float, float]:
    """(purity, completeness, unassigned share) of a segmentation `rows` against `oids`."""
    on = rows >= 0
    purity, completeness = purity_completeness(rows[on], oids[on], np.ones(int(on.sum())))
    return purity, completeness, 1.0 - float(on.mean())


def _scene(index: int, seed: int, eps: float, camera: DepthCamera) -> dict[str, Any]:
    scene = sample_office_scenes(load_office(), index + 1, seed)[index]
    cfg = PerceptionConfig(pans_deg=(0.0,))
    pose = head_views(head_pose(scene, cfg.head_height), cfg.pans_deg, cfg.tilts_deg)[0]
    row: dict[str, Any] = {"scene": index}
    (depth, ids, _), row["cast_s"] = _timed(camera.cast, scene.primitives, pose)
    rays = camera.spec.pixel_rays().reshape(-1, 3)
    (o_depth, o_ids), row["o3d_cast_s"] = _timed(o3d_cast, scene.primitives, rays, pose)
    depth, ids = depth.ravel(), ids.ravel()
    both = np.isfinite(depth) & np.isfinite(o_depth)
    row["cast_same_object"] = float(np.mean(ids == o_ids))
    row["cast_depth_diff_mm"] = 1000.0 * float(np.median(np.abs(depth[both] - o_depth[both])))
    image = camera.render(scene.primitives, pose, rng=np.random.default_rng([seed, index]))
    points = image.points()
    finite = np.all(np.isfinite(points), axis=1)
    points, oids = points[finite], image.point_ids()[finite]
    eye = pose[:3, 3]
    (_, knn), row["knn_s"] = _timed(cKDTree(points).query, points, _K)
    o_knn, row["o3d_knn_s"] = _timed(o3d_knn, points, _K)
    row["knn_same_sets"] = float(np.mean(np.all(np.sort(knn, 1) == np.sort(o_knn, 1), axis=1)))
    normals, row["normals_s"] = _timed(estimate_normals, points, _K, viewpoint=eye)
    o_normals, row["o3d_normals_s"] = _timed(o3d_normals, points, _K, eye)
    cos = np.clip(np.abs(np.einsum("ij,ij->i", normals.normals, o_normals)), 0.0, 1.0)
    row["normals_median_deg"] = float(np.degrees(np.median(np.arccos(cos))))
    seg, row["region_growing_s"] = _timed(grow_regions, points, normals, cfg)
    clusters, row["o3d_dbscan_s"] = _timed(o3d_dbscan, points, eps, 10)
    segmentations = {"region_growing": seg.labels, "o3d_dbscan": clusters}
    labels_of = scene.label_of
    for name, rows in segmentations.items():
        purity, completeness, free = _quality(rows, oids)
        row[f"{name}_purity"], row[f"{name}_completeness"] = purity, completeness
        row[f"{name}_unassigned"] = free
        row[f"{name}_data"] = _segments(points, rows, oids, labels_of, eye)
    return row


def _labels(rows: list[dict[str, Any]], name: str, seed: int) -> tuple[float, float, int]:
    """Mean precision and recall (percent) of a 4-fold CV by scene, and the segments."""
    data = [r[f"{name}_data"] for r in rows]
    x = np.concatenate([d[0] for d in data])
    y = np.concatenate([d[1] for d in data])
    groups = np.concatenate([np.full(len(d[1]), i) for i, d in enumerate(data)])
    cv = cross_validate_labels(x, y, groups, n_splits=min(4, len(rows)), seed=seed)
    return 100.0 * cv.mean_precision, 100.0 * cv.mean_recall, len(y)


def main(argv: list[str] | None = None) -> int:
    """Run the comparison and write its tables; 2 for a bad flag or no Open3D."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", type=int, default=30)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--eps", type=float, default=0.03)
    parser.add_argument("--out", default="results/open3d_perception")
    args = parser.parse_args(argv)
    try:
        scenes = check_count("--scenes", args.scenes, minimum=2)
        seed = check_count("--seed", args.seed, minimum=0)
        eps = check_number("--eps", args.eps, bound="> 0", unit="m")
        require_open3d()
    except (ProbaffError, ImportError) as exc:
        print(f"open3d_perception: {exc}", file=sys.stderr)
        return 2
    camera = DepthCamera(load_camera())
    with threadpool_limits(limits=1):
        rows = [_scene(i, seed, eps, camera) for i in range(scenes)]
    pieces = []
    for piece, ours, theirs, agreement in (
        ("ray casting", "cast_s", "o3d_cast_s", ("cast_same_object", "cast_depth_diff_mm")),
        ("neighbour search (k = 30)", "knn_s", "o3d_knn_s", ("knn_same_sets",)),
        ("normals (k = 30)", "normals_s", "o3d_normals_s", ("normals_median_deg",)),
        (
            "segmentation",
            "region_growing_s",
            "o3d_dbscan_s",
            ("region_growing_purity", "o3d_dbscan_purity"),
        ),
    ):
        entry: dict[str, Any] = {
            "piece": piece,
            "hand_written_s": float(np.mean([r[ours] for r in rows])),
            "open3d_s": float(np.mean([r[theirs] for r in rows])),
        }
        entry["agreement"] = ", ".join(
            f"{a} {np.mean([r[a] for r in rows]):.3f}" for a in agreement
        )
        pieces.append(entry)
    quality = []
    for name in ("region_growing", "o3d_dbscan"):
        precision, recall, n = _labels(rows, name, seed)
        quality.append(
            {
                "segmentation": name,
                "segments": n,
                "purity": float(np.mean([r[f"{name}_purity"] for r in rows])),
                "completeness": float(np.mean([r[f"{name}_completeness"] for r in rows])),
                "unassigned": float(np.mean([r[f"{name}_unassigned"] for r in rows])),
                "label_precision_pct": precision,
                "label_recall_pct": recall,
            }
        )
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    write_csv(out / "pieces.csv", pieces)
    write_csv(out / "segmentation.csv", quality)
    text = "\n".join(
        [
            f"# Open3D against the hand-written perception ({scenes} scenes, centre view, "
            f"one thread, DBSCAN eps {eps:g} m)",
            "",
            "Seconds per scan (mean over scenes) and agreement:",
            "",
            markdown_table(pieces, ["piece", "hand_written_s", "open3d_s", "agreement"], 3),
            "",
            "Segmentation quality (point-weighted, against the objects) and the labels of the "
            "thesis's logistic regressions on each segmentation (4-fold CV by scene):",
            "",
            markdown_table(quality, list(quality[0]), 3),
            "",
        ]
    )
    (out / "summary.md").write_text(text)
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
