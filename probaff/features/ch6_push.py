"""Chapter 6 interactions of tabletop push datasets: the hand on o1, and object on object.

A push dataset (`probaff.data.PushDataset`) records, per push, the hand's commanded straight
path and every object's pose before and after. This module turns it into the rows a
per-skill push model learns from (`probaff.models.SkillTransitionModel`):

* ``"hand"`` rows: the actor is the hand (two fingers), its action the commanded push from
  the push origin over ``push_distance`` along ``push_yaw``; the target is o1. The reaction
  is the hand's deviation from its commanded pose, in the action frame's (x, y): at the
  commanded end point (``reaction="end"``, from ``traj_hand``), or, with ``reaction="path"``,
  that end point and the mean deviation along the whole push (from the dataset's
  ``hand_reaction``, sampled along the path; schema version 6), which a hand that lags while
  it pushes and catches up once the object stops shows and its end point does not.
* ``"objects"`` rows: for each consecutive pair ``(k, k + 1)`` of objects, the actor is object
  k moving from its pose before to its pose after the push (that motion is its action) and
  the target is object k + 1. A pair whose actor moved less than `min_action` is skipped: a
  motion that short has no direction. An object's motion is what it is, so its reaction is 0.

Geometry. Objects are the catalogue's boxes: ``size = (length, width, height)`` at the
dataset's observed poses, lifted with `tabletop_transform`; their surfaces and features come
from a `Ch6Geometry`, the same one a chained prediction (`ModularTransitionModel`) is
given, so training rows and chain links are computed alike. A finger is a box of
``2 r x 2 r x FINGER_LENGTH`` (r the finger radius) standing from the push height, the two of
them ``gripper_opening`` apart across the push: the round fingertips of the simulator's hand
drawn as their bounding boxes. Circular catalogue objects have no box; datasets holding one
are refused.

Effects are the target's observed rigid displacements in the action frame A_t
(`effect_in_action_frame`, six columns ``dx, dy, dz, rx, ry, rz``); on the table only
``dx`` (off the action), ``dy`` (along it) and ``rz`` (the turn) are non-zero
(`PLANAR_EFFECT_COLUMNS`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from probaff._checks import check_finite, check_positive
from probaff.data.schema import PushDataset
from probaff.errors import InputError
from probaff.features._common import FINGER_LENGTH, meta_float
from probaff.features.action_frame import effect_in_action_frame, tabletop_transform
from probaff.features.chain_geometry import Ch6Geometry, InteractionRows, resolve_geometry
from probaff.features.requirements import FEATURE_REQUIREMENTS, Requirements
from probaff.sim.specs import load_catalogue

__all__ = [
    "PAIR_KINDS",
    "PLANAR_EFFECT_COLUMNS",
    "REACTIONS",
    "REQUIRES",
    "PushInteractions",
    "box_sizes",
    "hand_poses",
    "push_interactions",
]

PAIR_KINDS = ("hand", "objects")
"""Kinds of interaction rows `push_interactions` builds."""

REQUIRES: dict[str, Requirements] = {
    kind: FEATURE_REQUIREMENTS[f"ch6.push.{kind}"] for kind in PAIR_KINDS
}
"""What `push_interactions` reads, by kind of row: ``"hand"`` rows the poses, the push, the
hand trajectory and the hand's geometry in meta; ``"objects"`` rows the poses."""

REACTIONS = {"end": 2, "path": 4}
"""Kinds of reaction columns of the hand rows, and their count: ``"end"`` the deviation
``(dx, dy)`` at the commanded end point; ``"path"`` that and the mean ``(dx, dy)`` over the
reaction sampled along the path (``hand_reaction``)."""

PLANAR_EFFECT_COLUMNS = (0, 1, 5)
"""Effect columns that move on the table: off-action dx, along-action dy, yaw turn rz."""


