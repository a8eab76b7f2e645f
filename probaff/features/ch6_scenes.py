"""Whole tabletop push scenes for chapter 6: chain inputs and the monolithic baseline's rows.

`push_interactions` cuts a push dataset into single interactions for the per-skill models.
This module keeps each push whole:

* `push_scenes` gives, per push, everything a chained prediction
  (`probaff.models.ChainScene`) needs: the cuboids' sizes and start poses, the hand's finger
  surface in the hand frame and its commanded start and end poses, in the same geometry
  (`Ch6Geometry`) as the training rows, and the observed final poses to score against.
* `scene_features` gives the thesis's monolithic baseline its rows: one per push, "the global
  configuration of end-effector and objects, relative objects' poses from the end-effector and
  the action", and as targets every object's planar displacement in the hand's action frame.

Frames. The hand's action frame A (`action_frame` of its commanded start and end poses) has y
along the push and x off it; world up is z. Scene features of object k, in A with the hand's
start as the origin, are ``x_k, y_k`` (its centre), ``cos 2 theta_k, sin 2 theta_k`` (its yaw
relative to the push, doubled because a cuboid looks the same turned by pi) and its footprint
``length_k, width_k``; then each later object's centre relative to object 0 in A, and the
push's length. The targets are ``dx_k, dy_k, dtheta_k`` (off the push, along it, the turn),
`SCENE_EFFECT_NAMES`, object after object.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from probaff._checks import check_count
from probaff.data.schema import PushDataset
from probaff.errors import InputError
from probaff.features.action_frame import action_frame, tabletop_transform
from probaff.features.ch6_push import box_sizes, hand_poses
from probaff.features.chain_geometry import Ch6Geometry, resolve_geometry
from probaff.features.requirements import FEATURE_REQUIREMENTS
from probaff.models.transitions.chain import ChainScene

__all__ = [
    "REQUIRES",
    "SCENE_EFFECT_NAMES",
    "PushScenes",
    "push_scenes",
    "scene_effects",
    "scene_feature_names",
    "scene_features",
]

REQUIRES = FEATURE_REQUIREMENTS["ch6.scenes"]
"""What `push_scenes`, `scene_features` and `scene_effects` read: the poses, the push and the
hand's geometry in meta."""

SCENE_EFFECT_NAMES = ("dx", "dy", "dtheta")
"""Per-object target columns of the monolithic rows: off the push, along it, the turn."""

_COARSE_SPACING = 0.05  # m; finger points of scenes used only for their frames
_PER_OBJECT = ("x", "y", "cos2theta", "sin2theta", "length", "width")


@dataclass(frozen=True)
class PushScenes:
    """Whole push scenes of cuboids, ready to be chained.

    Attributes:
        sizes: (N, K, 3) box extents ``(length, width, height)`` (m).
        T_world_obj: (N, K, 4, 4) the objects' start poses (box centres, world).
        T_world_obj_after: (N, K, 4, 4) their observed final poses.
        hand_points: (N, Q, 3) the fingers' surface points in the hand frame (m).
        hand_normals: (N, Q, 3) their outward unit normals in the hand frame.
        T_world_hand_start: (N, 4, 4) the hand's commanded start pose.
        T_world_hand_end: (N, 4, 4) its commanded end pose.
        T_world_action: (N, 4, 4) the hand's action frame A (y along the push).
    """

    sizes: np.ndarray
    T_world_obj: np.ndarray
    T_world_obj_after: np.ndarray
    hand_points: np.ndarray
    hand_normals: np.ndarray
    T_world_hand_start: np.ndarray
    T_world_hand_end: np.ndarray
    T_world_action: np.ndarray

    def __len__(self) -> int:
        return int(self.sizes.shape[0])

    @property
    def n_objects(self) -> int:
        """Objects per scene K."""
        return int(self.sizes.shape[1])

    def chain_scene(self, i: int) -> ChainScene:
        """Scene `i` as `probaff.models.ChainScene`, the input of a chained prediction."""
        return ChainScene(
            self.sizes[i],
            self.T_world_obj[i],
            self.hand_points[i],
            self.hand_normals[i],
            self.T_world_hand_start[i],
            self.T_world_hand_end[i],
        )


def _check_dataset(ds: PushDataset) -> None:
    if not isinstance(ds, PushDataset):
        raise InputError(
            f"ds must be a PushDataset (probaff.data.load_dataset), got {type(ds).__name__}."
        )
    if len(ds) == 0:
        raise InputError("the dataset has no pushes; generate at least one.")
    REQUIRES.check(ds)
    for name in ("state_before", "state_after", "push_origin", "push_yaw", "push_distance"):
        bad = np.argwhere(~np.isfinite(ds[name]))
        if bad.size:
            raise InputError(
                f"{name} holds a non-finite value in row {int(bad[0, 0])}; regenerate the "
                "dataset or drop that row."
            )


