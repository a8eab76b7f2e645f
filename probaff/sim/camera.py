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
from probaff.sim import world_files as wf
from probaff.sim.inputs import check_rng, check_type, floats
from probaff.sim.primitives import PrimitiveScene
from probaff.sim.raycast import cast_rays, rot_y, rot_z, rotvec
from probaff.sim.world_files import CheckedSpec

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
class CameraSpec(CheckedSpec):
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

    POSITIVE = (
        "hfov_deg",
        "vfov_deg",
        "min_range",
        "max_range",
        "baseline",
        "max_incidence_deg",
        "edge_threshold",
    )
    NONNEG = (
        "sigma_a",
        "sigma_b",
        "disparity_step",
        "edge_probability",
        "translation_std",
        "rotation_std_deg",
    )
    COUNTS = ("width", "height")

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
        super().__post_init__()
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
        R = rot_y(t) @ _R_HEAD_OPTICAL
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


_CAMERA_FILE: dict[str, dict[str, str]] = {
    "noise": {"a": "sigma_a", "b": "sigma_b"},
    "quantisation": {k: k for k in ("baseline", "disparity_step")},
    "dropout": {k: k for k in ("max_incidence_deg", "edge_threshold", "edge_probability")},
    "registration": {k: k for k in ("translation_std", "rotation_std_deg")},
}
"""The sections of ``worlds/camera.yaml`` besides ``image`` and ``range``: key -> field."""


def load_camera(
    path: Path | None = None, *, width: int | None = None, height: int | None = None
) -> CameraSpec:
    """Load and validate the depth camera (``worlds/camera.yaml``).

    Args:
        path: Another camera file; defaults to the one in `probaff.sim.world_files.worlds_dir()`.
        width: Image width in pixels in place of the file's, or None to keep the file's.
        height: Image height in pixels in place of the file's, or None to keep the file's.

    Raises:
        ConfigError: Naming the file and field of a missing, unknown or malformed entry, or
            for a `width` or `height` that is not a positive integer.
    """
    raw, w, _ = wf.load_root(path, "camera.yaml")
    wf.no_extra(w, raw, {"image", "range", "noise", "quantisation", "dropout", "registration"})
    img = wf.section(w, raw, "image", {"width", "height", "fov_deg"})
    hfov, vfov = wf.pair_field(f"{w}:image", img, "fov_deg")
    lo, hi = wf.range_field(w, raw, "range", positive=True)
    values: dict[str, float] = {}
    for key, names in _CAMERA_FILE.items():
        table = wf.section(w, raw, key, set(names))
        values.update(CameraSpec.read_fields(f"{w}:{key}", table, names))
    spec = CameraSpec(
        width=wf.count_field(f"{w}:image", img, "width"),
        height=wf.count_field(f"{w}:image", img, "height"),
        hfov_deg=hfov,
        vfov_deg=vfov,
        min_range=lo,
        max_range=hi,
        **values,
    )
    size = {k: v for k, v in (("width", width), ("height", height)) if v is not None}
    return dataclasses.replace(spec, **size) if size else spec


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
        check_type("spec", self.spec, CameraSpec)
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


def _check_pose(name: str, T: object) -> np.ndarray:
    """`T` as a (4, 4) float64 rigid transform, or an `InputError` naming `name`."""
    arr = floats(name, T)
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
    return np.random.default_rng(0) if rng is None else check_rng(rng)


def _check_scene(scene: object) -> PrimitiveScene:
    if not isinstance(scene, PrimitiveScene):
        raise InputError(
            f"scene must be a probaff.sim.primitives.PrimitiveScene, got {type(scene).__name__}."
        )
    return scene


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
        self.spec = check_type("spec", spec, CameraSpec, "see load_camera")
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
        t, ids, normal = cast_rays(scene, o, d, unit)
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
        arr = np.atleast_1d(floats(name, value))
        check_shape(name, arr, (None,))
        check_finite(name, arr)
        if arr.size == 0:
            raise InputError(f"{name} is empty; give at least one angle (degrees).")
        angles.append(np.radians(arr))
    poses = []
    for pan in angles[0]:
        for tilt in angles[1]:
            pose = np.eye(4)
            pose[:3, :3] = rot_z(pan) @ rot_y(tilt) @ _R_HEAD_OPTICAL
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
    check_type("camera", camera, DepthCamera)
    gen = _check_rng(rng)
    arr = floats("poses", poses)
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
            delta[:3, :3] = rotvec(w)
            delta[:3, 3] = spec.translation_std * gen.standard_normal(3)
        image = camera.render(scene, T, rng=gen, noise=noise)
        views.append(
            DepthImage(image.depth, image.object_id, image.normal, T.copy(), T @ delta, spec)
        )
    return views