@dataclass(frozen=True)
class PushInteractions(InteractionRows):
    """Interaction rows of a push dataset.

    Attributes:
        features: (n, D) the geometry's features of the n rows.
        touches: (n,) whether the actor touches the target during its action.
        T_world_action: (n, 4, 4) the action frames A_t.
        effect: (n, 6) observed displacement of each row's target in its action frame.
        reaction: (n, Er) the actor's deviation (m) from its command in the action frame
            (`REACTIONS`: Er = 2 for ``"end"``, 4 for ``"path"``): the hand's for ``"hand"``
            rows, 0 for object actors.
        reaction_path: (n, R, 2) the deviation ``(dx, dy)`` (m) at the R points along the
            push the dataset records (``hand_reaction``); (n, 0, 2) when it records none.
        push: (n,) the push (row of the dataset) of each interaction.
        actor: (n,) the acting object's index, -1 for the hand.
        target: (n,) the target object's index.
    """

    push: np.ndarray
    actor: np.ndarray
    target: np.ndarray
    reaction_path: np.ndarray


def _check_finite_rows(name: str, values: np.ndarray, length: np.ndarray | None = None) -> None:
    """Raise `InputError` naming `name` and its first row holding NaN or inf.

    Args:
        name: The dataset array's name, as ``ds[name]`` reads it.
        values: (N, ...) the array, or (N, T, ...) a trajectory when `length` is given.
        length: (N,) valid samples of each row of a trajectory (the rest repeat the last one
            and are not read); ``None`` checks every entry.
    """
    arr = np.asarray(values)
    n = arr.shape[0]
    if arr.size == 0:
        return
    if length is None:
        bad = ~np.isfinite(arr.reshape(n, -1))
    else:
        steps = arr.shape[1]
        bad = ~np.isfinite(arr.reshape(n, steps, -1))
        bad &= (np.arange(steps)[None, :] < np.asarray(length)[:, None])[..., None]
    rows = np.flatnonzero(bad.reshape(n, -1).any(axis=1))
    if rows.size:
        i = int(rows[0])
        others = rows.size - 1
        more = f" (and {others} more row{'s' if others > 1 else ''})" if others else ""
        valid = arr[i] if length is None else arr[i, : int(length[i])]
        check_finite(f"{name} in row {i}{more}", valid)


def box_sizes(ds: PushDataset) -> np.ndarray:
    """(N, K, 3) ``(length, width, height)`` of every object (m); refuses circular ones.

    Args:
        ds: A push dataset whose objects are in the catalogue.

    Raises:
        InputError: For an object missing from the catalogue or one that is not a box.
    """
    catalogue = load_catalogue()
    names = ds.object_names
    table = np.zeros((len(names), 3))
    for i, name in enumerate(names):
        spec = catalogue.get(name)
        if spec is None:
            raise InputError(
                f"dataset object {name!r} is not in the catalogue; regenerate the dataset with "
                "this version of probaff."
            )
        table[i] = (*spec.size, spec.height) if spec.shape == "box" else np.nan
    sizes = table[ds["object_ids"]]
    bad = np.unique(ds["object_ids"][np.isnan(sizes[..., 0])])
    if bad.size:
        raise InputError(
            f"chapter 6 interactions need cuboid objects; the dataset holds "
            f"{[names[i] for i in bad]} (circular). Use a scene of boxes."
        )
    return sizes


def _boxes(geometry: Ch6Geometry, sizes: np.ndarray, poses: np.ndarray) -> tuple[np.ndarray, ...]:
    """Surface points and normals of boxes `(n, 3)` at planar poses `(n, 3)`, and the lifts."""
    T = tabletop_transform(poses, sizes[:, 2])
    points, normals = geometry.surface(sizes, T)
    return points, normals, T


