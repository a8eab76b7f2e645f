"""A pinhole depth camera with a structured-light noise model, ray-cast against primitives.

The camera sees a `probaff.sim.primitives.PrimitiveScene` (upright boxes and vertical
cylinders). Every pixel casts one ray from the camera centre; the nearest positive hit over all
primitives gives the pixel's depth, object id and surface normal. Rays are cast in numpy,
vectorised over the pixels: the slab method in each box's own frame (yaw about world z), a
quadratic for a cylinder's side plus a plane test for each of its two caps. Each primitive is
tested only on the rays that enter the cone of its bounding sphere and have not yet hit anything
nearer, the primitives taken nearest first; this culling changes no result, only the cost.

Frames and units: metres and radians unless a name ends in ``_deg``. The world frame is the
scene's (z up). The camera frame is the optical frame of OpenCV: x right, y down, z forward
along the optical axis; a pose ``T_world_camera`` (4, 4) maps camera coordinates to world
coordinates. Pixel ``(u, v)`` (column, row) has its centre on the ray
``((u - cx) / fx, (v - cy) / fy, 1)`` with ``cx = (W - 1) / 2``, ``cy = (H - 1) / 2``,
``fx = W / (2 tan(hfov / 2))`` and ``fy = H / (2 tan(vfov / 2))``, so the field of view spans
the outer edges of the outer pixels. Depth is the distance along the optical axis (camera z),
as a Kinect reports it, not the length of the ray.

The sensor model, every parameter in ``worlds/camera.yaml`` (`CameraSpec`):

- Field of view 57 x 43 degrees and range 0.5-4.5 m: the Kinect v1's. Depths outside the range
  return nothing (NaN).
- Depth noise ``sigma(z) = a + b z^2``, Gaussian along the optical axis: the standard model of
  a structured-light (triangulating) sensor, whose disparity error is constant so the depth
  error grows as ``z^2 / (f baseline)`` (Khoshelham and Elberink, Sensors 12(2), 2012;
  Nguyen, Izadi and Lovell, 3DIMPVT 2012, who add the constant ``a``). ``b = 0.0015 / m``
  gives 1.5 mm at 1 m; ``a = 0``.
- Disparity quantisation: the noisy depth is turned into the disparity ``d = f baseline / z``
  (pixels), rounded to a multiple of ``disparity_step`` and turned back, so the depth step is
  ``z^2 disparity_step / (f baseline)``. Baseline 7.5 cm (Kinect v1). Step 1/32 px: our
  choice; the Kinect's 1/8 px at 640 x 480 would be 1/16 px at 320 x 240, a 2.8 mm step at 1 m
  that would swamp the 1.5 mm noise, where 1/32 px adds under 4 % to the noise's std.
- Dropouts: a ray whose angle to the surface normal exceeds ``max_incidence_deg`` (75 degrees,
  our choice after the Kinect's loss of returns at grazing angles) returns nothing; a pixel at
  a depth discontinuity (a 4-neighbour's exact depth differs by more than ``edge_threshold``,
  5 cm, or the neighbour's ray hits nothing) returns nothing with probability
  ``edge_probability`` (0.5, our choice), as a Kinect loses the pixels at object boundaries.
- Registration error (multi-view scans, `scan_views`): each view's estimated pose is its true
  pose times a random rigid transform in the camera frame, a translation with std
  ``translation_std`` (1 cm) per axis and a rotation vector with std ``rotation_std_deg``
  (0.5 degrees) per component: our choice, well below the 5 cm merge distance of chapter 2.

With ``noise=False`` the camera is ideal: the exact depth of every ray's hit within range, no
noise, quantisation or dropout. Random draws come only from the ``rng`` passed in (a
`numpy.random.Generator`, seeded 0 when none is given), so a scan is reproducible.

`head_views` gives the camera poses of a pan-tilt head: head frame x forward, y left, z up
(the robot convention of the thesis); pan turns about the head's z, then tilt about the new y
(positive tilt looks down); the camera centre is the head's origin.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike

from probaff._checks import check_count, check_finite, check_shape
from probaff.errors import ConfigError, InputError
from probaff.sim.config import (
    _check_spec,
    _count_field,
    _field,
    _load_root,
    _mapping,
    _no_extra,
    _pair,
    _range,
    _take,
)
from probaff.sim.primitives import PrimitiveScene

__all__ = [
    "CameraSpec",
    "DepthCamera",
    "DepthImage",
    "head_views",
    "load_camera",
    "scan_views",
]

_RIGID_TOL = 1e-6  # max deviation of R^T R from I, det R from 1 and the last row from (0, 0, 0, 1)

# Head axes (x forward, y left, z up) as columns of the optical frame: R_head_optical.
_R_HEAD_OPTICAL = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])


@dataclass(frozen=True)
class CameraSpec:
    """The depth camera's intrinsics and noise model (``worlds/camera.yaml``).

    Attributes:
        width: Image width (pixels).
        height: Image height (pixels).
        hfov_deg: Horizontal field of view (degrees, in (0, 180)).
        vfov_deg: Vertical field of view (degrees, in (0, 180)).
        min_range: Smallest depth returned (m, along the optical axis).
        max_range: Largest depth returned (m, > min_range).
        sigma_a: Constant term of the depth noise std ``a + b z^2`` (m).
        sigma_b: Quadratic term of the depth noise std (1/m).
        baseline: Projector-to-camera baseline of the disparity (m).
        disparity_step: Disparity quantisation step (pixels); 0 turns quantisation off.
        max_incidence_deg: Largest angle between a ray and the surface normal that still
            returns (degrees, in (0, 90]).
        edge_threshold: Depth jump to a 4-neighbour that makes a pixel an edge (m).
        edge_probability: Chance that an edge pixel returns nothing (in [0, 1]).
        translation_std: Std of a view's registration error, per camera axis (m).
        rotation_std_deg: Std of a view's registration rotation vector, per component (deg).

    Raises:
        ConfigError: Naming the first field out of range.
    """

    width: int = 320
    height: int = 240
    hfov_deg: float = 57.0
    vfov_deg: float = 43.0
    min_range: float = 0.5
    max_range: float = 4.5
    sigma_a: float = 0.0
    sigma_b: float = 0.0015
    baseline: float = 0.075
    disparity_step: float = 0.03125
    max_incidence_deg: float = 75.0
    edge_threshold: float = 0.05
    edge_probability: float = 0.5
    translation_std: float = 0.01
    rotation_std_deg: float = 0.5

    def __post_init__(self) -> None:
        _check_spec(
            self,
            positive=(
                "hfov_deg",
                "vfov_deg",
                "min_range",
                "max_range",
                "baseline",
                "max_incidence_deg",
                "edge_threshold",
            ),
            nonneg=(
                "sigma_a",
                "sigma_b",
                "disparity_step",
                "edge_probability",
                "translation_std",
                "rotation_std_deg",
            ),
            counts=("width", "height"),
        )
        for name in ("hfov_deg", "vfov_deg"):
            if getattr(self, name) >= 180.0:
                raise ConfigError(f"CameraSpec.{name} must be < 180, got {getattr(self, name)}.")
        if self.min_range >= self.max_range:
            raise ConfigError(
                f"CameraSpec.min_range {self.min_range} must be < max_range {self.max_range}."
            )
        if self.max_incidence_deg > 90.0:
            raise ConfigError(
                f"CameraSpec.max_incidence_deg must be <= 90, got {self.max_incidence_deg}."
            )
        if self.edge_probability > 1.0:
            raise ConfigError(
                f"CameraSpec.edge_probability must be <= 1, got {self.edge_probability}."
            )
        object.__setattr__(self, "width", int(self.width))
        object.__setattr__(self, "height", int(self.height))

    @property
    def fx(self) -> float:
        """Horizontal focal length (pixels)."""
        return self.width / (2.0 * math.tan(math.radians(self.hfov_deg) / 2.0))

    @property
    def fy(self) -> float:
        """Vertical focal length (pixels)."""
        return self.height / (2.0 * math.tan(math.radians(self.vfov_deg) / 2.0))

    @property
    def cx(self) -> float:
        """Principal point's column (pixels), the image centre."""
        return (self.width - 1) / 2.0

    @property
    def cy(self) -> float:
        """Principal point's row (pixels), the image centre."""
        return (self.height - 1) / 2.0

    def pixel_rays(self) -> np.ndarray:
        """Each pixel centre's ray in the camera frame, scaled to unit depth.

        Returns:
            (H, W, 3) ``((u - cx) / fx, (v - cy) / fy, 1)`` for row v and column u.
        """
        u = (np.arange(self.width) - self.cx) / self.fx
        v = (np.arange(self.height) - self.cy) / self.fy
        rays = np.ones((self.height, self.width, 3))
        rays[..., 0] = u[None, :]
        rays[..., 1] = v[:, None]
        return rays

    def binned(self, factor: int) -> CameraSpec:
        """The same sensor read out at ``1 / factor`` of the resolution (pixel binning).

        The field of view, range, noise, dropouts and registration stay; the disparity step
        shrinks with the focal length, so that the depth step at a given range is the
        full-resolution sensor's.

        Args:
            factor: A positive integer dividing both the width and the height.

        Returns:
            The binned camera (``self`` for a factor of 1).

        Raises:
            InputError: If `factor` is not a positive integer dividing both image sides.
        """
        factor = check_count("factor", factor)
        if self.width % factor or self.height % factor:
            raise InputError(
                f"factor {factor} must divide the image's {self.width} x {self.height} pixels."
            )
        if factor == 1:
            return self
        return dataclasses.replace(
            self,
            width=self.width // factor,
            height=self.height // factor,
            disparity_step=self.disparity_step / factor,
        )

    def floor_band(self, R_world_camera: np.ndarray) -> tuple[float, float]:
        """Least and greatest downward component of the pixel rays of unit depth.

        A camera ``h`` above a horizontal floor meets it along a pixel's ray at depth ``h / s``
        (along the optical axis), ``s`` the downward (world -z) component of the ray scaled to
        unit depth; ``s <= 0`` never meets it. ``s`` is linear in the pixel coordinates, so
        its extremes over the image lie at the corner pixels.

        Args:
            R_world_camera: (3, 3) the camera's orientation (optical frame to world).

        Returns:
            ``(s_min, s_max)`` over the image's pixel centres.
        """
        u, v = self.cx / self.fx, self.cy / self.fy
        corners = np.array([[a * u, b * v, 1.0] for a in (-1.0, 1.0) for b in (-1.0, 1.0)])
        down = -(corners @ np.asarray(R_world_camera, dtype=np.float64).T)[:, 2]
        return float(down.min()), float(down.max())

    def floor_heights(self, tilt_deg: float) -> tuple[float, float] | None:
        """Heights (m) from which a view tilted down by `tilt_deg` images floor within range.

        With ``(s_min, s_max)`` the view's `floor_band`, floor in the camera's depth range
        ``[min_range, max_range]`` shows exactly from heights ``h`` with
        ``min_range max(s_min, 0) <= h <= max_range s_max``: higher, even the nearest floor
        is beyond the range; lower, even the farthest is too near. (The camera's pan does not
        change the band.) With the Kinect's 43-degree vertical field of view and 0.5-4.5 m
        range, a 30-degree tilt gives 0.08-3.78 m.

        Args:
            tilt_deg: The tilt below the horizon (degrees; negative looks up).

        Returns:
            ``(low, high)`` (m), or ``None`` if the view looks wholly above the horizon and
            never images the floor (a tilt up by more than half the vertical field of view).
        """
        t = math.radians(float(tilt_deg))
        R = _rot_y(t) @ _R_HEAD_OPTICAL
        s_min, s_max = self.floor_band(R)
        if s_max <= 0.0:
            return None
        return self.min_range * max(s_min, 0.0), self.max_range * s_max

    @property
    def floor_tilt_deg(self) -> float:
        """The tilt (degrees) above which a view's bottom row still meets the floor."""
        return -math.degrees(math.atan(self.cy / self.fy))

    def sigma(self, depth: np.ndarray | float) -> np.ndarray:
        """Depth noise std ``a + b z^2`` (m) at depths `depth` (m), any shape."""
        z = np.asarray(depth, dtype=np.float64)
        return self.sigma_a + self.sigma_b * z * z


