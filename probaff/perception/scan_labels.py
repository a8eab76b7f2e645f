"""Chapter 2's pipeline from a scanned office scene to labelled segments with ground truth.

One office scene (`probaff.sim.office.OfficeScene`) is scanned by the depth camera
(`probaff.sim.camera.scan_views`) from a pan-tilt head; each view is cut into segments and
described on its own, as the thesis classifies each view before merging:

1. the view's points are taken through its estimated (registered) pose; pixels without a
   return (NaN depth: out of range, grazing angle, edge dropout) are dropped and counted;
2. the points are brought into the robot frame and get k-NN PCA normals and curvature
   (`estimate_normals`, oriented towards the camera);
3. region growing (`region_growing`) cuts them into smooth segments;
4. each segment gets its 25 features (`segment_features`, normals towards the camera) and
   its 23 context descriptors (`context_features`: support, load, free space around);
5. each segment's ground-truth object is the majority of its points' object ids, and the
   share of that majority is its purity; the segment takes that object's labels
   (`OfficeScene.label_of`). Floor and wall segments are kept with all-false labels (the
   office's rule: the floor and the walls carry no label; the thesis's 195 segments include
   them), unless ``PerceptionConfig.keep_structure`` is False, which drops them.

`label_dataset` samples office scenes, scans each from its robot's pose and stacks the segments
of all views of all scenes, with the scene index as the group for cross-validation by scene.

Frames and units: metres and degrees (names ending in ``_deg``). The world frame is the
scene's (z up). The robot frame is the one of the thesis and of the features: origin at the
robot's ``(x, y)`` on the floor, x forward along its yaw, y left, z up; with the office's
default robot pose (origin, yaw 0) it is the world frame. The head frame is the robot frame
raised by ``head_height``; views pan about its z and tilt about the panned y (positive tilt
looks down). Every point, centroid and feature of the result is in the robot frame.

Defaults of `PerceptionConfig` and their sources (numbers measured on noisy 320 x 240 scans of
5 office scenes sampled with seed 0, three views each, about 1.1 million returned points):

- ``k = 30`` neighbours for normals and region growing: PCL's tutorial value, which the thesis
  uses.
- ``smoothness_deg = 7``: not PCL's 3 degrees. With the camera's noise (1.5 mm at 1 m, growing
  with the square of the range) the normals of a plane scatter by a few degrees, and 3 degrees
  leaves many points unassigned. Unassigned share of the returned points, and point-weighted
  mean segment purity: 3 degrees 0.21 and 1.000; 7 degrees 0.10 and 0.998; 10 degrees 0.05
  and 0.89; 15 degrees 0.02 and 0.83. From 10 degrees on, large segments take in more than one
  object (growth crosses creases that the k-NN normals round off); 7 degrees assigns twice as
  many points as 3 at almost no loss of purity. Lowering the curvature
  threshold instead does not help on noisy scans: 10 degrees with a threshold of 0.05 leaves
  0.21 unassigned, with 0.02 0.64, since noise raises every point's curvature.
- ``curvature_threshold = 1.0``: PCL's default (above every surface variation, so every point
  may seed).
- ``min_size = 50`` points: PCL's tutorial value.
- ``neighbour_distance = 0.15`` m: `segment_features`'s default (see there).
- views ``pans_deg = (-30, 0, 30)``, ``tilts_deg = (30,)``: our choice. Three views 30 degrees
  apart overlap by about half the 57-degree field of view, so `merge_views` has segments seen
  twice; a 30-degree tilt from 1.2 m puts the optical axis on the floor 2.1 m ahead, the
  middle of the 5 m room, and the vertical field of view (43 degrees) spans the floor from 0.95
  m to beyond the far wall.
- ``head_height = 1.2`` m: about a PR2's head with its torso down.
- ``noise = True``, ``registration = True``: the camera's sensor model and the registration
  error between views (``worlds/camera.yaml``).

Every view must image some of the floor (z = 0, on which every object stands) within the
camera's depth range: a view whose rays miss the floor, or meet it only nearer than the
camera's ``min_range`` or farther than its ``max_range``, returns no usable points. A pixel ray
of unit depth whose downward component is ``s`` meets the floor at depth ``h / s`` from a
camera ``h`` above it; over the image ``s`` spans ``[s_min, s_max]`` (`CameraSpec.floor_band`),
so a view sees floor in range exactly when ``s_max > 0`` and
``min_range s_min <= h <= max_range s_max`` (`CameraSpec.floor_heights`). With the Kinect's
43-degree vertical field of view and 0.5-4.5 m range, a 30-degree tilt allows head heights of
0.08-3.78 m, and a view tilted up by more than about 21 degrees never sees the floor.
`PerceptionConfig` checks its ``head_height`` and ``tilts_deg`` this way against the default
camera (`CameraSpec()`, the one of ``worlds/camera.yaml``) when it is built; `scan_segments`,
`scenes_dataset` and `label_dataset` check again against the camera they are given, and its
resolution against ``k``, before any scan.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from probaff._checks import check_count, check_positive, real_float64
from probaff.errors import InputError
from probaff.perception.labels import LABELS, label_index
from probaff.perception.normals import Normals, estimate_normals
from probaff.perception.region_growing import Segmentation, region_growing
from probaff.perception.segment_context import CONTEXT_NAMES, context_features
from probaff.perception.segment_features import FEATURE_NAMES, segment_features
from probaff.sim.camera import (
    CameraSpec,
    DepthCamera,
    DepthImage,
    head_views,
    load_camera,
    scan_views,
)
from probaff.sim.office import OfficeScene, sample_office_scenes
from probaff.sim.office_config import OfficeSpec

__all__ = [
    "LabelDataset",
    "PerceptionConfig",
    "ScanSegments",
    "ViewSegments",
    "grow_regions",
    "head_pose",
    "label_dataset",
    "scan_segments",
    "scenes_dataset",
]

_STRUCTURE = ("floor", "wall")  # object kinds that carry no label


def _angles(name: str, value: Sequence[float]) -> tuple[float, ...]:
    bad = InputError(f"{name} must be a non-empty list of finite angles (degrees), got {value!r}.")
    if isinstance(value, (str, bytes)):
        raise bad
    arr = real_float64(value)
    if arr is None:
        raise bad
    arr = np.atleast_1d(arr)
    if arr.ndim != 1 or arr.size == 0 or not np.all(np.isfinite(arr)):
        raise bad
    return tuple(float(a) for a in arr)


def _number(name: str, value: object) -> float:
    """`value` as a finite float > 0, or an `InputError` naming `name`."""
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise InputError(f"{name} must be a finite number > 0, got {value!r}.")
    check_positive(name, float(value))
    return float(value)


def _check_views(
    tilts_deg: tuple[float, ...], head_height: float, spec: CameraSpec, camera: str
) -> None:
    """Raise `InputError` unless every tilt images floor within range from `head_height`.

    Args:
        tilts_deg: The views' tilts (degrees, down positive).
        head_height: The camera centre's height above the floor (m).
        spec: The camera.
        camera: How the camera is named in messages.
    """
    band = f"range {spec.min_range:g}-{spec.max_range:g} m"
    lo, hi = (0.0, tilts_deg[0]), (math.inf, tilts_deg[0])  # (height, the tilt that sets it)
    for tilt in tilts_deg:
        heights = spec.floor_heights(tilt)
        if heights is None:
            raise InputError(
                f"tilts_deg holds {tilt:g}: a view tilted so sees no floor with {camera} (its "
                f"whole field of view is above the horizon); use tilts above "
                f"{spec.floor_tilt_deg:.1f} degrees (positive tilts look down)."
            )
        lo = max(lo, (heights[0], tilt))
        hi = min(hi, (heights[1], tilt))
    if lo[0] > hi[0]:
        raise InputError(
            f"tilts_deg {list(tilts_deg)} cannot all image the floor from one head height with "
            f"{camera} ({band}): the view tilted {lo[1]:g} degrees needs head_height >= "
            f"{lo[0]:.3f} m, the one tilted {hi[1]:g} degrees head_height <= {hi[0]:.3f} m; "
            "use closer tilts."
        )
    if not lo[0] <= head_height <= hi[0]:
        raise InputError(
            f"head_height {head_height:g} m leaves {camera} ({band}) unable to image the floor "
            f"at tilts_deg {list(tilts_deg)}; head_height must lie in [{lo[0]:.3f}, "
            f"{hi[0]:.3f}] m."
        )


def _check_camera(camera: object, config: PerceptionConfig) -> DepthCamera:
    """`camera` after checking it against `config`, before any scan."""
    if not isinstance(camera, DepthCamera):
        raise InputError(
            f"camera must be a DepthCamera (DepthCamera(load_camera())), got "
            f"{type(camera).__name__}."
        )
    spec = camera.spec
    if spec.width * spec.height < config.k:
        raise InputError(
            f"k={config.k} exceeds the camera's {spec.width} x {spec.height} = "
            f"{spec.width * spec.height} pixels: no view can return k points; lower k or "
            "raise the camera's resolution."
        )
    return camera


@dataclass(frozen=True)
class PerceptionConfig:
    """Settings of the scan-to-segments pipeline (see the module docstring for each source).

    Attributes:
        k: Neighbours of each point for normals and region growing (>= 3).
        smoothness_deg: Region growing's smoothness angle (degrees, in (0, 180)).
        curvature_threshold: Region growing's seed curvature threshold (> 0).
        min_size: Smallest segment kept by region growing (points).
        neighbour_distance: Shortest distance of neighbouring segments for the occupancy
            features (m, > 0).
        pans_deg: (P,) pan angles of the head's views (degrees, left positive).
        tilts_deg: (Q,) tilt angles of the head's views (degrees, down positive).
        head_height: Height of the head above the floor (m); every view must image the
            floor within the camera's range from it (see the module docstring: 0.08-3.79 m
            for a 30-degree tilt with the default camera).
        noise: Apply the camera's sensor model (noise, quantisation, dropouts).
        registration: Perturb each view's pose by the camera's registration error.
        keep_structure: Keep floor and wall segments (all-false labels); False drops them.

    Raises:
        InputError: Naming the first field out of range or of the wrong type, or a
            ``head_height`` or ``tilts_deg`` from which a view of the default camera images no
            floor within its range, with the valid range of ``head_height``.
    """

    k: int = 30
    smoothness_deg: float = 7.0
    curvature_threshold: float = 1.0
    min_size: int = 50
    neighbour_distance: float = 0.15
    pans_deg: tuple[float, ...] = (-30.0, 0.0, 30.0)
    tilts_deg: tuple[float, ...] = (30.0,)
    head_height: float = 1.2
    noise: bool = True
    registration: bool = True
    keep_structure: bool = True

    def __post_init__(self) -> None:
        object.__setattr__(self, "k", check_count("k", self.k, minimum=3))
        object.__setattr__(self, "min_size", check_count("min_size", self.min_size))
        for name in ("smoothness_deg", "curvature_threshold", "neighbour_distance", "head_height"):
            object.__setattr__(self, name, _number(name, getattr(self, name)))
        if not self.smoothness_deg < 180.0:
            raise InputError(f"smoothness_deg must be < 180 degrees, got {self.smoothness_deg}.")
        object.__setattr__(self, "pans_deg", _angles("pans_deg", self.pans_deg))
        object.__setattr__(self, "tilts_deg", _angles("tilts_deg", self.tilts_deg))
        for name in ("noise", "registration", "keep_structure"):
            if not isinstance(getattr(self, name), (bool, np.bool_)):
                raise InputError(f"{name} must be True or False, got {getattr(self, name)!r}.")
            object.__setattr__(self, name, bool(getattr(self, name)))
        _check_views(self.tilts_deg, self.head_height, CameraSpec(), "the default camera")


@dataclass(frozen=True, eq=False)
class ViewSegments:
    """The labelled segments of one view; S segments, N returned points.

    Attributes:
        features: (S, 25) segment features, columns `FEATURE_NAMES` (robot frame).
        context: (S, 23) context descriptors, columns `CONTEXT_NAMES` (robot frame).
        labels: (S, 6) bool ground-truth labels of each segment's majority object, `LABELS`.
        object_ids: (S,) int64 majority object id of each segment.
        purity: (S,) share of each segment's points on its majority object, in (0, 1].
        centroids: (S, 3) segment centroids (robot frame, m).
        point_counts: (S,) int64 points per segment.
        points: (N, 3) the view's returned points (robot frame, m).
        point_segments: (N,) int64 each point's row in the segment arrays, -1 when it is in
            no kept segment (unassigned by region growing, or its segment was skipped).
        point_object_ids: (N,) int64 each point's ground-truth object id.
        viewpoint: (3,) the camera centre through the estimated pose (robot frame, m).
        n_nan: Pixels without a return (NaN depth), dropped.
        n_unassigned: Returned points that region growing left in no segment.
        n_skipped: Segments skipped by the features (too small or degenerate) or dropped as
            floor or wall when ``keep_structure`` is False.
    """

    features: np.ndarray
    context: np.ndarray
    labels: np.ndarray
    object_ids: np.ndarray
    purity: np.ndarray
    centroids: np.ndarray
    point_counts: np.ndarray
    points: np.ndarray
    point_segments: np.ndarray
    point_object_ids: np.ndarray
    viewpoint: np.ndarray
    n_nan: int
    n_unassigned: int
    n_skipped: int

    @property
    def n_segments(self) -> int:
        """S, the number of segments."""
        return len(self.features)


def _stacked(name: str, doc: str) -> Any:
    """A read-only property: the views' arrays `name`, concatenated view by view."""

    def get(self: ScanSegments) -> np.ndarray:
        return np.concatenate([getattr(v, name) for v in self.views])

    return property(get, doc=doc)


