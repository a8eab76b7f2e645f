"""Chapter 6 interaction features and action-frame geometry.

Covers probaff.features.ch6, probaff.features.action_frame and the pair search of
probaff.features.contact_pairs (exact against brute force).
"""

import itertools

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from probaff.errors import InputError, ProbaffError
from probaff.features import (
    INTERACTION_FEATURE_COUNT,
    INTERACTION_GROUPS,
    InteractionFeatureConfig,
    action_frame,
    apply_effect,
    box_surface,
    effect_in_action_frame,
    interaction_features,
    planar_pose_from_sideview,
    planar_pose_from_tabletop,
    sideview_transform,
    tabletop_transform,
)
from probaff.features import contact_pairs as pairs_module

BINARY = ("shape", "contact")
CONTINUOUS = ("pose", "action")
R_D = InteractionFeatureConfig().contact_distance


def _pose(xyz, R=None):
    """(N, 4, 4) transforms from (N, 3) positions and (N, 3, 3) rotations (identity)."""
    xyz = np.atleast_2d(np.asarray(xyz, dtype=float))
    T = np.tile(np.eye(4), (len(xyz), 1, 1))
    if R is not None:
        T[:, :3, :3] = R
    T[:, :3, 3] = xyz
    return T


def _moved(T_end_like, T_start):
    """The start poses translated to the positions of `T_end_like`."""
    T = T_start.copy()
    T[:, :3, 3] = T_end_like
    return T


def _hand_push(start, end, hand_size=(0.02, 0.04, 0.04), cube=0.10, spacing=0.01):
    """A 10 cm cube resting at the origin and a box-shaped hand moving from start to end."""
    n = len(start)
    target_T = tabletop_transform(np.zeros((n, 3)), np.full(n, cube))
    t_pts, t_nrm = box_surface(np.full((n, 3), cube), target_T, spacing)
    T_s = _pose(start)
    a_pts, a_nrm = box_surface(np.tile(hand_size, (n, 1)), T_s, spacing)
    return t_pts, t_nrm, a_pts, a_nrm, T_s, _moved(np.asarray(end, float), T_s)


def _move_scene(M, scene):
    """Target, actor and action moved together by the rigid 4 x 4 transform M."""
    t_pts, t_nrm, a_pts, a_nrm, T_s, T_e = scene
    R, t = M[:3, :3], M[:3, 3]
    return t_pts @ R.T + t, t_nrm @ R.T, a_pts @ R.T + t, a_nrm @ R.T, M @ T_s, M @ T_e


def _tabletop_scene(rng, n):
    """Random pushes of random boxes; half of the boxes are turned to face the push."""
    size = rng.uniform(0.1, 0.25, (n, 3))
    ang = rng.uniform(-np.pi, np.pi, n)
    theta = np.where(np.arange(n) % 2 == 0, ang, rng.uniform(-np.pi, np.pi, n))
    pose = np.column_stack([rng.uniform(-0.1, 0.1, (n, 2)), theta])
    t_pts, t_nrm = box_surface(size, tabletop_transform(pose, size[:, 2]), 0.02)
    d = np.column_stack([np.cos(ang), np.sin(ang), np.zeros(n)])
    side = np.column_stack([-np.sin(ang), np.cos(ang), np.zeros(n)])
    lift = rng.uniform(0.02, 0.08, n)
    start = np.column_stack([pose[:, :2], lift]) - 0.3 * d + rng.uniform(-0.15, 0.15, (n, 1)) * side
    end = start + 0.35 * d + np.column_stack([np.zeros((n, 2)), rng.uniform(-0.05, 0.05, n)])
    T_s = tabletop_transform(np.column_stack([start[:, :2], ang]), 2 * lift)
    a_pts, a_nrm = box_surface(np.tile([0.02, 0.04, 0.04], (n, 1)), T_s, 0.01)
    return t_pts, t_nrm, a_pts, a_nrm, T_s, _moved(end, T_s)


def _rotations(rng, n, max_angle=3.0):
    """(n, 3, 3) random rotations, each by less than `max_angle` rad."""
    axis = rng.normal(size=(n, 3))
    axis /= np.linalg.norm(axis, axis=1, keepdims=True)
    return Rotation.from_rotvec(axis * rng.uniform(0.0, max_angle, (n, 1))).as_matrix()


def _assert_same_features(a, b):
    for g in BINARY:
        np.testing.assert_array_equal(a.features.select(g), b.features.select(g))
    for g in CONTINUOUS:
        np.testing.assert_allclose(a.features.select(g), b.features.select(g), rtol=0, atol=1e-9)
    np.testing.assert_array_equal(np.isinf(a.touch_distance), np.isinf(b.touch_distance))
    hit = np.isfinite(a.touch_distance)
    np.testing.assert_allclose(a.touch_distance[hit], b.touch_distance[hit], rtol=0, atol=1e-9)