def load_camera(path: Path | None = None) -> CameraSpec:
    """Load and validate the depth camera (``worlds/camera.yaml``).

    Args:
        path: Another camera file; defaults to the one in `probaff.sim.config.worlds_dir()`.

    Raises:
        ConfigError: Naming the file and field of a missing, unknown or malformed entry.
    """
    raw, w, _ = _load_root(path, "camera.yaml")
    _no_extra(w, raw, {"image", "range", "noise", "quantisation", "dropout", "registration"})
    img = _mapping(f"{w}:image", _take(w, raw, "image"))
    _no_extra(f"{w}:image", img, {"width", "height", "fov_deg"})
    noise = _mapping(f"{w}:noise", _take(w, raw, "noise"))
    _no_extra(f"{w}:noise", noise, {"a", "b"})
    quant = _mapping(f"{w}:quantisation", _take(w, raw, "quantisation"))
    _no_extra(f"{w}:quantisation", quant, {"baseline", "disparity_step"})
    drop = _mapping(f"{w}:dropout", _take(w, raw, "dropout"))
    _no_extra(f"{w}:dropout", drop, {"max_incidence_deg", "edge_threshold", "edge_probability"})
    reg = _mapping(f"{w}:registration", _take(w, raw, "registration"))
    _no_extra(f"{w}:registration", reg, {"translation_std", "rotation_std_deg"})
    hfov, vfov = _pair(f"{w}:image.fov_deg", _take(f"{w}:image", img, "fov_deg"))
    lo, hi = _range(f"{w}:range", _take(w, raw, "range"), positive=True)
    return CameraSpec(
        width=_count_field(w, "image", img, "width"),
        height=_count_field(w, "image", img, "height"),
        hfov_deg=hfov,
        vfov_deg=vfov,
        min_range=lo,
        max_range=hi,
        sigma_a=_field(w, "noise", noise, "a", nonneg=True),
        sigma_b=_field(w, "noise", noise, "b", nonneg=True),
        baseline=_field(w, "quantisation", quant, "baseline", positive=True),
        disparity_step=_field(w, "quantisation", quant, "disparity_step", nonneg=True),
        max_incidence_deg=_field(w, "dropout", drop, "max_incidence_deg", positive=True),
        edge_threshold=_field(w, "dropout", drop, "edge_threshold", positive=True),
        edge_probability=_field(w, "dropout", drop, "edge_probability", nonneg=True),
        translation_std=_field(w, "registration", reg, "translation_std", nonneg=True),
        rotation_std_deg=_field(w, "registration", reg, "rotation_std_deg", nonneg=True),
    )


