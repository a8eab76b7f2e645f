"""What a planner scores: where candidate pushes leave the objects, by one transition protocol.

Every planner asks a `Transition` one batched question: for N candidate pushes (a
`PushBatch`: the K objects' world poses before each, a hand start and a push yaw each, one push
length), where do the objects end up? The answer is a `TransitionPrediction`: the (N, K, 3)
predicted poses and, for a probabilistic model asked for them, (S, N, K, 3) draws from its
predictive distribution. A task adapts its own state to this shape (the push-to-edge task's
book and battery are K = 2 objects, of which only the book moves; the tool push's tool and
target are K = 2 objects that both move); object 0 is always the pushed one.

Implementations:

- `LearnedTransition`: a fitted push model with its features (`FeaturePushModel`) predicts the
  pushing-frame effects ``(dy_p, dz_p, dtheta_p)`` of the first M objects (M = its outputs / 3:
  the book alone for chapter 4's models, the tool and the target for chapter 5's); the others
  stay where they are. Its answer is the predictive mean, and it draws samples when asked.
- `SimulatorTransition`: the true simulator with the catalogue's nominal masses and frictions
  and uniform pressure (an episode's randomised physics stays unknown to it), on an ideal
  straight hand path: the upper bound. Deterministic.
- `QuasiStaticTransition`: the limit-surface model of `probaff.sim.friction` simplified for
  centred pushes of a uniform object: by symmetry the limit surface's answer to a push through
  the centre is a pure translation along the push (no turn). The hand meets object 0 after
  ``start_gap`` and carries it the remaining ``L - start_gap``; every other object is an
  obstacle that cannot move and stops object 0 where their footprints (`probaff.planning
  .geometry`, circles as their bounding squares) would meet. What it ignores: friction at the
  fingertips turning the object, uneven pressure, momentum after the hand stops, obstacles
  that give way. Deterministic.

`check_transition`, `check_moves` and `checked_prediction` are the planners' guards: a model
that is not a transition, that predicts the effects of fewer objects than the task moves, or
whose predictions are of the wrong shape or not finite, is refused with an `InputError` that
names it.

Covered by tests/planning/test_planning_transitions.py.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Protocol, TypeVar, runtime_checkable

import numpy as np
import torch
from torch.distributions import Distribution

from probaff._checks import (
    check_array_fields,
    check_count,
    check_positive,
)
from probaff.data.queries import PushQueries
from probaff.errors import InputError
from probaff.planning._checks import check_instance
from probaff.planning.geometry import boxes_overlap
from probaff.planning.learned import apply_effects
from probaff.sim.runner import straight_path
from probaff.sim.specs import ObjectSpec
from probaff.sim.tabletop import SceneInstance, simulate_push
from probaff.sim.tabletop_config import TabletopSpec

__all__ = [
    "LearnedTransition",
    "PushBatch",
    "Pushes",
    "QuasiStaticTransition",
    "QueryModel",
    "SimulatorTransition",
    "Transition",
    "TransitionPrediction",
    "check_moves",
    "check_transition",
    "checked_prediction",
]


@dataclass(frozen=True)
class TransitionPrediction:
    """Predicted outcomes of N candidate pushes.

    Attributes:
        mean: (N, K, 3) predicted world ``(x, y, theta)`` of every object after each push (a
            task adapter may hand its planner the pushed object's (N, 3) alone).
        samples: (S, N, K, 3) draws from the predictive distribution, or ``None`` for a
            deterministic model or when none were asked for.
        effect_std: (N, K, 3) predictive standard deviation of each object's pushing-frame
            effect ``(dy_p, dz_p, dtheta_p)``, for a model that gives it in closed form (zero
            for a deterministic one), or ``None``.
        pusher: (N, P) the state of what pushes after each push, for a task whose next push
            starts where the last one left it (Push-T's agent: position and velocity), or
            ``None`` where the hand is placed afresh.
    """

    mean: np.ndarray
    samples: np.ndarray | None = None
    effect_std: np.ndarray | None = None
    pusher: np.ndarray | None = None


@dataclass(frozen=True)
class PushBatch:
    """N candidate pushes of object 0 among K objects: what a transition is asked.

    Attributes:
        objects: The K catalogue objects; object 0 is the pushed one.
        poses: (N, K, 3) world poses of the objects before each push.
        origins: (N, 2) world hand starts.
        yaws: (N,) world push yaws of z_p (rad).
        distance: The hand's travel per push, d_p (m).

    Raises:
        InputError: For objects that are not catalogue objects, arrays of other shapes or
            not finite, or a distance that is not > 0.
    """

    objects: tuple[ObjectSpec, ...]
    poses: np.ndarray
    origins: np.ndarray
    yaws: np.ndarray
    distance: float

    def __post_init__(self) -> None:
        objects = tuple(self.objects) if isinstance(self.objects, (tuple, list)) else ()
        if not objects or not all(isinstance(o, ObjectSpec) for o in objects):
            raise InputError(
                "PushBatch.objects must be the K catalogue objects (ObjectSpec of "
                f"load_catalogue()), the pushed one first, got {self.objects!r}."
            )
        n = len(np.asarray(self.poses))
        shapes = {"poses": (n, len(objects), 3), "origins": (n, 2), "yaws": (n,)}
        check_array_fields(self, "PushBatch", shapes)
        check_positive("PushBatch.distance (m)", self.distance)
        object.__setattr__(self, "objects", objects)
        object.__setattr__(self, "distance", float(self.distance))

    def __len__(self) -> int:
        return len(self.poses)


Pushes = TypeVar("Pushes", contravariant=True)
"""What a transition is asked: the tabletop's `PushBatch`, or a task's own batch of pushes."""


@runtime_checkable
class Transition(Protocol[Pushes]):
    """A model of where pushes leave the objects.

    Generic in the batch it is asked (`Transition` alone: any batch): the tabletop's
    transitions read a `PushBatch`; a task whose pushes are not the tabletop's hands its own
    (Push-T's `probaff.experiments.pusht.transitions.TeePushes`) and gets the same
    `TransitionPrediction`.
    """

    name: str

    def predict(
        self, pushes: Pushes, *, n_samples: int = 0, rng: np.random.Generator | None = None
    ) -> TransitionPrediction:
        """Predict N pushes in one call.

        Args:
            pushes: The N candidate pushes and the K objects' poses before each.
            n_samples: Draws from the predictive distribution (ignored by deterministic
                models).
            rng: Randomness of the prediction (e.g. of sensed clouds); ``None`` for the
                model's own.

        Returns:
            The prediction, its mean (N, K, 3).
        """
        ...


class QueryModel(Protocol):
    """What `LearnedTransition` needs of a fitted model: `FeaturePushModel`'s interface."""

    @property
    def cloud_points(self) -> int:
        """Points per sensed object cloud."""
        ...

    @property
    def cloud_noise(self) -> float:
        """Noise (m) of the sensed clouds."""
        ...

    def predict(self, queries: PushQueries) -> Distribution:
        """Predictive distribution of the pushing-frame effects of C queries."""
        ...


def check_transition(transition: Any) -> Transition:
    """`transition`, or `InputError` unless it is a push transition model.

    Args:
        transition: What a planner was given as its model of the pushes.

    Returns:
        `transition`, unchanged.
    """
    return check_instance(
        transition,
        Transition,  # type: ignore[type-abstract]
        "transition must be a push transition model with a name and predict(pushes, "
        "n_samples=, rng=) (LearnedTransition, SimulatorTransition or QuasiStaticTransition "
        "on a PushBatch; Push-T's ModelTransition or EnvTransition on its TeePushes)",
    )


def check_moves(transition: Transition, n_objects: int, task: str, fix: str) -> None:
    """Refuse a transition whose model predicts the effects of fewer objects than the task moves.

    A `LearnedTransition` moves the first M objects its push model has effects for (M = its
    outputs / 3) and leaves the others where they are; a planner given one whose M is below
    the objects its task moves would plan as if they never moved. Transitions that do not
    say how many objects they move (`LearnedTransition.n_moved` is None, or another kind)
    are taken to move them all.

    Args:
        transition: The planner's model of the pushes.
        n_objects: The objects the task moves (the first of the (K,) objects).
        task: The task, as the message names it (e.g. ``"the tool push"``).
        fix: What model to give instead.

    Raises:
        InputError: Naming the model, its outputs and the task.
    """
    moved = getattr(transition, "n_moved", None)
    if isinstance(moved, int) and moved < n_objects:
        raise InputError(
            f"the transition model {_model_name(transition)} predicts the effects of "
            f"{moved} object(s) ({3 * moved} outputs), but {task} moves {n_objects} objects; "
            f"the others would never move in its plans. {fix}"
        )


def _model_name(model: Any) -> str:
    label = getattr(model, "name", None)
    kind = type(model).__name__
    return f"{kind} {label!r}" if isinstance(label, str) and label else kind


def checked_prediction(
    transition: Transition, pred: Any, shape: tuple[int, int], n_samples: int = 0
) -> TransitionPrediction:
    """`pred`, or `InputError` unless it holds finite poses of the asked shapes.

    A model whose predictions are NaN or infinite is broken (a bad fit, or inputs unlike its
    training data); the planners refuse its predictions instead of pruning them.

    Args:
        transition: The model that made the prediction (named in the error).
        pred: What its ``predict`` returned.
        shape: ``(N, K)``: the pushes and the objects asked for.
        n_samples: Predictive draws asked for (0: none are read).

    Returns:
        `pred`, its arrays as float arrays.
    """
    who = _model_name(transition)
    if not isinstance(pred, TransitionPrediction):
        raise InputError(
            f"the transition model {who} returned {type(pred).__name__}, not a "
            "TransitionPrediction; make its predict return TransitionPrediction(mean, samples)."
        )
    n, k = shape
    mean = np.asarray(pred.mean, dtype=float)
    samples = None if pred.samples is None else np.asarray(pred.samples, dtype=float)
    arrays: list[tuple[str, np.ndarray, tuple[int, ...]]] = [("predicted poses", mean, (n, k, 3))]
    if n_samples > 0 and samples is not None:
        arrays.append(("predictive draws", samples, (n_samples, n, k, 3)))
    for what, arr, want in arrays:
        if arr.shape != want:
            raise InputError(
                f"the transition model {who} returned {what} of shape {arr.shape}, expected "
                f"{want}; make its predict return one (x, y, theta) per object and push."
            )
        bad = int(arr.size - np.count_nonzero(np.isfinite(arr)))
        if bad:
            raise InputError(
                f"the transition model {who} predicted {bad} NaN or infinite value(s) in its "
                f"{what} of {n} push(es): its predictions are not finite; refit the model or "
                "check its inputs (features, training data)."
            )
    return TransitionPrediction(mean, samples, pred.effect_std, pred.pusher)


def _world(source: Any, owner: str) -> TabletopSpec:
    """The tabletop world of `source`: a `TabletopSpec`, or a task that holds one."""
    if isinstance(source, TabletopSpec):
        return source
    return check_instance(
        getattr(source, "world", source),
        TabletopSpec,
        f"{owner} needs the tabletop world: a TabletopSpec (load_tabletop()) or a task that "
        "holds one (load_edge_task())",
    )


class _Implementation:
    """What the implementations share: the world, a name for tables, a count of calls."""

    def __init__(self, world: Any, name: str) -> None:
        self.world = _world(world, type(self).__name__)
        if not isinstance(name, str) or not name:
            raise InputError(f"name must be a non-empty label, got {name!r}.")
        self.name = name
        self.calls = 0


class LearnedTransition(_Implementation):
    """A fitted push model of the pushing-frame effects, on the features it was fitted on.

    Each call senses one cloud per object (`PushQueries.from_states`, moved rigidly to every
    candidate's state), stacks every candidate into one query batch and asks the model once;
    the predictive mean of the first M objects' ``(dy_p, dz_p, dtheta_p)`` (M = the model's
    outputs / 3) is mapped back to world poses with `apply_effects`. Predictive draws are
    seeded by the transition's seed and its count of calls.

    Args:
        model: A fitted `FeaturePushModel` (`fit_edge_model`, `fit_tool_push_model`), or
            anything with its ``predict(queries)``, ``cloud_points`` and ``cloud_noise``.
        world: The tabletop world (its geometry goes into the queries), or a task holding it.
        seed: Seeds the cloud sensor when a call brings no generator, and the predictive
            draws, so a plan is reproducible.
        name: A label for tables.

    Raises:
        InputError: For a `model` that is not a fitted model with its features, a `world`
            that is not the tabletop, a negative seed or an empty name. A call raises it if
            the model's effects are not finite, or are not 3 per object for at most K
            objects, or the model was fitted on other features (`FeaturePushModel`).
    """

    def __init__(self, model: QueryModel, world: Any, seed: int = 0, name: str = "learned") -> None:
        needs = ("cloud_points", "cloud_noise")
        if not callable(getattr(model, "predict", None)) or not all(
            hasattr(model, a) for a in needs
        ):
            raise InputError(
                "model must be a fitted push model with its features, a FeaturePushModel "
                f"(fit_edge_model, fit_tool_push_model), got {type(model).__name__}."
            )
        super().__init__(world, name)
        self.model = model
        seed = check_count("seed", seed, minimum=0)
        self._rng = np.random.default_rng(seed)
        self._seed = seed

    def predict(
        self, pushes: PushBatch, *, n_samples: int = 0, rng: np.random.Generator | None = None
    ) -> TransitionPrediction:
        """See `Transition.predict`; one batched call of the model."""
        self.calls += 1
        poses = pushes.poses
        n, k = poses.shape[:2]
        queries = PushQueries.from_states(
            pushes.objects,
            poses,
            pushes.origins,
            pushes.yaws,
            pushes.distance,
            self.world,
            self._rng if rng is None else rng,
            cloud_points=self.model.cloud_points,
            cloud_noise=self.model.cloud_noise,
        )
        dist = self.model.predict(queries)
        effects = dist.mean.detach().cpu().numpy()
        m = self._moved(effects, n, k)
        mean = poses.copy()
        mean[:, :m] = apply_effects(poses[:, :m], effects.reshape(n, m, 3), pushes.yaws)
        if n_samples <= 0:
            return TransitionPrediction(mean)
        with torch.random.fork_rng():
            torch.manual_seed(self._seed * 1_000_003 + self.calls)
            draws = dist.sample(torch.Size([n_samples])).detach().numpy()[..., : 3 * m]
        if not np.isfinite(draws).all():
            raise InputError(
                f"the push model {self._inner} of transition {self.name!r} drew NaN or "
                "infinite effects: its predictions are not finite; refit the model or "
                "check its inputs (features, training data)."
            )
        samples = np.repeat(poses[None], n_samples, axis=0)
        samples[:, :, :m] = apply_effects(
            poses[None, :, :m], draws.reshape(n_samples, n, m, 3), pushes.yaws[None]
        )
        return TransitionPrediction(mean, samples)

    @property
    def n_moved(self) -> int | None:
        """Objects whose effects the push model predicts (its outputs / 3), None if unknown."""
        inner = getattr(self.model, "model", self.model)
        outputs = getattr(inner, "n_outputs", None)
        if isinstance(outputs, int) and outputs > 0 and outputs % 3 == 0:
            return outputs // 3
        return None

    @property
    def _inner(self) -> str:
        return type(getattr(self.model, "model", self.model)).__name__

    def _moved(self, effects: np.ndarray, n: int, k: int) -> int:
        """How many objects the model's (n, 3 M) effects move, or `InputError`."""
        if not np.isfinite(effects).all():
            raise InputError(
                f"the push model {self._inner} predicted NaN or infinite effects for {n} "
                "candidate push(es): its predictions are not finite; refit the model or check "
                "its inputs (features, training data)."
            )
        width = effects.shape[1] if effects.ndim == 2 and len(effects) == n else 0
        if width == 0 or width % 3 or width > 3 * k:
            raise InputError(
                f"the push model predicts effects of shape {effects.shape[1:]}, but a push of "
                f"{k} object(s) needs (dy_p, dz_p, dtheta_p) of its first M <= {k} objects "
                f"(3 M values); fit it on ds['effect'][:, :M].reshape(N, 3 M) "
                "(fit_edge_model, fit_tool_push_model)."
            )
        return width // 3


class SimulatorTransition(_Implementation):
    """The true simulator with nominal physics, one `simulate_push` rollout per push.

    Deterministic.

    Args:
        world: The tabletop world, or a task holding it.
        name: A label for tables.

    Raises:
        InputError: For a `world` that is not the tabletop, or an empty name.
    """

    def __init__(self, world: Any, name: str = "simulator") -> None:
        super().__init__(world, name)

    def predict(
        self, pushes: PushBatch, *, n_samples: int = 0, rng: np.random.Generator | None = None
    ) -> TransitionPrediction:
        """See `Transition.predict`; one rollout per push (`n_samples` and `rng` unused)."""
        self.calls += 1
        out = np.empty_like(pushes.poses)
        for i in range(len(pushes.poses)):
            scene = SceneInstance.nominal(
                pushes.objects,
                pushes.poses[i],
                pushes.origins[i],
                float(pushes.yaws[i]),
                pushes.distance,
                self.world.physics.friction_grid,
            )
            path = straight_path(
                self.world, pushes.origins[i], float(pushes.yaws[i]), pushes.distance
            )
            out[i] = simulate_push(self.world, scene, path).state_after
        return TransitionPrediction(out)


class QuasiStaticTransition(_Implementation):
    """The analytic quasi-static model: object 0 slides along the push until an obstacle.

    See the module docstring. Deterministic.

    Args:
        world: The tabletop world, or a task holding it (the push-to-edge task also gives
            the defaults of `start_gap` and `contact_tolerance`).
        step: Resolution (m) of the search for where an obstacle stops the pushed object (a
            finite number > 0); its path is checked at most this far apart.
        name: A label for tables.
        start_gap: Hand travel (m) before it meets object 0; the task's ``start_gap``, or 0.
        contact_tolerance: Footprints that overlap by less than this (m) touch, they do not
            collide; the task's ``contact_tolerance``, or 0.

    Raises:
        InputError: For a `world` that is not the tabletop, a `step` that is not > 0, a
            negative gap or tolerance, or an empty name.
    """

    def __init__(
        self,
        world: Any,
        step: float = 0.005,
        name: str = "quasi-static",
        *,
        start_gap: float | None = None,
        contact_tolerance: float | None = None,
    ) -> None:
        super().__init__(world, name)
        check_positive("QuasiStaticTransition step (m)", step)
        self.step = float(step)
        self.start_gap = _from_task(world, "start_gap", start_gap)
        self.contact_tolerance = _from_task(world, "contact_tolerance", contact_tolerance)

    def predict(
        self, pushes: PushBatch, *, n_samples: int = 0, rng: np.random.Generator | None = None
    ) -> TransitionPrediction:
        """See `Transition.predict` (`n_samples` and `rng` unused: it is deterministic)."""
        self.calls += 1
        poses, yaws = pushes.poses, pushes.yaws
        travel = max(pushes.distance - self.start_gap, 0.0)
        s = np.linspace(0.0, travel, max(1, math.ceil(travel / self.step - 1e-9)) + 1)  # (T,)
        d = np.stack([np.cos(yaws), np.sin(yaws)], -1)  # (N, 2)
        path = np.repeat(poses[:, 0][:, None, :], len(s), axis=1)  # (N, T, 3)
        path[..., :2] += s[None, :, None] * d[:, None, :]
        blocked = np.zeros(path.shape[:2], dtype=bool)  # (N, T)
        for k in range(1, len(pushes.objects)):
            # a push away from an obstacle is never blocked, even from a resting contact
            toward = (d * (poses[:, k, :2] - poses[:, 0, :2])).sum(-1) > 0  # (N,)
            blocked |= (
                self._hits(path, pushes.objects[0], pushes.objects[k], poses[:, k])
                & toward[:, None]
            )
        first = np.where(blocked.any(1), blocked.argmax(1), len(s))
        last = np.maximum(first - 1, 0)
        mean = poses.copy()
        mean[:, 0] = path[np.arange(len(poses)), last]
        return TransitionPrediction(mean)

    def _hits(
        self, path: np.ndarray, pushed: ObjectSpec, other: ObjectSpec, at: np.ndarray
    ) -> np.ndarray:
        """(N, T) whether the pushed object's path overlaps an obstacle at poses `at` (N, 3)."""
        hit = np.zeros(path.shape[:2], dtype=bool)
        for pose in np.unique(at, axis=0):
            rows = (at == pose).all(-1)
            sub = path if rows.all() else path[rows]
            hit[rows] = boxes_overlap(
                sub, pushed.size, pose, other.size, margin=-self.contact_tolerance
            )
        return hit


def _from_task(source: Any, name: str, given: float | None) -> float:
    """`given`, else the task's attribute `name` (0 for a bare world), checked >= 0."""
    value = getattr(source, name, 0.0) if given is None else given
    check_positive(f"QuasiStaticTransition {name} (m)", value, allow_zero=True)
    return float(value)