def test_columns_and_groups_tile_169():
    assert INTERACTION_FEATURE_COUNT == 169
    sizes = {g: s.stop - s.start for g, s in INTERACTION_GROUPS.items()}
    assert sizes == {"shape": 125, "pose": 6, "contact": 32, "action": 6}
    cols = np.concatenate([np.arange(169)[s] for s in INTERACTION_GROUPS.values()])
    np.testing.assert_array_equal(cols, np.arange(169))
    out = interaction_features(*_hand_push([[-0.2, 0.0, 0.05]], [[0.15, 0.0, 0.05]]))
    assert out.features.values.shape == (1, 169)
    assert len(set(out.features.names)) == 169
    assert out.features.groups == INTERACTION_GROUPS


def test_invariant_to_turning_and_moving_the_tabletop_scene():
    rng = np.random.default_rng(6)
    scene = _tabletop_scene(rng, 16)
    base = interaction_features(*scene)
    assert 3 <= base.touches.sum() < 16  # some pushes touch, some miss
    assert base.features.select("contact").sum() > 0
    again = interaction_features(*scene)
    np.testing.assert_array_equal(base.features.values, again.features.values)
    for _ in range(3):
        M = np.eye(4)
        M[:3, :3] = Rotation.from_euler("z", rng.uniform(-np.pi, np.pi)).as_matrix()
        M[:3, 3] = rng.uniform(-5.0, 5.0, 3)
        moved = interaction_features(*_move_scene(M, scene))
        _assert_same_features(base, moved)
        np.testing.assert_allclose(moved.T_world_object, M @ base.T_world_object, atol=1e-9)


def test_results_do_not_depend_on_the_chunk_size():
    scene = _tabletop_scene(np.random.default_rng(8), 11)
    whole = interaction_features(*scene)
    parts = interaction_features(*scene, chunk=4)
    np.testing.assert_array_equal(whole.features.values, parts.features.values)
    np.testing.assert_array_equal(whole.touch_distance, parts.touch_distance)
    np.testing.assert_array_equal(whole.T_world_contact, parts.T_world_contact)
    for bad in (0, 2.5, "4"):
        with pytest.raises(InputError, match="chunk"):
            interaction_features(*scene, chunk=bad)


def test_invariant_to_moving_a_vertical_pick():
    rng = np.random.default_rng(7)
    n = 8
    size = rng.uniform(0.1, 0.25, (n, 3))
    t_pts, t_nrm = box_surface(
        size,
        sideview_transform(
            np.column_stack([rng.uniform(-0.05, 0.05, n), size[:, 2] / 2, np.zeros(n)])
        ),
        0.02,
    )
    start = np.column_stack([rng.uniform(-0.1, 0.1, n), np.zeros(n), size[:, 2] + 0.15])
    T_s = _pose(start)
    a_pts, a_nrm = box_surface(np.tile([0.04, 0.04, 0.02], (n, 1)), T_s, 0.01)
    T_e = _moved(start - [0.0, 0.0, 0.2], T_s)
    scene = (t_pts, t_nrm, a_pts, a_nrm, T_s, T_e)
    base = interaction_features(*scene)
    assert base.touches.sum() >= n // 2
    assert base.features.select("contact").sum() > 0
    M = _pose(rng.uniform(-3.0, 3.0, 3))[0]
    _assert_same_features(base, interaction_features(*_move_scene(M, scene)))


def test_push_into_a_face_touches_at_the_gap_with_contact_on_the_face():
    # hand front face at x = -0.19, cube face at x = -0.05: a 14 cm gap
    out = interaction_features(*_hand_push([[-0.2, 0.0, 0.05]], [[0.15, 0.0, 0.05]]))
    # aligned grids: the first actor point to come within r_d is straight in front of its mate
    np.testing.assert_allclose(out.touch_distance, [0.14 - R_D], rtol=0, atol=1e-12)
    np.testing.assert_allclose(out.T_world_contact[0, :3, 3], [-0.05, 0.0, 0.05], atol=1e-12)
    np.testing.assert_allclose(out.T_world_contact[0, :3, :3], out.T_world_action[0, :3, :3])
    # the 5 x 5 contact patch, split 2 | 3 across x and z about C_t, all at y >= 0 (cell j = 1)
    contact = out.features.select("contact")[0]
    expected = [(i * 2 + 1) * 4 + k for i in (1, 2) for k in (1, 2)]
    np.testing.assert_array_equal(np.flatnonzero(contact), expected)
    # a cell needs more than n_c points: with n_c = 5 the 2 x 2 quarter drops out
    strict = interaction_features(
        *_hand_push([[-0.2, 0.0, 0.05]], [[0.15, 0.0, 0.05]]),
        InteractionFeatureConfig(min_contact_points=5),
    )
    assert np.flatnonzero(strict.features.select("contact")[0]).tolist() == expected[1:]


