"""Tests of chapter 2's pipeline from a scan to labelled segments (`scan_labels`)."""

import numpy as np
import pytest

from probaff.errors import InputError
from probaff.perception.normals import estimate_normals
from probaff.perception.region_growing import region_growing
from probaff.perception.scan_labels import (
    PerceptionConfig,
    grow_regions,
    head_pose,
    label_dataset,
    scan_segments,
    scenes_dataset,
)
from probaff.sim.camera import CameraSpec, DepthCamera, head_views, scan_views
from probaff.sim.office import OfficeLabelRules, OfficeObject, assemble_office_scene
from probaff.sim.office_config import load_office

# A small camera keeps the tests fast; the pipeline does not depend on the resolution.
CAMERA = DepthCamera(CameraSpec(width=160, height=120))
ONE_VIEW = PerceptionConfig(pans_deg=(0.0,), tilts_deg=(30.0,), min_size=30)


def _scene():
    """Floor (0), a wall at x = 3 (1), a large box (2) and a thin box (3) in front."""
    floor = OfficeObject(0, "floor", "floor", boxes=np.array([[1.5, 0, -0.025, 6, 6, 0.05, 0]]))
    wall = OfficeObject(1, "wall", "wall_+x", boxes=np.array([[3.05, 0, 1.2, 0.1, 6, 2.4, 0]]))
    big = OfficeObject(
        2, "box", "box_2", boxes=np.array([[2.0, -0.35, 0.25, 0.5, 0.5, 0.5, 0]]), mass=1.0
    )
    thin = OfficeObject(
        3, "box", "box_3", boxes=np.array([[2.0, 0.45, 0.25, 0.3, 0.12, 0.5, 0]]), mass=0.5
    )
    return assemble_office_scene([floor, wall, big, thin], OfficeLabelRules())


def test_segments_of_a_handbuilt_scene_match_its_objects_and_labels():
    scene = _scene()
    scan = scan_segments(scene, CAMERA, head_pose(scene), ONE_VIEW, np.random.default_rng(1))
    (view,) = scan.views
    assert view.features.shape == (view.n_segments, 25)
    assert set(view.object_ids.tolist()) >= {0, 2, 3}  # the far wall may be lost to noise
    for oid, lab in zip(view.object_ids, view.labels, strict=True):
        np.testing.assert_array_equal(lab, scene.label_of(int(oid)))
    assert not view.labels[np.isin(view.object_ids, [0, 1])].any()
    assert scene.label_of(3)[5] and not scene.label_of(2)[5]  # only the thin box is graspable
    # The largest segment of each object is nearly pure and its centroid lies on the object.
    for oid, centre in ((0, None), (2, (2.0, -0.35)), (3, (2.0, 0.45))):
        rows = np.flatnonzero(view.object_ids == oid)
        best = rows[np.argmax(view.point_counts[rows])]
        assert view.purity[best] > 0.95
        if centre is not None:
            np.testing.assert_allclose(view.centroids[best, :2], centre, atol=0.3)
    # Point bookkeeping: counts agree with the per-point segment rows.
    on = view.point_segments >= 0
    np.testing.assert_array_equal(
        np.bincount(view.point_segments[on], minlength=view.n_segments), view.point_counts
    )
    outside = int(np.count_nonzero(view.point_segments < 0))
    assert outside == len(view.points) - int(view.point_counts.sum())
    assert 0 < view.n_unassigned <= outside


def test_grow_regions_is_region_growing_with_the_configs_settings():
    rng = np.random.default_rng(0)
    plane = np.column_stack([rng.uniform(0, 1, (300, 2)), np.zeros(300)])
    wall = np.column_stack([np.full(300, 1.2), rng.uniform(0, 1, (300, 2))])
    pts = np.vstack([plane, wall])
    config = PerceptionConfig(k=10, min_size=20)
    nrm = estimate_normals(pts, config.k, viewpoint=np.array([0.5, 0.5, 2.0]))
    seg = grow_regions(pts, nrm, config)
    ref = region_growing(
        pts,
        nrm.normals,
        nrm.curvature,
        k=10,
        smoothness_deg=config.smoothness_deg,
        curvature_threshold=config.curvature_threshold,
        min_size=20,
        neighbours=nrm.neighbours,
    )
    np.testing.assert_array_equal(seg.labels, ref.labels)
    assert seg.n_segments == ref.n_segments >= 2


