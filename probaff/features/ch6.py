"""Chapter 6 interaction features (n = 169): shape, relative pose, contact and action.

An interaction is an actor (the hand, or in a chain another object) moving from a commanded
start pose to a commanded end pose towards a target object. Both are given as point sets with
unit normals, so the features serve every world (tabletop pushes, side-view pick and place)
and object-object interactions alike. Frames (see `probaff.features.action_frame`):

* A_t, the action frame: origin at the actor's start position, y along the action, x
  off-action, z up where the action allows;
* B_t, the object frame: origin at the object's centre, the component-wise median of its
  points along A_t's axes (the thesis's "median of the object cloud", taken in A_t so that it
  moves with the scene), orientation that of A_t;
* C_t, the contact frame: origin at the mean of the contact points, orientation that of A_t;
  where the actor makes no contact, C_t is B_t.

Columns (all lengths in m, angles in rad):
    shape (125): a 25 cm cube centred at B_t, cut into 5 x 5 x 5 voxels of 5 cm
        (``[-0.125, 0.125)`` along each axis); a voxel is 1 when it holds any point of the
        object or of the actor (at its start pose), else 0. Column ``(i * 5 + j) * 5 + k`` is
        voxel ``(i, j, k)`` along B_t's (x, y, z).
    pose (6): the actor's start pose in B_t: the position of its origin (3) and the rotation
        vector of ``R_B^T R_actor`` (3).
    contact (32): a 20 x 10 x 20 cm grid of 5 cm cells centred at C_t (``[-0.10, 0.10)`` along
        x, ``[-0.05, 0.05)`` along y, ``[-0.10, 0.10)`` along z: 4 x 2 x 4 cells); a cell is 1
        when more than ``min_contact_points`` contact points fall in it (the thesis's n_c,
        here applied to each cell rather than to a sample's contact points in all). Column
        ``(i * 2 + j) * 4 + k`` is cell ``(i, j, k)``.
    action (6): the commanded motion A_t of the actor, in B_t's axes: its displacement
        ``p_end - p_start`` (3; as B_t takes A_t's orientation this is ``(0, |action|, 0)``,
        so the middle column is the action's length) and the rotation vector of
        ``R_start^T R_end`` expressed in B_t (3; zero for a straight push, the turn of the
        actor object in a chain). The pose of A_t's origin in B_t is the actor's position,
        already in ``pose``. The length is also returned as `InteractionFeatures.action_length`.

First touch and contact. The actor usually starts away from the target, so contact is judged
where it first touches: its points are moved along A_t's y by the smallest distance
``s`` in ``[0, |action|]`` at which some actor point comes within ``contact_distance`` (r_d)
of a target point, found exactly from every (actor, target) pair whose offset across the
action is below r_d (``s = max(0, w_y - sqrt(r_d^2 - w_x^2 - w_z^2))`` for the offset w in A_t,
target minus actor, among pairs that meet before the action ends; the search skips only
pairs that provably change neither the touch nor the contact). That
``s`` is the touch distance (``inf`` when the actor never touches). To see more than the one
pair exactly r_d apart, contact is then evaluated with the actor moved on by ``r_d / 2``
(capped at the action's length): a contact pair is an (object point, actor point) pair closer
than r_d whose normals face each other, ``n_o . n_e < normal_threshold`` (r_n), and the
contact points are the object points of those pairs, each counted once, so C_t lies on the
object's surface. The thesis gives no values for r_d, r_n and n_c; the defaults are
r_d = 1 cm, r_n = -0.5 (normals more than 120 degrees apart) and n_c = 2.

Cell boundaries: a coordinate within 1 nm below a voxel or cell boundary counts as on the
boundary (cells are closed below, open above), so that the rounding of rigid transforms
cannot move a point that lies on a boundary, as the points of a box face often do.

Invariance: the features depend only on the scene relative to A_t, so they do not change when
the target, the actor and the action are translated together, nor, for actions within 45
degrees of horizontal, turned together about world up.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

from probaff._checks import as_float_array, check_count, check_finite, check_positive, check_shape
from probaff.errors import InputError
from probaff.features.action_frame import _check_transforms, action_frame
from probaff.features.contact_pairs import BOUNDARY_TOL, candidate_pairs
from probaff.features.featureset import FeatureSet

__all__ = [
    "INTERACTION_FEATURE_COUNT",
    "INTERACTION_GROUPS",
    "InteractionFeatureConfig",
    "InteractionFeatures",
    "interaction_features",
]

_SHAPE_CELLS = (5, 5, 5)
_SHAPE_SIZE = 0.05  # m, voxel edge; 5 voxels span the 25 cm cube
_CONTACT_CELLS = (4, 2, 4)
_CONTACT_SIZE = 0.05  # m, cell edge; the grid spans 20 x 10 x 20 cm
_NORMAL_TOL = 1e-4  # allowed deviation of a normal's length from 1

INTERACTION_GROUPS: dict[str, slice] = {
    "shape": slice(0, 125),
    "pose": slice(125, 131),
    "contact": slice(131, 163),
    "action": slice(163, 169),
}
"""Column slices of the four feature groups, in order; they tile ``range(169)``."""

INTERACTION_FEATURE_COUNT = 169
"""Number of chapter 6 interaction features: 125 + 6 + 32 + 6."""


@dataclass(frozen=True)
class InteractionFeatureConfig:
    """Thresholds of the contact test.

    Attributes:
        contact_distance: r_d (m), > 0: an object point and an actor point closer than this
            are near enough to be in contact; also the distance that defines the first touch.
        normal_threshold: r_n, in (-1, 1]: a pair is in contact only when the dot product of
            its unit normals is below this (the surfaces face each other).
        min_contact_points: n_c, an integer >= 0: a contact cell is 1 when it holds more than
            this many contact points.
    """

    contact_distance: float = 0.01
    normal_threshold: float = -0.5
    min_contact_points: int = 2

    def __post_init__(self) -> None:
        check_positive("contact_distance", self.contact_distance)
        try:
            r_n = float(self.normal_threshold)
        except (TypeError, ValueError):
            raise InputError(
                f"normal_threshold must be a number in (-1, 1], got {self.normal_threshold!r}."
            ) from None
        if not -1.0 < r_n <= 1.0:
            raise InputError(
                f"normal_threshold must lie in (-1, 1] (a dot product of unit normals that "
                f"some pair can fall below), got {self.normal_threshold!r}."
            )
        n_c = check_count("min_contact_points", self.min_contact_points, minimum=0)
        object.__setattr__(self, "contact_distance", float(self.contact_distance))
        object.__setattr__(self, "normal_threshold", r_n)
        object.__setattr__(self, "min_contact_points", n_c)


@dataclass(frozen=True)
class InteractionFeatures:
    """The chapter 6 features of N interactions, with the frames they are taken in.

    Attributes:
        features: (N, 169) `FeatureSet` with groups ``shape``, ``pose``, ``contact``,
            ``action`` (`INTERACTION_GROUPS`).
        touch_distance: (N,) distance (m) the actor travels along the action before it first
            comes within r_d of the target; ``inf`` when it never does.
        T_world_action: (N, 4, 4) action frames A_t.
        T_world_object: (N, 4, 4) object frames B_t.
        T_world_contact: (N, 4, 4) contact frames C_t (B_t where there is no contact).
        action_length: (N,) length of the commanded displacement (m).
    """

    features: FeatureSet
    touch_distance: np.ndarray
    T_world_action: np.ndarray
    T_world_object: np.ndarray
    T_world_contact: np.ndarray
    action_length: np.ndarray

    @property
    def touches(self) -> np.ndarray:
        """(N,) whether the actor touches the target during the action."""
        return np.isfinite(self.touch_distance)


def _names() -> tuple[str, ...]:
    names = [
        f"shape.x{i}.y{j}.z{k}"
        for i in range(_SHAPE_CELLS[0])
        for j in range(_SHAPE_CELLS[1])
        for k in range(_SHAPE_CELLS[2])
    ]
    names += [f"pose.pos_{a}" for a in "xyz"] + [f"pose.rot_{a}" for a in "xyz"]
    names += [
        f"contact.x{i}.y{j}.z{k}"
        for i in range(_CONTACT_CELLS[0])
        for j in range(_CONTACT_CELLS[1])
        for k in range(_CONTACT_CELLS[2])
    ]
    names += [f"action.pos_{a}" for a in "xyz"] + [f"action.rot_{a}" for a in "xyz"]
    return tuple(names)


def _cloud(name: str, x: Any, n: int | None = None) -> np.ndarray:
    """Validate an (N, P, 3) point or normal set with N, P >= 1; return it as float64."""
    arr = as_float_array(name, x)
    check_shape(name, arr, (n, None, 3))
    if arr.shape[0] == 0:
        raise InputError(f"{name} holds no samples; pass at least one (1, P, 3) set.")
    if arr.shape[1] == 0:
        raise InputError(f"{name} holds no points; every sample needs at least one point.")
    check_finite(name, _distinct(arr))
    return arr


def _distinct(arr: np.ndarray) -> np.ndarray:
    """(N, ...) samples, or only the first where all are one memory (a broadcast, stride 0)."""
    return arr[:1] if arr.strides[0] == 0 else arr


def _unit_normals(name: str, x: Any, shape: tuple[int, ...]) -> np.ndarray:
    arr = _cloud(name, x, shape[0])
    check_shape(name, arr, shape)
    rows = _distinct(arr)
    sq = np.einsum("npi,npi->np", rows, rows)
    if np.any(np.abs(sq - 1.0) > 2.0 * _NORMAL_TOL):
        norm = np.sqrt(sq)
        raise InputError(
            f"{name} must hold unit vectors; lengths range over [{norm.min():.4g}, "
            f"{norm.max():.4g}]. Divide each normal by its length first."
        )
    return arr


def _in_frame(points: np.ndarray, T_world_frame: np.ndarray) -> np.ndarray:
    """(N, P, 3) world points as (3, N, P) coordinates along a frame's axes, contiguous."""
    rel = points - T_world_frame[:, None, :3, 3]
    return np.ascontiguousarray((rel @ T_world_frame[:, :3, :3]).transpose(2, 0, 1))