@dataclass(frozen=True, eq=False)
class ScanSegments:
    """The segments of every view of one scan.

    Attributes:
        views: One `ViewSegments` per view, in `head_views` order (pan-major).
        camera_poses: (V, 4, 4) the true ``T_world_camera`` of each view (world frame).
    """

    views: tuple[ViewSegments, ...]
    camera_poses: np.ndarray

    features = _stacked("features", "(S, 25) features of all views' segments, view by view.")
    context = _stacked("context", "(S, 23) context descriptors of all views' segments.")
    labels = _stacked("labels", "(S, 6) bool labels of all views' segments.")
    object_ids = _stacked("object_ids", "(S,) int64 majority object ids of all views' segments.")
    purity = _stacked("purity", "(S,) purity of all views' segments.")
    point_counts = _stacked("point_counts", "(S,) int64 points of all views' segments.")

    @property
    def view_index(self) -> np.ndarray:
        """(S,) int64 the view of each segment."""
        return np.concatenate(
            [np.full(v.n_segments, i, dtype=np.int64) for i, v in enumerate(self.views)]
        )

    @property
    def n_nan(self) -> int:
        """Pixels without a return over all views."""
        return sum(v.n_nan for v in self.views)


@dataclass(frozen=True, eq=False)
class LabelDataset:
    """Segments of several scanned scenes, stacked; S segments in all.

    Attributes:
        features: (S, 25) segment features (robot frame of each scene).
        labels: (S, 6) bool ground-truth labels, columns `LABELS`.
        groups: (S,) int64 scene index of each segment (0 .. n_scenes - 1).
        views: (S,) int64 view index of each segment within its scene.
        object_ids: (S,) int64 majority object id (unique within a scene only).
        purity: (S,) purity of each segment.
        centroids: (S, 3) centroids (robot frame of each scene, m).
        point_counts: (S,) int64 points per segment.
        n_nan: Pixels without a return over all scans.
        n_points: Returned points over all scans.
        n_unassigned: Returned points left in no segment over all scans.
        feature_names: The 25 column names of `features`.
    """

    features: np.ndarray
    labels: np.ndarray
    groups: np.ndarray
    views: np.ndarray
    object_ids: np.ndarray
    purity: np.ndarray
    centroids: np.ndarray
    point_counts: np.ndarray
    n_nan: int
    n_points: int
    n_unassigned: int
    feature_names: tuple[str, ...] = FEATURE_NAMES

    def label(self, name: str) -> np.ndarray:
        """(S,) bool column of label `name`.

        Raises:
            InputError: For a name not in `LABELS`.
        """
        return self.labels[:, label_index(name)]


