"""Chapter 6's stepped push model: a forward and a backward model rolled out step by step.

The thesis (sections 6.3.1 and 6.6.2) steps a push as piecewise-linear actions and lets a
backward model correct the end-effector's pose at every step. `SteppedPushModel` holds, per
link kind, a forward model f_t -> e_t (the target's effect over one step) and a backward
model [f_t, e_t] -> r_t (the actor's actual minus commanded position at t + 1): one pair for
the hand on o1 (``hand_forward``, ``hand_backward``) and one for an object on the next
object (``link_forward``, ``link_backward``). Each is a `SkillTransitionModel` without its
own backward component (a GP, or a mixture of GP experts) fitted by `fit_transition`; the
feature layer builds their rows (`probaff.features.ch6_stepped.fit_stepped`).

`rollout` runs the steps from a scene's start, with mean predictions:

1. the hand moves from its pose at t towards its command at t + 1; their features against o1
   (contacts included) give o1's effect e_t (zero when the hand does not touch it) and the
   hand's reaction r_t;
2. for each object k in order, its predicted motion over the step is the action on object
   k + 1: their features give k + 1's effect and object k's reaction, which corrects k;
3. the hand is set to ``commanded_{t+1} + r_t``; the next step's features are computed from
   the new poses.

Without the backward predictors (`StepComponents.without_backward`) every reaction is zero:
the hand follows its command and the objects their forward effects, open-loop chaining.

Like `ModularTransitionModel`, the rollout takes its surfaces, features and effects from an
injected `InteractionGeometry`. Frames: planar poses are world ``(x, y, yaw)`` (m, m, rad);
the hand's frame stands at the push height with x along the push; effects ``(dx, dy, rz)``
and reactions ``(dx, dy)`` are in each step's action frame (y along the actor's command).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np
import torch

from probaff._checks import as_float_array, check_count, check_positive
from probaff.errors import InputError
from probaff.models.options import EMOptions, GPOptions
from probaff.models.transitions.chain import _overlapping_pairs, planar_poses, wrap_angle
from probaff.models.transitions.modular import InteractionGeometry
from probaff.models.transitions.transition import SkillTransitionModel, fit_transition
from probaff.models.transitions.transition_base import TRANSITION_GP, check_transition_gp

__all__ = [
    "COMPONENT_NAMES",
    "MeanPredictor",
    "Rollout",
    "StepComponents",
    "SteppedModelOptions",
    "SteppedPushModel",
    "SteppedScenes",
    "lift",
    "mean_predictor",
    "rollout",
]

MeanPredictor = Callable[[np.ndarray], np.ndarray]
"""Mean prediction of a component: inputs ``(n, D_in)`` to outputs ``(n, D_out)``."""

COMPONENT_NAMES = ("hand_forward", "hand_backward", "link_forward", "link_backward")
"""The components of a `SteppedPushModel`."""

_PLANAR = (0, 1, 5)  # effect columns dx, dy, rz of the 6 action-frame components


def lift(pose: np.ndarray, height: np.ndarray | float) -> np.ndarray:
    """(n, 4, 4) frames of planar poses `(n, 3)` with their origin at half of `height`.

    A box of height h resting on the table has its centre at h / 2; the hand's frame at
    push height p is lifted with ``height = 2 p``.

    Raises:
        InputError: For a `pose` that is not ``(n, 3)`` numbers, or a `height` that is not a
            number or ``(n,)`` numbers.
    """
    p = as_float_array("pose", pose)
    if p.ndim != 2 or p.shape[1] != 3:
        raise InputError(f"pose must be (n, 3) planar poses (x, y, yaw), got shape {p.shape}.")
    h = as_float_array("height", height)
    if h.shape not in ((), (len(p),)):
        raise InputError(f"height must be a number or ({len(p)},) numbers, got shape {h.shape}.")
    c, s = np.cos(p[:, 2]), np.sin(p[:, 2])
    T = np.zeros((len(p), 4, 4))
    T[:, 0, 0], T[:, 0, 1], T[:, 1, 0], T[:, 1, 1] = c, -s, s, c
    T[:, 2, 2] = T[:, 3, 3] = 1.0
    T[:, 0, 3], T[:, 1, 3] = p[:, 0], p[:, 1]
    T[:, 2, 3] = 0.5 * h
    return T


@dataclass(frozen=True)
class SteppedScenes:
    """What a rollout reads of N scenes of K boxes pushed in S steps.

    Attributes:
        sizes: (N, K, 3) box extents ``(length, width, height)`` (m).
        start: (N, K, 3) the objects' planar start poses.
        commanded: (N, S + 1, 3) the hand's commanded planar pose at every step boundary.
        finger_points: (Q, 3) the fingers' surface points in the hand frame (m).
        finger_normals: (Q, 3) their outward unit normals in the hand frame.
        hand_height: The push height (m) of the hand frame.
    """

    sizes: np.ndarray
    start: np.ndarray
    commanded: np.ndarray
    finger_points: np.ndarray
    finger_normals: np.ndarray
    hand_height: float

    def __post_init__(self) -> None:
        """Raise `InputError` for mismatched shapes or objects that overlap at the start."""
        n, k = self.sizes.shape[:2]
        if self.start.shape != (n, k, 3) or self.commanded.shape[::2] != (n, 3):
            raise InputError(
                f"sizes {self.sizes.shape}, start {self.start.shape} and commanded "
                f"{self.commanded.shape} must be (N, K, 3), (N, K, 3) and (N, S + 1, 3)."
            )
        if self.commanded.shape[1] < 2:
            raise InputError("commanded holds one pose; a rollout needs at least one step.")
        check_positive("hand_height", self.hand_height)
        flat = lift(self.start.reshape(-1, 3), self.sizes.reshape(-1, 3)[:, 2])
        T = flat.reshape(n, k, 4, 4)
        for i in range(n):
            pairs = _overlapping_pairs(self.sizes[i], T[i])
            if pairs:
                a, b = pairs[0]
                raise InputError(
                    f"scene {i} starts with objects {a} and {b} overlapping; a rollout needs "
                    "objects that do not interpenetrate: separate them."
                )

    def __len__(self) -> int:
        return int(self.sizes.shape[0])

    @property
    def n_steps(self) -> int:
        """Steps per push S."""
        return int(self.commanded.shape[1]) - 1


@dataclass(frozen=True)
class StepComponents:
    """The mean predictors a rollout uses.

    Attributes:
        hand_forward: o1's step effect ``(n, D) -> (n, 3)`` from the hand link's features.
        hand_backward: The hand's reaction ``(n, D + 3) -> (n, 2)``; ``None``: zero.
        link_forward: Object k + 1's step effect from the link's features; ``None``: objects
            never push others.
        link_backward: Object k's reaction from the link's features and effect; ``None``:
            zero.
    """

    hand_forward: MeanPredictor
    hand_backward: MeanPredictor | None = None
    link_forward: MeanPredictor | None = None
    link_backward: MeanPredictor | None = None

    def without_backward(self) -> StepComponents:
        """The same forward models with zero reactions."""
        return StepComponents(self.hand_forward, None, self.link_forward, None)


@dataclass(frozen=True)
class Rollout:
    """Rolled-out pushes.

    Attributes:
        hand: (N, S + 1, 3) the hand's planar pose at every step boundary.
        objects: (N, S + 1, K, 3) the objects' planar poses (yaw continuous from the start).
        touched: (N, K) whether each object was ever touched.
    """

    hand: np.ndarray
    objects: np.ndarray
    touched: np.ndarray

    @property
    def final(self) -> np.ndarray:
        """(N, K, 3) the objects' final planar poses."""
        return self.objects[:, -1]


