"""Chained predictions of one model per skill over scenes of n objects (chapter 6).

`ModularTransitionModel` predicts what happens to a row of objects when the hand acts on the
first one: the first link is the hand's commanded motion acting on the first object of the
chain order, predicted by the model of the scene's skill; every later link is the previous
object's predicted motion (from its start pose to its sampled end pose) acting on the next
object, predicted by the push model (an object moved into another pushes it). A scene of n
objects therefore needs no model beyond the per-skill ones.

The chain is sampled: `S` samples run through all links at once (vectorised over samples;
only the links are a loop). The hand's link is the same in every sample, so its features
are computed once and its effect drawn `S` times. In every link, the samples whose actor
moved less than 1 mm, or whose actor does not touch the target during its motion (the
geometry's touch test), leave the target exactly where it was; only the others reach the
feature code and the model. A sample's effect is one draw of the model's predictive
distribution at its features, drawn with one seeded `torch.Generator`, so the same seed
gives the same chain.

The models know nothing of the feature layer: the chain takes its geometry, the box surface
points, the interaction features and the application of an effect, from an
`InteractionGeometry` (`probaff.features.chain_geometry.Ch6Geometry` is the chapter 6 one).

Frames: poses are world-from-object transforms ``T_world_obj`` of the box centres; the
hand's points are given in the hand frame and placed by its commanded poses. Effects are
the 6 action-frame components ``(dx, dy, dz, rx, ry, rz)`` of
`probaff.features.action_frame.effect_in_action_frame`; the skill models predict the
``effect_columns`` of them and the rest are 0. Planar summaries are tabletop poses
``(x, y, yaw)`` with yaw the turn about world up.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import numpy as np
import torch
from torch.distributions import (
    Distribution,
    Independent,
    MixtureSameFamily,
    MultivariateNormal,
    Normal,
)

from probaff._checks import as_float_array, check_count, check_finite, check_shape
from probaff.errors import InputError
from probaff.models.transition import SKILLS, SkillTransitionModel

__all__ = [
    "CHAIN_SKILL",
    "MIN_ACTION_LENGTH",
    "ChainPrediction",
    "ChainScene",
    "InteractionGeometry",
    "ModularTransitionModel",
]

CHAIN_SKILL = "push"
"""The skill of every object-on-object link of a chain (a moved object pushes the next)."""

MIN_ACTION_LENGTH = 1e-3
"""Actions shorter than this (m) move nothing; they never reach the feature code."""

_EFFECT_SIZE = 6  # (dx, dy, dz, rx, ry, rz) in the action frame
_RIGID_TOL = 1e-6  # tolerance of the orthonormality and bottom-row checks
_NORMAL_TOL = 1e-4  # allowed deviation of a normal's length from 1
_OVERLAP_TOL = 1e-6  # m; boxes may interpenetrate this much (faces in contact)
_AXIS_TOL = 1e-9  # cross products of near-parallel edges shorter than this are no axis
_COV_JITTER = 1e-10  # added to the diagonal of the moment-matched covariance


# ------------------------------------------------------------------ protocol
@runtime_checkable
class InteractionGeometry(Protocol):
    """What the chain needs from the feature layer: surfaces, features and effects."""

    def surface(self, size: np.ndarray, T_world_box: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Points and outward unit normals on the surfaces of boxes.

        Args:
            size: (N, 3) box extents along their own axes (m).
            T_world_box: (N, 4, 4) poses of the box centres in the world.

        Returns:
            ``(points, normals)``, each (N, P, 3) in the world.
        """
        ...

    def features(
        self,
        target_points: np.ndarray,
        target_normals: np.ndarray,
        actor_points: np.ndarray,
        actor_normals: np.ndarray,
        T_world_actor_start: np.ndarray,
        T_world_actor_end: np.ndarray,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Interaction features of N actor motions towards a target.

        Args:
            target_points: (N, P, 3) world points of the target.
            target_normals: (N, P, 3) their outward unit normals.
            actor_points: (N, Q, 3) world points of the actor at its start pose.
            actor_normals: (N, Q, 3) their outward unit normals.
            T_world_actor_start: (N, 4, 4) the actor's start pose.
            T_world_actor_end: (N, 4, 4) its end pose (at least 1 mm away in position).

        Returns:
            ``(X, touches, T_world_action)``: features (N, D), whether the actor touches the
            target during the motion (N,) bool, and the action frames (N, 4, 4).
        """
        ...

    def apply_effect(
        self, T_world_action: np.ndarray, T_world_before: np.ndarray, effect: np.ndarray
    ) -> np.ndarray:
        """The target's pose after an effect given in the action frame.

        Args:
            T_world_action: (N, 4, 4) action frames.
            T_world_before: (N, 4, 4) the target's pose before the action.
            effect: (N, 6) ``(dx, dy, dz, rx, ry, rz)`` in the action frame (m, rad).

        Returns:
            (N, 4, 4) the target's pose after the action.
        """
        ...


# ------------------------------------------------------------------ checks
def _rigid(name: str, T: Any, shape: tuple[int | None, ...]) -> np.ndarray:
    """Validate rigid transforms of `shape` (ending in ``(4, 4)``); return them as float64."""
    arr = as_float_array(name, T, copy=True)
    check_shape(name, arr, shape)
    check_finite(name, arr)
    flat = arr.reshape(-1, 4, 4)
    R = flat[:, :3, :3]
    bottom = np.abs(flat[:, 3] - np.array([0.0, 0.0, 0.0, 1.0])).max(axis=1)
    ortho = np.abs(R.transpose(0, 2, 1) @ R - np.eye(3)).max(axis=(1, 2))
    bad = np.flatnonzero((bottom > _RIGID_TOL) | (ortho > _RIGID_TOL) | (np.linalg.det(R) <= 0))
    if bad.size:
        raise InputError(
            f"{name} is not a rigid transform at index {bad[:5].tolist()}: the last row must "
            "be (0, 0, 0, 1) and the 3 x 3 block a rotation (orthonormal, det +1)."
        )
    return arr


def _points(name: str, x: Any) -> np.ndarray:
    """Validate a non-empty, finite (Q, 3) point set; return it as float64."""
    arr = as_float_array(name, x, copy=True)
    check_shape(name, arr, (None, 3))
    if arr.shape[0] == 0:
        raise InputError(f"{name} holds no points; give at least one (1, 3) point.")
    check_finite(name, arr)
    return arr


def _frozen(arr: np.ndarray) -> np.ndarray:
    arr.setflags(write=False)
    return arr


def _check_order(order: Any, n_objects: int) -> tuple[int, ...]:
    """The chain order as distinct object indices; ``()`` means ``0 .. K-1``."""
    if isinstance(order, (str, bytes)) or not isinstance(order, Sequence | np.ndarray):
        raise InputError(f"order must be a sequence of object indices, got {order!r}.")
    if len(order) == 0:
        return tuple(range(n_objects))
    idx = tuple(check_count("order", i, minimum=0) for i in order)
    out = [i for i in idx if i >= n_objects]
    if out:
        raise InputError(
            f"order names object(s) {out}, but the scene has {n_objects} objects "
            f"(indices 0 .. {n_objects - 1})."
        )
    if len(set(idx)) != len(idx):
        raise InputError(f"order lists an object more than once: {list(idx)}; each acts once.")
    return idx


def _overlapping_pairs(sizes: np.ndarray, T_world_obj: np.ndarray) -> list[tuple[int, int]]:
    """Pairs of boxes that interpenetrate by more than `_OVERLAP_TOL`, by separating axes.

    Two boxes are disjoint when some axis separates their projections; for boxes, testing
    the 3 face normals of each and the 9 cross products of their edge directions decides it.
    Along an axis ``a`` (unit), a box of half extents ``h`` and rotation ``R`` projects to a
    half width ``sum_m h_m |R[:, m] . a|`` about its centre.

    Args:
        sizes: (K, 3) box extents (m).
        T_world_obj: (K, 4, 4) box centre poses.

    Returns:
        The overlapping pairs ``(i, j)``, ``i < j``.
    """
    i, j = np.triu_indices(sizes.shape[0], k=1)
    if i.size == 0:
        return []
    R = T_world_obj[:, :3, :3]
    Ri, Rj = R[i].transpose(0, 2, 1), R[j].transpose(0, 2, 1)  # (M, 3 edges, 3)
    cross = np.cross(Ri[:, :, None, :], Rj[:, None, :, :]).reshape(-1, 9, 3)
    axes = np.concatenate([Ri, Rj, cross], axis=1)  # (M, 15, 3)
    norm = np.linalg.norm(axes, axis=2)
    valid = norm > _AXIS_TOL
    axes = axes / np.where(valid, norm, 1.0)[..., None]
    half_i = np.abs(np.einsum("mae,mke->mak", axes, Ri)) @ (0.5 * sizes[i])[..., None]
    half_j = np.abs(np.einsum("mae,mke->mak", axes, Rj)) @ (0.5 * sizes[j])[..., None]
    offset = T_world_obj[j, :3, 3] - T_world_obj[i, :3, 3]
    dist = np.abs(np.einsum("mae,me->ma", axes, offset))
    separated = valid & (dist >= half_i[..., 0] + half_j[..., 0] - _OVERLAP_TOL)
    hit = ~separated.any(axis=1)
    return [(int(a), int(b)) for a, b in zip(i[hit], j[hit], strict=True)]


# ------------------------------------------------------------------- scene
@dataclass(frozen=True, eq=False)
class ChainScene:
    """A scene of K boxes and one commanded hand motion, validated once.

    Objects must not overlap at the start: two boxes overlap when no separating axis exists
    between them (of the 3 face normals of each and the 9 cross products of their edges),
    allowing 1 um of interpenetration so that boxes whose faces touch are accepted. For
    upright boxes on a table this is the separating-axis test of their footprints in the
    plane, combined with their vertical extents.

    Attributes:
        sizes: (K, 3) box extents along each box's own x, y, z (m), > 0.
        T_world_obj: (K, 4, 4) start poses of the box centres in the world.
        hand_points: (Q, 3) the hand's surface points in the hand frame (m).
        hand_normals: (Q, 3) their outward unit normals in the hand frame.
        T_world_hand_start: (4, 4) the hand's commanded start pose.
        T_world_hand_end: (4, 4) its commanded end pose, at least 1 mm from the start in
            position.
        skill: The skill of the hand's interaction with the first object (one of `SKILLS`).
        order: The chain: the object indices in the order they act on each other, each at
            most once; the hand acts on ``order[0]``, ``order[k]`` on ``order[k + 1]``.
            Objects not listed stay where they are. ``()`` (default) is ``0 .. K-1``.

    Raises:
        InputError: For malformed, empty or non-finite arrays, sizes that are not positive,
            transforms that are not rigid, normals that are not unit length, a hand motion
            shorter than 1 mm, an unknown skill, a malformed order, or overlapping objects;
            each message names the argument.
    """

    sizes: np.ndarray
    T_world_obj: np.ndarray
    hand_points: np.ndarray
    hand_normals: np.ndarray
    T_world_hand_start: np.ndarray
    T_world_hand_end: np.ndarray
    skill: str = "push"
    order: tuple[int, ...] = ()

    def __post_init__(self) -> None:
        sizes = as_float_array("sizes", self.sizes, copy=True)
        check_shape("sizes", sizes, (None, 3))
        if sizes.shape[0] == 0:
            raise InputError("sizes holds no objects; give at least one (1, 3) box size.")
        check_finite("sizes", sizes)
        if np.any(sizes <= 0):
            raise InputError("sizes must be > 0 along every axis; got a zero or negative extent.")
        k = sizes.shape[0]
        T_obj = _rigid("T_world_obj", self.T_world_obj, (k, 4, 4))
        points = _points("hand_points", self.hand_points)
        normals = _points("hand_normals", self.hand_normals)
        check_shape("hand_normals", normals, points.shape)
        length = np.linalg.norm(normals, axis=1)
        if np.any(np.abs(length - 1.0) > _NORMAL_TOL):
            raise InputError(
                f"hand_normals must be unit vectors; lengths range over [{length.min():.4g}, "
                f"{length.max():.4g}]. Divide each normal by its length first."
            )
        T_start = _rigid("T_world_hand_start", self.T_world_hand_start, (4, 4))
        T_end = _rigid("T_world_hand_end", self.T_world_hand_end, (4, 4))
        move = float(np.linalg.norm(T_end[:3, 3] - T_start[:3, 3]))
        if move < MIN_ACTION_LENGTH:
            raise InputError(
                f"T_world_hand_end is {move:.3g} m from T_world_hand_start; the hand must move "
                f"at least {MIN_ACTION_LENGTH} m for the chain to have an action."
            )
        if not isinstance(self.skill, str) or self.skill not in SKILLS:
            known = ", ".join(repr(s) for s in SKILLS)
            raise InputError(f"unknown skill {self.skill!r}; known skills: {known}.")
        order = _check_order(self.order, k)
        overlap = _overlapping_pairs(sizes, T_obj)
        if overlap:
            raise InputError(
                f"objects {overlap[:5]} overlap at the start (sizes and T_world_obj); move "
                "them apart so that every pair is separated or at most touching."
            )
        for name, value in (
            ("sizes", sizes),
            ("T_world_obj", T_obj),
            ("hand_points", points),
            ("hand_normals", normals),
            ("T_world_hand_start", T_start),
            ("T_world_hand_end", T_end),
        ):
            object.__setattr__(self, name, _frozen(value))
        object.__setattr__(self, "order", order)

    @property
    def n_objects(self) -> int:
        """Number of objects K."""
        return int(self.sizes.shape[0])

    def hand_in_world(self) -> tuple[np.ndarray, np.ndarray]:
        """The hand's points and normals at its start pose, each (Q, 3) in the world."""
        R, t = self.T_world_hand_start[:3, :3], self.T_world_hand_start[:3, 3]
        return self.hand_points @ R.T + t, self.hand_normals @ R.T


# -------------------------------------------------------------- prediction
def _planar(T: np.ndarray) -> np.ndarray:
    """(..., 3) tabletop summaries ``(x, y, yaw)`` of (..., 4, 4) poses; yaw about world up."""
    return np.stack([T[..., 0, 3], T[..., 1, 3], np.arctan2(T[..., 1, 0], T[..., 0, 0])], -1)


def _wrap(angle: np.ndarray) -> np.ndarray:
    """Angles wrapped to ``[-pi, pi)``."""
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


@dataclass(frozen=True, eq=False)
class ChainPrediction:
    """Sampled outcome of a chain: S samples of the final poses of K objects.

    Attributes:
        samples: (S, K, 4, 4) final world poses of every object in every sample.
        planar: (S, K, 3) their tabletop summaries ``(x, y, yaw)`` (m, rad); yaw is the start
            yaw plus the object's turn wrapped to ``[-pi, pi)``, so it varies continuously
            about the start.
        start_planar: (K, 3) the summaries of the start poses.
        touched: (S, K) whether each object was touched (and so moved by its model's draw).
        order: The chain order the scene used.
    """

    samples: np.ndarray
    planar: np.ndarray
    start_planar: np.ndarray
    touched: np.ndarray
    order: tuple[int, ...]

    @property
    def n_samples(self) -> int:
        """Number of samples S."""
        return int(self.samples.shape[0])

    @property
    def displacement(self) -> np.ndarray:
        """(S, K, 3) planar displacement ``(dx, dy, dyaw)`` of every object (world axes)."""
        return self.planar - self.start_planar

    @property
    def mean_displacement(self) -> np.ndarray:
        """(K, 3) mean planar displacement of each object over the samples."""
        return self.displacement.mean(axis=0)

    @property
    def std_displacement(self) -> np.ndarray:
        """(K, 3) standard deviation (over the S samples, ddof 0) of the displacements."""
        return self.displacement.std(axis=0)

    def interval(
        self, level: float = 0.9, *, of: str = "displacement"
    ) -> tuple[np.ndarray, np.ndarray]:
        """Central sample interval of every object and coordinate.

        Args:
            level: Probability in (0, 1) the interval holds; its ends are the sample
                quantiles ``(1 - level) / 2`` and ``(1 + level) / 2`` (linear interpolation).
            of: ``"displacement"`` (default) or ``"pose"`` (the final planar poses).

        Returns:
            ``(lo, hi)``, each (K, 3).

        Raises:
            InputError: For a level outside (0, 1) or an unknown `of`.
        """
        try:
            p = float(level)
        except (TypeError, ValueError):
            raise InputError(f"level must be a number in (0, 1), got {level!r}.") from None
        if not 0.0 < p < 1.0:
            raise InputError(f"level must lie in (0, 1), got {level!r}.")
        if of == "displacement":
            values = self.displacement
        elif of == "pose":
            values = self.planar
        else:
            raise InputError(f"of must be 'displacement' or 'pose', got {of!r}.")
        lo, hi = np.quantile(values, [(1.0 - p) / 2.0, (1.0 + p) / 2.0], axis=0)
        return lo, hi

    def final_distribution(self) -> MultivariateNormal:
        """A normal over the (K * 3) final planar poses, moment-matched to the samples.

        The mean is the sample mean of `planar` flattened object after object (object k's
        ``(x, y, yaw)`` at columns ``3k .. 3k + 2``), the covariance the unbiased sample
        covariance plus 1e-10 on the diagonal (objects that never move have none of their
        own). A moment match keeps only two moments: a chain's samples are often
        multi-modal (touched in some samples, not in others).

        Returns:
            A `MultivariateNormal` with event shape `(K * 3,)`, float64.

        Raises:
            InputError: With fewer than 2 samples (no covariance).
        """
        if self.n_samples < 2:
            raise InputError(
                f"a covariance needs n_samples >= 2, but the prediction has {self.n_samples}."
            )
        flat = torch.as_tensor(self.planar.reshape(self.n_samples, -1))
        mean = flat.mean(dim=0)
        centred = flat - mean
        cov = centred.T @ centred / (self.n_samples - 1)
        cov = cov + _COV_JITTER * torch.eye(flat.shape[1], dtype=flat.dtype)
        return MultivariateNormal(mean, covariance_matrix=cov)


# ------------------------------------------------------------------ model
def _check_models(models: Any) -> dict[str, SkillTransitionModel]:
    if not isinstance(models, Mapping) or len(models) == 0:
        raise InputError(
            "models must be a non-empty mapping from skill name to SkillTransitionModel, "
            f"got {type(models).__name__}."
        )
    out: dict[str, SkillTransitionModel] = {}
    known = ", ".join(repr(s) for s in SKILLS)
    for key, model in models.items():
        if not isinstance(key, str) or key not in SKILLS:
            raise InputError(f"models has an unknown skill key {key!r}; known skills: {known}.")
        if not isinstance(model, SkillTransitionModel):
            raise InputError(
                f"models[{key!r}] must be a SkillTransitionModel, got {type(model).__name__}."
            )
        if model.skill != key:
            raise InputError(
                f"models[{key!r}] is a {model.skill} model: a model of one skill used for "
                f"another. Put it under {model.skill!r} or give a {key} model."
            )
        out[key] = model
    return out


def _check_effect_columns(columns: Any) -> tuple[int, ...]:
    if isinstance(columns, (str, bytes)) or not isinstance(columns, Sequence | np.ndarray):
        raise InputError(f"effect_columns must be a sequence of indices, got {columns!r}.")
    idx = tuple(check_count("effect_columns", c, minimum=0) for c in columns)
    if not idx:
        raise InputError("effect_columns is empty; name the effect components the models predict.")
    if max(idx) >= _EFFECT_SIZE or len(set(idx)) != len(idx):
        raise InputError(
            f"effect_columns must be distinct indices in 0 .. 5 of (dx, dy, dz, rx, ry, rz), "
            f"got {list(idx)}."
        )
    return idx


def _geometry_output(
    out: tuple[np.ndarray, np.ndarray, np.ndarray], n: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Check a geometry's ``(X (n, D), touches (n,), T_world_action (n, 4, 4))``."""
    X, touches, T_a = (np.asarray(a) for a in out)
    check_shape("geometry.features X", X, (n, None))
    check_shape("geometry.features touches", touches, (n,))
    check_shape("geometry.features T_world_action", T_a, (n, 4, 4))
    return X, touches.astype(bool), T_a


def _draw(dist: Distribution, n_draws: int, generator: torch.Generator) -> torch.Tensor:
    """Draw `n_draws` values from a prediction of batch `(N,)`, event `(E,)`: `(n_draws, N, E)`.

    Supports the predictions of `SkillTransitionModel`: independent normals, and mixtures of
    them (the expert of each draw first, then its normal).
    """
    if isinstance(dist, MixtureSameFamily):
        comp = dist.component_distribution
        base = comp.base_dist if isinstance(comp, Independent) else comp
        if not (isinstance(comp, Independent) and isinstance(base, Normal)):
            raise InputError(f"cannot sample a mixture of {type(comp).__name__} components.")
        probs = dist.mixture_distribution.probs  # (N, M)
        pick = torch.multinomial(probs, n_draws, replacement=True, generator=generator)
        rows = torch.arange(probs.shape[0])[:, None]
        loc = base.loc[rows, pick].transpose(0, 1)  # (n_draws, N, E)
        scale = base.scale[rows, pick].transpose(0, 1)
    elif isinstance(dist, Independent) and isinstance(dist.base_dist, Normal):
        normal = dist.base_dist
        loc = normal.loc.expand(n_draws, *normal.loc.shape)
        scale = normal.scale.expand_as(loc)
    else:
        raise InputError(
            f"the chain samples independent normals or mixtures of them; a model predicted "
            f"a {type(dist).__name__}."
        )
    eps = torch.randn(loc.shape, generator=generator, dtype=loc.dtype)
    return loc + scale * eps


class ModularTransitionModel(torch.nn.Module):
    """Chains of one transition model per skill over scenes of any number of objects.

    See the module docstring for the chain. The skill models are submodules, so the chain's
    `state_dict` holds them.

    Args:
        models: The fitted (or later fitted) `SkillTransitionModel` of each skill, keyed by
            its skill name; a chain of more than one object needs the ``"push"`` model.
        geometry: The feature layer's surfaces, features and effects.
        effect_columns: Which of the 6 action-frame effect components
            ``(dx, dy, dz, rx, ry, rz)`` the models predict, in their output order; the
            others are 0. The default ``(0, 1, 5)`` is the planar tabletop effect: dx
            off-action, dy along the action, rz the yaw.

    Raises:
        InputError: For an empty mapping, an unknown skill key, a model of another skill
            under a key, a geometry without the `InteractionGeometry` methods, or
            malformed effect columns.
    """

    def __init__(
        self,
        models: Mapping[str, SkillTransitionModel],
        geometry: InteractionGeometry,
        *,
        effect_columns: Sequence[int] = (0, 1, 5),
    ) -> None:
        super().__init__()
        self.models = torch.nn.ModuleDict(_check_models(models))
        if not isinstance(geometry, InteractionGeometry):
            raise InputError(
                f"geometry must implement InteractionGeometry (surface, features, "
                f"apply_effect), got {type(geometry).__name__}."
            )
        self.geometry = geometry
        self.effect_columns = _check_effect_columns(effect_columns)

    def skill_model(self, skill: str) -> SkillTransitionModel:
        """The fitted model of `skill`.

        Raises:
            InputError: If there is no model for `skill`, or it predicts another number of
                effect components than `effect_columns`.
            NotFittedError: If the model is not fitted.
        """
        if skill not in self.models:
            raise InputError(
                f"models has no {skill!r} model (it has {sorted(self.models)}); the chain "
                f"needs one for this link."
            )
        model = self.models[skill]
        assert isinstance(model, SkillTransitionModel)
        model.check_fitted()
        if model.n_outputs != len(self.effect_columns):
            raise InputError(
                f"the {skill} model predicts {model.n_outputs} effect components but "
                f"effect_columns names {len(self.effect_columns)}; they must match."
            )
        return model

    def _effects(
        self, model: SkillTransitionModel, X: np.ndarray, n_draws: int, gen: torch.Generator
    ) -> np.ndarray:
        """Sampled 6-component effects `(n_draws, N, 6)` of `model` at features `X (N, D)`."""
        with torch.no_grad():
            dist = model.predict(torch.as_tensor(X, dtype=torch.float64), skill=model.skill)
            draws = _draw(dist, n_draws, gen).numpy()
        effect = np.zeros((*draws.shape[:2], _EFFECT_SIZE))
        effect[..., list(self.effect_columns)] = draws
        return effect

    def predict_chain(
        self, scene: ChainScene, *, n_samples: int = 256, seed: int = 0
    ) -> ChainPrediction:
        """Sample the final poses of every object of a scene.

        Args:
            scene: The objects, the hand's motion, its skill and the chain order.
            n_samples: Number of samples S, a positive integer.
            seed: Seed of the chain's `torch.Generator`, an integer >= 0.

        Returns:
            The S sampled final poses, their planar summaries and where objects were touched.

        Raises:
            InputError: For a scene of another type, a non-integer `n_samples` or `seed`, a
                missing skill model or one of the wrong output size, or features the model
                refuses (another feature width).
            NotFittedError: If a model the chain needs is not fitted.
        """
        if not isinstance(scene, ChainScene):
            raise InputError(f"scene must be a ChainScene, got {type(scene).__name__}.")
        s = check_count("n_samples", n_samples)
        gen = torch.Generator().manual_seed(check_count("seed", seed, minimum=0))
        first = self.skill_model(scene.skill)
        follow = self.skill_model(CHAIN_SKILL) if len(scene.order) > 1 else first
        geo = self.geometry
        start = np.asarray(scene.T_world_obj)
        # each box on its own: a joint call may pad smaller boxes with repeated points
        surfaces = [
            geo.surface(scene.sizes[k : k + 1], start[k : k + 1]) for k in range(len(start))
        ]
        points = [p[0] for p, _ in surfaces]  # K arrays (P_k, 3), world
        normals = [n[0] for _, n in surfaces]
        poses = np.repeat(start[None], s, axis=0)  # (S, K, 4, 4)
        touched = np.zeros((s, scene.n_objects), dtype=bool)

        # link 1: the hand's commanded motion on the first object, the same in every sample
        k0 = scene.order[0]
        hand_p, hand_n = scene.hand_in_world()
        X, touch, T_a = _geometry_output(
            geo.features(
                points[k0][None],
                normals[k0][None],
                hand_p[None],
                hand_n[None],
                np.asarray(scene.T_world_hand_start)[None],
                np.asarray(scene.T_world_hand_end)[None],
            ),
            1,
        )
        if bool(touch[0]):
            effect = self._effects(first, X, s, gen)[:, 0]  # (S, 6)
            poses[:, k0] = geo.apply_effect(
                np.repeat(T_a, s, axis=0), np.repeat(start[k0][None], s, axis=0), effect
            )
            touched[:, k0] = True

        # link k: object `prev`, from its start to its sampled end pose, acts on `cur`
        for prev, cur in zip(scene.order[:-1], scene.order[1:], strict=True):
            moved = np.linalg.norm(poses[:, prev, :3, 3] - start[prev, :3, 3], axis=1)
            active = np.flatnonzero(moved >= MIN_ACTION_LENGTH)
            if active.size == 0:
                continue
            n = active.size
            X, touch, T_a = _geometry_output(
                geo.features(
                    np.broadcast_to(points[cur], (n, *points[cur].shape)),
                    np.broadcast_to(normals[cur], (n, *normals[cur].shape)),
                    np.broadcast_to(points[prev], (n, *points[prev].shape)),
                    np.broadcast_to(normals[prev], (n, *normals[prev].shape)),
                    np.broadcast_to(start[prev], (n, 4, 4)),
                    poses[active, prev],
                ),
                n,
            )
            hit = active[touch]
            if hit.size == 0:
                continue
            effect = self._effects(follow, X[touch], 1, gen)[0]  # (n_hit, 6)
            poses[hit, cur] = geo.apply_effect(
                T_a[touch], np.broadcast_to(start[cur], (hit.size, 4, 4)), effect
            )
            touched[hit, cur] = True

        start_planar = _planar(start)
        planar = _planar(poses)
        planar[..., 2] = start_planar[:, 2] + _wrap(planar[..., 2] - start_planar[:, 2])
        return ChainPrediction(
            samples=poses,
            planar=planar,
            start_planar=start_planar,
            touched=touched,
            order=scene.order,
        )

    def predict_final_distribution(
        self, scene: ChainScene, *, n_samples: int = 256, seed: int = 0
    ) -> MultivariateNormal:
        """A normal over the (K * 3) final planar poses, moment-matched to sampled chains.

        The `MultivariateNormal` of `ChainPrediction.final_distribution` (sample mean and
        covariance of `predict_chain`'s planar summaries, object after object).

        Args:
            scene: The scene.
            n_samples: Number of samples S, an integer >= 2.
            seed: Seed of the chain's generator, an integer >= 0.

        Returns:
            A `MultivariateNormal`, event shape `(K * 3,)`.

        Raises:
            InputError: As `predict_chain`, and for fewer than 2 samples.
        """
        s = check_count("n_samples", n_samples, minimum=2)
        return self.predict_chain(scene, n_samples=s, seed=seed).final_distribution()