def _occupancy(
    rel: np.ndarray, sample: np.ndarray, n: int, counts: tuple[int, int, int], size: float
) -> np.ndarray:
    """(n, cells) number of points in every cell of each sample's grid.

    The grid is centred at the origin of the points' coordinates, with ``counts`` cells of
    edge ``size`` along x, y, z; cell ``(i, j, k)`` is column ``(i * cy + j) * cz + k``.

    Args:
        rel: (3, ...) point coordinates relative to their sample's grid centre (m).
        sample: Sample of each point, broadcastable to ``rel.shape[1:]``.
        n: Number of samples.
        counts: Cells along x, y, z.
        size: Cell edge (m).
    """
    # one more than the position in cell units from the grid's lower corner, nudged up by
    # the boundary tolerance; truncating it and subtracting 1 is the floor wherever the
    # result can be a valid cell (and negative elsewhere)
    lift = (0.5 * size * np.asarray(counts, dtype=np.float64) + BOUNDARY_TOL) / size + 1.0
    idx = [(rel[a] * (1.0 / size) + lift[a]).astype(np.int64) - 1 for a in range(3)]
    inside = np.ones(rel.shape[1:], dtype=bool)
    for a, c in enumerate(counts):
        inside &= idx[a].view(np.uint64) < c  # a negative index wraps to a huge one
    cells = counts[0] * counts[1] * counts[2]
    flat = (idx[0] * counts[1] + idx[1]) * counts[2] + idx[2] + sample * cells
    return np.bincount(flat[inside], minlength=n * cells).reshape(n, cells)