def test_offset_hand_touches_at_the_analytic_distance():
    delta = 0.003  # the hand's grid is 3 mm off the cube's across the push
    out = interaction_features(*_hand_push([[-0.2, delta, 0.05]], [[0.15, delta, 0.05]]))
    np.testing.assert_allclose(
        out.touch_distance, [0.14 - np.sqrt(R_D**2 - delta**2)], rtol=0, atol=1e-12
    )
    assert out.features.select("contact").sum() > 0
    np.testing.assert_allclose(out.T_world_contact[0, 0, 3], -0.05, atol=1e-12)


def test_actor_beside_or_short_of_the_box_never_touches():
    out = interaction_features(
        *_hand_push([[-0.2, 0.2, 0.05], [-0.3, 0.0, 0.05]], [[0.15, 0.2, 0.05], [-0.2, 0.0, 0.05]])
    )
    assert np.all(np.isinf(out.touch_distance))
    assert not out.touches.any()
    assert out.features.select("contact").sum() == 0
    np.testing.assert_array_equal(out.T_world_contact, out.T_world_object)


def test_actor_starting_at_the_face_touches_at_zero():
    out = interaction_features(*_hand_push([[-0.06, 0.0, 0.05]], [[0.1, 0.0, 0.05]]))
    assert out.touch_distance[0] == 0.0


def test_surfaces_that_do_not_face_each_other_touch_without_contact():
    t_pts, t_nrm, a_pts, a_nrm, T_s, T_e = _hand_push([[-0.2, 0.0, 0.05]], [[0.15, 0.0, 0.05]])
    out = interaction_features(t_pts, t_nrm, a_pts, -a_nrm, T_s, T_e)
    np.testing.assert_allclose(out.touch_distance, [0.14 - R_D], atol=1e-12)
    assert out.features.select("contact").sum() == 0
    np.testing.assert_array_equal(out.T_world_contact, out.T_world_object)


def test_touch_and_contact_match_a_brute_force_search():
    rng = np.random.default_rng(11)
    n, p, q = 24, 80, 50
    cfg = InteractionFeatureConfig(contact_distance=0.03, normal_threshold=0.2)
    r = cfg.contact_distance

    def unit(shape):
        v = rng.normal(size=shape)
        return v / np.linalg.norm(v, axis=-1, keepdims=True)

    t_pts = rng.uniform(-0.1, 0.1, (n, p, 3))
    start = rng.uniform(-0.3, 0.3, (n, 3))
    a_pts = start[:, None] + rng.uniform(-0.06, 0.06, (n, q, 3))
    T_s = _pose(start, _rotations(rng, n))
    T_e = _moved(start + 0.5 * (rng.uniform(-0.1, 0.1, (n, 3)) - start), T_s)
    t_nrm, a_nrm = unit((n, p, 3)), unit((n, q, 3))
    out = interaction_features(t_pts, t_nrm, a_pts, a_nrm, T_s, T_e, cfg)
    assert 5 < out.touches.sum() < n
    R, o = out.T_world_action[:, :3, :3], out.T_world_action[:, :3, 3]
    w = ((t_pts - o[:, None]) @ R)[:, :, None] - ((a_pts - o[:, None]) @ R)[:, None]  # (n,p,q,3)
    across2 = w[..., 0] ** 2 + w[..., 2] ** 2
    h = np.sqrt(np.clip(r * r - across2, 0.0, None))
    length = out.action_length[:, None, None]
    ok = (across2 < r * r) & (w[..., 1] + h >= 0) & (w[..., 1] - h <= length)
    touch = np.where(ok, np.maximum(w[..., 1] - h, 0.0), np.inf).min(axis=(1, 2))
    np.testing.assert_array_equal(np.isinf(touch), ~out.touches)
    np.testing.assert_allclose(out.touch_distance[out.touches], touch[out.touches], atol=1e-12)
    probe = np.minimum(touch + r / 2, out.action_length)[:, None, None]
    facing = np.einsum("npi,nqi->npq", t_nrm, a_nrm) < cfg.normal_threshold
    pair = (across2 + (w[..., 1] - probe) ** 2 < r * r) & facing
    in_contact = pair.any(axis=2)  # (n, p) target points in contact
    has = in_contact.any(axis=1)
    assert has.sum() >= 3
    mean = (in_contact[..., None] * t_pts).sum(1) / np.maximum(in_contact.sum(1), 1)[:, None]
    expected = np.where(has[:, None], mean, out.T_world_object[:, :3, 3])
    np.testing.assert_allclose(out.T_world_contact[:, :3, 3], expected, atol=1e-12)