@dataclass(frozen=True, eq=False)
class DepthImage:
    """One depth view.

    Attributes:
        depth: (H, W) float64, depth along the optical axis (m); NaN where no return.
        object_id: (H, W) int64, the object id of each pixel's hit; -1 where no return.
        normal: (H, W, 3) world-frame unit normal of the surface hit; NaN where no return.
        T_world_camera: (4, 4) the true camera pose the view was rendered from.
        T_world_camera_estimated: (4, 4) the pose the robot believes it had (the true pose
            perturbed by the registration error); `points` maps through it.
        spec: The camera that took the view (its intrinsics map pixels to rays).
    """

    depth: np.ndarray
    object_id: np.ndarray
    normal: np.ndarray
    T_world_camera: np.ndarray
    T_world_camera_estimated: np.ndarray
    spec: CameraSpec = field(default_factory=CameraSpec)

    def __post_init__(self) -> None:
        if not isinstance(self.spec, CameraSpec):
            raise InputError(f"spec must be a CameraSpec, got {type(self.spec).__name__}.")
        h, w = self.spec.height, self.spec.width
        check_shape("depth", self.depth, (h, w))
        check_shape("object_id", self.object_id, (h, w))
        check_shape("normal", self.normal, (h, w, 3))
        check_shape("T_world_camera", self.T_world_camera, (4, 4))
        check_shape("T_world_camera_estimated", self.T_world_camera_estimated, (4, 4))

    @property
    def valid(self) -> np.ndarray:
        """(H, W) bool, the pixels with a return."""
        return np.isfinite(self.depth)

    def camera_points(self) -> np.ndarray:
        """(M, 3) camera-frame points of the valid pixels, in row-major pixel order."""
        valid = self.valid
        return self.spec.pixel_rays()[valid] * self.depth[valid][:, None]

    def points(self) -> np.ndarray:
        """(M, 3) world-frame points of the valid pixels, through the estimated pose.

        Row-major pixel order, the order of `point_ids`.
        """
        T = self.T_world_camera_estimated
        return self.camera_points() @ T[:3, :3].T + T[:3, 3]

    def point_ids(self) -> np.ndarray:
        """(M,) int64 object id of each of `points`."""
        return self.object_id[self.valid]


