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
from typing import Protocol, runtime_checkable

import numpy as np
import torch

from probaff.data.queries import PushQueries
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
        self.model = model
        self.task = task
        self.name = name
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
            samples = apply_effects(book[None, :, None], draws[:, :, None], yaws[None])[:, :, 0]
        return TransitionPrediction(mean, samples)


class SimulatorTransition:
    """The true simulator with nominal physics, one push at a time.

    Args:
        task: The task.
        name: A label for tables.
    """

    def __init__(self, task: EdgeTask, name: str = "simulator") -> None:
        self.task = task
        self.name = name
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
        step: Resolution (m) of the search for where the battery stops the book.
        name: A label for tables.
    """

    def __init__(self, task: EdgeTask, step: float = 0.005, name: str = "quasi-static") -> None:
        self.task = task
        self.step = step
        self.name = name
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
        s = np.arange(0.0, travel + 1e-9, self.step)  # (T,)
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
        xy_resolution: Cell size (m).
        yaw_bins: Yaw bins per turn.
    """

    def __init__(self, task: EdgeTask, xy_resolution: float = 0.01, yaw_bins: int = 64) -> None:
        self.arm: Arm = load_arm(task.world.arm)
        self.distance = task.push_distance
        self.res = xy_resolution
        self.bins = yaw_bins
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