@pytest.mark.parametrize(("cube", "lo", "hi"), [(0.10, 1, 3), (0.20, 0, 4)])
def test_shape_voxels_of_a_cube_at_the_origin(cube, lo, hi):
    t_pts, t_nrm = box_surface([[cube] * 3], _pose([0.0, 0.0, 0.0]), 0.01)
    T_s = _pose([[-0.5, 0.0, 0.0]])
    a_pts, a_nrm = box_surface([[0.02, 0.04, 0.04]], T_s, 0.01)
    out = interaction_features(t_pts, t_nrm, a_pts, a_nrm, T_s, _moved([[-0.4, 0.0, 0.0]], T_s))
    np.testing.assert_allclose(out.T_world_object[0, :3, 3], 0.0, atol=1e-12)
    shell = {
        (i * 5 + j) * 5 + k
        for i, j, k in itertools.product(range(lo, hi + 1), repeat=3)
        if lo in (i, j, k) or hi in (i, j, k)
    }
    assert set(np.flatnonzero(out.features.select("shape")[0]).tolist()) == shell
    # the hand starts 50 cm behind B_t along the action (y); A_t = B_t is the world turned by
    # -90 degrees about z (y along world x), so the unturned hand is at +90 degrees in B_t
    np.testing.assert_allclose(
        out.features.select("pose")[0], [0, -0.5, 0, 0, 0, np.pi / 2], atol=1e-12
    )
    # the commanded motion: 10 cm along y, no turn
    np.testing.assert_allclose(out.features.select("action")[0], [0, 0.1, 0, 0, 0, 0], atol=1e-12)
    assert out.action_length[0] == pytest.approx(0.1)
    # an actor that also turns by 0.3 rad about world up shows the turn about B_t's z
    T_e = _moved([[-0.4, 0.0, 0.0]], T_s)
    c, s = np.cos(0.3), np.sin(0.3)
    T_e[0, :3, :3] = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]) @ T_e[0, :3, :3]
    turned = interaction_features(t_pts, t_nrm, a_pts, a_nrm, T_s, T_e)
    np.testing.assert_allclose(
        turned.features.select("action")[0], [0, 0.1, 0, 0, 0, 0.3], atol=1e-12
    )


def test_effect_round_trip_is_exact():
    rng = np.random.default_rng(3)
    n = 50
    T_a = action_frame(_pose(rng.normal(size=(n, 3))), _pose(rng.normal(size=(n, 3))))
    T_b = _pose(rng.normal(size=(n, 3)), _rotations(rng, n))
    rotvec = Rotation.from_matrix(_rotations(rng, n, 2.5)).as_rotvec()
    effect = np.column_stack([rng.normal(size=(n, 3)), rotvec])
    T_f = apply_effect(T_a, T_b, effect)
    np.testing.assert_allclose(effect_in_action_frame(T_a, T_b, T_f), effect, atol=1e-12)
    T_g = _pose(rng.normal(size=(n, 3)), _rotations(rng, n))
    back = apply_effect(T_a, T_b, effect_in_action_frame(T_a, T_b, T_g))
    np.testing.assert_allclose(back, T_g, atol=1e-12)


def test_translation_along_the_action_is_a_pure_dy():
    rng = np.random.default_rng(4)
    n = 6
    start = rng.normal(size=(n, 3))
    T_a = action_frame(_pose(start), _pose(start + rng.normal(size=(n, 3))))
    T_b = _pose(rng.normal(size=(n, 3)), _rotations(rng, n))
    d = rng.uniform(0.01, 0.3, n)
    T_f = T_b.copy()
    T_f[:, :3, 3] += d[:, None] * T_a[:, :3, 1]
    expected = np.zeros((n, 6))
    expected[:, 1] = d
    np.testing.assert_allclose(effect_in_action_frame(T_a, T_b, T_f), expected, atol=1e-12)


def test_action_frame_axes():
    rng = np.random.default_rng(5)
    n = 20
    start = rng.normal(size=(n, 3))
    step = rng.normal(size=(n, 3))
    step[:10, 2] = 0.0  # horizontal pushes
    T = action_frame(_pose(start), _pose(start + step))
    R = T[:, :3, :3]
    np.testing.assert_allclose(
        R.transpose(0, 2, 1) @ R, np.broadcast_to(np.eye(3), R.shape), atol=1e-12
    )
    np.testing.assert_allclose(np.linalg.det(R), 1.0)
    np.testing.assert_allclose(T[:, :3, 3], start)
    np.testing.assert_allclose(R[:, :, 1], step / np.linalg.norm(step, axis=1, keepdims=True))
    np.testing.assert_allclose(R[:10, :, 2], np.tile([0.0, 0.0, 1.0], (10, 1)), atol=1e-15)
    # straight down and up (pick, lift): z = world x, x = -y / +y (the viewing axis)
    down_up = action_frame(_pose([[0, 0, 0], [0, 0, 0]]), _pose([[0, 0, -1], [0, 0, 1]]))
    np.testing.assert_allclose(down_up[:, :3, 2], [[1, 0, 0], [1, 0, 0]], atol=1e-15)
    np.testing.assert_allclose(down_up[:, :3, 0], [[0, -1, 0], [0, 1, 0]], atol=1e-15)