def hand_poses(ds: PushDataset, geometry: Ch6Geometry) -> tuple[np.ndarray, ...]:
    """Finger points, normals, and the hand's start and commanded end poses.

    Args:
        ds: A push dataset with the hand's meta (``finger_radius``, ``gripper_opening``,
            ``push_height``).
        geometry: The chapter 6 geometry (finger sampling).

    Returns:
        The two fingers' surface points `(N, P, 3)` and outward normals `(N, P, 3)`, then the
        hand's start and commanded end poses `(N, 4, 4)`, all in the world frame (m).
    """
    n = len(ds)
    r = meta_float(ds, "finger_radius")
    opening = meta_float(ds, "gripper_opening")
    height = meta_float(ds, "push_height")
    yaw = ds["push_yaw"]
    # a "box" of height 2 h has its centre at the push height h: the hand frame, x along z_p
    T_s = tabletop_transform(np.column_stack([ds["push_origin"], yaw]), np.full(n, 2 * height))
    T_e = T_s.copy()
    T_e[:, :2, 3] += ds["push_distance"][:, None] * np.column_stack([np.cos(yaw), np.sin(yaw)])
    finger = np.array([2 * r, 2 * r, FINGER_LENGTH])
    pts, nrm = [], []
    for side in (-0.5, 0.5):
        offset = np.eye(4)
        offset[1, 3] = side * opening
        offset[2, 3] = 0.5 * FINGER_LENGTH
        p, q = geometry.surface(np.tile(finger, (n, 1)), T_s @ offset)
        pts.append(p)
        nrm.append(q)
    return np.concatenate(pts, axis=1), np.concatenate(nrm, axis=1), T_s, T_e


def _hand_reaction(ds: PushDataset, T_a: np.ndarray, T_e: np.ndarray) -> np.ndarray:
    """(N, 2) the hand's end-point deviation from the commanded end, in A_t's (x, y)."""
    if not ds.has_trajectories:
        raise InputError(
            "the hand's reaction needs the hand trajectory; regenerate the dataset with "
            "trajectories (GenerateConfig(trajectories=True), the default)."
        )
    end = ds["traj_hand"][:, -1, :2].astype(np.float64)
    miss = end - T_e[:, :2, 3]
    R = T_a[:, :2, :2]
    return np.einsum("nji,nj->ni", R, miss)


def _reaction_path(ds: PushDataset, T_a: np.ndarray) -> np.ndarray:
    """(N, R, 2) the recorded reaction along the path in A_t's (x, y); (N, 0, 2) without it."""
    if "hand_reaction" not in ds.arrays:
        return np.zeros((len(ds), 0, 2))
    dev = ds["hand_reaction"].astype(np.float64)  # (N, R, 3) pushing frame (dy_p, dz_p, dth)
    yaw = ds["push_yaw"]
    z_p = np.column_stack([np.cos(yaw), np.sin(yaw)])
    y_p = np.column_stack([-np.sin(yaw), np.cos(yaw)])
    world = dev[..., :1] * y_p[:, None, :] + dev[..., 1:2] * z_p[:, None, :]
    return np.einsum("nji,nrj->nri", T_a[:, :2, :2], world)


def _reaction_columns(kind: str, end: np.ndarray, path: np.ndarray) -> np.ndarray:
    """The reaction columns of `kind` from the end point (n, 2) and the path (n, R, 2)."""
    if kind == "end":
        return end
    return np.concatenate([end, path.mean(axis=1)], axis=1)