def _robot_transform(pose: tuple[float, float, float]) -> np.ndarray:
    """(4, 4) ``T_world_robot`` of a robot pose ``(x, y, yaw)`` (m, m, rad)."""
    x, y, yaw = pose
    c, s = math.cos(yaw), math.sin(yaw)
    T = np.eye(4)
    T[:3, :3] = [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]
    T[:2, 3] = (x, y)
    return T


def _check_scene(scene: object) -> OfficeScene:
    if not isinstance(scene, OfficeScene):
        raise InputError(
            f"scene must be a probaff.sim.office.OfficeScene (from sample_office_scenes or "
            f"assemble_office_scene), got {type(scene).__name__}."
        )
    return scene


def _check_config(config: object) -> PerceptionConfig:
    if config is None:
        return PerceptionConfig()
    if not isinstance(config, PerceptionConfig):
        raise InputError(f"config must be a PerceptionConfig, got {type(config).__name__}.")
    return config


def _check_head(poses: np.ndarray, spec: CameraSpec) -> None:
    """Raise `InputError` unless every view pose (V, 4, 4) images floor within range."""
    for pose in poses:
        s_min, s_max = spec.floor_band(pose[:3, :3])
        h = float(pose[2, 3])
        near = h / s_max if h > 0 and s_max > 0 else math.inf
        far = h / s_min if s_min > 0 else math.inf
        if near > spec.max_range or far < spec.min_range:
            raise InputError(
                f"T_world_head puts the camera {h:.3f} m above the floor, where a view of it "
                f"images no floor within the camera's range {spec.min_range:g}-"
                f"{spec.max_range:g} m; place the head above the floor at a height the "
                "views can see it from (see PerceptionConfig.head_height)."
            )


