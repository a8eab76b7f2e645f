"""Where Push-T's primitives leave the T, on probaff's one transition protocol.

The planner asks a `probaff.planning.transitions.Transition` (``Transition[TeePushes]``) one
batched question, as the tabletop planners do, and gets the same
`probaff.planning.transitions.TransitionPrediction`: for N primitives (`TeePushes`: the T's
centre-of-gravity pose and the agent's state before each, the primitive's contact, angle and
length), the T's world pose after each as its only object (``mean`` (N, 1, 3), px and rad),
the predictive standard deviation of its pushing-frame effect (``effect_std`` (N, 1, 3): px,
px, rad) and the agent's state after it (``pusher`` (N, 4): position and velocity, px and
px per control step). Push-T's batch is its own (the tabletop's `PushBatch` holds catalogue
objects and one hand travel in metres; a Push-T push is a primitive of its own length, and the
next one starts where the agent was left).

Implementations:

- `ModelTransition`: a push model of the pushing-frame effects (`probaff.experiments.pusht
  .models`: a fitted mixture or single GP, or the analytic `QuasiStaticTee`), its predictive
  mean and standard deviation; the agent ends where the primitive's push ends, at rest. The
  analytic model pushes the batch's T (`TeePushes.tee`: from pixels, the perceived one).
- `EnvTransition`: a second instance of the environment rolls every primitive out from the
  state (the upper bound); deterministic (zero spread).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from probaff._checks import check_array_fields
from probaff.experiments.pusht.env import PushTWorker
from probaff.experiments.pusht.geometry import GYM_TEE, TeeGeometry, cog_pose, origin_pose, to_world
from probaff.experiments.pusht.models import PushModel, QuasiStaticTee, predict_moments
from probaff.experiments.pusht.primitives import PrimitiveSettings, primitive_actions, push_frames
from probaff.planning.transitions import TransitionPrediction

__all__ = ["EnvTransition", "ModelTransition", "TeePushes"]


@dataclass(frozen=True)
class TeePushes:
    """N Push-T primitives, each from its own state: what a Push-T transition is asked.

    Attributes:
        poses: (N, 3) world centre-of-gravity poses of the T before each push (px, rad).
        agents: (N, 2) world positions of the agent before each push (px).
        agent_vels: (N, 2) the agent's velocities before each push.
        prims: (N, 3) primitives ``(s, phi, length)`` (`probaff.experiments.pusht.primitives`).
        settings: The primitives' settings.
        tee: The T pushed (its outline and centre of gravity set the block frame): gym-pusht's,
            or the one perceived from the images.

    Raises:
        InputError: For arrays of other shapes or not finite.
    """

    poses: np.ndarray
    agents: np.ndarray
    agent_vels: np.ndarray
    prims: np.ndarray
    settings: PrimitiveSettings
    tee: TeeGeometry = GYM_TEE

    def __post_init__(self) -> None:
        n = len(np.asarray(self.prims))
        shapes = {"poses": (n, 3), "agents": (n, 2), "agent_vels": (n, 2), "prims": (n, 3)}
        check_array_fields(self, "TeePushes", shapes)

    def __len__(self) -> int:
        return len(self.prims)


class ModelTransition:
    """Outcomes predicted by a push model: its predictive mean, and its standard deviation.

    Args:
        model: A `LearnedModel` or a calibrated `QuasiStaticTee`.
        name: A label for tables (the model's name by default).
    """

    def __init__(self, model: PushModel, name: str | None = None) -> None:
        self.model = model
        self.name = name or str(getattr(model, "name", type(model).__name__))

    @property
    def observation(self) -> str | None:
        """Where the model's training poses came from (``"state"``, ``"pixels"`` or None)."""
        return self.model.observation

    def predict(
        self, pushes: TeePushes, *, n_samples: int = 0, rng: np.random.Generator | None = None
    ) -> TransitionPrediction:
        """See `probaff.planning.transitions.Transition.predict` (closed-form spread only).

        One call of the model for the N pushes; `n_samples` and `rng` are unused (its spread
        is `TransitionPrediction.effect_std`).
        """
        geo = push_frames(pushes.prims, pushes.settings, pushes.tee)
        travel = pushes.settings.gap + pushes.prims[:, 2]
        X = np.column_stack([geo["start"], geo["direction"], travel])
        model = self.model
        if isinstance(model, QuasiStaticTee) and model.tee is not pushes.tee:
            model = dataclasses.replace(model, tee=pushes.tee)  # the T as observed
        mean, std = predict_moments(model, X)
        pose = pushes.poses
        yaw = pose[:, 2] + geo["yaw"]
        c, s = np.cos(yaw), np.sin(yaw)
        dx = c * mean[:, 1] - s * mean[:, 0]
        dy = s * mean[:, 1] + c * mean[:, 0]
        after = np.column_stack([pose[:, 0] + dx, pose[:, 1] + dy, pose[:, 2] + mean[:, 2]])
        ends = to_world(pose, (geo["start"] + geo["direction"] * travel[:, None])[:, None])[:, 0]
        pusher = np.column_stack([ends, np.zeros_like(ends)])
        return TransitionPrediction(after[:, None], effect_std=std[:, None], pusher=pusher)


class EnvTransition:
    """Outcomes simulated by a second instance of the environment (the upper bound).

    Args:
        worker: The Push-T worker whose model environment runs the rollouts.
        name: A label for tables.
    """

    def __init__(self, worker: PushTWorker, name: str = "env") -> None:
        self.worker, self.name = worker, name

    def predict(
        self, pushes: TeePushes, *, n_samples: int = 0, rng: np.random.Generator | None = None
    ) -> TransitionPrediction:
        """See `probaff.planning.transitions.Transition.predict`: deterministic rollouts.

        The pushes from one state (consecutive rows) are rolled out in one request.
        """
        poses, agents, pushers = [], [], []
        start = 0
        while start < len(pushes):
            same = (
                (pushes.poses[start:] == pushes.poses[start]).all(-1)
                & (pushes.agents[start:] == pushes.agents[start]).all(-1)
                & (pushes.agent_vels[start:] == pushes.agent_vels[start]).all(-1)
            )
            stop = start + (int(np.argmin(same)) if not same.all() else len(same))
            seqs = [
                primitive_actions(
                    pushes.poses[start], pushes.agents[start], p, pushes.settings, pushes.tee
                ).actions.tolist()
                for p in pushes.prims[start:stop]
            ]
            state = {
                "agent": pushes.agents[start].tolist(),
                "agent_vel": pushes.agent_vels[start].tolist(),
                "block": origin_pose(pushes.poses[start], pushes.tee).tolist(),
            }
            for r in self.worker.ask("rollout", state=state, sequences=seqs)["results"]:
                poses.append(cog_pose(np.array(r["block"]), pushes.tee))
                agents.append(np.array(r["agent"], dtype=float))
                pushers.append(np.array(r["agent_vel"], dtype=float))
            start = stop
        n = len(pushes)
        pusher = np.column_stack([np.reshape(agents, (n, 2)), np.reshape(pushers, (n, 2))])
        mean = np.reshape(poses, (n, 1, 3))
        return TransitionPrediction(mean, effect_std=np.zeros_like(mean), pusher=pusher)