def push_interactions(
    ds: PushDataset,
    kind: str = "hand",
    *,
    geometry: Ch6Geometry | None = None,
    min_action: float = 1e-3,
    reaction: str = "end",
) -> PushInteractions:
    """Chapter 6 interaction rows of a tabletop push dataset.

    Args:
        ds: A push dataset of cuboid objects.
        kind: ``"hand"`` (the hand on o1, one row per push) or ``"objects"`` (object k on
            object k + 1, for each consecutive pair whose actor moved).
        geometry: Surfaces and features (``Ch6Geometry()`` if ``None``).
        min_action: Shortest actor motion (m) that makes an ``"objects"`` row, > 0.
        reaction: The reaction columns (`REACTIONS`): ``"end"`` (the deviation at the
            commanded end point) or ``"path"`` (that and its mean along the push; needs a
            dataset that records ``hand_reaction``, schema version 6).

    Returns:
        The rows, their features, observed effects and reactions.

    Raises:
        InputError: For an unknown kind, reaction or geometry, circular objects, missing
            trajectories (``"hand"`` rows need the hand's path), a ``"path"`` reaction from a
            dataset without ``hand_reaction``, or another array or ``meta`` entry of
            `REQUIRES` (naming it), a dataset without rows, or NaN or inf in an array the rows
            read (naming the array and its first such row).
    """
    geometry = resolve_geometry(geometry)
    if kind not in PAIR_KINDS:
        raise InputError(f"unknown interaction kind {kind!r}; use one of {list(PAIR_KINDS)}.")
    if not isinstance(reaction, str) or reaction not in REACTIONS:
        raise InputError(f"unknown reaction {reaction!r}; use one of {list(REACTIONS)}.")
    if reaction == "path" and kind == "hand" and "hand_reaction" not in ds.arrays:
        raise InputError(
            "reaction='path' needs the hand's reaction along the path (array 'hand_reaction'), "
            "which this dataset lacks (schema version 1 or 2); regenerate it with this version "
            "of probaff, or use reaction='end'."
        )
    check_positive("min_action", min_action)
    if len(ds) == 0:
        raise InputError("the dataset has no pushes.")
    REQUIRES[kind].check(ds)
    for name in ("state_before", "state_after"):
        _check_finite_rows(name, ds[name])
    sizes = box_sizes(ds)
    before, after = ds["state_before"], ds["state_after"]
    n, k = before.shape[:2]
    if kind == "hand":
        for name in ("push_origin", "push_yaw", "push_distance"):
            _check_finite_rows(name, ds[name])
        if ds.has_trajectories:
            _check_finite_rows("traj_hand", ds["traj_hand"])
        if "hand_reaction" in ds.arrays:
            _check_finite_rows("hand_reaction", ds["hand_reaction"])
        t_pts, t_nrm, T_before = _boxes(geometry, sizes[:, 0], before[:, 0])
        a_pts, a_nrm, T_s, T_e = hand_poses(ds, geometry)
        X, touches, T_a = geometry.features(t_pts, t_nrm, a_pts, a_nrm, T_s, T_e)
        T_after = tabletop_transform(after[:, 0], sizes[:, 0, 2])
        path = _reaction_path(ds, T_a)
        return PushInteractions(
            X,
            touches,
            T_a,
            effect_in_action_frame(T_a, T_before, T_after),
            _reaction_columns(reaction, _hand_reaction(ds, T_a, T_e), path),
            np.arange(n),
            np.full(n, -1),
            np.zeros(n, dtype=int),
            path,
        )
    if k < 2:
        raise InputError("object-on-object rows need scenes of at least two objects.")
    push = np.repeat(np.arange(n), k - 1)  # (n (K - 1),) push of each candidate pair
    actor = np.tile(np.arange(k - 1), n)  # its acting object
    moved = np.linalg.norm(after[push, actor, :2] - before[push, actor, :2], axis=1)
    keep = moved >= min_action
    if not keep.any():
        raise InputError(f"no object moved by {min_action} m or more; there are no rows.")
    push, actor = push[keep], actor[keep]
    target = actor + 1
    t_pts, t_nrm, T_before = _boxes(geometry, sizes[push, target], before[push, target])
    a_pts, a_nrm, T_s = _boxes(geometry, sizes[push, actor], before[push, actor])
    T_e = tabletop_transform(after[push, actor], sizes[push, actor, 2])
    X, touches, T_a = geometry.features(t_pts, t_nrm, a_pts, a_nrm, T_s, T_e)
    T_after = tabletop_transform(after[push, target], sizes[push, target, 2])
    return PushInteractions(
        X,
        touches,
        T_a,
        effect_in_action_frame(T_a, T_before, T_after),
        np.zeros((len(push), REACTIONS[reaction])),
        push,
        actor,
        target.astype(int),
        np.zeros((len(push), 0, 2)),
    )
