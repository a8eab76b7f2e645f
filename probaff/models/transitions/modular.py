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

from collections.abc import Mapping, Sequence
from typing import Any, Protocol, runtime_checkable

import numpy as np
import torch
from torch.distributions import MultivariateNormal

from probaff._checks import check_count, check_shape
from probaff.errors import InputError
from probaff.models.transitions.chain import (
    MIN_ACTION_LENGTH,
    ChainPrediction,
    ChainScene,
    planar_poses,
    wrap_angle,
)
from probaff.models.transitions.transition import SKILLS, SkillTransitionModel
from probaff.models.transitions.transition_base import sample_effects

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

_EFFECT_SIZE = 6  # (dx, dy, dz, rx, ry, rz) in the action frame


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
            draws = sample_effects(dist, n_draws, gen).numpy()
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

        start_planar = planar_poses(start)
        planar = planar_poses(poses)
        planar[..., 2] = start_planar[:, 2] + wrap_angle(planar[..., 2] - start_planar[:, 2])
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