def _floats(name: str, value: object) -> np.ndarray:
    """`value` as a float64 array, or an `InputError` naming `name` if it holds no numbers."""
    try:
        return np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise InputError(f"{name} must hold numbers, got {value!r}.") from None


def _check_pose(name: str, T: object) -> np.ndarray:
    """`T` as a (4, 4) float64 rigid transform, or an `InputError` naming `name`."""
    arr = _floats(name, T)
    check_shape(name, arr, (4, 4))
    check_finite(name, arr)
    R = arr[:3, :3]
    if (
        np.abs(R.T @ R - np.eye(3)).max() > _RIGID_TOL
        or abs(np.linalg.det(R) - 1.0) > _RIGID_TOL
        or np.abs(arr[3] - (0.0, 0.0, 0.0, 1.0)).max() > _RIGID_TOL
    ):
        raise InputError(
            f"{name} is not a rigid transform: its upper-left 3 x 3 block must be a rotation "
            "(orthonormal, determinant 1) and its last row (0, 0, 0, 1); build it from a "
            "rotation matrix and a translation."
        )
    return arr


def _check_rng(rng: object) -> np.random.Generator:
    if rng is None:
        return np.random.default_rng(0)
    if not isinstance(rng, np.random.Generator):
        raise InputError(
            f"rng must be a numpy.random.Generator (np.random.default_rng(seed)), got "
            f"{type(rng).__name__}."
        )
    return rng


