"""Chapter 6 geometry: action frames, effects in them, and point sets of cuboids.

All frames are 4 x 4 homogeneous float64 transforms ``T_world_X`` (a point in X's
coordinates maps to the world as ``T_world_X @ [p, 1]``), batched as (N, 4, 4). World z is up.

Action frame A_t (`action_frame`): origin at the actor's commanded start position; y along the
commanded displacement ``p_end - p_start`` ("along the action"); z orthogonal to y; x = y x z
("off-action"). The choice of z:

* an action at most 45 degrees from horizontal (``|y . up| <= cos 45deg``) takes z = world up
  projected orthogonal to y. Every tabletop push (horizontal) therefore has z = world up, for
  every push direction;
* a steeper action (pick, lift and place are vertical) takes z = world x projected orthogonal
  to y, which is well defined there (``|y . x| < cos 45deg``). A vertical action down has
  z = world x, x = -world y; one up has z = world x, x = +world y.

In the side-view (x, z) plane both rules give the in-plane normal of y, so x is always the
viewing axis (+/- world y). The frame varies continuously with the direction for all horizontal
actions and for in-plane actions near vertical or near horizontal; the two rules agree in the
quadrants (down, +x) and (up, -x) of the side-view plane and disagree, so the frame jumps, only
where an action 45 degrees from vertical points to (down, -x) or (up, +x). A continuous rule
for every direction cannot exist (a tangent field on the sphere must vanish somewhere).
Because of world up, A_t moves with the scene under translations and, for actions within 45
degrees of horizontal, rotations about world up; steeper actions follow translations only.

Effect e_t (`effect_in_action_frame`): the object's rigid displacement in A_t's axes,
``(dx, dy, dz, rx, ry, rz)``: the translation of the object's origin, and the rotation vector
of ``R_A^T R_after R_before^T R_A`` (the turn of the object, expressed in A_t). `apply_effect`
is its exact inverse.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from probaff._checks import (
    as_float_array,
    check_box_sizes,
    check_finite,
    check_positive,
    check_rows,
    check_shape,
)
from probaff.errors import InputError

__all__ = [
    "action_frame",
    "apply_effect",
    "box_surface",
    "effect_in_action_frame",
    "planar_pose_from_sideview",
    "planar_pose_from_tabletop",
    "sideview_transform",
    "tabletop_transform",
]

_MIN_ACTION = 1e-9  # m; shorter commanded displacements have no direction
_STEEP_COS = math.cos(math.pi / 4)  # |y . up| above this uses world x for z
_RIGID_TOL = 1e-6  # tolerance of the orthonormality and bottom-row checks
_PLANAR_TOL = 1e-6  # tolerance of the "rotation about one axis" checks
_MAX_BOX_POINTS = 50_000_000  # points box_surface may return in all


def _check_transforms(name: str, T: Any, n: int | None = None) -> np.ndarray:
    """Validate (N, 4, 4) rigid transforms and return them as float64.

    Args:
        name: The argument's name.
        T: (N, 4, 4) homogeneous transforms.
        n: Required N, or ``None`` for any N >= 1.

    Returns:
        `T` as a float64 array.

    Raises:
        InputError: For a wrong shape, no samples, NaN/inf, a bottom row other than
            ``(0, 0, 0, 1)`` or a rotation block that is not a proper rotation.
    """
    arr = as_float_array(name, T)
    check_shape(name, arr, (n, 4, 4))
    if arr.shape[0] == 0:
        raise InputError(f"{name} holds no transforms; pass at least one (1, 4, 4) transform.")
    check_finite(name, arr)
    bottom = np.abs(arr[:, 3] - np.array([0.0, 0.0, 0.0, 1.0])).max(axis=1)
    R = arr[:, :3, :3]
    ortho = np.abs(R.transpose(0, 2, 1) @ R - np.eye(3)).max(axis=(1, 2))
    det = np.linalg.det(R)
    bad = np.flatnonzero((bottom > _RIGID_TOL) | (ortho > _RIGID_TOL) | (det <= 0))
    if bad.size:
        raise InputError(
            f"{name} is not a rigid transform at sample(s) {bad[:5].tolist()}: the last row "
            "must be (0, 0, 0, 1) and the 3 x 3 block a rotation (orthonormal, det +1)."
        )
    return arr


def _check_same_n(name: str, arr: np.ndarray, n: int) -> None:
    if arr.shape[0] != n:
        raise InputError(f"{name} has {arr.shape[0]} samples, expected {n} (one per sample).")


def action_frame(T_world_actor_start: Any, T_world_actor_end: Any) -> np.ndarray:
    """The action frame A_t of each commanded actor motion.

    Args:
        T_world_actor_start: (N, 4, 4) the actor's commanded start pose in the world.
        T_world_actor_end: (N, 4, 4) its commanded end pose.

    Returns:
        (N, 4, 4) ``T_world_action``: origin at the start position, y along
        ``p_end - p_start``, z by the rule in the module docstring, x = y x z.

    Raises:
        InputError: For malformed transforms, or an action shorter than 1 nm (it has no
            direction), naming the samples.
    """
    T_s = _check_transforms("T_world_actor_start", T_world_actor_start)
    T_e = _check_transforms("T_world_actor_end", T_world_actor_end)
    _check_same_n("T_world_actor_end", T_e, T_s.shape[0])
    d = T_e[:, :3, 3] - T_s[:, :3, 3]
    length = np.linalg.norm(d, axis=1)
    short = np.flatnonzero(length < _MIN_ACTION)
    if short.size:
        raise InputError(
            f"T_world_actor_end equals T_world_actor_start in position at sample(s) "
            f"{short[:5].tolist()}: a zero-length action has no direction; give each action "
            "a displacement of at least 1 nm."
        )
    y = d / length[:, None]
    steep = np.abs(y[:, 2]) > _STEEP_COS
    ref = np.where(steep[:, None], np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.0, 1.0]))
    z = ref - np.sum(ref * y, axis=1, keepdims=True) * y
    z /= np.linalg.norm(z, axis=1, keepdims=True)
    x = np.cross(y, z)
    T = np.zeros_like(T_s)
    T[:, :3, 0], T[:, :3, 1], T[:, :3, 2] = x, y, z
    T[:, :3, 3] = T_s[:, :3, 3]
    T[:, 3, 3] = 1.0
    return T


def effect_in_action_frame(
    T_world_action: Any, T_world_obj_before: Any, T_world_obj_after: Any
) -> np.ndarray:
    """The object's rigid displacement expressed in the action frame.

    Args:
        T_world_action: (N, 4, 4) action frames A_t.
        T_world_obj_before: (N, 4, 4) the object's pose before the action.
        T_world_obj_after: (N, 4, 4) its pose after.

    Returns:
        (N, 6) ``(dx, dy, dz, rx, ry, rz)``: ``R_A^T (p_after - p_before)`` and the rotation
        vector (rad, norm in [0, pi]) of ``R_A^T R_after R_before^T R_A``.

    Raises:
        InputError: For malformed transforms or mismatched N.
    """
    T_a = _check_transforms("T_world_action", T_world_action)
    n = T_a.shape[0]
    T_b = _check_transforms("T_world_obj_before", T_world_obj_before, n)
    T_f = _check_transforms("T_world_obj_after", T_world_obj_after, n)
    R_a = T_a[:, :3, :3]
    R_aT = R_a.transpose(0, 2, 1)
    shift = (R_aT @ (T_f[:, :3, 3] - T_b[:, :3, 3])[..., None])[..., 0]
    turn = R_aT @ T_f[:, :3, :3] @ T_b[:, :3, :3].transpose(0, 2, 1) @ R_a
    rotvec = Rotation.from_matrix(turn).as_rotvec()
    return np.concatenate([shift, rotvec], axis=1)


def apply_effect(T_world_action: Any, T_world_obj_before: Any, effect: Any) -> np.ndarray:
    """The object's pose after an effect: the inverse of `effect_in_action_frame`.

    Args:
        T_world_action: (N, 4, 4) action frames A_t.
        T_world_obj_before: (N, 4, 4) the object's pose before the action.
        effect: (N, 6) ``(dx, dy, dz, rx, ry, rz)`` in A_t's axes (m, rad).

    Returns:
        (N, 4, 4) ``T_world_obj_after``: position ``p_before + R_A d`` and rotation
        ``R_A exp(r) R_A^T R_before``.

    Raises:
        InputError: For malformed transforms, a malformed or non-finite effect, or mismatched N.
    """
    T_a = _check_transforms("T_world_action", T_world_action)
    n = T_a.shape[0]
    T_b = _check_transforms("T_world_obj_before", T_world_obj_before, n)
    e = as_float_array("effect", effect)
    check_shape("effect", e, (n, 6))
    check_finite("effect", e)
    R_a = T_a[:, :3, :3]
    turn = Rotation.from_rotvec(e[:, 3:]).as_matrix()
    out = np.zeros_like(T_b)
    out[:, :3, :3] = R_a @ turn @ R_a.transpose(0, 2, 1) @ T_b[:, :3, :3]
    out[:, :3, 3] = T_b[:, :3, 3] + (R_a @ e[:, :3, None])[..., 0]
    out[:, 3, 3] = 1.0
    return out


def _face_coordinate(index: np.ndarray, count: np.ndarray, size: np.ndarray) -> np.ndarray:
    """Coordinate of grid line `index` of `count` lines spanning ``[-size/2, size/2]``."""
    return size * (index / (count - 1) - 0.5)


def box_surface(
    size: Any, T_world_box: Any, spacing: float = 0.01
) -> tuple[np.ndarray, np.ndarray]:
    """Deterministic points and outward unit normals on the six faces of cuboids.

    Each face of a box of size ``(sx, sy, sz)`` carries a full grid of points, edges included,
    with ``m = ceil(s / spacing) + 1`` (at least 2; the ceiling ignores an excess below 1e-9
    spacings, so that 0.1 / 0.01 gives 11 lines) evenly spaced lines along each of its sides, so
    neighbouring points are at most `spacing` apart. Points on an edge or a corner appear
    once per face that holds them, each time with that face's normal. The points are listed
    as the +x, +y and +z faces (``H = my mz + mx mz + mx my`` points) followed by their exact
    mirror images through the box centre (the -x, -y and -z faces), so a box has ``P = 2 H``
    points, a number fixed by its size alone.

    Boxes of different sizes in one call are padded to the largest P by repeating their own
    points cyclically, in mirror pairs: the padded set stays symmetric about the box centre, so
    its component-wise median along any axes is still the centre, but the repeated points count
    more in any point density.

    Args:
        size: (N, 3) box extents along the box's own x, y, z (m), each > 0.
        T_world_box: (N, 4, 4) pose of each box's centre.
        spacing: Largest distance between neighbouring points along a face (m), > 0.

    Returns:
        ``(points, normals)``, each (N, P, 3) in the world; normals are unit length.

    Raises:
        InputError: For malformed sizes or transforms, a spacing that is not positive, or a
            spacing so fine that the points would exceed 50 million in all.
    """
    s = check_box_sizes("size", size, "size holds no boxes; pass at least one (1, 3) size.")
    T = _check_transforms("T_world_box", T_world_box, s.shape[0])
    check_positive("spacing", spacing)
    m = np.maximum(np.ceil(s / float(spacing) - 1e-9), 1.0).astype(np.int64) + 1  # (N, 3)
    mx, my, mz = m[:, 0:1], m[:, 1:2], m[:, 2:3]
    f1 = my * mz
    f2 = f1 + mx * mz
    half = f2 + mx * my  # (N, 1) points on the three positive faces
    h_max = int(half.max())
    if 2 * h_max * s.shape[0] > _MAX_BOX_POINTS:
        raise InputError(
            f"box_surface would return {2 * h_max * s.shape[0]} points; use a coarser spacing "
            f"than {spacing} or fewer boxes."
        )
    q = np.arange(h_max)[None, :] % half  # (N, H) slot -> point of the positive faces
    sx, sy, sz = s[:, 0:1], s[:, 1:2], s[:, 2:3]
    r1, r2 = q - f1, q - f2  # indices within the +y and +z faces (negative: not on them)
    on_x, on_y = q < f1, (q >= f1) & (q < f2)
    hx, hy, hz = (np.broadcast_to(0.5 * e, q.shape) for e in (sx, sy, sz))
    g = _face_coordinate
    faces = [on_x, on_y]
    px = np.select(faces, [hx, g(r1 // mz, mx, sx)], g(r2 // my, mx, sx))
    py = np.select(faces, [g(q // mz, my, sy), hy], g(r2 % my, my, sy))
    pz = np.select(faces, [g(q % mz, mz, sz), g(r1 % mz, mz, sz)], hz)
    local = np.stack([px, py, pz], axis=-1)
    face = np.where(on_x, 0, np.where(on_y, 1, 2))
    normal = np.eye(3)[face]
    local = np.concatenate([local, -local], axis=1)
    normal = np.concatenate([normal, -normal], axis=1)
    R = T[:, :3, :3]
    points = local @ R.transpose(0, 2, 1) + T[:, None, :3, 3]
    normals = normal @ R.transpose(0, 2, 1)
    return points, normals


def _planar(name: str, pose: Any) -> np.ndarray:
    return check_rows(name, pose, 3, f"{name} holds no poses; pass at least one (1, 3) pose.")


def tabletop_transform(pose: Any, height: Any) -> np.ndarray:
    """Lift tabletop poses ``(x, y, theta)`` of boxes resting on the table (z = 0) to 3-D.

    Args:
        pose: (N, 3) planar poses: position on the table (m) and yaw theta about world up (rad,
            counter-clockwise seen from above).
        height: (N,) box heights (m), > 0; the centre is at ``z = height / 2``.

    Returns:
        (N, 4, 4) ``T_world_box``.

    Raises:
        InputError: For malformed poses or heights.
    """
    p = _planar("pose", pose)
    h = as_float_array("height", height)
    check_shape("height", h, (p.shape[0],))
    check_finite("height", h)
    if np.any(h <= 0):
        raise InputError("height must be > 0 for every box; got a zero or negative height.")
    c, s = np.cos(p[:, 2]), np.sin(p[:, 2])
    T = np.zeros((p.shape[0], 4, 4))
    T[:, 0, 0], T[:, 0, 1], T[:, 1, 0], T[:, 1, 1] = c, -s, s, c
    T[:, 2, 2] = T[:, 3, 3] = 1.0
    T[:, 0, 3], T[:, 1, 3], T[:, 2, 3] = p[:, 0], p[:, 1], 0.5 * h
    return T


def sideview_transform(pose: Any) -> np.ndarray:
    """Lift side-view poses ``(x, z, phi)`` in the world's vertical x-z plane to 3-D.

    The view looks along +y (from -y), with x to the right and z up. ``phi`` is a turn about
    the viewing axis -y, so a positive phi is counter-clockwise in the view: the box's x axis
    goes to ``(cos phi, 0, sin phi)`` and its z axis to ``(-sin phi, 0, cos phi)``.

    Args:
        pose: (N, 3) planar poses: centre ``x, z`` (m, world y = 0) and phi (rad).

    Returns:
        (N, 4, 4) ``T_world_box``.

    Raises:
        InputError: For malformed poses.
    """
    p = _planar("pose", pose)
    c, s = np.cos(p[:, 2]), np.sin(p[:, 2])
    T = np.zeros((p.shape[0], 4, 4))
    T[:, 0, 0], T[:, 0, 2], T[:, 2, 0], T[:, 2, 2] = c, -s, s, c
    T[:, 1, 1] = T[:, 3, 3] = 1.0
    T[:, 0, 3], T[:, 2, 3] = p[:, 0], p[:, 1]
    return T


def planar_pose_from_tabletop(T: Any) -> np.ndarray:
    """Planar ``(x, y, theta)`` of tabletop transforms, the inverse of `tabletop_transform`.

    Args:
        T: (N, 4, 4) transforms whose rotation is a turn about world up.

    Returns:
        (N, 3) ``(x, y, theta)`` with theta in (-pi, pi].

    Raises:
        InputError: For malformed transforms or a rotation that tilts world up.
    """
    arr = _check_transforms("T", T)
    tilted = np.flatnonzero(np.abs(arr[:, 2, 2] - 1.0) > _PLANAR_TOL)
    if tilted.size:
        raise InputError(
            f"T is not a turn about world up at sample(s) {tilted[:5].tolist()}; a tabletop "
            "pose needs R[2, 2] = 1."
        )
    theta = np.arctan2(arr[:, 1, 0], arr[:, 0, 0])
    return np.stack([arr[:, 0, 3], arr[:, 1, 3], theta], axis=1)


def planar_pose_from_sideview(T: Any) -> np.ndarray:
    """Planar ``(x, z, phi)`` of side-view transforms, the inverse of `sideview_transform`.

    Args:
        T: (N, 4, 4) transforms whose rotation is a turn about world y.

    Returns:
        (N, 3) ``(x, z, phi)`` with phi in (-pi, pi]; the world y of the origin is dropped.

    Raises:
        InputError: For malformed transforms or a rotation that is not about world y.
    """
    arr = _check_transforms("T", T)
    tilted = np.flatnonzero(np.abs(arr[:, 1, 1] - 1.0) > _PLANAR_TOL)
    if tilted.size:
        raise InputError(
            f"T is not a turn about the viewing axis (world y) at sample(s) "
            f"{tilted[:5].tolist()}; a side-view pose needs R[1, 1] = 1."
        )
    phi = np.arctan2(arr[:, 2, 0], arr[:, 0, 0])
    return np.stack([arr[:, 0, 3], arr[:, 2, 3], phi], axis=1)
