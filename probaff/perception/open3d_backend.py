"""Open3D counterparts of the hand-written perception, for side-by-side measurement.

Open3D (``open3d-cpu``, the point-cloud library the field uses) does k-NN normals, KD-tree
neighbour search, DBSCAN clustering and ray casting (``RaycastingScene``). This module wraps
the four with the hand-written functions' inputs and outputs, so that
``benchmarks/open3d_perception.py`` can run both on the same scans:

* `o3d_normals`: ``PointCloud.estimate_normals`` with ``KDTreeSearchParamKNN(k)``, oriented
  towards a viewpoint, against `probaff.perception.normals.estimate_normals`;
* `o3d_knn`: ``open3d.core.nns.NearestNeighborSearch.knn_search`` against scipy's
  ``cKDTree.query``;
* `o3d_dbscan`: ``PointCloud.cluster_dbscan`` against region growing
  (`probaff.perception.region_growing`);
* `o3d_cast`: the primitives of a `PrimitiveScene` tessellated into triangle meshes and cast
  with ``RaycastingScene``, against `probaff.sim.camera.DepthCamera.cast`.

Open3D is an optional dependency, measured but not adopted. On 30 office scans (centre view,
one thread, ``benchmarks/open3d_perception.py --scenes 30``, on a machine shared with other
work) its ray caster, neighbour search and normals agree with the hand-written ones (the same
object at every pixel and a median depth difference below 0.001 mm; the same 30 neighbours for
99.7 % of the points; a median normal angle below 0.001 degrees) and take 0.4, 0.8 and 0.55
times as long (0.019 against 0.048 s, 0.27 against 0.33 s and 0.23 against 0.41 s per scan).
The 0.3 % of neighbour lists that differ are ties broken otherwise, so its normals would change
the segments. Its DBSCAN (eps 0.03 m) takes 2.3 times as long as region growing (0.24 against
0.11 s), is as pure (0.997 for both, point-weighted) and more complete (0.75 and 0.68) but
leaves more points in no segment (0.17 and 0.12); it cuts by distance alone, not by surface
smoothness, and the thesis's logistic regressions label its segments worse (mean precision /
recall 73.4 / 55.8 % against 77.4 / 73.9 %, 4-fold CV by scene). The pipeline keeps the
hand-written pieces because Open3D cannot be a dependency of the project's install: ``pip
install open3d-cpu`` (0.20.0, a 105 MB wheel, and 17 packages the project does not carry:
dash, plotly, flask, ipywidgets and theirs) succeeds, but ``import open3d`` then fails with
``ImportError: libusb-1.0.so.0: cannot open shared object file: No such file or directory`` (a
system library, absent from a bare Linux image; the 30-scene run above loaded it from Debian's
``libusb-1.0-0`` through ``LD_LIBRARY_PATH``) and, installed without its dependencies, with
``ModuleNotFoundError: No module named 'plotly'`` and then ``'dash'`` (imported at start-up by
its visualisation package), neither of which the project's install carries; and a pipeline
whose numbers change with an optional library would make the study's results depend on the
machine. The speed-ups are recorded here for a future install that can carry it. Each function
raises `InputError` for a cloud of the wrong dtype or shape before Open3D is imported, and
`require_open3d` an `ImportError` saying how to install it when it is missing.

Frames and units: points in any one frame (the robot frame in the study), metres.
"""

from __future__ import annotations

from types import ModuleType
from typing import Any

import numpy as np

from probaff._checks import check_count, check_number
from probaff.errors import InputError
from probaff.sim.primitives import PrimitiveScene

__all__ = ["o3d_cast", "o3d_dbscan", "o3d_knn", "o3d_normals", "require_open3d"]

INSTALL = (
    "pip install open3d-cpu==0.20.0 (it also needs the system library libusb-1.0, e.g. "
    "apt-get install libusb-1.0-0)"
)


def require_open3d() -> ModuleType:
    """The ``open3d`` module, or an `ImportError` naming how to install it."""
    try:
        import open3d
    except ImportError as exc:  # missing wheel, or a system library it loads
        raise ImportError(
            f"the Open3D-backed perception needs open3d, which failed to import ({exc}); "
            f"install it with: {INSTALL}."
        ) from exc
    return open3d


def _cloud(name: str, points: Any, min_points: int = 1) -> np.ndarray:
    """`points` as a C-contiguous (N, 3) float64 array, or an `InputError` naming `name`."""
    arr = np.asarray(points)
    if arr.dtype.kind != "f":
        raise InputError(
            f"{name} must be a floating-point (N, 3) array (float32 or float64), got dtype "
            f"{arr.dtype}; convert it with np.asarray({name}, dtype=np.float64)."
        )
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise InputError(f"{name} must have shape (N, 3), got {arr.shape}.")
    if len(arr) < min_points:
        raise InputError(f"{name} has {len(arr)} point(s); it needs at least {min_points}.")
    if not np.all(np.isfinite(arr)):
        raise InputError(f"{name} holds NaN or inf; drop those rows first.")
    return np.ascontiguousarray(arr, dtype=np.float64)


