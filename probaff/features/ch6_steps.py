"""Chapter 6 pushes cut into steps of fixed hand travel (thesis section 6.3.1).

The thesis steps a skill as piecewise-linear actions A_t = P^e_{t+1} - P^e_t. This module cuts
every recorded push of a dataset (``traj_hand``, ``traj_commanded``, ``traj_objects``) at the
times the commanded hand has travelled ``0, L, 2 L, ...`` along the push (L the
`StepOptions.step_length`), and at the end of the recording for the last boundary, so that the
steps of a push add up to the whole push, settling included. Poses between recorded samples
are interpolated linearly in time.

Step t of a link (an actor acting on a target) has:

* features f_t: the geometry's interaction features (`Ch6Geometry.features`) of the actor
  moving from its actual pose at t to its commanded pose at t + 1, against the target at its
  pose at t: the target relative to the actor, contacts included, as the whole-push rows of
  `probaff.features.ch6_push` are built;
* an effect e_t: the target's planar displacement over the step in that step's action frame
  (``dx`` off the action, ``dy`` along it, ``rz`` the turn; `STEP_EFFECT_NAMES`);
* a reaction r_t: the actor's actual minus its commanded position at t + 1, in the action
  frame's ``(x, y)`` (`STEP_REACTION_NAMES`).

The hand's link has the hand as actor and o1 as target; its commanded poses are the
recorded ``traj_commanded``. For an object link ``(k, k + 1)``, the actor's command over a
step is what the link upstream of it predicts (object k's forward effect), which only a
model knows: `link_steps` takes it as an argument.

Frames: planar poses are world ``(x, y, yaw)`` (m, m, rad); the hand's pose is its frame at
the push height, x along the push (as `probaff.features.ch6_push.hand_poses`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from probaff._checks import check_positive
from probaff.data.schema import PushDataset
from probaff.errors import InputError
from probaff.features._common import FINGER_LENGTH, meta_float
from probaff.features.action_frame import effect_in_action_frame, tabletop_transform
from probaff.features.ch6_push import PLANAR_EFFECT_COLUMNS, box_sizes
from probaff.features.chain_geometry import Ch6Geometry, InteractionRows, resolve_geometry
from probaff.models.transitions.stepped_transition import SteppedScenes

__all__ = [
    "HAND_STARTS",
    "STEP_EFFECT_NAMES",
    "STEP_REACTION_NAMES",
    "LinkSteps",
    "StepOptions",
    "StepTrajectories",
    "check_step_length",
    "finger_surface",
    "hand_steps",
    "hand_transform",
    "in_frame",
    "link_steps",
    "step_trajectories",
]

STEP_EFFECT_NAMES = ("dx", "dy", "rz")
"""Columns of a step's effect: off the action, along it (m), the turn (rad)."""

STEP_REACTION_NAMES = ("dx", "dy")
"""Columns of a step's reaction: the actor's actual minus commanded position in the action
frame, off the action and along it (m)."""

HAND_STARTS = ("actual", "commanded")
"""Where a hand step's motion starts (`hand_steps`): the recorded or the commanded pose."""

_DIVIDE_TOL = 1e-6  # m; a push of length D is cut into n steps when |D - n L| is below this


@dataclass(frozen=True)
class StepOptions:
    """How pushes are cut into steps.

    Attributes:
        step_length: Commanded hand travel per step L (m), a positive finite length that
            divides every push's distance (0.35 m pushes: 0.025 gives 14 steps).
    """

    step_length: float = 0.025

    def __post_init__(self) -> None:
        """Raise `InputError` for a step length that is not a positive finite length."""
        check_step_length(self.step_length)


def _dividers(distance: float, length: float) -> list[int]:
    """Step counts whose lengths divide `distance` nearest to `length`, whole mm first."""
    counts = np.arange(1, max(2, int(distance / 1e-3)) + 1)
    lengths = distance / counts
    whole = np.abs(lengths * 1e3 - np.rint(lengths * 1e3)) < 1e-6
    pool = counts[whole] if whole.sum() >= 2 else counts
    shorter = pool[distance / pool <= length][:1]  # the longest step below `length`
    longer = pool[distance / pool > length][-1:]  # the shortest step above it
    return [int(n) for n in (*shorter, *longer)]