def _commanded_motion(T_world_frame: np.ndarray, T_s: np.ndarray, T_e: np.ndarray) -> np.ndarray:
    """(N, 6) the actor's motion in a frame's axes: displacement (3) and rotation vector (3).

    The rotation is that of ``R_s^T R_e`` (in the actor's start frame) turned into the frame's
    axes, so it does not depend on where the scene stands.
    """
    R_fT = T_world_frame[:, :3, :3].transpose(0, 2, 1)
    shift = (R_fT @ (T_e[:, :3, 3] - T_s[:, :3, 3])[..., None])[..., 0]
    turn = Rotation.from_matrix(T_s[:, :3, :3].transpose(0, 2, 1) @ T_e[:, :3, :3]).as_rotvec()
    in_frame = (R_fT @ T_s[:, :3, :3] @ turn[..., None])[..., 0]
    return np.concatenate([shift, in_frame], axis=1)


def _relative_pose(T_world_frame: np.ndarray, T_world_x: np.ndarray) -> np.ndarray:
    """(N, 6) pose of X in a frame: position (3) and rotation vector of ``R_F^T R_X`` (3)."""
    R_fT = T_world_frame[:, :3, :3].transpose(0, 2, 1)
    pos = (R_fT @ (T_world_x[:, :3, 3] - T_world_frame[:, :3, 3])[..., None])[..., 0]
    rot = Rotation.from_matrix(R_fT @ T_world_x[:, :3, :3]).as_rotvec()
    return np.concatenate([pos, rot], axis=1)