def o3d_normals(points: np.ndarray, k: int = 30, viewpoint: np.ndarray | None = None) -> np.ndarray:
    """Open3D's k-NN PCA normals, oriented towards `viewpoint`.

    Args:
        points: (N, 3) float points (m), finite, N >= k.
        k: Neighbours of each point (>= 3).
        viewpoint: (3,) the point the normals face (m); the origin when None.

    Returns:
        (N, 3) unit normals.

    Raises:
        InputError: For a cloud of the wrong dtype or shape, non-finite, or smaller than k.
        ImportError: Without Open3D.
    """
    k = check_count("k", k, minimum=3)
    pts = _cloud("points", points, k)
    view = (
        np.zeros(3) if viewpoint is None else _cloud("viewpoint", np.reshape(viewpoint, (1, 3)))[0]
    )
    o3d = require_open3d()
    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(pts))
    cloud.estimate_normals(o3d.geometry.KDTreeSearchParamKNN(k))
    normals = np.asarray(cloud.normals).copy()
    flip = np.einsum("ij,ij->i", normals, view - pts) < 0
    normals[flip] *= -1.0
    return normals


def o3d_knn(points: np.ndarray, k: int) -> np.ndarray:
    """(N, k) int64 indices of each point's k nearest points (itself first), by Open3D.

    Raises:
        InputError: For a cloud of the wrong dtype or shape, non-finite, or smaller than k.
        ImportError: Without Open3D.
    """
    k = check_count("k", k)
    pts = _cloud("points", points, k)
    o3d = require_open3d()
    tensor = o3d.core.Tensor(pts)
    search = o3d.core.nns.NearestNeighborSearch(tensor)
    search.knn_index()
    idx, _ = search.knn_search(tensor, k)
    return idx.numpy().astype(np.int64)


def o3d_dbscan(points: np.ndarray, eps: float, min_points: int) -> np.ndarray:
    """(N,) int64 DBSCAN cluster of each point (-1: noise), by Open3D.

    Raises:
        InputError: For a cloud of the wrong dtype or shape, or a bad `eps` or `min_points`.
        ImportError: Without Open3D.
    """
    radius = check_number("eps", eps, bound="> 0", unit="m")
    least = check_count("min_points", min_points)
    pts = _cloud("points", points)
    o3d = require_open3d()
    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(pts))
    return np.asarray(cloud.cluster_dbscan(radius, least), dtype=np.int64)


def _meshes(o3d: ModuleType, scene: PrimitiveScene, resolution: int) -> list[tuple[Any, int]]:
    """(legacy triangle mesh, object id) of every box and cylinder of `scene` (world frame)."""
    out = []
    for (cx, cy, cz, sx, sy, sz, yaw), oid in zip(scene.boxes, scene.box_ids, strict=True):
        mesh = o3d.geometry.TriangleMesh.create_box(sx, sy, sz)
        mesh.translate((-sx / 2, -sy / 2, -sz / 2))
        c, s = np.cos(yaw), np.sin(yaw)
        mesh.rotate(np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]), center=(0, 0, 0))
        mesh.translate((cx, cy, cz))
        out.append((mesh, int(oid)))
    for (cx, cy, cz, r, h), oid in zip(scene.cylinders, scene.cylinder_ids, strict=True):
        mesh = o3d.geometry.TriangleMesh.create_cylinder(r, h, resolution=resolution)
        mesh.translate((cx, cy, cz))
        out.append((mesh, int(oid)))
    return out


def o3d_cast(
    scene: PrimitiveScene,
    rays: np.ndarray,
    T_world_camera: np.ndarray,
    *,
    resolution: int = 64,
) -> tuple[np.ndarray, np.ndarray]:
    """Depth along the optical axis and object id of each camera ray, by Open3D.

    Args:
        scene: The primitives (world frame).
        rays: (R, 3) float rays in the camera frame at unit depth (``CameraSpec.pixel_rays``
            reshaped).
        T_world_camera: (4, 4) camera pose.
        resolution: Segments of each cylinder's tessellated circle (>= 3).

    Returns:
        ``(depth (R,), object_id (R,))``: inf and -1 where a ray hits nothing.

    Raises:
        InputError: For a scene that is not a `PrimitiveScene`, rays of the wrong dtype or
            shape, or a pose that is not (4, 4) and finite.
        ImportError: Without Open3D.
    """
    if not isinstance(scene, PrimitiveScene):
        raise InputError(f"scene must be a PrimitiveScene, got {type(scene).__name__}.")
    d_cam = _cloud("rays", rays)
    pose = np.asarray(T_world_camera, dtype=np.float64)
    if pose.shape != (4, 4) or not np.all(np.isfinite(pose)):
        raise InputError(f"T_world_camera must be a finite (4, 4) pose, got shape {pose.shape}.")
    steps = check_count("resolution", resolution, minimum=3)
    o3d = require_open3d()
    caster = o3d.t.geometry.RaycastingScene()
    ids = []
    for mesh, oid in _meshes(o3d, scene, steps):
        caster.add_triangles(o3d.t.geometry.TriangleMesh.from_legacy(mesh))
        ids.append(oid)
    d_world = d_cam @ pose[:3, :3].T
    unit = d_world / np.linalg.norm(d_world, axis=1, keepdims=True)
    origin = np.broadcast_to(pose[:3, 3], unit.shape)
    cast = caster.cast_rays(o3d.core.Tensor(np.hstack([origin, unit]).astype(np.float32)))
    t = cast["t_hit"].numpy().astype(np.float64)
    geometry = cast["geometry_ids"].numpy().astype(np.int64)
    hit = np.isfinite(t)
    lookup = np.asarray(ids, dtype=np.int64)
    object_id = np.where(hit, lookup[np.minimum(geometry, len(lookup) - 1)], -1)
    depth = np.where(hit, t / np.linalg.norm(d_cam, axis=1), np.inf)
    return depth, object_id