def _check_setup(config: PerceptionConfig, camera: object) -> DepthCamera:
    """The camera (``DepthCamera(load_camera())`` when None), checked against `config`."""
    cam = DepthCamera(load_camera()) if camera is None else camera
    cam = _check_camera(cam, config)
    _check_views(config.tilts_deg, config.head_height, cam.spec, "the camera")
    return cam


def head_pose(scene: OfficeScene, height: float = 1.2) -> np.ndarray:
    """The head's pose above the scene's robot: the robot frame raised by `height`.

    Args:
        scene: The office scene; its ``robot_pose`` ``(x, y, yaw)`` places the head.
        height: Height of the head above the floor (m, > 0).

    Returns:
        (4, 4) ``T_world_head`` (head frame: x forward, y left, z up).

    Raises:
        InputError: For a scene that is not an `OfficeScene` or a bad height.
    """
    sc = _check_scene(scene)
    check_positive("height", height)
    T = _robot_transform(sc.robot_pose)
    T[2, 3] = float(height)
    return T


def _majority(point_ids: np.ndarray, seg: np.ndarray, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Majority object (S,) and its share (S,) of the points `point_ids` (M,) per segment."""
    ids, inverse = np.unique(point_ids, return_inverse=True)
    table = np.zeros((n, len(ids)), dtype=np.int64)
    np.add.at(table, (seg, inverse), 1)
    top = table.argmax(axis=1)
    share = table[np.arange(n), top] / table.sum(axis=1)
    return ids[top].astype(np.int64), share


def grow_regions(points: np.ndarray, normals: Normals, config: PerceptionConfig) -> Segmentation:
    """Cut a view's points into smooth segments by region growing with `config`'s settings.

    Step 3 of the module docstring: `region_growing` with ``k``, ``smoothness_deg``,
    ``curvature_threshold`` and ``min_size`` of `config`, over the neighbours that
    `estimate_normals` found.

    Args:
        points: (N, 3) points (m).
        normals: Their normals, curvature and neighbours, from
            ``estimate_normals(points, config.k)``.
        config: The settings.

    Returns:
        The `Segmentation` of the N points.
    """
    return region_growing(
        points,
        normals.normals,
        normals.curvature,
        k=config.k,
        smoothness_deg=config.smoothness_deg,
        curvature_threshold=config.curvature_threshold,
        min_size=config.min_size,
        neighbours=normals.neighbours,
    )


def _view_segments(
    view: DepthImage,
    scene: OfficeScene,
    T_robot_world: np.ndarray,
    config: PerceptionConfig,
) -> ViewSegments:
    """Segments, features and ground truth of one view (see the module docstring)."""
    world = view.points()
    finite = np.all(np.isfinite(world), axis=1)
    n_nan = int(view.depth.size - np.count_nonzero(finite))
    world, pids = world[finite], view.point_ids()[finite]
    R, t = T_robot_world[:3, :3], T_robot_world[:3, 3]
    pts = world @ R.T + t
    eye = T_robot_world @ view.T_world_camera_estimated[:, 3]
    viewpoint = eye[:3]
    if len(pts) < config.k:
        raise InputError(
            f"a view returned {len(pts)} point(s), fewer than k={config.k}; point the head "
            "at the scene (pans_deg, tilts_deg, head_height) or lower k."
        )
    nrm = estimate_normals(pts, config.k, viewpoint=viewpoint)
    seg = grow_regions(pts, nrm, config)
    feats = segment_features(
        pts, seg.labels, neighbour_distance=config.neighbour_distance, viewpoint=viewpoint
    )
    kept = feats.segment_ids
    row = np.full(seg.n_segments, -1, dtype=np.int64)
    row[kept] = np.arange(len(kept))
    point_row = np.where(seg.labels >= 0, row[np.maximum(seg.labels, 0)], -1)
    n_skipped = feats.n_skipped
    on = point_row >= 0
    if len(kept):
        oids, purity = _majority(pids[on], point_row[on], len(kept))
    else:
        oids, purity = np.zeros(0, dtype=np.int64), np.zeros(0)
    kinds = {o.id: o.kind for o in scene.objects}
    structure = np.array([kinds[int(i)] in _STRUCTURE for i in oids], dtype=bool)
    keep = np.ones(len(kept), dtype=bool) if config.keep_structure else ~structure
    labels = np.zeros((len(kept), len(LABELS)), dtype=bool)
    for s, oid in enumerate(oids):
        labels[s] = scene.label_of(int(oid))
    counts = np.bincount(point_row[on], minlength=len(kept)).astype(np.int64)
    if not keep.all():
        n_skipped += int((~keep).sum())
        renumber = np.full(len(kept), -1, dtype=np.int64)
        renumber[keep] = np.arange(int(keep.sum()))
        point_row = np.where(on, renumber[np.maximum(point_row, 0)], -1)
    n_kept = int(keep.sum())
    context = context_features(pts, point_row, n_kept).reshape(n_kept, len(CONTEXT_NAMES))
    return ViewSegments(
        features=feats.features[keep],
        context=context,
        labels=labels[keep],
        object_ids=oids[keep],
        purity=purity[keep],
        centroids=feats.centroids[keep],
        point_counts=counts[keep],
        points=pts,
        point_segments=point_row,
        point_object_ids=pids.astype(np.int64),
        viewpoint=viewpoint,
        n_nan=n_nan,
        n_unassigned=int(np.count_nonzero(seg.labels < 0)),
        n_skipped=n_skipped,
    )


def scan_segments(
    scene: OfficeScene,
    camera: DepthCamera,
    T_world_head: np.ndarray,
    config: PerceptionConfig | None = None,
    rng: np.random.Generator | None = None,
) -> ScanSegments:
    """Scan one office scene from a pan-tilt head and label each view's segments.

    Args:
        scene: The office scene (its primitives and ground-truth labels).
        camera: The depth camera.
        T_world_head: (4, 4) the head's pose in the world (e.g. `head_pose`).
        config: The pipeline's settings; `PerceptionConfig()` when None.
        rng: The only source of random draws (noise, dropouts, registration);
            ``np.random.default_rng(0)`` when None.

    Returns:
        The `ScanSegments`, one `ViewSegments` per view of ``config.pans_deg`` x
        ``config.tilts_deg``.

    Raises:
        InputError: For a bad scene, camera, head pose, config or rng; a view that images no
            floor within the camera's range, or a camera with fewer pixels than ``config.k``
            (both before any scan); a camera centre inside an object; or a view with fewer
            returned points than ``config.k``.

    Example:
        Scan the first office scene of seed 0 from the head's centre view (the chapter 2
        study scans three) and read its segments' 25 features, 23 context descriptors and
        ground-truth labels, the inputs of `LabelClassifier` and `BoostedLabelClassifier`:

        >>> import numpy as np
        >>> from probaff.perception import PerceptionConfig, head_pose, scan_segments
        >>> from probaff.sim import DepthCamera, load_camera, load_office, sample_office_scenes
        >>> scene = sample_office_scenes(load_office(), 1, seed=0)[0]
        >>> config = PerceptionConfig(pans_deg=(0.0,))
        >>> pose = head_pose(scene, config.head_height)  # (4, 4) the head in the world
        >>> camera = DepthCamera(load_camera())
        >>> scan = scan_segments(scene, camera, pose, config, np.random.default_rng(0))
        >>> view = scan.views[0]
        >>> view.n_segments, view.features.shape, view.context.shape, view.labels.shape
        (28, (28, 25), (28, 23), (28, 6))
        >>> view.labels.sum(axis=0)  # segments with each label, in LABELS order
        array([ 9, 12, 16, 12,  7, 11])
    """
    sc = _check_scene(scene)
    cfg = _check_config(config)
    cam = _check_camera(camera, cfg)
    poses = head_views(T_world_head, cfg.pans_deg, cfg.tilts_deg)
    _check_head(poses, cam.spec)
    images = scan_views(
        cam,
        sc.primitives,
        poses,
        rng=rng,
        registration=cfg.registration,
        noise=cfg.noise,
    )
    T_robot_world = np.linalg.inv(_robot_transform(sc.robot_pose))
    views = tuple(_view_segments(im, sc, T_robot_world, cfg) for im in images)
    return ScanSegments(views=views, camera_poses=poses)


def scenes_dataset(
    scenes: Sequence[OfficeScene],
    seed: int = 0,
    config: PerceptionConfig | None = None,
    camera: DepthCamera | None = None,
) -> LabelDataset:
    """Scan each scene from its robot's head and stack the segments; groups = scene index.

    Scene i is scanned with the stream ``np.random.default_rng([seed, i])``, so the result
    depends only on the scenes, `seed` and `config`.

    Args:
        scenes: The office scenes (at least one).
        seed: Seed of the scans' random streams (an integer >= 0).
        config: The pipeline's settings; `PerceptionConfig()` when None.
        camera: The depth camera; ``DepthCamera(load_camera())`` when None.

    Returns:
        The stacked `LabelDataset`.

    Raises:
        InputError: For no scenes, a bad seed, config or camera, or any error of
            `scan_segments`.
    """
    if isinstance(scenes, OfficeScene) or not isinstance(scenes, Sequence) or not scenes:
        raise InputError("scenes is empty; give a list of at least one OfficeScene.")
    seed = check_count("seed", seed, minimum=0)
    cfg = _check_config(config)
    cam = _check_setup(cfg, camera)
    parts: list[ScanSegments] = []
    for i, scene in enumerate(scenes):
        head = head_pose(_check_scene(scene), cfg.head_height)
        rng = np.random.default_rng([seed, i])
        parts.append(scan_segments(scene, cam, head, cfg, rng))
    groups = [np.full(len(p.object_ids), i, dtype=np.int64) for i, p in enumerate(parts)]
    return LabelDataset(
        features=np.concatenate([p.features for p in parts]),
        labels=np.concatenate([p.labels for p in parts]),
        groups=np.concatenate(groups),
        views=np.concatenate([p.view_index for p in parts]),
        object_ids=np.concatenate([p.object_ids for p in parts]),
        purity=np.concatenate([p.purity for p in parts]),
        centroids=np.concatenate([v.centroids for p in parts for v in p.views]),
        point_counts=np.concatenate([p.point_counts for p in parts]),
        n_nan=sum(p.n_nan for p in parts),
        n_points=sum(len(v.points) for p in parts for v in p.views),
        n_unassigned=sum(v.n_unassigned for p in parts for v in p.views),
    )


def label_dataset(
    spec: OfficeSpec,
    n_scenes: int,
    seed: int = 0,
    config: PerceptionConfig | None = None,
    camera: DepthCamera | None = None,
) -> LabelDataset:
    """Sample office scenes, scan each from its robot's head and stack the labelled segments.

    The scenes are `sample_office_scenes(spec, n_scenes, seed)`; the scans are those of
    `scenes_dataset` with the same `seed`. The same arguments give the same dataset.

    Args:
        spec: The office world (`load_office`).
        n_scenes: How many scenes (a positive integer; the thesis used 10).
        seed: The root seed of scenes and scans (an integer >= 0).
        config: The pipeline's settings; `PerceptionConfig()` when None.
        camera: The depth camera; ``DepthCamera(load_camera())`` when None.

    Returns:
        The `LabelDataset`, ``groups`` the scene index.

    Raises:
        InputError: For a non-positive or non-integer `n_scenes`, a bad spec or seed, or any
            error of `scenes_dataset`.
    """
    n = check_count("n_scenes", n_scenes)
    seed = check_count("seed", seed, minimum=0)
    cfg = _check_config(config)
    cam = _check_setup(cfg, camera)
    scenes = sample_office_scenes(spec, n, seed)
    return scenes_dataset(scenes, seed, cfg, cam)