def _call(predict: MeanPredictor, X: np.ndarray, width: int, name: str) -> np.ndarray:
    out = np.asarray(predict(X), dtype=np.float64)
    if out.shape != (X.shape[0], width):
        raise InputError(f"{name} must return ({X.shape[0]}, {width}) means, got {out.shape}.")
    return out


def _move(
    geometry: InteractionGeometry,
    size: np.ndarray,
    pose: np.ndarray,
    T_a: np.ndarray,
    effect: np.ndarray,
) -> np.ndarray:
    """(n, 3) planar poses `(n, 3)` of boxes `(n, 3)` moved by effects `(n, 3)` in `T_a`."""
    full = np.zeros((len(effect), 6))
    full[:, list(_PLANAR)] = effect
    after = planar_poses(geometry.apply_effect(T_a, lift(pose, size[:, 2]), full))
    after[:, 2] = pose[:, 2] + wrap_angle(after[:, 2] - pose[:, 2])
    return after


def _hand_link(
    geometry: InteractionGeometry,
    scenes: SteppedScenes,
    hand: np.ndarray,
    command: np.ndarray,
    o1: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Features, touches and action frames of the hand `(N, 3)` commanded to `(N, 3)`."""
    T_s = lift(hand, 2.0 * scenes.hand_height)
    T_c = lift(command, 2.0 * scenes.hand_height)
    pts = np.einsum("nij,qj->nqi", T_s[:, :3, :3], scenes.finger_points) + T_s[:, None, :3, 3]
    nrm = np.einsum("nij,qj->nqi", T_s[:, :3, :3], scenes.finger_normals)
    size = scenes.sizes[:, 0]
    t_pts, t_nrm = geometry.surface(size, lift(o1, size[:, 2]))
    X, touch, T_a = geometry.features(t_pts, t_nrm, pts, nrm, T_s, T_c)
    return np.asarray(X), np.asarray(touch, dtype=bool), np.asarray(T_a)


def _link_step(
    components: StepComponents,
    geometry: InteractionGeometry,
    sizes: np.ndarray,
    actor: int,
    cur: np.ndarray,
    new: np.ndarray,
    touched: np.ndarray,
    min_action: float,
) -> None:
    """Object `actor`'s predicted motion (`cur` to `new`) acts on the next; updates `new`."""
    assert components.link_forward is not None
    moved = np.linalg.norm(new[:, actor, :2] - cur[:, actor, :2], axis=1)
    rows = np.flatnonzero(moved >= min_action)
    if rows.size == 0:
        return
    size_a, size_b = sizes[rows, actor], sizes[rows, actor + 1]
    T_s = lift(cur[rows, actor], size_a[:, 2])
    a_pts, a_nrm = geometry.surface(size_a, T_s)
    t_pts, t_nrm = geometry.surface(size_b, lift(cur[rows, actor + 1], size_b[:, 2]))
    X, touch, T_a = geometry.features(
        t_pts, t_nrm, a_pts, a_nrm, T_s, lift(new[rows, actor], size_a[:, 2])
    )
    touch = np.asarray(touch, dtype=bool)
    hit = rows[touch]
    if hit.size == 0:
        return
    X, T_a = np.asarray(X)[touch], np.asarray(T_a)[touch]
    effect = _call(components.link_forward, X, 3, "link_forward")
    new[hit, actor + 1] = _move(geometry, size_b[touch], cur[hit, actor + 1], T_a, effect)
    touched[hit, actor + 1] = True
    if components.link_backward is not None:
        r = _call(components.link_backward, np.concatenate([X, effect], 1), 2, "link_backward")
        new[hit, actor, :2] += np.einsum("nij,nj->ni", T_a[:, :2, :2], r)


def rollout(
    components: StepComponents,
    geometry: InteractionGeometry,
    scenes: SteppedScenes,
    *,
    min_action: float = 1e-3,
) -> Rollout:
    """Roll pushes out step by step from their start poses (see the module docstring).

    Args:
        components: The mean predictors.
        geometry: The surfaces, features and effects the components were trained with.
        scenes: The objects' start poses and sizes, the fingers and the commanded hand path.
        min_action: Shortest predicted object motion (m) that acts on the next object.

    Returns:
        The rolled-out poses; the hand starts at its first commanded pose.

    Raises:
        InputError: For predictors that return the wrong shape, or a `min_action` that is
            not positive.
    """
    if not isinstance(scenes, SteppedScenes):
        raise InputError(f"scenes must be SteppedScenes, got {type(scenes).__name__}.")
    check_positive("min_action", min_action)
    n, s, k = len(scenes), scenes.n_steps, scenes.sizes.shape[1]
    poses = np.zeros((n, s + 1, k, 3))
    hands = np.zeros((n, s + 1, 3))
    poses[:, 0], hands[:, 0] = scenes.start, scenes.commanded[:, 0]
    touched = np.zeros((n, k), dtype=bool)
    for t in range(s):
        cur = poses[:, t]
        new = cur.copy()
        command = scenes.commanded[:, t + 1]
        X, touch, T_a = _hand_link(geometry, scenes, hands[:, t], command, cur[:, 0])
        effect = np.zeros((n, 3))
        if touch.any():
            effect[touch] = _call(components.hand_forward, X[touch], 3, "hand_forward")
            new[touch, 0] = _move(
                geometry, scenes.sizes[touch, 0], cur[touch, 0], T_a[touch], effect[touch]
            )
            touched[touch, 0] = True
        hands[:, t + 1] = command
        if components.hand_backward is not None:
            inputs = np.concatenate([X, effect], axis=1)
            reaction = _call(components.hand_backward, inputs, 2, "hand_backward")
            hands[:, t + 1, :2] += np.einsum("nij,nj->ni", T_a[:, :2, :2], reaction)
        if components.link_forward is not None:
            for actor in range(k - 1):
                _link_step(components, geometry, scenes.sizes, actor, cur, new, touched, min_action)
        poses[:, t + 1] = new
    return Rollout(hands, poses, touched)


@dataclass(frozen=True)
class SteppedModelOptions:
    """The components of a `SteppedPushModel`.

    Attributes:
        kind: ``"gp"`` (one GP per component, the thesis) or ``"mixture"``.
        n_experts: Experts of each mixture component (``kind="mixture"``).
        gp: The GP settings of every component (`SkillTransitionModel`'s ``gp``): by
            default `TRANSITION_GP` with the length-scale prior on, 50 L-BFGS iterations per
            fit (``GPOptions(max_iter=50, lengthscale_prior=True, noise_floor="auto",
            outputscale=0.1)``).
        max_rows: Most step rows a component is fitted on (beyond it a seeded random subset),
            bounding the exact GP's cost.
        seed: Seed of the row subsets and of the mixtures' EM.
        em: The mixtures' EM settings.
        min_action: Shortest object motion (m) that acts on the next object.
    """

    kind: str = "gp"
    n_experts: int = 2
    gp: GPOptions = field(default=replace(TRANSITION_GP, lengthscale_prior=True))
    max_rows: int = 1500
    seed: int = 0
    em: EMOptions = field(default_factory=lambda: EMOptions(max_iter=10))
    min_action: float = 1e-3

    def __post_init__(self) -> None:
        """Raise `InputError` for an unknown kind, bad counts, GP settings or minimum action."""
        if self.kind not in ("gp", "mixture"):
            raise InputError(f"kind must be 'gp' or 'mixture', got {self.kind!r}.")
        check_count("n_experts", self.n_experts)
        check_transition_gp(self.gp)
        check_count("max_rows", self.max_rows, minimum=2)
        check_count("seed", self.seed, minimum=0)
        if not isinstance(self.em, EMOptions):
            raise InputError(f"em must be an EMOptions, got {type(self.em).__name__}.")
        check_positive("min_action", self.min_action)


def mean_predictor(model: SkillTransitionModel) -> MeanPredictor:
    """The mean of a fitted model's predictive distribution as a function of its inputs."""

    def predict(X: np.ndarray) -> np.ndarray:
        with torch.no_grad():
            dist = model.predict(torch.as_tensor(X, dtype=torch.float64), skill=model.skill)
            return np.asarray(dist.mean.numpy(), dtype=np.float64)

    return predict


class SteppedPushModel:
    """The four step components of chapter 6's stepped push model, and their rollout.

    Args:
        geometry: The surfaces, features and effects of the step rows.
        options: How the components are built and fitted.
        backward: Whether the model has backward components (reactions).

    Attributes:
        models: The fitted `SkillTransitionModel` of each component, by name
            (`COMPONENT_NAMES`); ``link_*`` only for scenes of two or more objects.
    """

    def __init__(
        self,
        geometry: InteractionGeometry,
        options: SteppedModelOptions | None = None,
        *,
        backward: bool = True,
    ) -> None:
        if not isinstance(geometry, InteractionGeometry):
            raise InputError(
                "geometry must implement InteractionGeometry (surface, features, apply_effect), "
                f"got {type(geometry).__name__}."
            )
        self.geometry = geometry
        self.options = SteppedModelOptions() if options is None else options
        if not isinstance(self.options, SteppedModelOptions):
            raise InputError(
                f"options must be a SteppedModelOptions, got {type(self.options).__name__}."
            )
        self.backward = bool(backward)
        self.models: dict[str, SkillTransitionModel] = {}

    def fit_component(self, name: str, X: np.ndarray, Y: np.ndarray) -> SkillTransitionModel:
        """Fit component `name` on inputs `X (n, D_in)` and targets `Y (n, D_out)`.

        Raises:
            InputError: For an unknown name, a backward component of a forward-only model,
                or fewer than two rows (or fewer rows than experts).
        """
        if name not in COMPONENT_NAMES:
            raise InputError(f"unknown component {name!r}; use one of {list(COMPONENT_NAMES)}.")
        if name.endswith("backward") and not self.backward:
            raise InputError(f"this model has backward=False; it has no {name} component.")
        o = self.options
        if len(X) < (max(2, o.n_experts) if o.kind == "mixture" else 2):
            raise InputError(
                f"the {name} component has {len(X)} training step(s); fit on more pushes that "
                "make this contact."
            )
        if len(X) > o.max_rows:
            keep = np.sort(np.random.default_rng(o.seed).choice(len(X), o.max_rows, replace=False))
            X, Y = X[keep], Y[keep]
        model = SkillTransitionModel(
            "push",
            kind=o.kind,
            backward=False,
            n_experts=o.n_experts if o.kind == "mixture" else None,
            gp=o.gp,
        )
        if o.kind == "mixture":
            fit_transition(model, X, Y, options=o.em, seed=o.seed)
        else:
            fit_transition(model, X, Y)
        self.models[name] = model
        return model

    def components(self, *, backward: bool | None = None) -> StepComponents:
        """The fitted mean predictors; ``backward=False`` gives zero reactions.

        Raises:
            InputError: Before ``hand_forward`` is fitted, or for ``backward=True`` on a
                forward-only model.
        """
        use = self.backward if backward is None else bool(backward)
        if use and not self.backward:
            raise InputError("this model was built with backward=False; it has no reactions.")
        if "hand_forward" not in self.models:
            raise InputError("the hand_forward component is not fitted; fit the model first.")
        pred = {name: mean_predictor(m) for name, m in self.models.items()}
        comps = StepComponents(
            pred["hand_forward"],
            pred.get("hand_backward"),
            pred.get("link_forward"),
            pred.get("link_backward"),
        )
        return comps if use else comps.without_backward()

    def rollout(self, scenes: SteppedScenes, *, backward: bool | None = None) -> Rollout:
        """Roll `scenes` out with the fitted components (`rollout`)."""
        return rollout(
            self.components(backward=backward),
            self.geometry,
            scenes,
            min_action=self.options.min_action,
        )
