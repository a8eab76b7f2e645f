"""Fitting chapter 6's stepped push model on the steps of a push dataset.

`fit_stepped` builds the step rows of `probaff.features.ch6_steps` and fits the components
of a `probaff.models.SteppedPushModel` on them:

* ``hand_forward`` on the steps where the hand touches o1 (f_t -> e_t; the hand's motion
  from its recorded pose at t, or from its commanded one for a model without reactions), and
  ``hand_backward`` on every step ([f_t, e_t] -> r_t, the hand's actual minus commanded
  position at t + 1);
* ``link_forward`` and ``link_backward`` on the object links (k, k + 1) whose actor touches
  its target. An object has no recorded command: its command over a step is its pose moved
  by the upstream link's predicted effect (the hand's forward model for o1, the fitted link
  forward model for the objects after it), as in a rollout, and its reaction is its observed
  pose at t + 1 minus that command.
"""

from __future__ import annotations

import numpy as np

from probaff.errors import InputError
from probaff.features.ch6_push import PLANAR_EFFECT_COLUMNS
from probaff.features.ch6_steps import LinkSteps, StepTrajectories, hand_steps, link_steps
from probaff.features.chain_geometry import Ch6Geometry, resolve_geometry
from probaff.models.transitions.stepped_transition import (
    MeanPredictor,
    SteppedModelOptions,
    SteppedPushModel,
    lift,
    mean_predictor,
)

__all__ = ["fit_stepped", "link_training_rows"]

_FIELDS = ("features", "touches", "T_world_action", "effect", "reaction", "push", "step", "actor")


def _concat(parts: list[LinkSteps]) -> LinkSteps:
    return LinkSteps(*(np.concatenate([getattr(p, f) for p in parts]) for f in _FIELDS))


def _commands(
    traj: StepTrajectories,
    geometry: Ch6Geometry,
    actor: int,
    upstream: LinkSteps,
    predict: MeanPredictor,
) -> np.ndarray:
    """(N, S, 3) object `actor`'s pose at t moved by the upstream prediction where it touches."""
    cmd = traj.objects[:, :-1, actor].copy()  # no motion where nothing pushes it
    up = upstream.select(upstream.touches)
    if len(up) == 0:
        return cmd
    effect = np.zeros((len(up), 6))
    effect[:, list(PLANAR_EFFECT_COLUMNS)] = predict(up.features)
    pose = traj.objects[up.push, up.step, actor]
    T_after = geometry.apply_effect(
        up.T_world_action, lift(pose, traj.sizes[up.push, actor, 2]), effect
    )
    moved = np.column_stack(
        [T_after[:, 0, 3], T_after[:, 1, 3], np.arctan2(T_after[:, 1, 0], T_after[:, 0, 0])]
    )
    moved[:, 2] = pose[:, 2] + np.angle(np.exp(1j * (moved[:, 2] - pose[:, 2])))
    cmd[up.push, up.step] = moved
    return cmd


def link_training_rows(
    model: SteppedPushModel, traj: StepTrajectories, hand: LinkSteps | None = None
) -> LinkSteps:
    """The touching object-link rows of `traj`, every actor commanded by its upstream link.

    Args:
        model: A stepped model whose ``hand_forward`` is fitted. Pairs after the first need
            ``link_forward``: it is fitted on the first pair's rows if missing.
        traj: The pushes at their step boundaries, two or more objects per scene.
        hand: The hand's step rows of `traj` (built if ``None``, from the hand's recorded
            poses for a model with reactions and from its commanded ones without).

    Returns:
        The rows of every pair (k, k + 1), pair after pair.

    Raises:
        InputError: For scenes of one object, or a model without ``hand_forward``.
    """
    if traj.n_objects < 2:
        raise InputError("object links need scenes of at least two objects.")
    if "hand_forward" not in model.models:
        raise InputError("fit the hand_forward component before building object-link rows.")
    geometry = model.geometry
    assert isinstance(geometry, Ch6Geometry)
    start = "actual" if model.backward else "commanded"
    upstream = hand_steps(traj, geometry, start=start) if hand is None else hand
    predict = mean_predictor(model.models["hand_forward"])
    parts: list[LinkSteps] = []
    for actor in range(traj.n_objects - 1):
        cmd = _commands(traj, geometry, actor, upstream, predict)
        rows = link_steps(traj, actor, cmd, geometry, model.options.min_action)
        rows = rows.select(rows.touches)
        parts.append(rows)
        if actor + 2 < traj.n_objects:
            if "link_forward" not in model.models:
                model.fit_component("link_forward", rows.features, rows.effect)
            upstream, predict = rows, mean_predictor(model.models["link_forward"])
    return _concat(parts)


def fit_stepped(
    traj: StepTrajectories,
    geometry: Ch6Geometry | None = None,
    options: SteppedModelOptions | None = None,
    *,
    backward: bool = True,
) -> SteppedPushModel:
    """Fit a stepped push model on the steps of the pushes `traj` (see the module docstring).

    Args:
        traj: The training pushes at their step boundaries (`step_trajectories`; with
            ``backward=True`` cut with ``reaction=True``, from ``traj_commanded``).
        geometry: The geometry of the features (``Ch6Geometry()`` if ``None``); the fingers of
            `traj` must have been sampled with it.
        options: The components (``SteppedModelOptions()`` if ``None``).
        backward: Fit the backward components. Without them a rollout keeps the hand on its
            command, so the hand's steps are then learnt from the commanded poses
            (``hand_steps(start="commanded")``, the planned actions); with them, from the
            recorded ones, as the corrected rollout places the hand.

    Returns:
        The fitted model.

    Raises:
        InputError: For a component with too few training steps (naming it).
    """
    geometry = resolve_geometry(geometry)
    model = SteppedPushModel(geometry, options, backward=backward)
    hand = hand_steps(traj, geometry, start="actual" if backward else "commanded")
    model.fit_component("hand_forward", hand.features[hand.touches], hand.effect[hand.touches])
    if backward:
        inputs = np.concatenate([hand.features, hand.effect], axis=1)
        model.fit_component("hand_backward", inputs, hand.reaction)
    if traj.n_objects > 1:
        links = link_training_rows(model, traj, hand)
        model.models.pop("link_forward", None)
        model.fit_component("link_forward", links.features, links.effect)
        if backward:
            inputs = np.concatenate([links.features, links.effect], axis=1)
            model.fit_component("link_backward", inputs, links.reaction)
    return model
