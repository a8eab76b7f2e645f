"""The pinhole depth camera: analytic depths, silhouettes, occlusion, noise, dropouts, errors.

Covers probaff.sim.camera and its ray casting, probaff.sim.raycast.
"""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from probaff.errors import ConfigError, InputError
from probaff.sim.camera import (
    CameraSpec,
    DepthCamera,
    DepthImage,
    head_views,
    load_camera,
    scan_views,
)
from probaff.sim.primitives import PrimitiveScene

FORWARD = head_views(np.eye(4), [0.0], [0.0])[0]  # camera at the origin looking along world +x


@pytest.fixture(scope="module")
def spec() -> CameraSpec:
    return load_camera()


@pytest.fixture(scope="module")
def small(spec: CameraSpec) -> DepthCamera:
    return DepthCamera(replace(spec, width=80, height=60))


def _boxes(rows: list[list[float]], ids: list[int]) -> PrimitiveScene:
    return PrimitiveScene(boxes=np.array(rows), box_ids=np.array(ids))


def _cylinders(rows: list[list[float]], ids: list[int]) -> PrimitiveScene:
    return PrimitiveScene(cylinders=np.array(rows), cylinder_ids=np.array(ids))


def _wall(distance: float, yaw: float = 0.0, oid: int = 1) -> PrimitiveScene:
    """A big 2 cm thick wall whose camera-side face passes through (distance, 0, 0)."""
    n = np.array([math.cos(yaw), math.sin(yaw), 0.0])
    c = np.array([distance, 0.0, 0.0]) + 0.01 * n
    return _boxes([[*c, 0.02, 40.0, 40.0, yaw]], [oid])


def _range_along_ray(cam: DepthCamera, image: DepthImage) -> np.ndarray:
    return image.depth * np.linalg.norm(cam.spec.pixel_rays(), axis=2)


def test_spec_from_yaml_matches_the_kinect_model(spec: CameraSpec) -> None:
    assert (spec.width, spec.height) == (320, 240)
    assert (spec.hfov_deg, spec.vfov_deg) == (57.0, 43.0)
    assert spec.sigma(1.0) == pytest.approx(0.0015, rel=0.05)
    # the outer pixel edges span the field of view
    assert 2 * math.degrees(math.atan((spec.width / 2) / spec.fx)) == pytest.approx(57.0)
    assert 2 * math.degrees(math.atan((spec.height / 2) / spec.fy)) == pytest.approx(43.0)


def test_plane_facing_the_camera_has_exact_depth(small: DepthCamera) -> None:
    image = small.render(_wall(1.7), FORWARD, noise=False)
    assert np.all(image.valid)
    np.testing.assert_allclose(image.depth, 1.7, atol=1e-12)
    assert np.all(image.object_id == 1)
    np.testing.assert_allclose(image.normal[..., 0], -1.0, atol=1e-12)
    np.testing.assert_allclose(image.normal[..., 1:], 0.0, atol=1e-12)
    np.testing.assert_allclose(image.points()[:, 0], 1.7, atol=1e-12)


@pytest.mark.parametrize("yaw_deg", [20.0, -35.0])
def test_tilted_plane_range_is_distance_over_cos(small: DepthCamera, yaw_deg: float) -> None:
    yaw = math.radians(yaw_deg)
    d = 1.5
    image = small.render(_wall(d, yaw), FORWARD, noise=False)
    normal = np.array([math.cos(yaw), math.sin(yaw), 0.0])
    rays = small.spec.pixel_rays() @ FORWARD[:3, :3].T  # world directions
    unit = rays / np.linalg.norm(rays, axis=2, keepdims=True)
    cos = unit @ normal
    expected = d * math.cos(yaw) / cos  # perpendicular distance over cos of the incidence
    np.testing.assert_allclose(_range_along_ray(small, image), expected, rtol=1e-10)


