"""A simulated depth sensor on the warehouse robot: vectorised ray casting against the boxes.

Frames: every position is in the warehouse world frame of `probaff.sim.warehouse` (x to the
right, y up the map, z up from the floor; the map spans ``[0, cols s] x [0, rows s]``). The
sensor sits at ``(x, y, sensor_height)`` above the robot's position and turns all the way round:
``sensor_azimuths`` azimuths evenly over 360 degrees (azimuth 0 along +x, counter-clockwise)
times the ``sensor_elevations`` of the spec (degrees, positive up).

The obstacles are axis-aligned boxes: one per block of the map, a box or an interior wall block
(a ``box_size`` square centred on its cell, ``box_height`` tall), and the four walls
(``wall_thickness`` thick, just outside the grid, ``wall_height`` tall). A ray returns the first
surface it meets, the floor included, if that lies within ``sensor_range``; a ray passing over
every obstacle returns nothing. Ranges get Gaussian noise of standard deviation ``sensor_noise``
along the ray.

Besides the 3-D points, each scan carries one horizontal ray per azimuth at sensor height, whose
end point bounds the free space seen in the plane: the occupancy grid traces these.

Two sensors share that interface (``spec.sensor_kind``):

* ``"scanner"``: the idealised range scanner above, Gaussian range noise only;
* ``"camera"``: the head's depth camera of chapter 2 (`probaff.sim.camera`, ``spec.camera``)
  at ``sensor_height``, panned to ``camera_pans`` azimuths evenly over 360 degrees (the first
  along +x) and tilted down by ``camera_tilt_deg``. It sees `warehouse_scene`: the obstacles
  and the floor. Its depth has the camera's range-squared noise, disparity quantisation and
  dropouts at grazing angles and edges, only returns within its 0.5-4.5 m range, and every view
  comes back through its own registration error (the points are mapped through the view's
  estimated pose). Its horizontal rays are the image's columns projected on the floor plane:
  a column whose returns include an obstacle (a return above ``floor_band``) ends at the
  nearest such surface (a hit), at the median reach of the column's returns no more than
  0.15 m behind its nearest one (the nearest alone would be biased short by the noise); a
  column that sees only floor ends, without a hit, at its farthest floor return, since a floor
  point in view proves the line of sight to it free (the obstacles are upright boxes standing
  on the floor). A column with no return carries nothing and is left out; so is an obstacle
  return farther than ``sensor_range``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from probaff._checks import check_finite, check_shape, real_float64
from probaff.errors import InputError
from probaff.sim.camera import DepthCamera, DepthImage, head_views, scan_views
from probaff.sim.inputs import check_rng
from probaff.sim.primitives import PrimitiveScene
from probaff.sim.warehouse import WarehouseMap, _check_world
from probaff.sim.warehouse_config import WarehouseSpec

_SURFACE_DEPTH = 0.15  # m: a column's returns this close behind its nearest are one surface

__all__ = ["DepthScan", "DepthSensor", "first_entry", "obstacle_bounds", "warehouse_scene"]


@dataclass(frozen=True)
class DepthScan:
    """One turn of the depth sensor.

    Attributes:
        points: (M, 3) world frame, the surface points seen (noisy), ordered by azimuth then
            elevation; rays that met nothing within range are left out.
        origin: (3,) world frame, the sensor position.
        azimuths: (A,) azimuth of each horizontal ray (rad, from +x counter-clockwise).
        ends: (A, 2) world frame xy, where each horizontal ray at sensor height ended: the (noisy)
            surface it hit, or the range limit.
        hits: (A,) bool, whether that horizontal ray hit a surface within range.
    """

    points: np.ndarray
    origin: np.ndarray
    azimuths: np.ndarray
    ends: np.ndarray
    hits: np.ndarray


def obstacle_bounds(spec: WarehouseSpec, m: WarehouseMap) -> tuple[np.ndarray, np.ndarray]:
    """The axis-aligned obstacles of a map: its boxes, then the four walls.

    Args:
        spec: The warehouse world (box and wall dimensions).
        m: The map.

    Returns:
        ``(lo, hi)``, each (K, 3) world frame: the lower and upper corners of the K obstacles.

    Raises:
        InputError: For a `spec` or `m` of the wrong type.
    """
    _check_world(spec, m)
    rows, cols = m.shape
    s = m.cell_size
    centres = m.cell_centre(m.boxes)
    half = 0.5 * spec.box_size
    box_lo = np.column_stack([centres - half, np.zeros(len(centres))])
    box_hi = np.column_stack([centres + half, np.full(len(centres), spec.box_height)])
    t, W, H, h = spec.wall_thickness, cols * s, rows * s, spec.wall_height
    wall_lo = np.array([[-t, -t, 0.0], [W, -t, 0.0], [-t, -t, 0.0], [-t, H, 0.0]])
    wall_hi = np.array([[0.0, H + t, h], [W + t, H + t, h], [W + t, 0.0, h], [W + t, H + t, h]])
    return np.concatenate([box_lo, wall_lo]), np.concatenate([box_hi, wall_hi])


def warehouse_scene(spec: WarehouseSpec, m: WarehouseMap) -> PrimitiveScene:
    """What the depth camera sees of a map: its obstacles and the floor, as primitives.

    Args:
        spec: The warehouse world (box and wall dimensions).
        m: The map.

    Returns:
        The boxes of `obstacle_bounds` (object ids ``0 .. K-1``, in that order: the map's boxes,
        then the four walls) and a 0.1 m floor slab under ``z = 0`` spanning the walls
        (object id K).
    """
    _check_world(spec, m)
    lo, hi = obstacle_bounds(spec, m)
    rows, cols = m.shape
    s, t = m.cell_size, spec.wall_thickness
    floor = np.array([[cols * s / 2, rows * s / 2, -0.05, cols * s + 2 * t, rows * s + 2 * t, 0.1]])
    boxes = np.column_stack(
        [np.concatenate([(lo + hi) / 2, floor[:, :3]]), np.concatenate([hi - lo, floor[:, 3:]])]
    )
    boxes = np.column_stack([boxes, np.zeros(len(boxes))])
    return PrimitiveScene(boxes=boxes, box_ids=np.arange(len(boxes)))


def first_entry(
    origin: np.ndarray, directions: np.ndarray, lo: np.ndarray, hi: np.ndarray
) -> np.ndarray:
    """Distance along each ray to the first axis-aligned box it enters (slab method).

    All rays are tested against all boxes at once. A box that holds the origin does not count.

    Args:
        origin: (D,) start of every ray.
        directions: (R, D) unit ray directions.
        lo: (K, D) lower box corners.
        hi: (K, D) upper box corners.

    Returns:
        (R,) distance to the first box entered; ``inf`` where a ray meets none.
    """
    o = np.asarray(origin, dtype=float)
    d = np.asarray(directions, dtype=float)[:, None, :]
    if len(lo) == 0:
        return np.full(d.shape[0], np.inf)
    with np.errstate(divide="ignore", invalid="ignore"):
        t1 = (lo - o) / d
        t2 = (hi - o) / d
    near, far = np.minimum(t1, t2), np.maximum(t1, t2)
    parallel = d == 0.0
    within = (o >= lo) & (o <= hi)  # (K, D): the origin lies in the slab
    near = np.where(parallel, np.where(within, -np.inf, np.inf), near)
    far = np.where(parallel, np.where(within, np.inf, -np.inf), far)
    enter, leave = near.max(-1), far.min(-1)
    entered = (enter <= leave) & (enter >= 0.0)
    return np.where(entered, enter, np.inf).min(-1)


class DepthSensor:
    """The robot's depth sensor in one warehouse map.

    Args:
        spec: The warehouse world (sensor height, range, resolution and noise; obstacle sizes).
        m: The map whose boxes the sensor sees.
    """

    def __init__(self, spec: WarehouseSpec, m: WarehouseMap) -> None:
        _check_world(spec, m)
        self.spec = spec
        self.map = m
        self.lo, self.hi = obstacle_bounds(spec, m)
        if spec.sensor_kind == "camera":
            assert spec.camera is not None  # WarehouseSpec checks it
            self._camera = DepthCamera(spec.camera)
            self._scene = warehouse_scene(spec, m)
            self._pans = 360.0 * np.arange(spec.camera_pans) / spec.camera_pans
        n_az = spec.sensor_azimuths
        self.azimuths = 2.0 * np.pi * np.arange(n_az) / n_az
        el = np.deg2rad(np.asarray(spec.sensor_elevations, dtype=float))
        az = self.azimuths[:, None]
        self._rays = np.stack(
            np.broadcast_arrays(np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)), -1
        ).reshape(-1, 3)  # (A E, 3) unit directions, azimuth-major
        self._flat = np.column_stack(
            [np.cos(self.azimuths), np.sin(self.azimuths), np.zeros(n_az)]
        )  # (A, 3) horizontal rays
        sin_el = np.broadcast_to(np.sin(el), (n_az, len(el))).ravel()
        with np.errstate(divide="ignore"):
            floor = np.where(sin_el < 0, spec.sensor_height / -sin_el, np.inf)
        self._floor = floor  # (A E,) distance to the floor along each ray

    def check_position(self, position: np.ndarray) -> np.ndarray:
        """Validate a robot position.

        Args:
            position: (2,) world frame xy.

        Returns:
            (2,) float copy.

        Raises:
            InputError: If it is not a finite (2,) point strictly inside the walls and outside
                every box.
        """
        p = real_float64(position)
        if p is None:
            raise InputError(f"robot position must be a (2,) point, got {position!r}.")
        check_shape("robot position", p, (2,))
        check_finite("robot position", p)
        p = p.copy()
        rows, cols = self.map.shape
        s = self.map.cell_size
        if not (0.0 < p[0] < cols * s and 0.0 < p[1] < rows * s):
            raise InputError(
                f"robot position {p.tolist()} lies outside the {cols * s:g} x {rows * s:g} m "
                "warehouse; x runs from 0 to cols * cell_size and y from 0 to rows * cell_size."
            )
        n_boxes = len(self.map.boxes)
        inside = np.all((p >= self.lo[:n_boxes, :2]) & (p <= self.hi[:n_boxes, :2]), -1)
        if inside.any():
            cell = self.map.boxes[int(np.argmax(inside))].tolist()
            raise InputError(
                f"robot position {p.tolist()} lies inside the box at cell {cell}; place the "
                "robot on a free cell."
            )
        return p

    def scan(
        self, position: np.ndarray, rng: np.random.Generator, *, exact: bool = False
    ) -> DepthScan:
        """Take one scan from a robot position.

        Args:
            position: (2,) world frame xy of the robot.
            rng: Source of the sensor noise; the same generator state gives the same scan.
            exact: Leave out every error (noise, quantisation, dropouts, registration): the
                scan a perfect sensor would take, as predicted from a believed map.

        Returns:
            The scan.

        Raises:
            InputError: For a position that is not finite, outside the walls or inside a box,
                or an `rng` that is not a `numpy.random.Generator`.
        """
        xy = self.check_position(position)
        check_rng(rng)
        spec = self.spec
        origin = np.array([xy[0], xy[1], spec.sensor_height])
        if spec.sensor_kind == "camera":
            return self._camera_scan(origin, rng, exact)
        noise = 0.0 if exact else spec.sensor_noise
        t = np.minimum(first_entry(origin, self._rays, self.lo, self.hi), self._floor)
        seen = t <= spec.sensor_range
        r = np.maximum(t + noise * rng.standard_normal(t.shape), 0.0)
        points = origin + r[seen, None] * self._rays[seen]
        t_flat = first_entry(origin, self._flat, self.lo, self.hi)
        hits = t_flat <= spec.sensor_range
        noisy = np.maximum(t_flat + noise * rng.standard_normal(t_flat.shape), 0.0)
        r_flat = np.where(hits, noisy, spec.sensor_range)
        ends = xy + r_flat[:, None] * self._flat[:, :2]
        return DepthScan(
            points=points, origin=origin, azimuths=self.azimuths.copy(), ends=ends, hits=hits
        )

    def _camera_scan(self, origin: np.ndarray, rng: np.random.Generator, exact: bool) -> DepthScan:
        """One scan by the panned head camera (see the module docstring)."""
        T_head = np.eye(4)
        T_head[:3, 3] = origin
        poses = head_views(T_head, self._pans, [self.spec.camera_tilt_deg])
        views = scan_views(
            self._camera, self._scene, poses, rng=rng, registration=not exact, noise=not exact
        )
        clouds = [v.points() for v in views]  # (M_v, 3), world frame, estimated poses
        ends, hits = zip(
            *(self._columns(v, c, origin) for v, c in zip(views, clouds, strict=True)),
            strict=True,
        )
        points = np.concatenate(clouds)
        end = np.concatenate(ends)
        delta = end - origin[:2]
        return DepthScan(
            points=points,
            origin=origin,
            azimuths=np.mod(np.arctan2(delta[:, 1], delta[:, 0]), 2.0 * np.pi),
            ends=end,
            hits=np.concatenate(hits),
        )

    def _columns(
        self, view: DepthImage, cloud: np.ndarray, origin: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """The horizontal rays of one view: ``(ends (A, 2), hits (A,))``, one per seen column.

        Args:
            view: The view.
            cloud: (M, 3) its `DepthImage.points`, the valid pixels in row-major order.
            origin: (3,) the sensor position (world frame).
        """
        pts = np.full((*view.depth.shape, 3), np.nan)  # (H, W, 3), NaN: no return
        pts[view.valid] = cloud
        reach = np.hypot(pts[..., 0] - origin[0], pts[..., 1] - origin[1])  # (H, W)
        valid = np.isfinite(reach)
        obstacle = valid & (pts[..., 2] > self.spec.floor_band) & (reach <= self.spec.sensor_range)
        floor = valid & ~obstacle & (pts[..., 2] <= self.spec.floor_band)
        near = np.where(obstacle, reach, np.inf)
        first = np.argmin(near, axis=0)  # (W,) row of the nearest obstacle return
        cols = np.arange(near.shape[1])
        hit = obstacle.any(axis=0)
        nearest = near[first, cols]  # (W,)
        # The hit's reach is the median over the column's returns of that surface (within
        # _SURFACE_DEPTH of the nearest): the nearest alone is biased short by the noise.
        surface = obstacle & (reach < nearest[None] + _SURFACE_DEPTH)
        with np.errstate(invalid="ignore"):
            hit_reach = np.nanmedian(np.where(surface, reach, np.nan)[:, hit], axis=0)
        open_reach = np.where(floor & (reach < nearest[None]), reach, -np.inf)
        last = np.argmax(open_reach, axis=0)  # (W,) row of the farthest free floor return
        seen_floor = np.isfinite(open_reach[last, cols])
        ends = pts[last, cols, :2]
        direction = pts[first[hit], cols[hit], :2] - origin[:2]
        ends[hit] = origin[:2] + direction * (hit_reach / nearest[hit])[:, None]
        keep = hit | seen_floor
        return ends[keep], hit[keep]
