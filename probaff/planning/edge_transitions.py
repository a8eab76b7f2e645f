"""Transition models of the push-to-edge planner: where a candidate push leaves the book.

Every model answers one batched question: for N candidate pushes (a book pose, a hand start
and a push yaw each, the battery where it stands), where does the book end up? Learned models
answer with the predictive mean and draws from their predictive distribution; the simulator
and the analytic quasi-static model answer with one deterministic outcome.

- `LearnedTransition`: a fitted push model (`FeaturePushModel`, chapter 4 features) predicts
  the book's pushing-frame effect.
- `SimulatorTransition`: the true simulator with the catalogue's nominal masses and frictions
  and uniform pressure (the episode's randomised physics stays unknown to it), on an ideal
  straight hand path: the upper bound.
- `QuasiStaticTransition`: the limit-surface model of `probaff.sim.friction` simplified for
  these pushes. Each push points at the book's centre and the book's pressure is taken uniform,
  so by symmetry the limit surface's answer to a centred push is a pure translation along the
  push (no turn); the hand meets the book after ``start_gap`` and carries it the remaining
  ``L - start_gap``; the battery, which cannot move, stops a book pushed towards it where
  their footprints would meet. What it ignores: friction at the fingertips turning the book,
  uneven pressure, the book's momentum after the hand stops.

`PushReachability` answers which pushes the URDF arm can execute, by IK, cached per cell.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import numpy as np
import torch

from probaff._checks import check_count, check_positive
from probaff.data.queries import PushQueries
from probaff.errors import InputError
from probaff.planning.edge_task import EdgeTask
from probaff.planning.learned import FeaturePushModel, apply_effects
from probaff.sim.arm import Arm, load_arm
from probaff.sim.runner import straight_path
from probaff.sim.tabletop import SceneInstance, simulate_push

__all__ = [
    "EdgeTransition",
    "LearnedTransition",
    "PushReachability",
    "QuasiStaticTransition",
    "SimulatorTransition",
    "TransitionPrediction",
    "check_edge_transition",
    "checked_prediction",
]


@dataclass(frozen=True)
class TransitionPrediction:
    """Predicted outcomes of N candidate pushes.

    Attributes:
        mean: (N, 3) predicted world ``(x, y, theta)`` of the book after each push.
        samples: (S, N, 3) draws from the predictive distribution, or ``None`` for a
            deterministic model.
    """

    mean: np.ndarray
    samples: np.ndarray | None = None


@runtime_checkable
class EdgeTransition(Protocol):
    """A model of where pushes leave the book."""

    name: str

    def predict(
        self,
        book: np.ndarray,
        origins: np.ndarray,
        yaws: np.ndarray,
        battery: np.ndarray,
        n_samples: int = 0,
    ) -> TransitionPrediction:
        """Predict N pushes in one call.

        Args:
            book: (N, 3) world book poses before each push.
            origins: (N, 2) world hand starts.
            yaws: (N,) world push yaws (rad).
            battery: (3,) world battery pose.
            n_samples: Draws from the predictive distribution (ignored by deterministic
                models).
        """
        ...


def check_edge_transition(transition: Any) -> EdgeTransition:
    """`transition`, or `InputError` unless it is a push transition model.

    Args:
        transition: What a planner was given as its model of the pushes.

    Returns:
        `transition`, unchanged.
    """
    if not isinstance(transition, EdgeTransition):
        raise InputError(
            "transition must be a push transition model with a name and "
            "predict(book, origins, yaws, battery, n_samples) (QuasiStaticTransition, "
            f"SimulatorTransition or LearnedTransition), got {type(transition).__name__}."
        )
    return transition


def _model_name(model: Any) -> str:
    label = getattr(model, "name", None)
    kind = type(model).__name__
    return f"{kind} {label!r}" if isinstance(label, str) and label else kind


def checked_prediction(
    transition: EdgeTransition, pred: Any, n: int, n_samples: int = 0
) -> TransitionPrediction:
    """`pred`, or `InputError` unless it holds finite poses of the asked shapes.

    A model whose predictions are NaN or infinite is broken (a bad fit, or inputs unlike
    its training data); the planners refuse its predictions instead of pruning them.

    Args:
        transition: The model that made the prediction (named in the error).
        pred: What its ``predict`` returned for `n` pushes.
        n: Pushes asked for.
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
    mean = np.asarray(pred.mean, dtype=float)
    samples = None if pred.samples is None else np.asarray(pred.samples, dtype=float)
    arrays: list[tuple[str, np.ndarray, tuple[int, ...]]] = [("predicted poses", mean, (n, 3))]
    if n_samples > 0 and samples is not None:
        arrays.append(("predictive draws", samples, (n_samples, n, 3)))
    for what, arr, shape in arrays:
        if arr.shape != shape:
            raise InputError(
                f"the transition model {who} returned {what} of shape {arr.shape}, expected "
                f"{shape}; make its predict return one (x, y, theta) per push."
            )
        bad = int(arr.size - np.count_nonzero(np.isfinite(arr)))
        if bad:
            raise InputError(
                f"the transition model {who} predicted {bad} NaN or infinite value(s) in its "
                f"{what} of {n} push(es): its predictions are not finite; refit the model or "
                "check its inputs (features, training data)."
            )
    return TransitionPrediction(mean, samples)