def test_structure_segments_can_be_dropped():
    scene = _scene()
    cfg = PerceptionConfig(pans_deg=(0.0,), tilts_deg=(30.0,), min_size=30, keep_structure=False)
    (view,) = scan_segments(scene, CAMERA, head_pose(scene), cfg, np.random.default_rng(1)).views
    assert view.n_segments > 0
    assert not np.isin(view.object_ids, [0, 1]).any()
    assert view.point_segments.max() == view.n_segments - 1


def test_same_seed_same_segments_and_other_seed_differs():
    scene = _scene()
    head = head_pose(scene)
    a = scan_segments(scene, CAMERA, head, ONE_VIEW, np.random.default_rng(5))
    b = scan_segments(scene, CAMERA, head, ONE_VIEW, np.random.default_rng(5))
    c = scan_segments(scene, CAMERA, head, ONE_VIEW, np.random.default_rng(6))
    np.testing.assert_array_equal(a.features, b.features)
    np.testing.assert_array_equal(a.object_ids, b.object_ids)
    assert a.features.shape != c.features.shape or not np.array_equal(a.features, c.features)


def test_nan_pixels_are_dropped_and_counted():
    scene = _scene()
    head = head_pose(scene)
    scan = scan_segments(scene, CAMERA, head, ONE_VIEW, np.random.default_rng(2))
    (image,) = scan_views(
        CAMERA,
        scene.primitives,
        head_views(head, ONE_VIEW.pans_deg, ONE_VIEW.tilts_deg),
        rng=np.random.default_rng(2),
    )
    n_nan = int(np.isnan(image.depth).sum())
    assert n_nan > 0  # edge and grazing-angle dropouts
    assert scan.n_nan == n_nan
    (view,) = scan.views
    assert len(view.points) == image.depth.size - n_nan
    assert np.isfinite(view.points).all()


def test_label_dataset_shapes_groups_and_determinism():
    spec = load_office()
    a = label_dataset(spec, 2, seed=3, config=ONE_VIEW, camera=CAMERA)
    n = len(a.features)
    assert a.features.shape == (n, 25) and a.labels.shape == (n, 6)
    assert a.labels.dtype == bool
    assert a.groups.shape == a.object_ids.shape == a.purity.shape == (n,)
    assert set(a.groups.tolist()) == {0, 1}
    assert np.all(np.diff(a.groups) >= 0)
    assert ((a.purity > 0) & (a.purity <= 1)).all()
    assert a.label("graspable").shape == (n,)
    b = label_dataset(spec, 2, seed=3, config=ONE_VIEW, camera=CAMERA)
    np.testing.assert_array_equal(a.features, b.features)
    np.testing.assert_array_equal(a.labels, b.labels)


def test_bad_inputs_raise_input_errors():
    spec = load_office()
    with pytest.raises(InputError, match="scenes is empty"):
        scenes_dataset([], config=ONE_VIEW, camera=CAMERA)
    with pytest.raises(InputError, match="n_scenes"):
        label_dataset(spec, 0, config=ONE_VIEW, camera=CAMERA)
    with pytest.raises(InputError, match="n_scenes"):
        label_dataset(spec, 1.5, config=ONE_VIEW, camera=CAMERA)
    with pytest.raises(InputError, match="k"):
        PerceptionConfig(k=2)
    with pytest.raises(InputError, match="pans_deg"):
        PerceptionConfig(pans_deg=())
    scene = _scene()
    inside = head_pose(scene, 0.25)
    inside[:2, 3] = (2.0, -0.35)  # the centre of the large box
    with pytest.raises(InputError, match="inside"):
        scan_segments(scene, CAMERA, inside, ONE_VIEW, np.random.default_rng(0))
    with pytest.raises(InputError, match="OfficeScene"):
        scan_segments(scene.primitives, CAMERA, head_pose(scene), ONE_VIEW)
    data = scenes_dataset([scene], config=ONE_VIEW, camera=CAMERA)
    with pytest.raises(InputError, match="unknown label"):
        data.label("push_up")