def _chunk_features(
    obj_w: np.ndarray,
    obj_n: np.ndarray,
    act_w: np.ndarray,
    act_n: np.ndarray,
    T_s: np.ndarray,
    T_e: np.ndarray,
    T_a: np.ndarray,
    length: np.ndarray,
    config: InteractionFeatureConfig,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Features of validated samples: ``(values (n, 169), touch (n,), T_b, T_c (n, 4, 4))``.

    Args:
        obj_w: (n, P, 3) target points in the world.
        obj_n: (n, P, 3) their unit normals.
        act_w: (n, Q, 3) actor points in the world.
        act_n: (n, Q, 3) their unit normals.
        T_s: (n, 4, 4) the actor's start poses.
        T_e: (n, 4, 4) its commanded end poses.
        T_a: (n, 4, 4) the action frames.
        length: (n,) action lengths (m).
        config: Contact thresholds.
    """
    n, p = obj_w.shape[:2]
    R_a, o_a = T_a[:, :3, :3], T_a[:, :3, 3]
    obj = _in_frame(obj_w, T_a)  # (3, N, P) in A_t
    act = _in_frame(act_w, T_a)  # (3, N, Q) in A_t
    centre = np.median(obj, axis=2)  # (3, N) B_t's origin in A_t
    T_b = T_a.copy()
    T_b[:, :3, 3] = o_a + (R_a @ centre.T[..., None])[..., 0]

    rows = np.arange(n)[:, None]
    shape = _occupancy(obj - centre[:, :, None], rows, n, _SHAPE_CELLS, _SHAPE_SIZE)
    shape += _occupancy(act - centre[:, :, None], rows, n, _SHAPE_CELLS, _SHAPE_SIZE)

    r = config.contact_distance
    pairs = candidate_pairs(obj, act, length, r)
    h = np.sqrt(r * r - pairs.across2)
    touch = np.full(n, np.inf)
    np.minimum.at(touch, pairs.sample, np.maximum(pairs.along - h, 0.0))

    # (N,) how far the actor is moved to judge contact; samples without a touch have no pairs
    probe = np.minimum(touch + 0.5 * r, length)
    near = pairs.across2 + (pairs.along - probe[pairs.sample]) ** 2 < r * r
    target, actor = pairs.target[near], pairs.actor[near]
    dot = np.einsum("ki,ki->k", obj_n.reshape(-1, 3)[target], act_n.reshape(-1, 3)[actor])
    in_contact = np.zeros(obj_w.shape[0] * p, dtype=bool)
    in_contact[target[dot < config.normal_threshold]] = True
    contact_idx = np.flatnonzero(in_contact)  # flat, grouped by sample
    contact_sample = contact_idx // p
    contact_pts = obj.reshape(3, -1)[:, contact_idx]  # (3, M) in A_t
    n_contact = np.bincount(contact_sample, minlength=n)
    sums = np.stack(
        [np.bincount(contact_sample, weights=contact_pts[i], minlength=n) for i in range(3)]
    )
    c_origin = np.where(n_contact > 0, sums / np.maximum(n_contact, 1), centre)  # (3, N) in A_t
    T_c = T_a.copy()
    T_c[:, :3, 3] = o_a + (R_a @ c_origin.T[..., None])[..., 0]
    cell_count = _occupancy(
        contact_pts - c_origin[:, contact_sample],
        contact_sample,
        n,
        _CONTACT_CELLS,
        _CONTACT_SIZE,
    )
    contact = cell_count > config.min_contact_points

    values = np.concatenate(
        [
            (shape > 0).astype(np.float64),
            _relative_pose(T_b, T_s),
            contact.astype(np.float64),
            _commanded_motion(T_b, T_s, T_e),
        ],
        axis=1,
    )
    return values, touch, T_b, T_c


def interaction_features(
    target_points: Any,
    target_normals: Any,
    actor_points: Any,
    actor_normals: Any,
    T_world_actor_start: Any,
    T_world_actor_end: Any,
    config: InteractionFeatureConfig = InteractionFeatureConfig(),
    chunk: int = 2048,
) -> InteractionFeatures:
    """Chapter 6 features of N interactions of an actor with a target object.

    Args:
        target_points: (N, P, 3) world points of the object acted on.
        target_normals: (N, P, 3) their outward unit normals.
        actor_points: (N, Q, 3) world points of the actor at the action's start.
        actor_normals: (N, Q, 3) their outward unit normals.
        T_world_actor_start: (N, 4, 4) the actor's commanded start pose.
        T_world_actor_end: (N, 4, 4) its commanded end pose.
        config: Contact thresholds.
        chunk: Samples computed at once, a positive integer; bounds the memory of the
            pair search (results do not depend on it).

    Returns:
        The (N, 169) features (columns in the module docstring), touch distances, the frames
        A_t, B_t, C_t and the action lengths.

    Raises:
        InputError: For empty, mis-shaped or non-finite inputs, normals that are not unit
            length, transforms that are not rigid, a zero-length action, a `config` of
            another type or a `chunk` that is not a positive integer; each message names the
            argument.
    """
    if not isinstance(config, InteractionFeatureConfig):
        raise InputError(
            f"config must be an InteractionFeatureConfig, got {type(config).__name__}."
        )
    obj_w = _cloud("target_points", target_points)
    n = obj_w.shape[0]
    obj_n = _unit_normals("target_normals", target_normals, obj_w.shape)
    act_w = _cloud("actor_points", actor_points, n)
    act_n = _unit_normals("actor_normals", actor_normals, act_w.shape)
    T_s = _check_transforms("T_world_actor_start", T_world_actor_start, n)
    T_e = _check_transforms("T_world_actor_end", T_world_actor_end, n)
    T_a = action_frame(T_s, T_e)
    length = np.linalg.norm(T_e[:, :3, 3] - T_s[:, :3, 3], axis=1)

    chunk = check_count("chunk", chunk)
    parts = [
        _chunk_features(
            obj_w[rows],
            obj_n[rows],
            act_w[rows],
            act_n[rows],
            T_s[rows],
            T_e[rows],
            T_a[rows],
            length[rows],
            config,
        )
        for rows in (slice(i, i + chunk) for i in range(0, n, chunk))
    ]
    return InteractionFeatures(
        features=FeatureSet(
            np.concatenate([v for v, _, _, _ in parts]), dict(INTERACTION_GROUPS), _names()
        ),
        touch_distance=np.concatenate([tch for _, tch, _, _ in parts]),
        T_world_action=T_a,
        T_world_object=np.concatenate([b for _, _, b, _ in parts]),
        T_world_contact=np.concatenate([c for _, _, _, c in parts]),
        action_length=length,
    )
