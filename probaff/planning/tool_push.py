"""Chapter 5's two-step tool push: push one box into another to bring it within reach.

The scene (``worlds/scenes/tool_push.yaml``) holds two boxes: the *tool* (o1), which the arm
pushes, and the *target* (o2), which lies outside the reachable region. The planner of the
thesis (Section 5.5.4, Figure 5.7):

1. samples `n_first` (100) pushes of the tool and keeps the `n_keep` (10) that leave the two
   boxes closest (centre to centre, predicted);
2. samples `n_second` (100) more pushes of the tool from each kept predicted state;
3. takes the two-push sequence whose predicted final state puts the target furthest into the
   reachable region.

Every candidate's effect is predicted in one batched call per step (`n_first` queries, then
`n_keep * n_second`), by a `TransitionModel`: `ModelTransition` (a fitted chapter-5 mixture
predicting both objects' pushing-frame effects, through `FeaturePushModel`) or `SimTransition`
(the simulator itself with nominal masses and frictions, the oracle baseline). A learned
model's prediction is its predictive mean, which blends its experts where the gate is unsure
(e.g. whether the tool will hit the target). The plan is then
executed open loop, as in the thesis, by `PushSimulator.execute` (IK and physics) in an
episode whose masses, frictions and pressure distributions are drawn once per trial and are
unknown to the planner.

Reachable region. A single arm cannot do this task: a push that starts within its reach moves
objects away from it, so a target beyond its reach is never pushed back in. As on the thesis's
PR2, which pushed with one arm into the workspace of the other, the region is the reach of a
*receiving* arm: a second mount of the world's URDF arm at ``ToolPushConfig.goal_base_xy``
(default world (-1.0, 0.0), beside the table's -x end). A table point is reachable where IK
can point that arm's tool straight down at it at push height with any of
``ToolPushConfig.region_yaws`` yaws (`Arm.reachable_mask`), i.e. where the arm can grasp an
object from above. The mask is computed once per process on a grid over the table (cells
beyond the table edge count as unreachable), and its signed distance field (metres, positive
inside) scores how deep the target's centre lies in the region. Pushes are executed by the
world's arm (``worlds/tabletop.yaml``); candidate pushes are only those whose whole straight
path it can follow (`Arm.solve_pushes`, batched over all candidates of a step). That arm could
reach the target too; the task is tool use, so only the tool is ever pushed.

Unreachable goals. Two pushes move the target at most 2 d_p, so the planners refuse a state
whose target lies further than that outside the region (`InputError`); trials draw start
states whose target lies between ``min_outside`` and ``max_outside`` outside it.

Candidate pushes follow the scene's push skill, like `probaff.sim.sampling.sample_scene`: a
direction from ``push.direction``, a lateral offset of the push line from the tool's centre
from ``push.lateral_offset`` and a gap between the fingers and the tool from
``push.start_gap``; d_p is ``push.distance`` (0.25 m). Both pushes of a sequence push the
tool.

Planners (`TOOL_PUSH_PLANNERS`): ``"two_step"`` (the thesis planner with a learned model),
``"single_step"`` (the best of `n_first` single pushes by the same criterion), ``"random"`` (two
random reachable pushes, the second drawn around the tool's observed pose after the first)
and ``"two_step_sim"`` (the two-step planner with `SimTransition`; each candidate is a full
physics rollout, so it samples ``sim_n_first``, ``sim_n_keep`` and ``sim_n_second``
candidates instead of 100, 10 and 100).

Frames: poses are world ``(x, y, theta)`` (table centre at the origin, z up); pushes are a hand
start ``(x, y)`` and the world yaw of z_p. Every trial is deterministic given its seed.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass
from functools import lru_cache
from typing import Any, Protocol, runtime_checkable

import numpy as np
import pymunk
import torch
from scipy import ndimage
from torch.distributions import Distribution

from probaff._checks import check_count, check_finite, check_positive, check_shape
from probaff._threads import torch_threads
from probaff.data.queries import PushQueries
from probaff.data.schema import PushDataset
from probaff.errors import ConfigError, InputError, UnreachablePoseError
from probaff.features.ch5 import chapter5_features
from probaff.models import MixtureOfGPExperts, fit_em
from probaff.planning.learned import FeaturePushModel, apply_effects
from probaff.sim.arm import Arm, load_arm
from probaff.sim.config import (
    ArmSpec,
    ObjectSpec,
    SceneSpec,
    TabletopSpec,
    load_catalogue,
    load_scene,
    load_tabletop,
)
from probaff.sim.geometry import footprint_support
from probaff.sim.runner import PushSimulator, straight_path
from probaff.sim.sampling import sample_scene
from probaff.sim.tabletop import SceneInstance, simulate_push

__all__ = [
    "TOOL_PUSH_PLANNERS",
    "ModelTransition",
    "ReachableRegion",
    "SimTransition",
    "ToolPushCandidates",
    "ToolPushConfig",
    "ToolPushPlan",
    "ToolPushState",
    "ToolPushTrial",
    "TransitionModel",
    "draw_tool_push_episode",
    "fit_tool_push_model",
    "plan_random_push",
    "plan_single_push",
    "plan_tool_push",
    "reachable_region",
    "run_tool_push_trial",
    "sample_tool_pushes",
    "tool_push_scores",
]

TOOL_PUSH_PLANNERS = ("random", "single_step", "two_step", "two_step_sim")
"""Planners `run_tool_push_trial` runs, by name."""

_CLEARANCE = 0.003  # gap (m) the hand's start pose keeps from every object, as in sample_scene
_OVERLAP = 0.002  # deeper interpenetration (m) of the two footprints is an overlap
_MAX_ROUNDS = 6  # draws of candidate pushes before a state is declared unpushable
_N_OBJECTS = 2


@dataclass(frozen=True)
class ToolPushConfig:
    """Settings of the tool-push task and its planners (each default written once, here).

    Attributes:
        scene: Scene template of the start states and the pushes.
        n_first: Pushes of the tool sampled at the start state (thesis: 100).
        n_keep: Of those, the ones kept because they leave the boxes closest (thesis: 10).
        n_second: Pushes sampled from each kept predicted state (thesis: 100).
        sim_n_first: `n_first` of ``"two_step_sim"``, whose transitions are physics rollouts.
        sim_n_keep: `n_keep` of ``"two_step_sim"``.
        sim_n_second: `n_second` of ``"two_step_sim"``.
        goal_base_xy: World ``(x, y)`` of the receiving arm's base (m); its reach is the
            reachable region.
        region_resolution: Grid spacing of the region's IK mask (m).
        region_yaws: Tool yaws tried per grid point; a point is reachable with any of them.
        min_outside: A start state's target lies at least this far outside the region (m).
        max_outside: ... and at most this far (m); two pushes of d_p cannot move it further
            than 2 d_p.
        max_draws: Scene draws tried for one episode before giving up.
    """

    scene: str = "tool_push"
    n_first: int = 100
    n_keep: int = 10
    n_second: int = 100
    sim_n_first: int = 24
    sim_n_keep: int = 4
    sim_n_second: int = 12
    goal_base_xy: tuple[float, float] = (-1.0, 0.0)
    region_resolution: float = 0.02
    region_yaws: int = 2
    min_outside: float = 0.03
    max_outside: float = 0.25
    max_draws: int = 500

    def __post_init__(self) -> None:
        for name in (
            "n_first",
            "n_keep",
            "n_second",
            "sim_n_first",
            "sim_n_keep",
            "sim_n_second",
            "region_yaws",
            "max_draws",
        ):
            object.__setattr__(
                self, name, check_count(f"ToolPushConfig.{name}", getattr(self, name))
            )
        for first, keep in (("n_first", "n_keep"), ("sim_n_first", "sim_n_keep")):
            if getattr(self, keep) > getattr(self, first):
                raise InputError(
                    f"ToolPushConfig.{keep}={getattr(self, keep)} exceeds {first}="
                    f"{getattr(self, first)}; keep at most as many first pushes as are sampled."
                )
        if not isinstance(self.scene, str) or not self.scene:
            raise InputError(f"ToolPushConfig.scene must be a scene name, got {self.scene!r}.")
        base = tuple(self.goal_base_xy) if isinstance(self.goal_base_xy, (tuple, list)) else ()
        if len(base) != 2:
            raise InputError(
                f"ToolPushConfig.goal_base_xy must be a world (x, y) pair, got "
                f"{self.goal_base_xy!r}."
            )
        check_finite("ToolPushConfig.goal_base_xy", np.asarray(base, dtype=float))
        object.__setattr__(self, "goal_base_xy", (float(base[0]), float(base[1])))
        check_positive("ToolPushConfig.region_resolution", self.region_resolution)
        check_positive("ToolPushConfig.min_outside", self.min_outside, allow_zero=True)
        check_positive("ToolPushConfig.max_outside", self.max_outside)
        if self.min_outside > self.max_outside:
            raise InputError(
                f"ToolPushConfig.min_outside={self.min_outside} exceeds max_outside="
                f"{self.max_outside}; swap them."
            )


def _config(config: Any) -> ToolPushConfig:
    """`config`, the defaults for ``None``, or `InputError` for anything else."""
    if config is None:
        return ToolPushConfig()
    if not isinstance(config, ToolPushConfig):
        raise InputError(
            f"config must be a ToolPushConfig (or None for the defaults), got "
            f"{type(config).__name__}."
        )
    return config


def _check_rng(rng: Any) -> np.random.Generator:
    if not isinstance(rng, np.random.Generator):
        raise InputError(
            f"rng must be a numpy.random.Generator (np.random.default_rng(seed)), got "
            f"{type(rng).__name__}."
        )
    return rng


# ----------------------------------------------------------------------------- the region


@dataclass(frozen=True, eq=False)
class ReachableRegion:
    """The receiving arm's reachable region of the table and its signed distance field.

    Attributes:
        mask: (H, W) bool, indexed ``[iy, ix]``: the tool can point down at the grid point.
        xs: (W,) world x of the grid columns (m).
        ys: (H,) world y of the grid rows (m).
        sdf: (H, W) signed distance to the region's boundary (m): positive inside, negative
            outside. The table edge bounds the region.
        resolution: Grid spacing (m).
        base_xy: World ``(x, y)`` of the receiving arm's base.
    """

    mask: np.ndarray
    xs: np.ndarray
    ys: np.ndarray
    sdf: np.ndarray
    resolution: float
    base_xy: tuple[float, float]

    def depth(self, xy: np.ndarray) -> np.ndarray:
        """Signed distance of world points into the region (bilinear in the grid).

        Args:
            xy: (..., 2) world positions (m).

        Returns:
            (...,) metres; positive inside the region, negative outside. Beyond the grid,
            the value at the nearest grid point minus the distance to it.

        Raises:
            InputError: For a last axis that is not 2 or a NaN.
        """
        pts = np.asarray(xy, dtype=float)
        check_shape("xy", pts, (*(None,) * (pts.ndim - 1), 2))
        check_finite("xy", pts)
        fx = (pts[..., 0] - self.xs[0]) / self.resolution
        fy = (pts[..., 1] - self.ys[0]) / self.resolution
        cx = np.clip(fx, 0.0, len(self.xs) - 1.0)
        cy = np.clip(fy, 0.0, len(self.ys) - 1.0)
        inside = ndimage.map_coordinates(
            self.sdf, [cy.ravel(), cx.ravel()], order=1, mode="nearest"
        ).reshape(cx.shape)
        return np.asarray(inside - self.resolution * np.hypot(fx - cx, fy - cy))

    def contains(self, xy: np.ndarray) -> np.ndarray:
        """Whether world points lie inside the region.

        Args:
            xy: (..., 2) world positions (m).

        Returns:
            (...,) bool.
        """
        return self.depth(xy) > 0.0


def _goal_arm_spec(world: TabletopSpec, base_xy: tuple[float, float]) -> ArmSpec:
    return dataclasses.replace(world.arm, base_xyz=(base_xy[0], base_xy[1], world.arm.base_xyz[2]))


@lru_cache(maxsize=8)
def _region(
    world: TabletopSpec, base_xy: tuple[float, float], resolution: float, n_yaws: int
) -> ReachableRegion:
    arm = load_arm(_goal_arm_spec(world, base_xy))
    hx, hy = 0.5 * world.table_size[0], 0.5 * world.table_size[1]
    mask, xs, ys = arm.reachable_mask((-hx, hx), (-hy, hy), resolution, n_yaws, "any")
    padded = np.pad(mask, 1, constant_values=False)  # off the table is out of reach
    inside = ndimage.distance_transform_edt(padded)[1:-1, 1:-1] * resolution
    outside = ndimage.distance_transform_edt(~padded)[1:-1, 1:-1] * resolution
    sdf = np.where(mask, inside - 0.5 * resolution, -(outside - 0.5 * resolution))
    for arr in (mask, xs, ys, sdf):
        arr.setflags(write=False)
    return ReachableRegion(mask=mask, xs=xs, ys=ys, sdf=sdf, resolution=resolution, base_xy=base_xy)


def reachable_region(config: ToolPushConfig | None = None) -> ReachableRegion:
    """The reachable region of the task: the receiving arm's reach on the table.

    Computed from the arm's IK once per process and configuration (the mask is cached by
    `Arm.reachable_mask` and the distance field here).

    Args:
        config: Task settings (`goal_base_xy`, `region_resolution`, `region_yaws`).

    Returns:
        The region and its signed distance field.
    """
    config = _config(config)
    return _region(
        load_tabletop(), config.goal_base_xy, float(config.region_resolution), config.region_yaws
    )


# ------------------------------------------------------------------------------ the state


def _shape(space: pymunk.Space, obj: ObjectSpec, pose: np.ndarray, margin: float) -> pymunk.Shape:
    body = pymunk.Body(body_type=pymunk.Body.KINEMATIC)
    body.position, body.angle = (float(pose[0]), float(pose[1])), float(pose[2])
    if obj.shape == "circle":
        shape: pymunk.Shape = pymunk.Circle(body, obj.radius + margin)
    else:
        shape = pymunk.Poly.create_box(body, obj.size, radius=margin)
    space.add(body, shape)
    return shape


@dataclass(frozen=True, eq=False)
class ToolPushState:
    """What the planner knows of a scene: the two boxes and their poses.

    Attributes:
        objects: ``(tool, target)`` catalogue specs; the tool (o1) is the one pushed.
        poses: (2, 3) world ``(x, y, theta)`` of the tool and the target.

    Raises:
        InputError: For anything but two objects, a pose array that is not a finite (2, 3),
            a centre off the table, or footprints that overlap (by more than 2 mm: objects
            at rest against each other interpenetrate slightly in the physics).
    """

    objects: tuple[ObjectSpec, ...]
    poses: np.ndarray

    def __post_init__(self) -> None:
        objects = tuple(self.objects) if isinstance(self.objects, (tuple, list)) else ()
        if len(objects) != _N_OBJECTS or not all(isinstance(o, ObjectSpec) for o in objects):
            raise InputError(
                "ToolPushState.objects must be the (tool, target) pair of ObjectSpec from "
                f"load_catalogue(), got {self.objects!r}."
            )
        poses = np.array(self.poses, dtype=float)
        check_shape("ToolPushState.poses", poses, (_N_OBJECTS, 3))
        check_finite("ToolPushState.poses", poses)
        poses.setflags(write=False)
        object.__setattr__(self, "objects", objects)
        object.__setattr__(self, "poses", poses)
        hx, hy = (0.5 * s for s in load_tabletop().table_size)
        for k, name in enumerate(("tool", "target")):
            if abs(poses[k, 0]) > hx or abs(poses[k, 1]) > hy:
                raise InputError(
                    f"ToolPushState: the {name}'s centre ({poses[k, 0]:.3f}, {poses[k, 1]:.3f}) "
                    f"is off the {2 * hx:.2f} x {2 * hy:.2f} m table; place it on the table."
                )
        space = pymunk.Space()
        tool = _shape(space, objects[0], poses[0], 0.0)
        _shape(space, objects[1], poses[1], 0.0)
        depth = [p.distance for h in space.shape_query(tool) for p in h.contact_point_set.points]
        if depth and min(depth) < -_OVERLAP:
            raise InputError(
                f"ToolPushState: the tool ({objects[0].name}) and the target "
                f"({objects[1].name}) overlap at poses {poses.tolist()}; move them apart."
            )


# ------------------------------------------------------------------------- candidates


@dataclass(frozen=True)
class _Context:
    """What every planner reads, built once per configuration."""

    scene: SceneSpec
    world: TabletopSpec
    arm: Arm
    region: ReachableRegion


@lru_cache(maxsize=8)
def _context(config: ToolPushConfig) -> _Context:
    scene = load_scene(config.scene)
    world = load_tabletop()
    if len(scene.objects) != _N_OBJECTS:
        raise ConfigError(
            f"scene {config.scene!r} has {len(scene.objects)} objects; the tool push needs a "
            "tool and a target (see worlds/scenes/tool_push.yaml)."
        )
    return _Context(scene, world, load_arm(world.arm), reachable_region(config))


@dataclass(frozen=True)
class ToolPushCandidates:
    """Candidate pushes of the tool, from one or more states.

    Attributes:
        origin: (C, 2) world hand starts (m).
        yaw: (C,) world yaws of z_p (rad).
        state: (C,) index of the state each candidate pushes from.
    """

    origin: np.ndarray
    yaw: np.ndarray
    state: np.ndarray

    def __len__(self) -> int:
        return len(self.yaw)


def _hand_free(
    objects: tuple[ObjectSpec, ...],
    poses: np.ndarray,
    start: np.ndarray,
    yaw: np.ndarray,
    world: TabletopSpec,
) -> np.ndarray:
    """(M,) whether each hand start pose keeps clear of every object of one state."""
    space = pymunk.Space()
    for obj, pose in zip(objects, poses, strict=True):
        _shape(space, obj, pose, _CLEARANCE)
    g = world.gripper
    size = (2 * g.finger_radius, g.push_opening + 2 * g.finger_radius)
    free = np.empty(len(yaw), dtype=bool)
    for i in range(len(yaw)):
        body = pymunk.Body(body_type=pymunk.Body.KINEMATIC)
        body.position, body.angle = (float(start[i, 0]), float(start[i, 1])), float(yaw[i])
        hand = pymunk.Poly.create_box(body, size, radius=_CLEARANCE)
        space.add(body, hand)
        free[i] = not space.shape_query(hand)
        space.remove(body, hand)
    return free


def sample_tool_pushes(
    objects: Sequence[ObjectSpec],
    poses: np.ndarray,
    n: int,
    rng: np.random.Generator,
    config: ToolPushConfig | None = None,
    *,
    allow_empty: bool = False,
) -> ToolPushCandidates:
    """Sample reachable pushes of the tool (object 0), aimed near its centre.

    As `sample_scene` draws a push: a direction from the scene's ``push.direction``, a lateral
    offset of the push line from ``push.lateral_offset`` and a finger gap from
    ``push.start_gap``; the hand starts that gap behind the tool's footprint. A candidate is
    kept if the hand's start pose clears every object and the world's arm can follow the
    whole push of ``push.distance`` (`Arm.solve_pushes`, one batch per round for all states).

    Args:
        objects: The (tool, target) catalogue specs.
        poses: (K, 3) one state, or (S, K, 3) several, world ``(x, y, theta)``.
        n: Candidates per state (a positive integer).
        rng: Source of randomness.
        config: Task settings (the scene).
        allow_empty: Return no candidates for a state the arm cannot push from, instead of
            raising.

    Returns:
        Up to `n` candidates per state (fewer only where valid pushes are rare), grouped by
        state in order.

    Raises:
        InputError: For a bad `n` or pose array.
        UnreachablePoseError: If a state has no reachable push and not `allow_empty`.
    """
    n = check_count("n", n)
    ctx = _context(_config(config))
    _check_rng(rng)
    given = objects
    objects = tuple(objects) if isinstance(objects, (tuple, list)) else ()
    if not objects or not all(isinstance(o, ObjectSpec) for o in objects):
        raise InputError(
            "objects must be the (tool, target) ObjectSpec of load_catalogue(), the tool "
            f"first, got {given!r}."
        )
    P = np.asarray(poses, dtype=float)
    P = P[None] if P.ndim == 2 else P
    check_shape("poses", P, (None, len(objects), 3))
    check_finite("poses", P)
    S, push = P.shape[0], ctx.scene.push
    tool, fr = objects[0], ctx.world.gripper.finger_radius
    kept: list[list[tuple[np.ndarray, float]]] = [[] for _ in range(S)]
    for _ in range(_MAX_ROUNDS):
        need = [n - len(k) for k in kept]
        rows = [s for s in range(S) if need[s] > 0]
        if not rows:
            break
        starts, yaws, owner = [], [], []
        for s in rows:
            m = math.ceil(1.5 * need[s]) + 4
            phi = rng.uniform(*push.direction, size=m)
            offset = rng.uniform(*push.lateral_offset, size=m)
            gap = rng.uniform(*push.start_gap, size=m)
            d = np.stack([np.cos(phi), np.sin(phi)], -1)
            yp = np.stack([-d[:, 1], d[:, 0]], -1)
            back = np.array([footprint_support(tool, P[s, 0, 2], -di) for di in d]) + fr + gap
            start = P[s, 0, :2] + offset[:, None] * yp - back[:, None] * d
            free = _hand_free(objects, P[s], start, phi, ctx.world)
            starts.append(start[free])
            yaws.append(phi[free])
            owner.append(np.full(int(free.sum()), s))
        start_all, yaw_all = np.concatenate(starts), np.concatenate(yaws)
        owner_all = np.concatenate(owner)
        if len(yaw_all) == 0:
            continue
        ok = ctx.arm.solve_pushes(
            torch.as_tensor(start_all), torch.as_tensor(yaw_all), push.distance
        ).ok.numpy()
        for i in np.flatnonzero(ok):
            s = int(owner_all[i])
            if len(kept[s]) < n:
                kept[s].append((start_all[i], float(yaw_all[i])))
    empty = [s for s in range(S) if not kept[s]]
    if empty and not allow_empty:
        x, y = P[empty[0], 0, :2]
        raise UnreachablePoseError(
            f"no push of the tool at ({x:.3f}, {y:.3f}) is reachable by the arm (base at "
            f"{ctx.world.arm.base_xyz[:2]}) within the scene's push directions "
            f"{push.direction}; place the tool closer to the arm."
        )
    origin = np.array([o for k in kept for o, _ in k], dtype=float).reshape(-1, 2)
    yaw = np.array([a for k in kept for _, a in k], dtype=float)
    state = np.repeat(np.arange(S), [len(k) for k in kept])
    return ToolPushCandidates(origin, yaw, state)


# ------------------------------------------------------------------------ transitions


@runtime_checkable
class TransitionModel(Protocol):
    """Predicts the world poses after candidate pushes, all candidates in one call."""

    def predict_poses(
        self,
        objects: tuple[ObjectSpec, ...],
        poses: np.ndarray,
        push_origin: np.ndarray,
        push_yaw: np.ndarray,
        push_distance: float,
        rng: np.random.Generator,
    ) -> np.ndarray:
        """Poses after each candidate push.

        Args:
            objects: The K catalogue objects; the first is the pushed one.
            poses: (C, K, 3) world poses before each candidate.
            push_origin: (C, 2) world hand starts.
            push_yaw: (C,) world yaws of z_p.
            push_distance: d_p (m).
            rng: Randomness (e.g. of the sensed clouds).

        Returns:
            (C, K, 3) world poses after.
        """
        ...


class _QueryModel(Protocol):
    @property
    def cloud_points(self) -> int: ...
    @property
    def cloud_noise(self) -> float: ...

    def predict(self, queries: PushQueries) -> Distribution: ...


@dataclass(frozen=True)
class ModelTransition:
    """A learned transition: a chapter-5 model of both objects' pushing-frame effects.

    Each call senses one cloud per object (`PushQueries.from_states`, moved rigidly to every
    candidate's state), stacks every candidate into one query batch and asks the model once;
    the predictive mean of ``(dy_p, dz_p, dtheta_p)`` of o1 and o2 is mapped back to world
    poses with `apply_effects`.

    Attributes:
        model: A `FeaturePushModel` (or anything with its ``predict(queries)``,
            ``cloud_points`` and ``cloud_noise``) predicting 6 effects.
        world: The tabletop world (its geometry goes into the queries).
    """

    model: _QueryModel
    world: TabletopSpec

    def __post_init__(self) -> None:
        m = self.model
        needs = ("cloud_points", "cloud_noise")
        if not callable(getattr(m, "predict", None)) or not all(hasattr(m, a) for a in needs):
            raise InputError(
                "ModelTransition.model must be a fitted chapter-5 model with its features, a "
                f"FeaturePushModel (fit_tool_push_model), got {type(m).__name__}."
            )
        _check_world("ModelTransition", self.world)

    def predict_poses(
        self,
        objects: tuple[ObjectSpec, ...],
        poses: np.ndarray,
        push_origin: np.ndarray,
        push_yaw: np.ndarray,
        push_distance: float,
        rng: np.random.Generator,
    ) -> np.ndarray:
        """See `TransitionModel.predict_poses`.

        Raises:
            InputError: If the model does not predict 3 effects per object, or was fitted on
                other features (from `FeaturePushModel`).
        """
        poses = np.asarray(poses, dtype=float)
        C, K = poses.shape[:2]
        queries = PushQueries.from_states(
            objects,
            poses,
            push_origin,
            push_yaw,
            push_distance,
            self.world,
            rng,
            cloud_points=self.model.cloud_points,
            cloud_noise=self.model.cloud_noise,
        )
        pred = self.model.predict(queries)
        mean = pred.mean.detach().cpu().numpy()
        if not np.isfinite(mean).all():
            inner = getattr(self.model, "model", self.model)
            raise InputError(
                f"the push model {type(inner).__name__} predicted NaN or infinite effects for "
                f"{C} candidate push(es): its predictions are not finite; refit the model or "
                "check its inputs (features, training data)."
            )
        if mean.shape != (C, 3 * K):
            raise InputError(
                f"the push model predicts effects of shape {mean.shape[1:]}, but the tool push "
                f"needs (dy_p, dz_p, dtheta_p) of each of the {K} objects ({3 * K}); fit it on "
                "ds['effect'][:, :2].reshape(N, 6) of a two-object scene (fit_tool_push_model)."
            )
        return apply_effects(poses, mean.reshape(C, K, 3), push_yaw)


@dataclass(frozen=True)
class SimTransition:
    """The true simulator as a transition model, with nominal masses and frictions.

    Each candidate is a `simulate_push` rollout along `straight_path` (the ideal hand path,
    without the arm), with the catalogue's nominal parameters and uniform pressure; the
    episode's randomised parameters stay unknown.

    Attributes:
        world: The tabletop world.
    """

    world: TabletopSpec

    def __post_init__(self) -> None:
        _check_world("SimTransition", self.world)

    def predict_poses(
        self,
        objects: tuple[ObjectSpec, ...],
        poses: np.ndarray,
        push_origin: np.ndarray,
        push_yaw: np.ndarray,
        push_distance: float,
        rng: np.random.Generator,
    ) -> np.ndarray:
        """See `TransitionModel.predict_poses` (`rng` is unused: physics is deterministic)."""
        out = np.empty_like(np.asarray(poses, dtype=float))
        for c in range(len(push_yaw)):
            scene = SceneInstance.nominal(
                objects,
                poses[c],
                push_origin[c],
                float(push_yaw[c]),
                push_distance,
                self.world.physics.friction_grid,
            )
            path = straight_path(self.world, push_origin[c], float(push_yaw[c]), push_distance)
            out[c] = simulate_push(self.world, scene, path).state_after
        return out


def _check_world(owner: str, world: Any) -> None:
    if not isinstance(world, TabletopSpec):
        raise InputError(
            f"{owner}.world must be the tabletop world, a TabletopSpec (load_tabletop()), got "
            f"{type(world).__name__}."
        )


# ---------------------------------------------------------------------------- planning


@dataclass(frozen=True)
class ToolPushPlan:
    """A planned push sequence.

    Attributes:
        push_origin: (S, 2) world hand starts, in order (S = 1 or 2).
        push_yaw: (S,) world yaws of z_p.
        predicted: (S, 2, 3) predicted world poses of (tool, target) after each push.
        predicted_depth: Predicted final signed distance of the target into the region (m).
        planning_time_s: Wall-clock seconds spent planning.
        transition_calls: Calls to the transition model (one per step).
        n_candidates: Candidates evaluated at each step.
    """

    push_origin: np.ndarray
    push_yaw: np.ndarray
    predicted: np.ndarray
    predicted_depth: float
    planning_time_s: float
    transition_calls: int
    n_candidates: tuple[int, ...]


def _check_state(state: ToolPushState, ctx: _Context) -> None:
    if not isinstance(state, ToolPushState):
        raise InputError(
            f"state must be a ToolPushState (objects and poses), got {type(state).__name__}."
        )
    depth = float(ctx.region.depth(state.poses[1, :2]))
    bound = 2 * ctx.scene.push.distance
    if depth < -bound:
        raise InputError(
            f"the target at ({state.poses[1, 0]:.3f}, {state.poses[1, 1]:.3f}) lies "
            f"{-depth:.3f} m outside the reachable region; two pushes of d_p = "
            f"{ctx.scene.push.distance} m move it at most {bound:.2f} m, so it cannot be brought "
            "within reach: place it closer to the receiving arm (ToolPushConfig.goal_base_xy)."
        )


def _check_transition(transition: TransitionModel) -> None:
    if not isinstance(transition, TransitionModel):
        raise InputError(
            "transition must have predict_poses(objects, poses, push_origin, push_yaw, "
            f"push_distance, rng) (ModelTransition or SimTransition), got "
            f"{type(transition).__name__}."
        )


def _predict(
    transition: TransitionModel,
    state: ToolPushState,
    poses: np.ndarray,
    cand: ToolPushCandidates,
    ctx: _Context,
    rng: np.random.Generator,
) -> np.ndarray:
    out = np.asarray(
        transition.predict_poses(
            state.objects, poses, cand.origin, cand.yaw, ctx.scene.push.distance, rng
        ),
        dtype=float,
    )
    who = type(transition).__name__
    if out.shape != poses.shape:
        raise InputError(
            f"the transition model {who} predicted poses of shape {out.shape}, expected "
            f"{poses.shape}; make predict_poses return (C, K, 3) world poses."
        )
    bad = int(out.size - np.count_nonzero(np.isfinite(out)))
    if bad:
        raise InputError(
            f"the transition model {who} predicted {bad} NaN or infinite value(s) for "
            f"{len(cand)} candidate push(es): its predictions are not finite; refit the model "
            "or check its inputs (features, training data)."
        )
    return out


def plan_tool_push(
    transition: TransitionModel,
    state: ToolPushState,
    rng: np.random.Generator,
    config: ToolPushConfig | None = None,
    *,
    sizes: tuple[int, int, int] | None = None,
) -> ToolPushPlan:
    """The thesis's two-step planner.

    Args:
        transition: Predicts the poses after candidate pushes (one call per step).
        state: The start state.
        rng: Source of randomness (candidates, sensed clouds).
        config: Task settings.
        sizes: ``(n_first, n_keep, n_second)``; defaults to the config's.

    Returns:
        Two pushes (one if no kept state can be pushed again), with their predictions.

    Raises:
        InputError: For a bad transition, state or sizes, or a target that two pushes
            cannot bring within reach.
        UnreachablePoseError: If the arm can push the tool in no sampled direction.
    """
    config = _config(config)
    ctx = _context(config)
    _check_transition(transition)
    _check_state(state, ctx)
    _check_rng(rng)
    if sizes is None:
        sizes = (config.n_first, config.n_keep, config.n_second)
    if not isinstance(sizes, (tuple, list)) or len(sizes) != 3:
        raise InputError(f"sizes must be (n_first, n_keep, n_second), got {sizes!r}.")
    n_first, n_keep, n_second = (
        check_count(name, v)
        for name, v in zip(("n_first", "n_keep", "n_second"), sizes, strict=True)
    )
    if n_keep > n_first:
        raise InputError(
            f"sizes: n_keep={n_keep} exceeds n_first={n_first}; keep at most as many first "
            "pushes as are sampled."
        )
    start = time.perf_counter()
    first = sample_tool_pushes(state.objects, state.poses, n_first, rng, config)
    before = np.broadcast_to(state.poses, (len(first), *state.poses.shape))
    after1 = _predict(transition, state, before, first, ctx, rng)
    gap = np.linalg.norm(after1[:, 0, :2] - after1[:, 1, :2], axis=-1)
    keep = np.argsort(gap, kind="stable")[:n_keep]
    second = sample_tool_pushes(
        state.objects, after1[keep], n_second, rng, config, allow_empty=True
    )
    if len(second) == 0:
        depth1 = ctx.region.depth(after1[:, 1, :2])
        j = int(np.argmax(depth1))
        return ToolPushPlan(
            first.origin[j : j + 1],
            first.yaw[j : j + 1],
            after1[j : j + 1],
            float(depth1[j]),
            time.perf_counter() - start,
            1,
            (len(first),),
        )
    after2 = _predict(transition, state, after1[keep][second.state], second, ctx, rng)
    depth = ctx.region.depth(after2[:, 1, :2])
    best = int(np.argmax(depth))
    j = int(keep[second.state[best]])
    return ToolPushPlan(
        np.stack([first.origin[j], second.origin[best]]),
        np.array([first.yaw[j], second.yaw[best]]),
        np.stack([after1[j], after2[best]]),
        float(depth[best]),
        time.perf_counter() - start,
        2,
        (len(first), len(second)),
    )


def plan_single_push(
    transition: TransitionModel,
    state: ToolPushState,
    rng: np.random.Generator,
    config: ToolPushConfig | None = None,
    *,
    n: int | None = None,
) -> ToolPushPlan:
    """The best single push: of `n` candidates, the one predicted to put the target deepest.

    Args:
        transition: Predicts the poses after candidate pushes (one call).
        state: The start state.
        rng: Source of randomness.
        config: Task settings.
        n: Candidates; defaults to the config's `n_first`.

    Returns:
        One push with its prediction.

    Raises:
        InputError: As `plan_tool_push`.
        UnreachablePoseError: As `plan_tool_push`.
    """
    config = _config(config)
    ctx = _context(config)
    _check_transition(transition)
    _check_state(state, ctx)
    _check_rng(rng)
    n = check_count("n", config.n_first if n is None else n)
    start = time.perf_counter()
    cand = sample_tool_pushes(state.objects, state.poses, n, rng, config)
    before = np.broadcast_to(state.poses, (len(cand), *state.poses.shape))
    after = _predict(transition, state, before, cand, ctx, rng)
    depth = ctx.region.depth(after[:, 1, :2])
    j = int(np.argmax(depth))
    return ToolPushPlan(
        cand.origin[j : j + 1],
        cand.yaw[j : j + 1],
        after[j : j + 1],
        float(depth[j]),
        time.perf_counter() - start,
        1,
        (len(cand),),
    )


def plan_random_push(
    state: ToolPushState, rng: np.random.Generator, config: ToolPushConfig | None = None
) -> ToolPushPlan:
    """One random reachable push of the tool (no prediction: `predicted` is NaN).

    Args:
        state: The current state.
        rng: Source of randomness.
        config: Task settings.

    Returns:
        One push.

    Raises:
        InputError: For a `state`, `rng` or `config` of the wrong kind.
        UnreachablePoseError: If the arm can push the tool in no sampled direction.
    """
    config = _config(config)
    if not isinstance(state, ToolPushState):
        raise InputError(
            f"state must be a ToolPushState (objects and poses), got {type(state).__name__}."
        )
    _check_rng(rng)
    start = time.perf_counter()
    cand = sample_tool_pushes(state.objects, state.poses, 1, rng, config)
    return ToolPushPlan(
        cand.origin,
        cand.yaw,
        np.full((1, _N_OBJECTS, 3), np.nan),
        math.nan,
        time.perf_counter() - start,
        0,
        (1,),
    )


# ------------------------------------------------------------------------------ trials


def draw_tool_push_episode(seed: int, config: ToolPushConfig | None = None) -> SceneInstance:
    """The start state and hidden physical parameters of one trial.

    Scenes are drawn from the template (`sample_scene`: poses, masses, frictions and
    pressure distributions) until the target starts between `min_outside` and `max_outside`
    outside the reachable region and the arm can execute the drawn push of the tool.

    Args:
        seed: Trial seed (an integer >= 0); the episode depends on it alone.
        config: Task settings.

    Returns:
        The episode; its push fields are the drawn push, which no planner uses.

    Raises:
        InputError: For a bad seed.
        ConfigError: If no draw in `max_draws` qualifies.
    """
    config = _config(config)
    seed = check_count("seed", seed, minimum=0)
    ctx = _context(config)
    rng = np.random.default_rng(np.random.SeedSequence(seed).spawn(2)[0])
    catalogue = load_catalogue()
    for _ in range(config.max_draws):
        s = sample_scene(ctx.scene, catalogue, ctx.world, rng)
        if s is None:
            continue
        depth = float(ctx.region.depth(s.poses[1, :2]))
        if not -config.max_outside <= depth <= -config.min_outside:
            continue
        ok = ctx.arm.solve_pushes(
            torch.as_tensor(s.push_origin[None]),
            torch.tensor([s.push_yaw], dtype=torch.float64),
            s.push_distance,
        ).ok
        if bool(ok[0]):
            return s
    raise ConfigError(
        f"no draw of scene {config.scene!r} in {config.max_draws} puts the target between "
        f"{config.min_outside} and {config.max_outside} m outside the reachable region with a "
        "reachable push of the tool; widen ToolPushConfig.min_outside/max_outside or move the "
        "scene's objects (worlds/scenes/tool_push.yaml)."
    )


@dataclass(frozen=True)
class ToolPushTrial:
    """One executed tool-push trial.

    Attributes:
        planner: A name from `TOOL_PUSH_PLANNERS`.
        seed: The trial seed.
        objects: Catalogue names of (tool, target).
        initial: (2, 3) world poses at the start.
        initial_depth: The target's signed distance into the region at the start (m).
        pushes: (S, 3) executed hand starts and yaws ``(x, y, yaw)``.
        predicted: (S, 2, 3) the planner's predicted poses after each push (NaN for
            ``"random"``).
        executed: (S, 2, 3) the poses after each executed push.
        final_depth: The target's final signed distance into the region (m); positive
            inside.
        reached: The target ends inside the region, on the table.
        fell_off: An object fell off the table (the trial then stops).
        refused: The arm refused a planned push at execution (the trial then stops).
        planning_time_s: Seconds spent planning (all steps).
        transition_calls: Calls to the transition model.
    """

    planner: str
    seed: int
    objects: tuple[str, str]
    initial: np.ndarray
    initial_depth: float
    pushes: np.ndarray
    predicted: np.ndarray
    executed: np.ndarray
    final_depth: float
    reached: bool
    fell_off: bool
    refused: bool
    planning_time_s: float
    transition_calls: int = 0

    def to_dict(self) -> dict[str, Any]:
        """A JSON-able record (arrays as nested lists, NaN as ``None``)."""

        def plain(x: np.ndarray) -> Any:
            return [plain(v) for v in x] if x.ndim else (None if np.isnan(x) else float(x))

        return {
            "planner": self.planner,
            "seed": self.seed,
            "objects": list(self.objects),
            "initial": plain(self.initial),
            "initial_depth": self.initial_depth,
            "pushes": plain(self.pushes),
            "predicted": plain(self.predicted),
            "executed": plain(self.executed),
            "final_depth": self.final_depth,
            "reached": self.reached,
            "fell_off": self.fell_off,
            "refused": self.refused,
            "planning_time_s": self.planning_time_s,
            "transition_calls": self.transition_calls,
        }


@lru_cache(maxsize=4)
def _simulator(config: ToolPushConfig) -> PushSimulator:
    ctx = _context(config)
    return PushSimulator(ctx.scene, ctx.world)


def run_tool_push_trial(
    planner: str,
    model: FeaturePushModel | None,
    seed: int,
    config: ToolPushConfig | None = None,
) -> ToolPushTrial:
    """Draw an episode, plan with `planner`, execute with the arm and physics, score it.

    The plan is executed open loop (as in the thesis): each push runs from its planned hand
    start, whatever the previous push really did; ``"random"`` draws its second push around
    the tool's observed pose. Torch runs single-threaded during the trial.

    Args:
        planner: A name from `TOOL_PUSH_PLANNERS`.
        model: The learned chapter-5 model (``"two_step"``, ``"single_step"``); ignored by
            the others and may be ``None`` for them.
        seed: Trial seed (an integer >= 0): the same seed gives every planner the same
            episode, and the same planner the same trial.
        config: Task settings.

    Returns:
        The trial.

    Raises:
        InputError: For an unknown planner, a missing or mismatched model, or a bad seed.
    """
    if not isinstance(planner, str) or planner not in TOOL_PUSH_PLANNERS:
        raise InputError(f"unknown planner {planner!r}; choose one of {TOOL_PUSH_PLANNERS}.")
    config = _config(config)
    if planner in ("two_step", "single_step") and not isinstance(model, FeaturePushModel):
        raise InputError(
            f"planner {planner!r} needs a fitted chapter-5 model as a FeaturePushModel "
            f"(fit_tool_push_model), got {type(model).__name__}."
        )
    seed = check_count("seed", seed, minimum=0)
    ctx = _context(config)
    with torch_threads(1):
        episode = draw_tool_push_episode(seed, config)
        state = ToolPushState(episode.objects, episode.poses)
        rng = np.random.default_rng(np.random.SeedSequence(seed).spawn(2)[1])
        plans: list[ToolPushPlan] = []
        if planner == "two_step":
            assert model is not None
            plans.append(plan_tool_push(ModelTransition(model, ctx.world), state, rng, config))
        elif planner == "single_step":
            assert model is not None
            plans.append(plan_single_push(ModelTransition(model, ctx.world), state, rng, config))
        elif planner == "two_step_sim":
            sizes = (config.sim_n_first, config.sim_n_keep, config.sim_n_second)
            plans.append(plan_tool_push(SimTransition(ctx.world), state, rng, config, sizes=sizes))
        sim = _simulator(config)
        poses, executed, pushes, predicted = episode.poses, [], [], []
        fell = refused = False
        for step in range(2 if planner == "random" else len(plans[0].push_yaw)):
            if planner == "random":
                try:
                    plans.append(
                        plan_random_push(ToolPushState(episode.objects, poses), rng, config)
                    )
                except (UnreachablePoseError, InputError):
                    break  # the tool left the arm's reach, or the boxes overlap after push 1
                plan, k = plans[-1], 0
            else:
                plan, k = plans[0], step
            push = dataclasses.replace(
                episode, poses=poses, push_origin=plan.push_origin[k], push_yaw=plan.push_yaw[k]
            )
            try:
                outcome = sim.execute([push])[0].outcome
            except UnreachablePoseError:
                refused = True  # IK of the lone push failed where the planner's batch passed
                break
            poses = outcome.state_after
            executed.append(poses)
            pushes.append([*plan.push_origin[k], plan.push_yaw[k]])
            predicted.append(plan.predicted[k])
            if outcome.fell_off.any():
                fell = True
                break
    final_depth = float(ctx.region.depth(poses[1, :2]))
    return ToolPushTrial(
        planner=planner,
        seed=seed,
        objects=(episode.objects[0].name, episode.objects[1].name),
        initial=np.array(episode.poses),
        initial_depth=float(ctx.region.depth(episode.poses[1, :2])),
        pushes=np.array(pushes, dtype=float).reshape(-1, 3),
        predicted=np.array(predicted, dtype=float).reshape(-1, _N_OBJECTS, 3),
        executed=np.array(executed, dtype=float).reshape(-1, _N_OBJECTS, 3),
        final_depth=final_depth,
        reached=bool(final_depth > 0 and not _off_table(poses[1], ctx.world)),
        fell_off=fell,
        refused=refused,
        planning_time_s=float(sum(p.planning_time_s for p in plans)),
        transition_calls=int(sum(p.transition_calls for p in plans)),
    )


def _off_table(pose: np.ndarray, world: TabletopSpec) -> bool:
    return bool(
        abs(pose[0]) > 0.5 * world.table_size[0] or abs(pose[1]) > 0.5 * world.table_size[1]
    )


def tool_push_scores(trials: Sequence[ToolPushTrial]) -> dict[str, dict[str, float]]:
    """Per planner: trials, success fraction, mean final depth and planning time.

    Args:
        trials: Trials of any planners.

    Returns:
        planner -> ``{"trials", "success", "mean_depth", "std_depth", "mean_planning_time_s"}``
        (success: the fraction whose target ends inside the region; depth in metres).

    Raises:
        InputError: If `trials` is empty or holds something other than `ToolPushTrial`.
    """
    trials = list(trials)
    if not trials or not all(isinstance(t, ToolPushTrial) for t in trials):
        raise InputError("trials must be a non-empty list of ToolPushTrial.")
    out: dict[str, dict[str, float]] = {}
    for name in sorted({t.planner for t in trials}):
        ts = [t for t in trials if t.planner == name]
        depth = np.array([t.final_depth for t in ts])
        out[name] = {
            "trials": float(len(ts)),
            "success": float(np.mean([t.reached for t in ts])),
            "mean_depth": float(depth.mean()),
            "std_depth": float(depth.std(ddof=1)) if len(ts) > 1 else 0.0,
            "mean_planning_time_s": float(np.mean([t.planning_time_s for t in ts])),
        }
    return out


# ----------------------------------------------------------------------------- fitting


def fit_tool_push_model(
    ds: PushDataset,
    *,
    n_experts: int = 3,
    groups: tuple[str, ...] = ("f_o", "f_c"),
    max_iter: int = 10,
    n_restarts: int = 3,
    gp_max_iter: int = 50,
    seed: int = 0,
) -> FeaturePushModel:
    """Fit chapter 5's mixture of GP experts on two-object pushes, for the planner.

    The gate and the experts read the chapter-5 feature groups `groups`; the targets are the
    pushing-frame effects ``(dy_p, dz_p, dtheta_p)`` of o1 then o2 (6 outputs).

    Args:
        ds: Pushes of a two-object scene (e.g. ``probaff generate --scene tool_push``).
        n_experts: Experts M.
        groups: Chapter-5 feature groups, e.g. ``("f_o", "f_c")``.
        max_iter: EM iterations.
        n_restarts: EM starts.
        gp_max_iter: L-BFGS iterations per expert fit.
        seed: Seed of the fit.

    Returns:
        The fitted model with the features it reads.

    Raises:
        InputError: If `ds` holds fewer than two objects per push, or for bad counts.
    """
    if not isinstance(ds, PushDataset) or ds["effect"].shape[1] < _N_OBJECTS:
        raise InputError(
            "ds must be a PushDataset of a two-object scene (probaff generate --scene tool_push)."
        )
    n_experts = check_count("n_experts", n_experts)
    for name, value in (("max_iter", max_iter), ("n_restarts", n_restarts)):
        check_count(name, value)
    gp_max_iter = check_count("gp_max_iter", gp_max_iter)
    check_count("seed", seed, minimum=0)
    groups = (groups,) if isinstance(groups, str) else tuple(groups)
    fs = chapter5_features(ds)
    if not groups or len(set(groups)) != len(groups) or not set(groups) <= set(fs.groups):
        raise InputError(
            f"groups {list(groups)} must name distinct chapter-5 feature groups; choose from "
            f"{list(fs.groups)}."
        )
    X = fs.select(*groups)
    Y = ds["effect"][:, :_N_OBJECTS].reshape(len(ds), 3 * _N_OBJECTS)
    offsets, start = {}, 0
    for g in groups:
        width = fs.groups[g].stop - fs.groups[g].start
        offsets[g] = slice(start, start + width)
        start += width
    model = MixtureOfGPExperts(
        n_experts, groups=offsets, gp_max_iter=gp_max_iter, lengthscale_prior=True
    )
    with torch_threads(1):
        fit_em(model, X, Y, max_iter=max_iter, n_restarts=n_restarts, seed=seed)
    return FeaturePushModel.for_dataset(model, "ch5", tuple(groups), ds)