def check_step_length(step_length: object, distances: np.ndarray | None = None) -> int | None:
    """Check a step length, and that it divides every push distance.

    Args:
        step_length: The step length L (m).
        distances: (N,) push distances (m) to divide, or ``None`` to check L alone.

    Returns:
        The number of steps per push (every push of a dataset of one distance), or ``None``
        without `distances`.

    Raises:
        InputError: For a step length that is not a positive finite number, one that does not
            divide a push (naming the push and lengths that do), or pushes of different
            step counts.
    """
    if isinstance(step_length, (bool, np.bool_)) or not isinstance(
        step_length, (int, float, np.integer, np.floating)
    ):
        raise InputError(
            f"step_length must be a positive length in metres (e.g. 0.025), got {step_length!r}."
        )
    length = float(step_length)
    if not math.isfinite(length) or length <= 0:
        raise InputError(
            f"step_length must be a positive finite length in metres (e.g. 0.025), "
            f"got {step_length!r}."
        )
    if distances is None:
        return None
    d = np.asarray(distances, dtype=np.float64)
    counts = np.rint(d / length)
    bad = np.flatnonzero((counts < 1) | (np.abs(d - counts * length) > _DIVIDE_TOL))
    if bad.size:
        i = int(bad[0])
        dist = float(d[i])
        fits = " or ".join(
            f"{dist / n:.6g} ({n} step{'s' if n > 1 else ''})" for n in _dividers(dist, length)
        )
        raise InputError(
            f"step_length={length:g} m does not divide the {dist:g} m push of row {i}; use "
            f"the push distance over a whole number of steps, e.g. step_length={fits}."
        )
    if np.unique(counts).size > 1:
        raise InputError(
            f"step_length={length:g} m cuts the pushes into {sorted(set(counts.astype(int)))} "
            "steps; step a dataset whose pushes share one distance."
        )
    return int(counts[0])


@dataclass(frozen=True)
class StepTrajectories:
    """Every push of a dataset at its step boundaries.

    Attributes:
        hand: (N, S + 1, 3) the hand's actual planar pose at each boundary.
        commanded: (N, S + 1, 3) its commanded pose.
        objects: (N, S + 1, K, 3) the objects' planar poses.
        sizes: (N, K, 3) box extents ``(length, width, height)`` (m).
        push_yaw: (N,) world yaw of the push direction.
        finger_points: (Q, 3) the fingers' surface points in the hand frame (m).
        finger_normals: (Q, 3) their outward unit normals in the hand frame.
        hand_height: Height (m) of the hand frame's lift (`hand_transform`).
        step_length: The step length L (m).
    """

    hand: np.ndarray
    commanded: np.ndarray
    objects: np.ndarray
    sizes: np.ndarray
    push_yaw: np.ndarray
    finger_points: np.ndarray
    finger_normals: np.ndarray
    hand_height: float
    step_length: float

    def __len__(self) -> int:
        return int(self.hand.shape[0])

    @property
    def n_steps(self) -> int:
        """Steps per push S."""
        return int(self.hand.shape[1]) - 1

    @property
    def n_objects(self) -> int:
        """Objects per scene K."""
        return int(self.objects.shape[2])

    def scenes(self) -> SteppedScenes:
        """What a rollout reads: the start poses, sizes, fingers and commanded path.

        Raises:
            InputError: For a push whose objects overlap at the start.
        """
        return SteppedScenes(
            self.sizes,
            self.objects[:, 0],
            self.commanded,
            self.finger_points,
            self.finger_normals,
            self.hand_height,
        )

    def subset(self, rows: np.ndarray | list[int]) -> StepTrajectories:
        """The trajectories of pushes `rows` (indices into this set)."""
        idx = np.asarray(rows, dtype=int)
        return StepTrajectories(
            self.hand[idx],
            self.commanded[idx],
            self.objects[idx],
            self.sizes[idx],
            self.push_yaw[idx],
            self.finger_points,
            self.finger_normals,
            self.hand_height,
            self.step_length,
        )