def push_scenes(ds: PushDataset, *, geometry: Ch6Geometry | None = None) -> PushScenes:
    """Every push of a dataset of cuboids as a whole scene.

    Args:
        ds: A push dataset of cuboid objects.
        geometry: The surfaces of the fingers (``Ch6Geometry()`` if ``None``); use the
            geometry the chain's models were trained with.

    Returns:
        The scenes, one per push.

    Raises:
        InputError: For another type of dataset, an empty one, one that lacks an array or
            ``meta`` entry of `REQUIRES` (naming it), circular objects, non-finite poses or a
            geometry of the wrong type.
    """
    geometry = resolve_geometry(geometry)
    _check_dataset(ds)
    sizes = box_sizes(ds)
    n, k = sizes.shape[:2]
    flat = sizes.reshape(-1, 3)
    T_obj = tabletop_transform(ds["state_before"].reshape(-1, 3), flat[:, 2]).reshape(n, k, 4, 4)
    T_after = tabletop_transform(ds["state_after"].reshape(-1, 3), flat[:, 2]).reshape(n, k, 4, 4)
    points, normals, T_s, T_e = hand_poses(ds, geometry)
    T_inv = np.linalg.inv(T_s)
    hand_p = np.einsum("nij,nqj->nqi", T_inv[:, :3, :3], points) + T_inv[:, None, :3, 3]
    hand_n = np.einsum("nij,nqj->nqi", T_inv[:, :3, :3], normals)
    return PushScenes(sizes, T_obj, T_after, hand_p, hand_n, T_s, T_e, action_frame(T_s, T_e))


def _hand_frames(ds: PushDataset) -> PushScenes:
    """The scenes with a coarse finger surface: for their frames, not for features."""
    return push_scenes(ds, geometry=Ch6Geometry(columns=[], spacing=_COARSE_SPACING))


def _in_action(T_a: np.ndarray, xy: np.ndarray) -> np.ndarray:
    """(N, K, 2) world offsets `xy (N, K, 2)` in the action frames' (x, y)."""
    R = T_a[:, :2, :2]  # columns: the frame's x and y in the world
    return np.einsum("nji,nkj->nki", R, xy)


def _turn(T_a: np.ndarray, yaw: np.ndarray) -> np.ndarray:
    """(N, K) yaws relative to the action frames' y axis."""
    push = np.arctan2(T_a[:, 1, 1], T_a[:, 0, 1])
    return yaw - push[:, None]


def scene_feature_names(n_objects: int) -> tuple[str, ...]:
    """Names of the `scene_features` columns of scenes of `n_objects` objects.

    Raises:
        InputError: If `n_objects` is not a positive integer.
    """
    n_objects = check_count("n_objects", n_objects)
    names = [f"{c}_{k}" for k in range(n_objects) for c in _PER_OBJECT]
    names += [f"{c}_{k}_rel0" for k in range(1, n_objects) for c in ("x", "y")]
    return (*names, "push_length")


def scene_features(ds: PushDataset) -> np.ndarray:
    """The monolithic baseline's features of every push (see the module docstring).

    Args:
        ds: A push dataset of cuboid objects, K per scene.

    Returns:
        (N, 7 K + 1) features, columns `scene_feature_names(K)`, in the hand's action frame.

    Raises:
        InputError: As `push_scenes`.
    """
    scenes = _hand_frames(ds)
    T_a = scenes.T_world_action
    centre = scenes.T_world_obj[:, :, :2, 3]
    origin = scenes.T_world_hand_start[:, None, :2, 3]
    xy = _in_action(T_a, centre - origin)
    turn = 2.0 * _turn(T_a, ds["state_before"][:, :, 2])
    per_object = np.concatenate(
        [xy, np.cos(turn)[..., None], np.sin(turn)[..., None], scenes.sizes[:, :, :2]], axis=2
    )
    rel = (xy[:, 1:] - xy[:, :1]).reshape(len(scenes), -1)
    length = np.linalg.norm(
        scenes.T_world_hand_end[:, :3, 3] - scenes.T_world_hand_start[:, :3, 3], axis=1
    )
    return np.concatenate([per_object.reshape(len(scenes), -1), rel, length[:, None]], axis=1)


def scene_effects(ds: PushDataset) -> np.ndarray:
    """Every object's observed planar displacement in the hand's action frame.

    Args:
        ds: A push dataset, K objects per scene.

    Returns:
        (N, 3 K): ``dx_k, dy_k, dtheta_k`` (m, m, rad; `SCENE_EFFECT_NAMES`) object after
        object, the turn wrapped to ``[-pi, pi)``.

    Raises:
        InputError: As `push_scenes`.
    """
    T_a = _hand_frames(ds).T_world_action
    d = ds["state_after"] - ds["state_before"]
    turn = (d[..., 2] + np.pi) % (2 * np.pi) - np.pi
    return np.concatenate([_in_action(T_a, d[..., :2]), turn[..., None]], axis=2).reshape(
        len(ds), -1
    )