def test_action_frame_is_continuous_in_the_side_view_near_vertical_and_horizontal():
    for base in (-np.pi / 2, np.pi / 2, 0.0, np.pi):  # down, up, +x, -x in the (x, z) plane
        a = base + np.array([-1e-6, 0.0, 1e-6])
        T = action_frame(
            _pose(np.zeros((3, 3))), _pose(np.column_stack([np.cos(a), 0 * a, np.sin(a)]))
        )
        np.testing.assert_allclose(T[0, :3, :3], T[1, :3, :3], atol=1e-5)
        np.testing.assert_allclose(T[2, :3, :3], T[1, :3, :3], atol=1e-5)
        np.testing.assert_allclose(np.abs(T[:, 1, 0]), 1.0)  # x is the viewing axis


def test_box_surface_points_and_normals():
    size = np.array([[0.1, 0.2, 0.3]])
    T = _pose([[0.3, -0.2, 0.1]], Rotation.from_euler("xyz", [0.3, -0.5, 1.0]).as_matrix())
    pts, nrm = box_surface(size, T, 0.01)
    m = np.array([11, 21, 31])
    assert pts.shape == nrm.shape == (1, 2 * (m[1] * m[2] + m[0] * m[2] + m[0] * m[1]), 3)
    local = (pts[0] - T[0, :3, 3]) @ T[0, :3, :3]
    local_n = nrm[0] @ T[0, :3, :3]
    np.testing.assert_allclose(np.linalg.norm(local_n, axis=1), 1.0)
    half = size[0] / 2
    np.testing.assert_allclose(np.max(np.abs(local) / half, axis=1), 1.0)
    np.testing.assert_allclose(np.sum(local * local_n, axis=1), np.abs(local_n) @ half)
    np.testing.assert_allclose(np.median(local, axis=0), 0.0, atol=1e-15)
    again = box_surface(size, T, 0.01)
    np.testing.assert_array_equal(pts, again[0])


def test_box_surface_pads_smaller_boxes_with_their_own_points():
    size = np.array([[0.1, 0.1, 0.1], [0.2, 0.15, 0.1]])
    T = _pose([[0.0, 0.0, 0.0], [1.0, 2.0, 3.0]])
    pts, nrm = box_surface(size, T, 0.01)
    alone, alone_n = box_surface(size[:1], T[:1], 0.01)
    assert pts.shape[1] > alone.shape[1] == 6 * 11 * 11

    def pairs(p, n):
        return {tuple(r) for r in np.round(np.concatenate([p, n], axis=1), 12)}

    assert pairs(pts[0], nrm[0]) == pairs(alone[0], alone_n[0])
    np.testing.assert_allclose(np.median(pts[0], axis=0), 0.0, atol=1e-15)
    np.testing.assert_allclose(np.median(pts[1], axis=0), [1.0, 2.0, 3.0], atol=1e-12)


def test_planar_lifts_round_trip():
    rng = np.random.default_rng(9)
    pose = np.column_stack([rng.normal(size=(10, 2)), rng.uniform(-np.pi, np.pi, 10)])
    h = rng.uniform(0.05, 0.3, 10)
    T = tabletop_transform(pose, h)
    np.testing.assert_allclose(T[:, 2, 3], h / 2)
    np.testing.assert_allclose(planar_pose_from_tabletop(T), pose, atol=1e-12)
    S = sideview_transform(pose)
    np.testing.assert_allclose(planar_pose_from_sideview(S), pose, atol=1e-12)
    quarter = sideview_transform([[0.0, 0.0, np.pi / 2]])[0, :3, :3]
    # counter-clockwise in the (x, z) view: x turns to +z, z turns to -x
    np.testing.assert_allclose(quarter @ [1, 0, 0], [0, 0, 1], atol=1e-15)
    np.testing.assert_allclose(quarter @ [0, 0, 1], [-1, 0, 0], atol=1e-15)
    with pytest.raises(InputError, match="world up"):
        planar_pose_from_tabletop(sideview_transform([[0.0, 0.0, 0.3]]))
    with pytest.raises(InputError, match="viewing axis"):
        planar_pose_from_sideview(T[:1])


