"""The simulated depth sensors: analytic ray casting, noise, determinism and bad poses.

The idealised scanner's cases run on ``sensor_kind="scanner"``; the head camera's (the world
file's default) on the camera.
"""

import dataclasses
import math

import numpy as np
import pytest

from probaff.errors import InputError
from probaff.sim.depth import DepthSensor, first_entry, obstacle_bounds, warehouse_scene
from probaff.sim.warehouse import WarehouseMap
from probaff.sim.warehouse_config import load_warehouse


@pytest.fixture(scope="module")
def camera_spec():
    return load_warehouse()


@pytest.fixture(scope="module")
def spec(camera_spec):
    return dataclasses.replace(camera_spec, sensor_kind="scanner")


@pytest.fixture(scope="module")
def exact(spec):
    return dataclasses.replace(spec, sensor_noise=0.0)


def _assert_deterministic(sensor, xy):
    """The same generator state gives the same scan, another a different one; returns one."""
    a = sensor.scan(xy, np.random.default_rng(3))
    b = sensor.scan(xy, np.random.default_rng(3))
    c = sensor.scan(xy, np.random.default_rng(4))
    np.testing.assert_array_equal(a.points, b.points)
    np.testing.assert_array_equal(a.ends, b.ends)
    assert not np.array_equal(a.points, c.points)
    return a


def test_first_entry_slab():
    lo, hi = np.array([[2.0, -1.0], [5.0, -1.0]]), np.array([[3.0, 1.0], [6.0, 1.0]])
    dirs = np.array([[1.0, 0.0], [-1.0, 0.0], [0.0, 1.0], [0.96, 0.28]])
    t = first_entry(np.zeros(2), dirs, lo, hi)
    np.testing.assert_allclose(t[:3], [2.0, np.inf, np.inf])
    assert t[3] == pytest.approx(2.0 / 0.96)  # enters the first box's face x = 2 at y = 0.58
    assert np.isinf(first_entry(np.array([2.5, 0.0]), dirs[:1], lo[:1], hi[:1]))[0]


def test_obstacles_are_boxes_then_walls(spec):
    m = WarehouseMap.from_boxes((12, 12), [(0, 0), (5, 7)])
    lo, hi = obstacle_bounds(spec, m)
    assert lo.shape == hi.shape == (6, 3)
    np.testing.assert_allclose(lo[1], [7.02, 6.02, 0.0])
    np.testing.assert_allclose(hi[1], [7.98, 6.98, spec.box_height])
    assert (hi[2:, 2] == spec.wall_height).all()


def test_box_face_points_are_exact(exact):
    m = WarehouseMap.from_boxes((12, 12), [(6, 8)])  # centre (8.5, 5.5); face at x = 8.02
    scan = DepthSensor(exact, m).scan(np.array([5.5, 5.5]), np.random.default_rng(0))
    ahead = scan.points[np.isclose(scan.points[:, 1], 5.5) & (scan.points[:, 0] > 5.5)]
    on_face = ahead[ahead[:, 2] > 1e-9]
    np.testing.assert_allclose(on_face[:, 0], 8.02, atol=1e-9)
    d = 8.02 - 5.5
    expected = [1.0 + d * math.tan(math.radians(e)) for e in exact.sensor_elevations]
    expected = [z for z in expected if 0.0 <= z <= exact.box_height]
    np.testing.assert_allclose(np.sort(on_face[:, 2]), np.sort(expected), atol=1e-9)
    assert scan.hits[0] and np.allclose(scan.ends[0], [8.02, 5.5])
    assert scan.origin.tolist() == [5.5, 5.5, exact.sensor_height]


def test_floor_points_lie_at_h_over_tan(exact):
    m = WarehouseMap(np.zeros((12, 12), dtype=bool))
    scan = DepthSensor(exact, m).scan(np.array([6.0, 6.0]), np.random.default_rng(0))
    floor = scan.points[np.abs(scan.points[:, 2]) < 1e-9]
    radius = np.hypot(floor[:, 0] - 6.0, floor[:, 1] - 6.0)
    want = [
        exact.sensor_height / math.tan(math.radians(-e))
        for e in exact.sensor_elevations
        if e < 0 and exact.sensor_height / math.sin(math.radians(-e)) <= exact.sensor_range
    ]
    np.testing.assert_allclose(np.unique(radius.round(9)), sorted(want), atol=1e-9)
    assert len(floor) == exact.sensor_azimuths * len(want)
    # no point higher than the walls, no ray passing over the walls returns anything
    assert scan.points[:, 2].max() <= exact.wall_height + 1e-9
    assert scan.points.shape[0] < exact.sensor_azimuths * len(exact.sensor_elevations)


def test_range_noise_and_determinism(spec):
    m = WarehouseMap.from_boxes((12, 12), [(6, 8)])
    sensor = DepthSensor(spec, m)
    xy = np.array([5.5, 5.5])
    rng = np.random.default_rng(7)
    ends = np.array([sensor.scan(xy, rng).ends[0, 0] for _ in range(300)])
    assert ends.mean() == pytest.approx(8.02, abs=0.003)
    assert ends.std() == pytest.approx(spec.sensor_noise, rel=0.2)
    _assert_deterministic(sensor, xy)