def finger_surface(
    ds: PushDataset, geometry: Ch6Geometry | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """The two fingers' surface in the hand frame, as `hand_poses` places them.

    Args:
        ds: A push dataset with the hand's meta (``finger_radius``, ``gripper_opening``).
        geometry: The chapter 6 geometry (finger sampling; ``Ch6Geometry()`` if ``None``).

    Returns:
        ``(points, normals)``, each (Q, 3) in the hand frame (m).
    """
    geometry = resolve_geometry(geometry)
    r = meta_float(ds, "finger_radius")
    opening = meta_float(ds, "gripper_opening")
    finger = np.array([[2 * r, 2 * r, FINGER_LENGTH]])
    pts, nrm = [], []
    for side in (-0.5, 0.5):
        offset = np.eye(4)[None]
        offset[0, 1, 3] = side * opening
        offset[0, 2, 3] = 0.5 * FINGER_LENGTH
        p, q = geometry.surface(finger, offset)
        pts.append(p[0])
        nrm.append(q[0])
    return np.concatenate(pts), np.concatenate(nrm)


def hand_transform(pose: np.ndarray, height: float) -> np.ndarray:
    """(N, 4, 4) hand frames of planar hand poses `(N, 3)` lifted to the push height `height`."""
    return tabletop_transform(pose, np.full(len(pose), 2.0 * height))


def _boundary_times(commanded: np.ndarray, yaw: float, steps: int, L: float) -> np.ndarray:
    """Fractional sample indices `(S + 1,)` where the commanded travel reaches 0, L, ... .

    Args:
        commanded: (T, 3) the commanded planar hand poses of one push.
        yaw: The push direction's world yaw.
        steps: Steps S.
        L: The step length (m).

    Returns:
        0, the samples (interpolated) where the travel along the push first reaches
        ``L, 2 L, ..., (S - 1) L``, and the last sample.
    """
    u = np.array([math.cos(yaw), math.sin(yaw)])
    travel = (commanded[:, :2] - commanded[0, :2]) @ u
    travel = np.maximum.accumulate(travel)
    marks = L * np.arange(1, steps)
    idx = np.arange(len(commanded), dtype=np.float64)
    if marks.size and travel[-1] < marks[-1]:
        raise InputError(
            f"the commanded hand travels {travel[-1]:.4f} m, less than {steps - 1} steps of "
            f"{L:g} m; use a longer step_length."
        )
    inner = np.interp(marks, travel, idx) if marks.size else np.zeros(0)
    return np.concatenate([[0.0], inner, [idx[-1]]])


def _at(values: np.ndarray, where: np.ndarray) -> np.ndarray:
    """`values (T, ...)` linearly interpolated at fractional sample indices `where (B,)`."""
    lo = np.floor(where).astype(int)
    hi = np.minimum(lo + 1, len(values) - 1)
    w = (where - lo).reshape(-1, *([1] * (values.ndim - 1)))
    return (1.0 - w) * values[lo] + w * values[hi]


def step_trajectories(
    ds: PushDataset,
    options: StepOptions | None = None,
    *,
    geometry: Ch6Geometry | None = None,
    reaction: bool = True,
) -> StepTrajectories:
    """Cut every push of a dataset at its step boundaries.

    Args:
        ds: A push dataset of cuboids recorded with trajectories.
        options: The step length (``StepOptions()`` if ``None``).
        geometry: The chapter 6 geometry, for the fingers' surface.
        reaction: Whether the caller needs the hand's reaction (a backward model): then the
            dataset must record ``traj_commanded`` (schema version 6). Without it, the
            commanded path is the straight push of ``push_origin``, ``push_yaw`` and
            ``push_distance``, timed by the recorded hand.

    Returns:
        The boundary poses of every push.

    Raises:
        InputError: For a step length that does not divide the pushes, a dataset without
            trajectories, a backward model asked of a dataset without ``traj_commanded``,
            circular objects, or NaN or inf in the trajectories.
    """
    options = StepOptions() if options is None else options
    if not isinstance(options, StepOptions):
        raise InputError(f"options must be a StepOptions, got {type(options).__name__}.")
    if not isinstance(ds, PushDataset):
        raise InputError(f"ds must be a PushDataset, got {type(ds).__name__}.")
    if len(ds) == 0:
        raise InputError("the dataset has no pushes; generate at least one.")
    steps = check_step_length(options.step_length, ds["push_distance"])
    assert steps is not None
    if not ds.has_trajectories:
        raise InputError(
            "stepped pushes need the recorded trajectories (traj_hand, traj_objects); "
            "regenerate the dataset without --no-trajectories."
        )
    if reaction and "traj_commanded" not in ds.arrays:
        raise InputError(
            "a backward model needs the hand's commanded path (array 'traj_commanded'), which "
            "this dataset lacks (schema version 1 or 2); regenerate it with this version of "
            "probaff, or fit the stepped model with backward=False."
        )
    geometry = resolve_geometry(geometry)
    sizes = box_sizes(ds)
    hand = np.asarray(ds["traj_hand"], dtype=np.float64)
    objects = np.asarray(ds["traj_objects"], dtype=np.float64)
    for name, arr in (("traj_hand", hand), ("traj_objects", objects)):
        if not np.isfinite(arr).all():
            raise InputError(f"{name} holds NaN or inf; regenerate the dataset.")
    yaw = np.asarray(ds["push_yaw"], dtype=np.float64)
    if "traj_commanded" in ds.arrays:
        commanded = np.asarray(ds["traj_commanded"], dtype=np.float64)
        if not np.isfinite(commanded).all():
            raise InputError("traj_commanded holds NaN or inf; regenerate the dataset.")
    else:  # the straight commanded push, timed by the hand's own travel
        u = np.column_stack([np.cos(yaw), np.sin(yaw)])
        along = np.einsum("ntj,nj->nt", hand[..., :2] - ds["push_origin"][:, None], u)
        along = np.clip(np.maximum.accumulate(along, axis=1), 0.0, ds["push_distance"][:, None])
        xy = ds["push_origin"][:, None] + along[..., None] * u[:, None]
        commanded = np.concatenate([xy, np.broadcast_to(yaw[:, None, None], xy[..., :1].shape)], 2)
    hand[..., 2] = np.unwrap(hand[..., 2], axis=1)
    commanded[..., 2] = np.unwrap(commanded[..., 2], axis=1)
    objects[..., 2] = np.unwrap(objects[..., 2], axis=1)
    n = len(ds)
    out_h = np.zeros((n, steps + 1, 3))
    out_c = np.zeros((n, steps + 1, 3))
    out_o = np.zeros((n, steps + 1, objects.shape[2], 3))
    for i in range(n):
        where = _boundary_times(commanded[i], yaw[i], steps, options.step_length)
        out_h[i], out_c[i], out_o[i] = (
            _at(hand[i], where),
            _at(commanded[i], where),
            _at(objects[i], where),
        )
    points, normals = finger_surface(ds, geometry)
    return StepTrajectories(
        out_h,
        out_c,
        out_o,
        sizes,
        yaw,
        points,
        normals,
        meta_float(ds, "push_height"),
        float(options.step_length),
    )


@dataclass(frozen=True)
class LinkSteps(InteractionRows):
    """Step rows of one kind of link (the hand on o1, or object k on object k + 1).

    Attributes:
        features: (n, D) the geometry's features f_t at each step's start.
        touches: (n,) whether the actor touches the target during the step's command.
        T_world_action: (n, 4, 4) the steps' action frames A_t.
        effect: (n, 3) the target's displacement over the step in A_t (`STEP_EFFECT_NAMES`).
        reaction: (n, 2) the actor's actual minus commanded position at t + 1 in A_t's
            ``(x, y)`` (m; `STEP_REACTION_NAMES`).
        push: (n,) the push (row of the trajectories) of each step.
        step: (n,) the step index t.
        actor: (n,) the acting object's index, -1 for the hand.
    """

    push: np.ndarray
    step: np.ndarray
    actor: np.ndarray

    def select(self, keep: np.ndarray) -> LinkSteps:
        """The rows where `keep (n,)` is true (or the indices `keep`)."""
        return LinkSteps(
            self.features[keep],
            self.touches[keep],
            self.T_world_action[keep],
            self.effect[keep],
            self.reaction[keep],
            self.push[keep],
            self.step[keep],
            self.actor[keep],
        )


def in_frame(T_a: np.ndarray, world_xy: np.ndarray) -> np.ndarray:
    """(n, 2) world offsets `world_xy (n, 2)` in the frames' `T_a (n, 4, 4)` (x, y)."""
    return np.einsum("nji,nj->ni", T_a[:, :2, :2], world_xy)


def _rows(
    geometry: Ch6Geometry,
    target_size: np.ndarray,
    target_before: np.ndarray,
    target_after: np.ndarray,
    actor_points: np.ndarray,
    actor_normals: np.ndarray,
    T_start: np.ndarray,
    T_command: np.ndarray,
    actual_end: np.ndarray,
) -> tuple[np.ndarray, ...]:
    """Features, touches, frames, effects (n, 3) and reactions (n, 2) of n steps."""
    T_b = tabletop_transform(target_before, target_size[:, 2])
    T_f = tabletop_transform(target_after, target_size[:, 2])
    t_pts, t_nrm = geometry.surface(target_size, T_b)
    X, touches, T_a = geometry.features(
        t_pts, t_nrm, actor_points, actor_normals, T_start, T_command
    )
    effect = effect_in_action_frame(T_a, T_b, T_f)[:, list(PLANAR_EFFECT_COLUMNS)]
    reaction = in_frame(T_a, actual_end[:, :2] - T_command[:, :2, 3])
    return X, touches, T_a, effect, reaction


def hand_steps(
    traj: StepTrajectories, geometry: Ch6Geometry | None = None, *, start: str = "actual"
) -> LinkSteps:
    """Step rows of the hand on o1: every step of every push.

    Args:
        traj: The pushes at their step boundaries (`step_trajectories`).
        geometry: The geometry the trajectories' fingers were sampled with.
        start: `HAND_STARTS`: where each step's hand motion starts, ``"actual"`` (the hand's
            recorded pose at t, as a rollout with reactions places it) or ``"commanded"``
            (its commanded pose at t: the planned piecewise-linear action, as a rollout
            without reactions places it).

    Returns:
        N S rows, push after push, step after step. The hand moves from its pose at t to its
        commanded pose at t + 1; o1's effect is its observed displacement.

    Raises:
        InputError: For an unknown `start`.
    """
    if start not in HAND_STARTS:
        raise InputError(f"unknown start {start!r}; use one of {list(HAND_STARTS)}.")
    geometry = resolve_geometry(geometry)
    n, s = len(traj), traj.n_steps
    push = np.repeat(np.arange(n), s)
    step = np.tile(np.arange(s), n)
    begin = traj.hand if start == "actual" else traj.commanded
    T_start = hand_transform(begin[push, step], traj.hand_height)
    T_cmd = hand_transform(traj.commanded[push, step + 1], traj.hand_height)
    pts = np.einsum("nij,qj->nqi", T_start[:, :3, :3], traj.finger_points) + T_start[:, None, :3, 3]
    nrm = np.einsum("nij,qj->nqi", T_start[:, :3, :3], traj.finger_normals)
    X, touches, T_a, effect, reaction = _rows(
        geometry,
        traj.sizes[push, 0],
        traj.objects[push, step, 0],
        traj.objects[push, step + 1, 0],
        pts,
        nrm,
        T_start,
        T_cmd,
        traj.hand[push, step + 1],
    )
    return LinkSteps(X, touches, T_a, effect, reaction, push, step, np.full(len(push), -1))


def link_steps(
    traj: StepTrajectories,
    actor: int,
    commanded: np.ndarray,
    geometry: Ch6Geometry | None = None,
    min_action: float = 1e-3,
) -> LinkSteps:
    """Step rows of object `actor` acting on object ``actor + 1``.

    Args:
        traj: The pushes at their step boundaries.
        actor: The acting object k (0 .. K - 2).
        commanded: (N, S, 3) the actor's commanded planar pose at the end of every step:
            its pose at t moved by the upstream link's predicted effect.
        geometry: The geometry the models read.
        min_action: Shortest commanded motion (m) that makes a row.

    Returns:
        The rows of the steps whose commanded actor motion is at least `min_action`; the
        actor's reaction is its observed pose at t + 1 minus `commanded`.

    Raises:
        InputError: For an actor without a next object or a malformed `commanded`.
    """
    geometry = resolve_geometry(geometry)
    check_positive("min_action", min_action)
    n, s, k = len(traj), traj.n_steps, traj.n_objects
    if not 0 <= actor < k - 1:
        raise InputError(f"actor must be an object with a next one, 0 .. {k - 2}; got {actor}.")
    cmd = np.asarray(commanded, dtype=np.float64)
    if cmd.shape != (n, s, 3):
        raise InputError(f"commanded must be (N, S, 3) = {(n, s, 3)}, got {cmd.shape}.")
    push = np.repeat(np.arange(n), s)
    step = np.tile(np.arange(s), n)
    start = traj.objects[push, step, actor]
    end = cmd.reshape(-1, 3)
    keep = np.linalg.norm(end[:, :2] - start[:, :2], axis=1) >= min_action
    push, step, start, end = push[keep], step[keep], start[keep], end[keep]
    size = traj.sizes[push, actor]
    T_start = tabletop_transform(start, size[:, 2]) if len(push) else np.zeros((0, 4, 4))
    if len(push) == 0:
        d = geometry.n_features
        return LinkSteps(
            np.zeros((0, d)),
            np.zeros(0, bool),
            np.zeros((0, 4, 4)),
            np.zeros((0, 3)),
            np.zeros((0, 2)),
            push,
            step,
            np.zeros(0, int),
        )
    T_cmd = tabletop_transform(end, size[:, 2])
    a_pts, a_nrm = geometry.surface(size, T_start)
    X, touches, T_a, effect, reaction = _rows(
        geometry,
        traj.sizes[push, actor + 1],
        traj.objects[push, step, actor + 1],
        traj.objects[push, step + 1, actor + 1],
        a_pts,
        a_nrm,
        T_start,
        T_cmd,
        traj.objects[push, step + 1, actor],
    )
    return LinkSteps(X, touches, T_a, effect, reaction, push, step, np.full(len(push), actor))