def _bad_inputs():
    good = list(_hand_push([[-0.2, 0.0, 0.05]], [[0.15, 0.0, 0.05]]))
    cases = []

    def case(i, value, match):
        args = list(good)
        args[i] = value
        cases.append((args, match))

    nan = good[0].copy()
    nan[0, 3, 1] = np.nan
    case(0, nan, "target_points")
    case(0, good[0][:0], "target_points")
    case(0, good[0][:, :0], "target_points")
    case(1, good[1][..., :2], "target_normals")
    case(1, 2 * good[1], "target_normals")
    case(2, good[2][..., :2], "actor_points")
    case(2, np.concatenate([good[2], good[2]]), "actor_points")
    case(3, np.full_like(good[3], np.inf), "actor_normals")
    skew = good[4].copy()
    skew[0, 0, 1] = 0.5
    case(4, skew, "T_world_actor_start")
    case(5, good[5][:, :3], "T_world_actor_end")
    case(5, good[4], "zero-length")
    case(0, "points", "target_points")
    return cases


@pytest.mark.parametrize(("args", "match"), _bad_inputs())
def test_bad_inputs_raise_input_error_naming_the_argument(args, match):
    with pytest.raises(InputError, match=match):
        interaction_features(*args)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"contact_distance": 0.0}, "contact_distance"),
        ({"contact_distance": -0.01}, "contact_distance"),
        ({"contact_distance": float("nan")}, "contact_distance"),
        ({"normal_threshold": -1.0}, "normal_threshold"),
        ({"normal_threshold": 1.5}, "normal_threshold"),
        ({"normal_threshold": "low"}, "normal_threshold"),
        ({"min_contact_points": 1.5}, "min_contact_points"),
        ({"min_contact_points": -1}, "min_contact_points"),
        ({"min_contact_points": True}, "min_contact_points"),
    ],
)
def test_bad_config_raises_input_error_naming_the_field(kwargs, match):
    with pytest.raises(InputError, match=match):
        InteractionFeatureConfig(**kwargs)


def test_config_of_another_type_and_bad_geometry_arguments():
    args = _hand_push([[-0.2, 0.0, 0.05]], [[0.15, 0.0, 0.05]])
    with pytest.raises(InputError, match="config"):
        interaction_features(*args, config={"contact_distance": 0.01})
    with pytest.raises(InputError, match="size"):
        box_surface([[0.1, -0.1, 0.1]], _pose([0, 0, 0]))
    with pytest.raises(InputError, match="spacing"):
        box_surface([[0.1, 0.1, 0.1]], _pose([0, 0, 0]), spacing=0.0)
    with pytest.raises(InputError, match="height"):
        tabletop_transform([[0.0, 0.0, 0.0]], [0.0])
    with pytest.raises(InputError, match="effect"):
        apply_effect(_pose([0, 0, 0]), _pose([0, 0, 0]), [[0, 0, 0, np.nan, 0, 0]])
    with pytest.raises(ProbaffError, match="T_world_obj_after"):
        effect_in_action_frame(_pose([0, 0, 0]), _pose([0, 0, 0]), _pose([[0, 0, 0], [1, 1, 1]]))


def _box_scene(rng, n):
    """Boxes pushed by boxes: rows at one height, rotated and tilted actors, misses.

    Samples cycle through four kinds: 0, boxes of one size in line (their tops, bottoms and
    sides are coplanar); 1, boxes of one height a little off line; 2, boxes turned about
    world up; 3, a turned and tilted actor. Every fifth action stops short of the target and
    every seventh passes beside it.
    """
    kind = np.arange(n) % 4
    t_size = rng.uniform(0.06, 0.12, (n, 3))
    a_size = rng.uniform(0.06, 0.12, (n, 3))
    a_size[kind == 0] = t_size[kind == 0]
    a_size[kind == 1, 2] = t_size[kind == 1, 2]
    t_yaw = np.where(kind >= 2, rng.uniform(-np.pi, np.pi, n), 0.0)
    a_yaw = np.where(kind >= 2, rng.uniform(-np.pi, np.pi, n), 0.0)
    T_t = tabletop_transform(np.column_stack([np.zeros((n, 2)), t_yaw]), t_size[:, 2])
    gap = rng.uniform(0.0, 0.05, n)
    side = np.where(kind == 1, rng.uniform(-0.01, 0.01, n), 0.0)
    side[kind >= 2] = rng.uniform(-0.05, 0.05, int((kind >= 2).sum()))
    side[np.arange(n) % 7 == 0] = 0.3
    back = (t_size[:, 1] + a_size[:, 1]) / 2 + gap
    back[kind >= 2] += 0.05  # room for the turned corners
    T_s = tabletop_transform(np.column_stack([side, -back, a_yaw]), a_size[:, 2])
    tilt = Rotation.from_rotvec(rng.normal(0.0, 0.3, (n, 3))).as_matrix()
    T_s[kind == 3, :3, :3] = tilt[kind == 3] @ T_s[kind == 3, :3, :3]
    T_s[kind == 3, 2, 3] += 0.03
    length = rng.uniform(0.02, 0.15, n) + np.where(kind >= 2, 0.05, 0.0)
    length[np.arange(n) % 5 == 0] = 0.5 * gap[np.arange(n) % 5 == 0] + 1e-3
    turn = rng.normal(0.0, 0.03, n)  # the push's direction, a little off world y
    step = np.column_stack([np.sin(turn), np.cos(turn), rng.normal(0.0, 0.01, n)])
    T_e = _moved(T_s[:, :3, 3] + length[:, None] * step, T_s)
    t_pts, t_nrm = box_surface(t_size, T_t, 0.02)
    a_pts, a_nrm = box_surface(a_size, T_s, 0.02)
    return t_pts, t_nrm, a_pts, a_nrm, T_s, T_e