class LearnedTransition:
    """A learned push model of the book's effect, on chapter 4 features.

    Args:
        model: The fitted model and its features; its first three outputs are the book's
            ``(dy_p, dz_p, dtheta_p)``.
        task: The task (objects, world, push length).
        seed: Seeds the cloud sensor and the predictive draws, so a plan is reproducible.
        name: A label for tables.
    """

    def __init__(
        self, model: FeaturePushModel, task: EdgeTask, seed: int = 0, name: str = "learned"
    ) -> None:
        if not isinstance(model, FeaturePushModel):
            raise InputError(
                "model must be a fitted push model with its features, a FeaturePushModel "
                f"(fit_edge_model), got {type(model).__name__}."
            )
        self.model = model
        self.task = _check_task(task)
        self.name = _check_name(name)
        seed = check_count("seed", seed, minimum=0)
        self._rng = np.random.default_rng(seed)
        self._seed = seed
        self.calls = 0

    def predict(
        self,
        book: np.ndarray,
        origins: np.ndarray,
        yaws: np.ndarray,
        battery: np.ndarray,
        n_samples: int = 0,
    ) -> TransitionPrediction:
        """See `EdgeTransition.predict`; one batched call of the model."""
        n = len(book)
        poses = np.stack([book, np.broadcast_to(battery, (n, 3))], axis=1)  # (N, 2, 3)
        queries = PushQueries.from_states(
            (self.task.book, self.task.battery),
            poses,
            origins,
            yaws,
            self.task.push_distance,
            self.task.world,
            self._rng,
            cloud_points=self.model.cloud_points,
            cloud_noise=self.model.cloud_noise,
        )
        self.calls += 1
        dist = self.model.predict(queries)
        mean = apply_effects(book[:, None], dist.mean.detach().numpy()[:, None, :3], yaws)[:, 0]
        samples = None
        if n_samples > 0:
            with torch.random.fork_rng():
                torch.manual_seed(self._seed * 1_000_003 + self.calls)
                draws = dist.sample(torch.Size([n_samples])).detach().numpy()[..., :3]
            if not np.isfinite(draws).all():
                raise InputError(
                    f"the push model {type(self.model.model).__name__} of transition "
                    f"{self.name!r} drew NaN or infinite effects: its predictions are not "
                    "finite; refit the model or check its inputs (features, training data)."
                )
            samples = apply_effects(book[None, :, None], draws[:, :, None], yaws[None])[:, :, 0]
        return TransitionPrediction(mean, samples)


class SimulatorTransition:
    """The true simulator with nominal physics, one push at a time.

    Args:
        task: The task.
        name: A label for tables.
    """

    def __init__(self, task: EdgeTask, name: str = "simulator") -> None:
        self.task = _check_task(task)
        self.name = _check_name(name)
        self.calls = 0

    def predict(
        self,
        book: np.ndarray,
        origins: np.ndarray,
        yaws: np.ndarray,
        battery: np.ndarray,
        n_samples: int = 0,
    ) -> TransitionPrediction:
        """See `EdgeTransition.predict`; simulates every push (deterministic)."""
        t = self.task
        self.calls += 1
        out = np.empty((len(book), 3))
        for i in range(len(book)):
            scene = SceneInstance.nominal(
                (t.book, t.battery),
                np.stack([book[i], battery]),
                origins[i],
                float(yaws[i]),
                t.push_distance,
                t.world.physics.friction_grid,
            )
            path = straight_path(t.world, origins[i], float(yaws[i]), t.push_distance)
            out[i] = simulate_push(t.world, scene, path).state_after[0]
        return TransitionPrediction(out)