def test_head_height_the_camera_cannot_see_from_is_refused_at_construction():
    # 30-degree tilt, 43-degree vertical field of view, 0.5-4.5 m: the floor is in range from
    # 0.08 m to 3.78 m (the bottom row meets it at h / sin(30 + 21.4 degrees) / cos(21.4)).
    with pytest.raises(InputError, match=r"head_height 100 m .* must lie in \[0\.080, 3\.779\] m"):
        PerceptionConfig(head_height=100)
    with pytest.raises(InputError, match=r"head_height 0\.05 m .*\[0\.080, 3\.779\]"):
        PerceptionConfig(head_height=0.05)
    assert PerceptionConfig(head_height=3.7).head_height == 3.7
    with pytest.raises(InputError, match=r"tilts_deg holds -30: .* use tilts above -21\.4"):
        PerceptionConfig(tilts_deg=(-30.0,))
    with pytest.raises(InputError, match=r"tilts_deg \[89\.0, -20\.0\] cannot all image"):
        PerceptionConfig(tilts_deg=(89.0, -20.0))


@pytest.mark.parametrize(
    ("field", "value", "message"),
    [
        ("head_height", "2", r"head_height must be a finite number > 0, got '2'"),
        ("smoothness_deg", None, r"smoothness_deg must be a finite number > 0, got None"),
        ("pans_deg", "abc", r"pans_deg must be a non-empty list of finite angles .*'abc'"),
        ("tilts_deg", ["a"], r"tilts_deg must be a non-empty list of finite angles"),
        ("noise", "no", r"noise must be True or False, got 'no'"),
        ("keep_structure", 1, r"keep_structure must be True or False, got 1"),
    ],
)
def test_config_fields_of_the_wrong_type_are_named(field, value, message):
    with pytest.raises(InputError, match=message):
        PerceptionConfig(**{field: value})


def test_camera_checked_against_the_config_before_any_scan(monkeypatch):
    from probaff.perception import scan_labels

    def tripwire(*args, **kwargs):
        raise AssertionError("a scan started")

    monkeypatch.setattr(scan_labels, "scan_views", tripwire)
    monkeypatch.setattr(scan_labels, "sample_office_scenes", tripwire)
    scene = _scene()
    short = DepthCamera(CameraSpec(width=160, height=120, min_range=0.3, max_range=1.0))
    with pytest.raises(InputError, match=r"head_height 1\.2 m leaves the camera \(range 0\.3-1 m"):
        scenes_dataset([scene], config=ONE_VIEW, camera=short)
    with pytest.raises(InputError, match=r"head_height 1\.2 m .* \[0\.049, 0\.838\] m"):
        label_dataset(load_office(), 2, config=ONE_VIEW, camera=short)
    tiny = DepthCamera(CameraSpec(width=4, height=4))
    with pytest.raises(InputError, match=r"k=30 exceeds the camera's 4 x 4 = 16 pixels"):
        scan_segments(scene, tiny, head_pose(scene), ONE_VIEW)
    high = head_pose(scene, 1.2)
    high[2, 3] = 100.0
    with pytest.raises(InputError, match=r"T_world_head puts the camera 100\.000 m above"):
        scan_segments(scene, CAMERA, high, ONE_VIEW)
    with pytest.raises(InputError, match="camera must be a DepthCamera"):
        scan_segments(scene, "kinect", head_pose(scene), ONE_VIEW)