def _cells(rel, counts, size):
    """(n, cells) number of points per cell of grids centred at 0, from (n, K, 3) coordinates.

    A point with an infinite coordinate lies in no cell.
    """
    scaled = (rel + 0.5 * size * np.asarray(counts) + 1e-9) / size
    idx = np.floor(np.where(np.isfinite(scaled), scaled, -1.0)).astype(int)
    inside = np.all((idx >= 0) & (idx < np.asarray(counts)), axis=-1)
    flat = (idx[..., 0] * counts[1] + idx[..., 1]) * counts[2] + idx[..., 2]
    out = np.zeros((rel.shape[0], int(np.prod(counts))), dtype=int)
    for i in range(rel.shape[0]):
        np.add.at(out[i], flat[i][inside[i]], 1)
    return out


def _brute_force(t_pts, t_nrm, a_pts, a_nrm, T_s, T_e, cfg):
    """The chapter 6 features from every (target, actor) point pair, as the definition says.

    Returns:
        ``(values (n, 169), touch (n,), T_a, T_b, T_c (n, 4, 4))``.
    """
    r = cfg.contact_distance
    T_a = action_frame(T_s, T_e)
    R, o = T_a[:, :3, :3], T_a[:, :3, 3]
    obj = (t_pts - o[:, None]) @ R  # (n, p, 3) in A_t
    act = (a_pts - o[:, None]) @ R  # (n, q, 3)
    length = np.linalg.norm(T_e[:, :3, 3] - T_s[:, :3, 3], axis=1)
    w = obj[:, :, None] - act[:, None]  # (n, p, q, 3) target minus actor
    across2 = w[..., 0] ** 2 + w[..., 2] ** 2
    h = np.sqrt(np.clip(r * r - across2, 0.0, None))
    meets = (across2 < r * r) & (w[..., 1] + h >= 0) & (w[..., 1] - h <= length[:, None, None])
    s = np.where(meets, np.maximum(w[..., 1] - h, 0.0), np.inf).min(axis=(1, 2))
    probe = np.minimum(s + r / 2, length)[:, None, None]
    facing = np.einsum("npi,nqi->npq", t_nrm, a_nrm) < cfg.normal_threshold
    in_contact = ((across2 + (w[..., 1] - probe) ** 2 < r * r) & facing).any(axis=2)  # (n, p)
    centre = np.median(obj, axis=1)  # (n, 3) B_t's origin in A_t
    count = in_contact.sum(axis=1)
    mean = (in_contact[..., None] * obj).sum(axis=1) / np.maximum(count, 1)[:, None]
    c = np.where(count[:, None] > 0, mean, centre)
    shape = _cells(obj - centre[:, None], (5, 5, 5), 0.05) + _cells(
        act - centre[:, None], (5, 5, 5), 0.05
    )
    rel = np.where(in_contact[..., None], obj - c[:, None], np.inf)  # others fall outside
    contact = _cells(rel, (4, 2, 4), 0.05) > cfg.min_contact_points
    T_b, T_c = T_a.copy(), T_a.copy()
    T_b[:, :3, 3] = o + (R @ centre[..., None])[..., 0]
    T_c[:, :3, 3] = o + (R @ c[..., None])[..., 0]
    Rt = R.transpose(0, 2, 1)
    R_s, R_e = T_s[:, :3, :3], T_e[:, :3, :3]
    pose = np.column_stack(
        [
            (Rt @ (T_s[:, :3, 3] - T_b[:, :3, 3])[..., None])[..., 0],
            Rotation.from_matrix(Rt @ R_s).as_rotvec(),
        ]
    )
    turn = Rotation.from_matrix(R_s.transpose(0, 2, 1) @ R_e).as_rotvec()
    action = np.column_stack(
        [
            (Rt @ (T_e[:, :3, 3] - T_s[:, :3, 3])[..., None])[..., 0],
            (Rt @ R_s @ turn[..., None])[..., 0],
        ]
    )
    values = np.column_stack([shape > 0, pose, contact, action]).astype(float)
    return values, s, T_a, T_b, T_c