def _check_scene(scene: object) -> PrimitiveScene:
    if not isinstance(scene, PrimitiveScene):
        raise InputError(
            f"scene must be a probaff.sim.primitives.PrimitiveScene, got {type(scene).__name__}."
        )
    return scene


def _rot_z(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _rot_y(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def _rotvec(w: np.ndarray) -> np.ndarray:
    """(3, 3) rotation of the rotation vector `w` (3,) (rad), by Rodrigues' formula."""
    theta = float(np.linalg.norm(w))
    if theta < 1e-15:
        return np.eye(3)
    k = w / theta
    K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + math.sin(theta) * K + (1.0 - math.cos(theta)) * (K @ K)


def _box_hits(box: np.ndarray, o: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Entry of rays into one box, by the slab method in the box's own frame.

    Args:
        box: (7,) ``(cx, cy, cz, sx, sy, sz, yaw)``.
        o: (3,) world-frame ray origin, outside the box.
        d: (N, 3) world-frame ray directions; the ray parameter t is depth.

    Returns:
        ``(t (N,), normal (N, 3))``: the entry parameter (inf for a miss) and the world-frame
        outward normal of the face entered (rows of misses are arbitrary).
    """
    R = _rot_z(float(box[6]))  # box -> world
    p = R.T @ (o - box[:3])
    db = d @ R  # (N, 3) directions in the box frame
    half = box[3:6] / 2.0
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / db
        t1 = (-half - p) * inv
        t2 = (half - p) * inv
    near = np.fmin(t1, t2)  # NaN (0 * inf, a ray in a face's plane) is ignored
    axis = near.argmax(axis=1)
    rows = np.arange(len(d))
    t_in = near[rows, axis]
    t_out = np.fmax(t1, t2).min(axis=1)
    hit = np.isfinite(t_in) & (t_in > 0.0) & (t_in <= t_out)
    n_box = np.zeros((len(d), 3))
    n_box[rows, axis] = -np.sign(db[rows, axis])
    return np.where(hit, t_in, np.inf), n_box @ R.T


def _cylinder_hits(cyl: np.ndarray, o: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Entry of rays into one vertical cylinder: its side (a quadratic) or a cap (a plane).

    Args:
        cyl: (5,) ``(cx, cy, cz, radius, height)``.
        o: (3,) world-frame ray origin, outside the cylinder.
        d: (N, 3) world-frame ray directions; the ray parameter t is depth.

    Returns:
        ``(t (N,), normal (N, 3))`` as `_box_hits`.
    """
    r, h = float(cyl[3]), float(cyl[4])
    q = o - cyl[:3]
    a = d[:, 0] ** 2 + d[:, 1] ** 2
    b = 2.0 * (q[0] * d[:, 0] + q[1] * d[:, 1])
    c = q[0] ** 2 + q[1] ** 2 - r * r
    disc = b * b - 4.0 * a * c
    with np.errstate(divide="ignore", invalid="ignore"):
        t_side = (-b - np.sqrt(disc)) / (2.0 * a)  # the nearer root: the camera is outside
    z_side = q[2] + t_side * d[:, 2]
    side = (disc >= 0.0) & (a > 0.0) & (t_side > 0.0) & (np.abs(z_side) <= h / 2.0)
    t = np.where(side, t_side, np.inf)
    normal_z = np.zeros(len(d))
    for zc in (h / 2.0, -h / 2.0):
        with np.errstate(divide="ignore", invalid="ignore"):
            t_cap = (zc - q[2]) / d[:, 2]
        xc, yc = q[0] + t_cap * d[:, 0], q[1] + t_cap * d[:, 1]
        cap = (t_cap > 0.0) & (xc * xc + yc * yc <= r * r) & (t_cap < t)
        t = np.where(cap, t_cap, t)
        normal_z = np.where(cap, math.copysign(1.0, zc), normal_z)
    n = np.zeros((len(d), 3))
    n[:, 2] = normal_z
    on_side = normal_z == 0.0
    with np.errstate(invalid="ignore"):
        n[on_side, 0] = (q[0] + t[on_side] * d[on_side, 0]) / r
        n[on_side, 1] = (q[1] + t[on_side] * d[on_side, 1]) / r
    return t, n


def _cast_all(
    scene: PrimitiveScene, o: np.ndarray, d: np.ndarray, unit: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The nearest hit of every ray over all primitives.

    Each primitive is tested only on the rays inside the cone of its bounding sphere that are
    not already stopped nearer; primitives go nearest first, so occluded ones cost little.

    Args:
        scene: The primitives.
        o: (3,) world-frame ray origin, outside every primitive.
        d: (N, 3) world-frame ray directions with unit depth.
        unit: (N, 3) the same directions, normalised.

    Returns:
        ``(t (N,), object_id (N,), normal (N, 3))``: depth (inf for none), id (-1 for none)
        and world-frame normal (NaN for none).
    """
    n = len(d)
    best = np.full(n, np.inf)
    best_range = np.full(n, np.inf)  # best t times the ray's length
    best_id = np.full(n, -1, dtype=np.int64)
    best_n = np.full((n, 3), np.nan)
    length = np.linalg.norm(d, axis=1)
    prims = [
        (b, i, _box_hits, 0.5 * float(np.linalg.norm(b[3:6])))
        for b, i in zip(scene.boxes, scene.box_ids, strict=True)
    ] + [
        (c, i, _cylinder_hits, math.hypot(c[3], c[4] / 2.0))
        for c, i in zip(scene.cylinders, scene.cylinder_ids, strict=True)
    ]
    near = [float(np.linalg.norm(p[0][:3] - o)) - p[3] for p in prims]
    for k in np.argsort(near, kind="stable"):
        prim, oid, hits, radius = prims[k]
        v = prim[:3] - o
        dist = float(np.linalg.norm(v))
        cand = best_range > dist - radius
        if dist > radius:
            cand &= unit @ v >= math.sqrt(dist * dist - radius * radius) - 1e-9
        idx = np.flatnonzero(cand)
        if len(idx) == 0:
            continue
        t, normal = hits(prim, o, d[idx])
        better = t < best[idx]
        sel = idx[better]
        best[sel] = t[better]
        best_range[sel] = t[better] * length[sel]
        best_id[sel] = oid
        best_n[sel] = normal[better]
    return best, best_id, best_n


def _edges(depth: np.ndarray, threshold: float) -> np.ndarray:
    """(H, W) bool: pixels with a hit whose 4-neighbour's depth differs by > `threshold`.

    Args:
        depth: (H, W) exact depth (m), inf where the ray hits nothing.
        threshold: The depth jump (m).
    """
    edge = np.zeros(depth.shape, dtype=bool)
    with np.errstate(invalid="ignore"):
        dv = np.abs(np.diff(depth, axis=0)) > threshold  # (H-1, W); inf - inf is NaN: no edge
        du = np.abs(np.diff(depth, axis=1)) > threshold
    edge[:-1] |= dv
    edge[1:] |= dv
    edge[:, :-1] |= du
    edge[:, 1:] |= du
    return edge & np.isfinite(depth)


class DepthCamera:
    """A pinhole depth camera (see the module docstring for frames and the sensor model).

    Args:
        spec: The camera; `load_camera()` when None.
    """

    def __init__(self, spec: CameraSpec | None = None) -> None:
        if spec is None:
            spec = load_camera()
        if not isinstance(spec, CameraSpec):
            raise InputError(
                f"spec must be a CameraSpec (see load_camera), got {type(spec).__name__}."
            )
        self.spec = spec
        self._rays = spec.pixel_rays().reshape(-1, 3)  # (H W, 3) camera frame, unit depth
        self._ray_norm = np.linalg.norm(self._rays, axis=1)  # (H W,)

    def cast(
        self, scene: PrimitiveScene, T_world_camera: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Exact ray casting: the nearest hit of every pixel's ray, with no range limit.

        Args:
            scene: The primitives.
            T_world_camera: (4, 4) camera pose (camera frame to world).

        Returns:
            ``(depth (H, W), object_id (H, W), normal (H, W, 3))``: depth along the optical
            axis (m, inf where the ray hits nothing), the hit's object id (-1 for none) and
            its world-frame normal (NaN for none).

        Raises:
            InputError: For a pose that is not a finite rigid transform, or whose camera
                centre lies inside a primitive.
        """
        scene = _check_scene(scene)
        T = _check_pose("T_world_camera", T_world_camera)
        o = T[:3, 3]
        if scene.contains(o[None])[0]:
            raise InputError(
                f"T_world_camera puts the camera centre {np.round(o, 4).tolist()} inside a "
                "primitive of the scene; move the camera outside every object."
            )
        d = self._rays @ T[:3, :3].T
        unit = d / self._ray_norm[:, None]
        t, ids, normal = _cast_all(scene, o, d, unit)
        h, w = self.spec.height, self.spec.width
        return t.reshape(h, w), ids.reshape(h, w), normal.reshape(h, w, 3)

    def render(
        self,
        scene: PrimitiveScene,
        T_world_camera: np.ndarray,
        *,
        rng: np.random.Generator | None = None,
        noise: bool = True,
    ) -> DepthImage:
        """Render one depth view.

        Args:
            scene: The primitives.
            T_world_camera: (4, 4) camera pose (camera frame to world).
            rng: The only source of random draws; ``np.random.default_rng(0)`` when None.
            noise: Apply the sensor model (noise, quantisation, dropouts); False gives the
                exact depth of every hit within range.

        Returns:
            The view; its estimated pose is the true one.

        Raises:
            InputError: For a bad pose or rng, or a camera centre inside a primitive.
        """
        gen = _check_rng(rng)
        T = _check_pose("T_world_camera", T_world_camera)
        exact, ids, normal = self.cast(scene, T)
        depth = exact.copy()
        if noise:
            depth = self._measure(exact, normal, T, gen)
        spec = self.spec
        with np.errstate(invalid="ignore"):
            keep = (depth >= spec.min_range) & (depth <= spec.max_range)
        depth = np.where(keep, depth, np.nan)
        ids = np.where(keep, ids, -1)
        normal = np.where(keep[..., None], normal, np.nan)
        return DepthImage(depth, ids, normal, T.copy(), T.copy(), spec)

    def _measure(
        self, exact: np.ndarray, normal: np.ndarray, T: np.ndarray, rng: np.random.Generator
    ) -> np.ndarray:
        """The measured depth (H, W) of the exact one: dropouts (NaN), noise, quantisation."""
        spec = self.spec
        shape = exact.shape
        edge_draw = rng.random(shape)
        gauss = rng.standard_normal(shape)
        drop = _edges(exact, spec.edge_threshold) & (edge_draw < spec.edge_probability)
        d_world = (self._rays @ T[:3, :3].T) / self._ray_norm[:, None]
        cos_inc = np.abs(np.einsum("ij,ij->i", normal.reshape(-1, 3), d_world)).reshape(shape)
        with np.errstate(invalid="ignore"):
            drop |= cos_inc < math.cos(math.radians(spec.max_incidence_deg)) - 1e-12
        hit = np.isfinite(exact) & ~drop
        z = np.where(hit, exact, np.nan)
        z = z + spec.sigma(z) * gauss
        if spec.disparity_step > 0:
            fb = spec.fx * spec.baseline
            with np.errstate(divide="ignore", invalid="ignore"):
                disparity = np.round(fb / z / spec.disparity_step) * spec.disparity_step
                z = np.where(disparity > 0, fb / disparity, np.nan)
        return z


def head_views(
    T_world_head: np.ndarray,
    pans_deg: ArrayLike,
    tilts_deg: ArrayLike,
) -> np.ndarray:
    """Camera poses of a pan-tilt head, every pan with every tilt.

    Args:
        T_world_head: (4, 4) the head's pose (head frame: x forward, y left, z up).
        pans_deg: (P,) pan angles about the head's z (degrees, counter-clockwise from above).
        tilts_deg: (Q,) tilt angles about the panned y (degrees, positive looks down).

    Returns:
        (P Q, 4, 4) ``T_world_camera`` (optical frame), pan-major: view ``i Q + j`` has pan i
        and tilt j.

    Raises:
        InputError: For a head pose that is not a finite rigid transform, or angle lists that
            are empty, not 1-D or not finite.
    """
    T = _check_pose("T_world_head", T_world_head)
    angles = []
    for name, value in (("pans_deg", pans_deg), ("tilts_deg", tilts_deg)):
        arr = np.atleast_1d(_floats(name, value))
        check_shape(name, arr, (None,))
        check_finite(name, arr)
        if arr.size == 0:
            raise InputError(f"{name} is empty; give at least one angle (degrees).")
        angles.append(np.radians(arr))
    poses = []
    for pan in angles[0]:
        for tilt in angles[1]:
            pose = np.eye(4)
            pose[:3, :3] = _rot_z(pan) @ _rot_y(tilt) @ _R_HEAD_OPTICAL
            poses.append(T @ pose)
    return np.stack(poses)


def scan_views(
    camera: DepthCamera,
    scene: PrimitiveScene,
    poses: np.ndarray,
    *,
    rng: np.random.Generator | None = None,
    registration: bool = True,
    noise: bool = True,
) -> list[DepthImage]:
    """Render several views, each registered through a perturbed (estimated) pose.

    Args:
        camera: The camera.
        scene: The primitives.
        poses: (V, 4, 4) true camera poses (e.g. from `head_views`).
        rng: The only source of random draws; ``np.random.default_rng(0)`` when None.
        registration: Perturb each view's estimated pose by the spec's registration error;
            False keeps the true poses.
        noise: Apply the sensor model, as in `DepthCamera.render`.

    Returns:
        V views; view i holds the true pose ``poses[i]`` and its estimated pose, through
        which its `DepthImage.points` come back in the world frame.

    Raises:
        InputError: For a bad camera, pose array or rng, or a camera inside a primitive.
    """
    if not isinstance(camera, DepthCamera):
        raise InputError(f"camera must be a DepthCamera, got {type(camera).__name__}.")
    gen = _check_rng(rng)
    arr = _floats("poses", poses)
    check_shape("poses", arr, (None, 4, 4))
    if len(arr) == 0:
        raise InputError("poses is empty; give at least one (4, 4) camera pose.")
    spec = camera.spec
    views = []
    for i, pose in enumerate(arr):
        T = _check_pose(f"poses[{i}]", pose)
        delta = np.eye(4)
        if registration:
            w = np.radians(spec.rotation_std_deg) * gen.standard_normal(3)
            delta[:3, :3] = _rotvec(w)
            delta[:3, 3] = spec.translation_std * gen.standard_normal(3)
        image = camera.render(scene, T, rng=gen, noise=noise)
        views.append(
            DepthImage(image.depth, image.object_id, image.normal, T.copy(), T @ delta, spec)
        )
    return views