def test_box_edge_lands_on_the_projected_pixel(small: DepthCamera) -> None:
    spec = small.spec
    y_edge, x_face = 0.1234, 2.0  # the box spans world y in [-5, y_edge]; camera x = -world y
    box = [x_face + 0.05, (y_edge - 5.0) / 2, 0.0, 0.1, 5.0 + y_edge, 4.0, 0.0]
    image = small.render(_boxes([box], [3]), FORWARD, noise=False)
    u_edge = spec.cx + spec.fx * (-y_edge) / x_face
    first = math.ceil(u_edge)
    row = image.object_id[spec.height // 2]
    assert np.all(row[:first] == -1)
    assert np.all(row[first:] == 3)
    np.testing.assert_allclose(image.depth[:, first:], x_face, atol=1e-12)


def test_nearer_box_occludes_a_farther_wall(small: DepthCamera) -> None:
    scene = _boxes(
        [[3.0, 0.0, 0.0, 0.02, 40.0, 40.0, 0.0], [1.5, 0.0, 0.0, 0.2, 0.4, 0.4, 0.0]], [1, 2]
    )
    image = small.render(scene, FORWARD, noise=False)
    near = image.object_id == 2
    assert near[small.spec.height // 2, small.spec.width // 2]
    np.testing.assert_allclose(image.depth[near], 1.4, atol=1e-12)
    np.testing.assert_allclose(image.depth[~near], 2.99, atol=1e-12)
    # the near box spans 0.4 m at 1.4 m: about 0.4 fx / 1.4 pixels wide
    width = near[small.spec.height // 2].sum()
    assert abs(width - 0.4 * small.spec.fx / 1.4) <= 1.0


def test_cylinder_silhouette_width_is_2rf_over_z(spec: CameraSpec) -> None:
    cam = DepthCamera(spec)
    r, z = 0.1, 2.0
    scene = _cylinders([[z, 0.0, 0.0, r, 1.0]], [4])
    image = cam.render(scene, FORWARD, noise=False)
    width = (image.object_id[spec.height // 2] == 4).sum()
    assert abs(width - 2 * r * spec.fx / z) <= 1.0
    assert np.nanmin(image.depth) == pytest.approx(z - r, abs=1e-4)
    # the side's normals are horizontal and face the camera
    n = image.normal[image.valid]
    np.testing.assert_allclose(n[:, 2], 0.0, atol=1e-12)
    assert np.all(n[:, 0] < 0)


def test_cylinder_cap_seen_from_above(small: DepthCamera) -> None:
    down = head_views(np.eye(4), [0.0], [90.0])[0]
    down[:3, 3] = [0.0, 0.0, 2.0]
    scene = _cylinders([[0.0, 0.0, 0.5, 0.3, 1.0]], [5])
    image = small.render(scene, down, noise=False)
    centre = (small.spec.height // 2, small.spec.width // 2)
    assert image.object_id[centre] == 5
    assert image.depth[centre] == pytest.approx(1.0)
    np.testing.assert_allclose(image.normal[centre], [0.0, 0.0, 1.0])


def test_culled_cast_equals_the_nearest_of_single_primitives(small: DepthCamera) -> None:
    rng = np.random.default_rng(5)
    k = 12
    boxes = np.column_stack(
        [
            rng.uniform(1.0, 4.0, k),
            rng.uniform(-1.5, 1.5, k),
            rng.uniform(-1.0, 1.0, k),
            rng.uniform(0.05, 0.8, (k, 3)),
            rng.uniform(-np.pi, np.pi, k),
        ]
    )
    cyls = np.column_stack(
        [
            rng.uniform(1.0, 4.0, 4),
            rng.uniform(-1.5, 1.5, 4),
            rng.uniform(-1.0, 1.0, 4),
            rng.uniform(0.05, 0.4, (4, 2)),
        ]
    )
    scene = PrimitiveScene(boxes, np.arange(k), cyls, np.arange(k, k + 4))
    depth, ids, normal = small.cast(scene, FORWARD)
    singles = [small.cast(_boxes([b.tolist()], [i]), FORWARD) for i, b in enumerate(boxes)]
    singles += [small.cast(_cylinders([c.tolist()], [k + i]), FORWARD) for i, c in enumerate(cyls)]
    stack = np.stack([s[0] for s in singles])  # (K, H, W)
    np.testing.assert_array_equal(depth, stack.min(axis=0))
    hit = np.isfinite(depth)
    assert 0.2 < hit.mean() < 1.0
    np.testing.assert_array_equal(ids[hit], stack.argmin(axis=0)[hit])
    np.testing.assert_array_equal(ids[~hit], -1)
    np.testing.assert_allclose(np.linalg.norm(normal[hit], axis=1), 1.0)


def _noise_std(spec: CameraSpec, distance: float) -> float:
    cam = DepthCamera(spec)
    image = cam.render(_wall(distance), FORWARD, rng=np.random.default_rng(3))
    assert image.valid.mean() > 0.99
    return float(np.nanstd(image.depth - distance))


def test_depth_noise_is_1p5_mm_at_1_m_and_grows_as_z_squared(spec: CameraSpec) -> None:
    s1, s2 = _noise_std(spec, 1.0), _noise_std(spec, 2.0)
    assert s1 == pytest.approx(0.0015, rel=0.2)
    assert s2 / s1 == pytest.approx(4.0, rel=0.25)


def test_depth_is_quantised_in_disparity(small: DepthCamera) -> None:
    spec = small.spec
    image = small.render(_wall(2.0), FORWARD, rng=np.random.default_rng(1))
    disparity = spec.fx * spec.baseline / image.depth[image.valid]
    steps = disparity / spec.disparity_step
    np.testing.assert_allclose(steps, np.round(steps), atol=1e-6)


def test_grazing_dropouts_only_above_the_threshold(spec: CameraSpec) -> None:
    cam = DepthCamera(replace(spec, width=160, height=120, edge_probability=0.0))
    yaw = math.radians(65.0)
    scene = _wall(0.8, yaw)
    exact = cam.render(scene, FORWARD, noise=False)
    noisy = cam.render(scene, FORWARD, rng=np.random.default_rng(2))
    rays = cam.spec.pixel_rays() @ FORWARD[:3, :3].T
    unit = rays / np.linalg.norm(rays, axis=2, keepdims=True)
    incidence = np.degrees(np.arccos(np.abs(unit @ [math.cos(yaw), math.sin(yaw), 0.0])))
    grazing = exact.valid & (incidence > spec.max_incidence_deg)
    facing = exact.valid & (incidence < spec.max_incidence_deg - 0.5)
    assert grazing.sum() > 100 and facing.sum() > 100
    assert not noisy.valid[grazing].any()
    assert noisy.valid[facing].mean() > 0.999  # only noise may push a few past the range


def test_edge_pixels_drop_with_their_probability(spec: CameraSpec) -> None:
    scene = _boxes(
        [[3.0, 0.0, 0.0, 0.02, 40.0, 40.0, 0.0], [1.5, 0.0, 0.0, 0.2, 0.4, 0.4, 0.0]], [1, 2]
    )
    base = replace(spec, width=80, height=60)
    exact = DepthCamera(base).render(scene, FORWARD, noise=False)
    kept = DepthCamera(replace(base, edge_probability=0.0)).render(scene, FORWARD)
    lost = DepthCamera(replace(base, edge_probability=1.0)).render(scene, FORWARD)
    assert kept.valid.all()
    dropped = exact.valid & ~lost.valid
    # exactly the pixels on either side of the near box's outline
    assert 0 < dropped.sum() < 0.2 * dropped.size
    assert set(np.unique(exact.object_id[dropped])) == {1, 2}
    inner = exact.object_id == 2
    inner[1:-1, 1:-1] &= inner[:-2, 1:-1] & inner[2:, 1:-1] & inner[1:-1, :-2] & inner[1:-1, 2:]
    assert lost.valid[inner].all() and not dropped[inner].any()


def test_out_of_range_returns_nothing(small: DepthCamera) -> None:
    for d in (0.3, 5.0):
        image = small.render(_wall(d), FORWARD, noise=False)
        assert not image.valid.any()
        assert np.all(image.object_id == -1) and np.isnan(image.normal).all()
        assert image.points().shape == (0, 3) and image.point_ids().shape == (0,)


def test_same_seed_same_image(small: DepthCamera) -> None:
    scene = _wall(2.0, math.radians(30.0))
    a = small.render(scene, FORWARD, rng=np.random.default_rng(7))
    b = small.render(scene, FORWARD, rng=np.random.default_rng(7))
    c = small.render(scene, FORWARD, rng=np.random.default_rng(8))
    np.testing.assert_array_equal(a.depth, b.depth)
    np.testing.assert_array_equal(a.object_id, b.object_id)
    assert not np.array_equal(a.depth, c.depth, equal_nan=True)
    default = small.render(scene, FORWARD)  # rng None: seeded 0
    np.testing.assert_array_equal(
        default.depth, small.render(scene, FORWARD, rng=np.random.default_rng(0)).depth
    )


def test_head_views_pan_then_tilt() -> None:
    head = np.eye(4)
    head[:3, 3] = [1.0, 2.0, 1.2]
    poses = head_views(head, [0.0, 90.0], [0.0, 30.0, 45.0])
    assert poses.shape == (6, 4, 4)
    np.testing.assert_allclose(poses[:, :3, 3], [[1.0, 2.0, 1.2]] * 6)
    axis = poses[:, :3, 2]  # the optical axis in the world
    np.testing.assert_allclose(axis[0], [1.0, 0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(axis[3], [0.0, 1.0, 0.0], atol=1e-12)
    s, c = math.sin(math.radians(30.0)), math.cos(math.radians(30.0))
    np.testing.assert_allclose(axis[4], [0.0, c, -s], atol=1e-12)
    # image x stays horizontal (no roll), image y points down-ish
    np.testing.assert_allclose(poses[:, 2, 0], 0.0, atol=1e-12)
    assert np.all(poses[:, 2, 1] < 0)


def test_scan_views_register_through_the_estimated_pose(small: DepthCamera) -> None:
    scene = _wall(2.0)
    poses = head_views(np.eye(4), [-10.0, 10.0], [0.0])
    views = scan_views(small, scene, poses, rng=np.random.default_rng(0), noise=False)
    ideal = scan_views(
        small, scene, poses, rng=np.random.default_rng(0), registration=False, noise=False
    )
    for view, ref, pose in zip(views, ideal, poses, strict=True):
        np.testing.assert_array_equal(view.T_world_camera, pose)
        assert not np.allclose(view.T_world_camera_estimated, pose)
        np.testing.assert_array_equal(ref.T_world_camera_estimated, pose)
        np.testing.assert_allclose(ref.points()[:, 0], 2.0, atol=1e-12)
        err = np.linalg.norm(view.points() - ref.points(), axis=1)
        assert 1e-4 < np.median(err) < 0.1  # misaligned by about the registration error
        np.testing.assert_array_equal(view.point_ids(), ref.point_ids())
    again = scan_views(small, scene, poses, rng=np.random.default_rng(0), noise=False)
    for a, b in zip(views, again, strict=True):
        np.testing.assert_array_equal(a.T_world_camera_estimated, b.T_world_camera_estimated)


def test_bad_poses_are_rejected(small: DepthCamera) -> None:
    scene = _wall(2.0)
    scaled = FORWARD.copy()
    scaled[:3, :3] *= 2.0
    nan = FORWARD.copy()
    nan[0, 3] = np.nan
    for pose, match in ((scaled, "rigid"), (nan, "NaN"), (np.eye(3), "shape")):
        with pytest.raises(InputError, match=match):
            small.render(scene, pose)
    inside = FORWARD.copy()
    inside[:3, 3] = [2.01, 0.0, 0.0]
    with pytest.raises(InputError, match="inside"):
        small.render(scene, inside)
    with pytest.raises(InputError, match="rng"):
        small.render(scene, FORWARD, rng=0)  # type: ignore[arg-type]
    with pytest.raises(InputError, match="scene"):
        small.render("wall", FORWARD)  # type: ignore[arg-type]
    with pytest.raises(InputError, match="poses"):
        scan_views(small, scene, np.zeros((0, 4, 4)))
    with pytest.raises(InputError, match="tilts_deg"):
        head_views(np.eye(4), [0.0], [])


def _write(tmp_path: Path, text: str) -> Path:
    src = Path(__file__).parents[2] / "worlds" / "camera.yaml"
    path = tmp_path / "camera.yaml"
    path.write_text(src.read_text().replace("width: 320", text))
    return path


@pytest.mark.parametrize(
    ("field", "match"),
    [
        ("width: 0", "image.width"),
        ("width: 2.5", "image.width"),
        ("width: -3", "image.width"),
        ("widht: 320", "widht"),
        ("width: [1", "valid YAML"),
    ],
)
def test_malformed_yaml_names_the_field(tmp_path: Path, field: str, match: str) -> None:
    with pytest.raises(ConfigError, match=match):
        load_camera(_write(tmp_path, field))


def test_load_camera_sets_the_image_size_in_place_of_the_files(spec: CameraSpec) -> None:
    assert load_camera(width=None, height=None) == spec
    assert load_camera(width=80, height=60) == replace(spec, width=80, height=60)
    assert load_camera(height=60) == replace(spec, height=60)
    with pytest.raises(ConfigError, match="width"):
        load_camera(width=0)


def test_spec_built_in_code_is_checked(spec: CameraSpec) -> None:
    with pytest.raises(ConfigError, match="height"):
        replace(spec, height=0)
    with pytest.raises(ConfigError, match="min_range"):
        replace(spec, min_range=5.0)
    with pytest.raises(ConfigError, match="edge_probability"):
        replace(spec, edge_probability=1.5)