@pytest.mark.parametrize(
    "cfg",
    [
        InteractionFeatureConfig(),
        InteractionFeatureConfig(contact_distance=0.015, normal_threshold=-0.2),
        InteractionFeatureConfig(contact_distance=0.025, min_contact_points=0),
    ],
)
def test_box_pushes_match_the_brute_force_definition(cfg):
    rng = np.random.default_rng(12)
    scene = _box_scene(rng, 28)
    out = interaction_features(*scene, cfg, chunk=10)
    values, touch, T_a, T_b, T_c = _brute_force(*scene, cfg)
    assert 10 < out.touches.sum() < 28
    assert out.touches[::4].sum() >= 3  # boxes in line, with coplanar faces, touch
    assert out.features.select("contact")[out.touches].any(axis=1).mean() > 0.5
    for g in BINARY:
        cols = INTERACTION_GROUPS[g]
        np.testing.assert_array_equal(out.features.select(g), values[:, cols])
    for g in CONTINUOUS:
        cols = INTERACTION_GROUPS[g]
        np.testing.assert_allclose(out.features.select(g), values[:, cols], rtol=0, atol=1e-12)
    np.testing.assert_array_equal(out.touches, np.isfinite(touch))
    np.testing.assert_allclose(out.touch_distance[out.touches], touch[out.touches], atol=1e-12)
    for got, want in [(out.T_world_action, T_a), (out.T_world_object, T_b)]:
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-12)
    np.testing.assert_allclose(out.T_world_contact, T_c, rtol=0, atol=1e-12)
    # the action frame's y is the commanded displacement
    step = scene[5][:, :3, 3] - scene[4][:, :3, 3]
    np.testing.assert_allclose(
        out.T_world_action[:, :3, 1], step / out.action_length[:, None], atol=1e-12
    )


def test_touch_searches_by_dense_and_sparse_tables_agree(monkeypatch):
    rng = np.random.default_rng(13)
    scenes = [_box_scene(rng, 24), _tabletop_scene(rng, 24)]
    dense = [interaction_features(*s, chunk=8) for s in scenes]
    monkeypatch.setattr(pairs_module, "_DENSE_CELLS", 0)
    monkeypatch.setattr(pairs_module, "_DENSE_CELLS_PER_POINT", 0)
    for s, d in zip(scenes, dense, strict=True):
        sparse = interaction_features(*s, chunk=8)
        np.testing.assert_array_equal(sparse.features.values, d.features.values)
        np.testing.assert_array_equal(sparse.touch_distance, d.touch_distance)
        np.testing.assert_array_equal(sparse.T_world_contact, d.T_world_contact)
        assert d.touches.any() and not d.touches.all()


def test_samples_broadcast_from_one_cloud_match_copies_and_are_validated():
    t_pts, t_nrm, a_pts, a_nrm, T_s, _ = _hand_push([[-0.2, 0.0, 0.05]], [[0.15, 0.0, 0.05]])
    n = 6
    T_s = np.repeat(T_s, n, axis=0)
    end = np.column_stack(
        [np.linspace(-0.15, 0.2, n), np.linspace(-0.02, 0.02, n), np.full(n, 0.05)]
    )
    T_e = _moved(end, T_s)

    def spread(x):
        return np.broadcast_to(x, (n, *x.shape[1:]))

    view = interaction_features(
        spread(t_pts), spread(t_nrm), spread(a_pts), spread(a_nrm), T_s, T_e
    )
    copy = interaction_features(
        *(np.repeat(x, n, axis=0) for x in (t_pts, t_nrm, a_pts, a_nrm)), T_s, T_e
    )
    assert 0 < view.touches.sum() < n
    np.testing.assert_array_equal(view.features.values, copy.features.values)
    np.testing.assert_array_equal(view.touch_distance, copy.touch_distance)
    np.testing.assert_array_equal(view.T_world_contact, copy.T_world_contact)
    nan = t_pts.copy()
    nan[0, 3, 1] = np.nan
    with pytest.raises(InputError, match="target_points"):
        interaction_features(spread(nan), spread(t_nrm), spread(a_pts), spread(a_nrm), T_s, T_e)
    with pytest.raises(InputError, match="actor_normals"):
        interaction_features(
            spread(t_pts), spread(t_nrm), spread(a_pts), spread(2 * a_nrm), T_s, T_e
        )
