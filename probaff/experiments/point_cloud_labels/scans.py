"""The chapter 2 study's scans: one office scene, or one scene seen from several views.

Both are study tasks (Dask workers import them): scene i of the study's seed is sampled by
`probaff.sim.office.sample_office_scenes` and scanned from its robot's head with
`probaff.perception.scan_labels.scan_segments`, from the stream ``[seed, i]`` (a scene scan,
as `scenes_dataset` does) or ``[seed, i, 1]`` (a merge scan). A record holds the segments
as lists; their per-point arrays go to an ``.npz`` file beside it, read back by
`read_arrays`. Robot frame (x forward, y left, z up), metres.
"""

from __future__ import annotations

import dataclasses
import io
from pathlib import Path
from typing import Any

import numpy as np

from probaff._checks import check_count
from probaff._io import atomic_write_bytes
from probaff.errors import DatasetError
from probaff.experiments.point_cloud_labels.oracle import object_segments, segment_diagnostics
from probaff.perception.scan_labels import PerceptionConfig, head_pose, scan_segments
from probaff.sim import DepthCamera, load_camera, load_office, sample_office_scenes

__all__ = ["merge_task", "read_arrays", "scan_task"]


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
        ``features`` (S, 25), ``context`` (S, 23), ``labels`` (S, 6) 0/1, ``object_ids``,
        ``purity``, ``centroids`` (S, 3), ``point_counts``, ``views`` (S,), the counts
        ``n_nan``, ``n_points``, ``n_unassigned``, ``n_skipped``; the error diagnostics
        ``mixed`` (S, 6) 0/1, ``fragment`` (S,) 0/1 and ``oracle_rows`` (S,) (each segment's
        object's row in ``oracle``, -1 if absent; `segment_diagnostics`), and ``oracle``: the
        views' object segments (`object_segments`) stacked, with ``features``, ``context``,
        ``labels``, ``object_ids``, ``point_counts`` and ``views``; robot frame, metres.
    """
    seed = check_count("seed", seed, minimum=0)
    index = check_count("index", index, minimum=0)
    scene, scan = _scan(seed, index, perception, (seed, index))
    oracles = [object_segments(v, scene, perception) for v in scan.views]
    diags = [segment_diagnostics(v, scene, o) for v, o in zip(scan.views, oracles, strict=True)]
    starts = np.cumsum([0] + [len(o.object_ids) for o in oracles])
    oracle_rows = np.concatenate(
        [np.where(d.oracle_rows >= 0, d.oracle_rows + starts[i], -1) for i, d in enumerate(diags)]
    )
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
        "context": scan.context.tolist(),
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
        "mixed": np.concatenate([d.mixed for d in diags]).astype(int).tolist(),
        "fragment": np.concatenate([d.fragment for d in diags]).astype(int).tolist(),
        "oracle_rows": oracle_rows.tolist(),
        "oracle": {
            "features": np.concatenate([o.features for o in oracles]).tolist(),
            "context": np.concatenate([o.context for o in oracles]).tolist(),
            "labels": np.concatenate([o.labels for o in oracles]).astype(int).tolist(),
            "object_ids": np.concatenate([o.object_ids for o in oracles]).tolist(),
            "point_counts": np.concatenate([o.point_counts for o in oracles]).tolist(),
            "views": np.repeat(np.arange(len(oracles)), np.diff(starts)).tolist(),
        },
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


def read_arrays(npz: Path, names: tuple[str, ...]) -> dict[str, np.ndarray]:
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