class QuasiStaticTransition:
    """The analytic quasi-static model (see the module docstring).

    Args:
        task: The task.
        step: Resolution (m) of the search for where the battery stops the book (a finite
            number > 0); the book's path is checked at most this far apart.
        name: A label for tables.

    Raises:
        InputError: For a `task` that is not an `EdgeTask` or a `step` that is not > 0.
    """

    def __init__(self, task: EdgeTask, step: float = 0.005, name: str = "quasi-static") -> None:
        self.task = _check_task(task)
        check_positive("QuasiStaticTransition step (m)", step)
        self.step = float(step)
        self.name = _check_name(name)
        self.calls = 0

    def predict(
        self,
        book: np.ndarray,
        origins: np.ndarray,
        yaws: np.ndarray,
        battery: np.ndarray,
        n_samples: int = 0,
    ) -> TransitionPrediction:
        """See `EdgeTransition.predict` (deterministic)."""
        t = self.task
        self.calls += 1
        travel = max(t.push_distance - t.start_gap, 0.0)
        s = np.linspace(0.0, travel, max(1, math.ceil(travel / self.step - 1e-9)) + 1)  # (T,)
        d = np.stack([np.cos(yaws), np.sin(yaws)], -1)  # (N, 2)
        path = np.repeat(book[:, None, :], len(s), axis=1)  # (N, T, 3)
        path[..., :2] += s[None, :, None] * d[:, None, :]
        # a push away from the battery is never blocked, even from a resting contact
        toward = (d * (battery[None, :2] - book[:, :2])).sum(-1) > 0  # (N,)
        blocked = t.collides(path, battery) & toward[:, None]  # (N, T)
        first = np.where(blocked.any(1), blocked.argmax(1), len(s))
        last = np.maximum(first - 1, 0)
        return TransitionPrediction(path[np.arange(len(book)), last])


class PushReachability:
    """Whether the arm can execute straight pushes, by IK, cached per cell.

    A push's start is snapped to a cell of `xy_resolution` and its yaw to one of `yaw_bins`
    (`snap`); the answer for a cell is computed once, by IK of the whole snapped push, so it
    does not depend on which pushes were asked before. An episode executes the snapped push,
    so the arm runs exactly the push whose reachability the planner was told.

    Args:
        task: The task (the world's arm, the push length).
        xy_resolution: Cell size (m), a finite number > 0.
        yaw_bins: Yaw bins per turn, a positive integer.

    Raises:
        InputError: For a `task` that is not an `EdgeTask`, an `xy_resolution` that is not
            > 0 or a `yaw_bins` that is not a positive integer.
    """

    def __init__(self, task: EdgeTask, xy_resolution: float = 0.01, yaw_bins: int = 64) -> None:
        task = _check_task(task)
        check_positive("PushReachability xy_resolution (m)", xy_resolution)
        self.bins = check_count("PushReachability yaw_bins", yaw_bins)
        self.res = float(xy_resolution)
        self.arm: Arm = load_arm(task.world.arm)
        self.distance = task.push_distance
        self._cache: dict[tuple[int, int, int], bool] = {}

    def _keys(self, origins: np.ndarray, yaws: np.ndarray) -> np.ndarray:
        ix = np.round(origins[..., 0] / self.res).astype(np.int64)
        iy = np.round(origins[..., 1] / self.res).astype(np.int64)
        iw = np.round(yaws / (2 * math.pi) * self.bins).astype(np.int64) % self.bins
        return np.stack([ix, iy, np.broadcast_to(iw, ix.shape)], -1)

    def snap(self, origins: np.ndarray, yaws: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The pushes whose reachability a cell stands for.

        Args:
            origins: (..., 2) world hand starts.
            yaws: (...,) push yaws, broadcastable.

        Returns:
            ``(origins, yaws)`` snapped to the cell centres and yaw bins.
        """
        keys = self._keys(origins, np.broadcast_to(yaws, origins.shape[:-1]))
        return keys[..., :2] * self.res, keys[..., 2] * (2 * math.pi / self.bins)

    def __call__(self, origins: np.ndarray, yaws: np.ndarray) -> np.ndarray:
        """Reachability of pushes.

        Args:
            origins: (..., 2) world hand starts.
            yaws: (...,) push yaws, broadcastable.

        Returns:
            (...,) bool.
        """
        keys = self._keys(origins, np.broadcast_to(yaws, origins.shape[:-1]))
        flat = [(int(a), int(b), int(c)) for a, b, c in keys.reshape(-1, 3)]
        missing = sorted({k for k in flat if k not in self._cache})
        if missing:
            m = torch.tensor(missing, dtype=torch.float64)
            xy = m[:, :2] * self.res
            yaw = m[:, 2] * (2 * math.pi / self.bins)
            ok = self.arm.solve_pushes(xy, yaw, self.distance).ok.numpy()
            self._cache.update(zip(missing, map(bool, ok), strict=True))
        ok = np.fromiter((self._cache[k] for k in flat), dtype=np.bool_, count=len(flat))
        return ok.reshape(keys.shape[:-1])


def _check_task(task: Any) -> EdgeTask:
    if not isinstance(task, EdgeTask):
        raise InputError(f"task must be an EdgeTask (load_edge_task()), got {type(task).__name__}.")
    return task


def _check_name(name: Any) -> str:
    if not isinstance(name, str) or not name:
        raise InputError(f"name must be a non-empty label, got {name!r}.")
    return name
