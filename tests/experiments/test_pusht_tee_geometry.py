"""The T as an object: gym-pusht's from its source, or one perceived from the images.

- `GYM_TEE` against the module's constants (the state path plans with them, unchanged);
- `TeeGeometry.from_shape` against a perceived outline's own area centroid, and its inertia
  against a uniform lamina integrated on a fine grid;
- the planner's pieces (contacts, distances, the analytic model through `ModelTransition`) take
  the T they are given: a push through the perceived T's centre does not turn it.

Covers probaff.experiments.pusht.geometry (TeeGeometry) and the T handed through
probaff.experiments.pusht.transitions.
"""

import numpy as np
import pytest

from probaff.errors import InputError
from probaff.experiments.pusht.geometry import (
    COG,
    GYM_TEE,
    INERTIA,
    OUTLINE,
    PERIMETER,
    RECTS,
    TeeGeometry,
    cog_pose,
    contact_points,
    distance_to_tee,
    keypoint_cost,
    origin_pose,
    to_block,
    to_world,
)
from probaff.experiments.pusht.models import QuasiStaticTee
from probaff.experiments.pusht.primitives import PrimitiveSettings
from probaff.experiments.pusht.template import TeeShape
from probaff.experiments.pusht.transitions import ModelTransition, TeePushes


def test_gym_tee_is_gym_pushts_source():
    assert GYM_TEE.rects is RECTS and GYM_TEE.outline is OUTLINE
    np.testing.assert_array_equal(RECTS, [[-60, -45, 60, -15], [-15, -15, 15, 75]])
    np.testing.assert_array_equal(COG, [0, 45])
    assert INERTIA == 3000.0 and PERIMETER == 480.0
    np.testing.assert_array_equal(OUTLINE.min(0), [-60, -45])


def _lamina(tee, cells=400):
    """Centre of area and polar moment per area of the T's boxes, by the midpoint rule (T frame)."""
    pts, weights = [], []
    for x0, y0, x1, y1 in tee.rects + np.r_[tee.cog, tee.cog]:
        xs = x0 + (np.arange(cells) + 0.5) * (x1 - x0) / cells
        ys = y0 + (np.arange(cells) + 0.5) * (y1 - y0) / cells
        pts.append(np.stack(np.meshgrid(xs, ys), -1).reshape(-1, 2))
        weights.append(np.full(cells * cells, (x1 - x0) * (y1 - y0)))
    p, w = np.concatenate(pts), np.concatenate(weights)
    c = w @ p / w.sum()
    return c, float(w @ ((p - c) ** 2).sum(1) / w.sum())


def test_a_perceived_tee_is_a_uniform_lamina_of_its_outline():
    shape = TeeShape(bar_length=118.7, bar_width=31.2, stem_width=29.1, stem_length=88.4)
    tee = TeeGeometry.from_shape(shape)
    np.testing.assert_allclose(tee.cog, shape.centroid(), atol=1e-12)
    centre, polar = _lamina(tee)
    np.testing.assert_allclose(centre, tee.cog, atol=1e-9)
    assert tee.inertia == pytest.approx(polar, rel=1e-4)  # the midpoint rule's error: 1e-5
    # the outline in the T frame is the perceived one, moved to the centre of gravity
    np.testing.assert_allclose(tee.outline + tee.cog, shape.outline(), atol=1e-12)
    assert tee.perimeter == pytest.approx(2 * (118.7 + 31.2 + 88.4))
    # gym-pusht's T as a camera sees it: its centre of area is not its centre of gravity
    seen = TeeGeometry.from_lengths(120, 30, 30, 90)
    assert seen.cog[1] == pytest.approx(40.714285714, abs=1e-9) and seen.inertia < INERTIA
    pose = np.array([200.0, 210.0, 0.7])
    np.testing.assert_allclose(cog_pose(origin_pose(pose, tee), tee), pose, atol=1e-12)


def test_contacts_and_distances_are_of_the_tee_given():
    tee = TeeGeometry.from_lengths(100, 20, 40, 60)
    pts, normals = contact_points(np.array([0.0, 50.0, tee.perimeter - 1e-9]), tee)
    np.testing.assert_allclose(pts[0], tee.outline[0])
    np.testing.assert_allclose(pts[1], tee.outline[0] + [50.0, 0.0])
    np.testing.assert_allclose(normals[1], [0.0, -1.0])
    d, _ = distance_to_tee(pts, tee)
    np.testing.assert_allclose(d, 0.0, atol=1e-9)
    d_gym, _ = distance_to_tee(tee.outline[4:5])
    assert d_gym[0] == pytest.approx(5.0)  # the stem's corner: 20 across, gym-pusht's is 15


def test_the_analytic_model_pushes_the_tee_of_the_batch():
    tee = TeeGeometry.from_shape(TeeShape(120.0, 30.0, 30.0, 90.0))
    qs = QuasiStaticTee(sigma=np.full(3, 0.1))
    s = PrimitiveSettings()
    # a push up the stem's foot (arc length 300: middle of the stem's bottom edge), straight in
    prims = np.array([[300.0, 0.0, 30.0]])
    state = (np.array([[256.0, 256.0, 0.0]]), np.array([[100.0, 100.0]]), np.zeros((1, 2)))
    perceived = ModelTransition(qs).predict(TeePushes(*state, prims, s, tee))
    gym = ModelTransition(qs).predict(TeePushes(*state, prims, s))
    # through the centre of either T: it slides along the push without turning
    assert abs(perceived.mean[0, 0, 2]) < 1e-9 and abs(gym.mean[0, 0, 2]) < 1e-9
    assert perceived.mean[0, 0, 1] < 256.0 - 20  # pushed up (towards smaller y) by the stem
    # the start of the push is on each T's own outline: the stem's foot is 4.3 px further out
    assert perceived.pusher[0, 1] - gym.pusher[0, 1] == pytest.approx(45 - tee.cog[1], abs=1e-9)


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda: cog_pose([[1.0, 2.0]]), r"origin must be \(\.\.\., 3\)"),
        (lambda: origin_pose("abc"), r"pose must be \(\.\.\., 3\) \(x, y, angle\) poses"),
        (lambda: to_world(np.zeros(3), np.zeros((4, 3))), r"points must be \(\.\.\., 2\)"),
        (lambda: to_block(np.zeros((2, 3)), np.zeros((4, 2))), "pose must be one"),
        (lambda: contact_points([[1.0, 2.0]]), r"s must be a \(K,\) array"),
        (lambda: distance_to_tee([[0.0, 0.0], [1.0]]), r"points must be \(\.\.\., 2\)"),
        (lambda: keypoint_cost(np.zeros(3), [1.0, 2.0]), r"goal must be \(\.\.\., 3\)"),
    ],
)
def test_tee_functions_name_malformed_input(call, message):
    with pytest.raises(InputError, match=message):
        call()


def test_an_unseen_pose_gives_nan_not_an_error():
    assert np.isnan(cog_pose(np.full(3, np.nan))).all()
    assert np.isnan(keypoint_cost(np.full((2, 3), np.nan), np.zeros(3))).all()