def test_range_limit(exact):
    m = WarehouseMap(np.zeros((2, 20), dtype=bool))
    scan = DepthSensor(exact, m).scan(np.array([1.0, 1.0]), np.random.default_rng(0))
    assert not scan.hits[0]  # the far wall is 19 m away
    np.testing.assert_allclose(scan.ends[0], [1.0 + exact.sensor_range, 1.0])
    assert (np.linalg.norm(scan.points - scan.origin, axis=1) <= exact.sensor_range + 1e-9).all()


@pytest.mark.parametrize(
    "pose", [[np.nan, 1.0], [-0.5, 1.0], [1.5, 20.0], [8.5, 5.5], [1.0, 1.0, 0.0]]
)
def test_bad_poses(spec, pose):
    m = WarehouseMap.from_boxes((12, 12), [(6, 8)])
    with pytest.raises(InputError):
        DepthSensor(spec, m).scan(np.array(pose), np.random.default_rng(0))


def test_warehouse_scene_holds_obstacles_and_floor(camera_spec):
    m = WarehouseMap.from_boxes((12, 12), [(0, 0), (5, 7)])
    scene = warehouse_scene(camera_spec, m)
    lo, hi = obstacle_bounds(camera_spec, m)
    assert scene.box_ids.tolist() == list(range(7))
    np.testing.assert_allclose(scene.boxes[:6, :3], (lo + hi) / 2)
    np.testing.assert_allclose(scene.boxes[:6, 3:6], hi - lo)
    assert scene.boxes[6, 2] + scene.boxes[6, 5] / 2 == pytest.approx(0.0)  # floor top at z = 0
    assert scene.contains(np.array([[3.0, 3.0, -0.01], [3.0, 3.0, 0.01]])).tolist() == [True, False]


def test_camera_scan_sees_a_box_face_and_the_floor_exactly(camera_spec):
    m = WarehouseMap.from_boxes((12, 12), [(6, 8)])  # centre (8.5, 5.5); face at x = 8.02
    sensor = DepthSensor(camera_spec, m)
    xy = np.array([5.5, 5.5])
    scan = sensor.scan(xy, np.random.default_rng(0), exact=True)
    face = scan.points[(scan.points[:, 0] > 7.9) & (np.abs(scan.points[:, 1] - 5.5) < 0.4)]
    face = face[face[:, 2] > 0.1]
    assert len(face) > 100
    np.testing.assert_allclose(face[:, 0], 8.02, atol=1e-9)
    x, y = scan.points[:, 0], scan.points[:, 1]
    walls = (x < 1e-6) | (x > 12 - 1e-6) | (y < 1e-6) | (y > 12 - 1e-6)
    box = (x > 8.02 - 1e-6) & (x < 8.98 + 1e-6) & (y > 5.02 - 1e-6) & (y < 5.98 + 1e-6)
    floor = scan.points[~walls & ~box]
    np.testing.assert_allclose(floor[:, 2], 0.0, atol=1e-9)  # all else in view is floor
    # the lowest image row looks down at tilt + vfov / 2: the floor starts at h / tan of that
    cam = camera_spec.camera
    steepest = math.radians(camera_spec.camera_tilt_deg) + math.atan((cam.height - 1) / 2 / cam.fy)
    reach = np.hypot(floor[:, 0] - 5.5, floor[:, 1] - 5.5)
    assert reach.min() >= camera_spec.sensor_height / math.tan(steepest) - 1e-6
    # the column straight ahead (azimuth 0) hits the face; the floor-only columns do not hit
    ahead = np.argmin(np.abs(np.angle(np.exp(1j * scan.azimuths))))
    assert scan.hits[ahead]
    # at the median reach of the column's face returns: a tilted column's rays fan out a little
    # in azimuth, so the reach along +x differs from the face's distance by micrometres
    np.testing.assert_allclose(scan.ends[ahead, 0], 8.02, atol=1e-4)
    open_ends = scan.ends[~scan.hits]
    assert len(open_ends) > 0
    assert np.hypot(*(open_ends - xy).T).max() <= cam.max_range / math.cos(
        math.radians(cam.hfov_deg / 2)
    )
    assert scan.origin.tolist() == [5.5, 5.5, camera_spec.sensor_height]


def test_camera_scan_noise_registration_and_determinism(camera_spec):
    m = WarehouseMap.from_boxes((12, 12), [(6, 8)])
    sensor = DepthSensor(camera_spec, m)
    xy = np.array([5.5, 5.5])
    exact = sensor.scan(xy, np.random.default_rng(0), exact=True)
    a = _assert_deterministic(sensor, xy)
    assert len(a.points) < len(exact.points)  # dropouts at edges and grazing angles
    face = a.points[(a.points[:, 0] > 7.8) & (np.abs(a.points[:, 1] - 5.5) < 0.4)]
    face = face[face[:, 2] > 0.2]
    # 2.5 m away: noise b z^2 ~ 1 cm, registration ~1 cm and 0.5 degrees
    assert 0.002 < face[:, 0].std() < 0.1
    assert abs(face[:, 0].mean() - 8.02) < 0.1


def test_camera_scan_without_returns_in_range_has_no_hits(camera_spec):
    m = WarehouseMap(np.zeros((12, 12), dtype=bool))
    scan = DepthSensor(camera_spec, m).scan(
        np.array([6.0, 6.0]), np.random.default_rng(0), exact=True
    )
    assert not scan.hits.any()  # every wall is 6 m away, beyond the camera's 4.5 m
    assert len(scan.ends) > 0 and (scan.points[:, 2] < 1e-9).all()
