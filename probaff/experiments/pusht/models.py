"""Push models of the T: features, the learned mixtures, the analytic quasi-static model.

Features (`push_features`, from a dataset's observation arrays only): where the pusher starts
in the block frame (px), the push direction in the block frame (cos, sin) and the target's
travel (px). Effects (`push_effects`): the dataset's pushing-frame effect ``(dy_p, dz_p,
dtheta)`` of the centre of gravity, in px and rad (``z_p`` along the push).

Learned models are probaff's `MixtureOfGPExperts` fitted by EM (`probaff.models.fit`), with
M experts (M = 1 is the single GP). The analytic baseline (`QuasiStaticTee`) is derived from
gym-pusht's physics under stated assumptions:

* the block's velocity is cancelled at every physics step (gym-pusht's space damping is 0), so
  each step the contact impulse ``J`` gives the block the twist ``V = M^-1 J`` with ``M =
  diag(m, m, I)``: an ellipsoidal limit surface whose ratio is the radius of gyration,
  ``rho^2 = I / m`` (`TeeGeometry.inertia`, m = 1), with the block turning about its centre of
  gravity;
* the contact is frictionless (gym-pusht gives its shapes no friction), so the impulse lies
  along the contact normal ``n``, and the block moves just enough that the pusher does not
  penetrate it: a normal push depth ``delta`` moves the block by
  ``lambda (n, (c x n) / rho^2)`` with ``lambda = delta / (1 + (c x n)^2 / rho^2)``;
* the pusher follows its target exactly (no lag), in `QuasiStaticTee.substeps` steps.

Its T is gym-pusht's by default (`GYM_TEE`: its source's outline, centre of gravity and
inertia); from pixels it is the perceived outline's, of uniform density
(`TeeGeometry.from_shape`).

Its predictive distribution is a Normal around that prediction with the standard deviation of
its residuals on the training pushes.

Where the training poses came from. A model remembers it (`LearnedModel.observation`,
`QuasiStaticTee.observation`: ``"state"`` or ``"pixels"``, `probaff.experiments.pusht.data
.dataset_observation`): pushes recorded from the simulator's state are exact and in gym-pusht's
T frame; pushes recorded from pixels carry the perception's noise and are in the perceived T's
frame. `check_model_observation` refuses (`ObservationMismatchError`) to plan from one with a
model fitted on the other, unless allowed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch
from torch.distributions import Distribution, Independent, Normal

from probaff.data import PushDataset
from probaff.errors import InputError
from probaff.eval.metrics import interval_coverage, marginal_components, nlpd, rmse
from probaff.experiments.pusht.geometry import (
    AGENT_RADIUS,
    GYM_TEE,
    PX,
    TeeGeometry,
    distance_to_tee,
    to_block,
)
from probaff.models import EMOptions, MixtureOfGPExperts, fit

__all__ = [
    "FEATURES",
    "LearnedModel",
    "ObservationMismatchError",
    "PushModel",
    "QuasiStaticTee",
    "check_model_observation",
    "evaluate",
    "fit_learned",
    "predict_moments",
    "push_effects",
    "push_features",
]

FEATURES = ("start_x", "start_y", "dir_cos", "dir_sin", "travel")
"""The feature columns a Push-T model is fitted on (px, px, 1, 1, px)."""


def push_features(ds: PushDataset) -> np.ndarray:
    """(N, 5) features of a push dataset's pushes (`FEATURES`), from observations only."""
    before = ds.arrays["state_before"][:, 0] / [PX, PX, 1.0]
    origin = ds.arrays["push_origin"] / PX
    start = np.stack([to_block(b, o[None])[0] for b, o in zip(before, origin, strict=True)])
    psi = ds.arrays["push_yaw"] - before[:, 2]
    travel = ds.arrays["push_distance"] / PX
    return np.column_stack([start, np.cos(psi), np.sin(psi), travel])


def push_effects(ds: PushDataset) -> np.ndarray:
    """(N, 3) pushing-frame effects ``(dy_p, dz_p, dtheta)`` in px, px, rad."""
    return ds.arrays["effect"][:, 0] / [PX, PX, 1.0]


@dataclass
class LearnedModel:
    """A fitted mixture with what it was fitted on.

    Attributes:
        name: ``"moe"`` or ``"gp"``.
        model: The fitted `MixtureOfGPExperts`.
        features: The feature columns it was fitted on (`FEATURES`).
        observation: Where the poses of its training pushes came from: ``"state"`` (the
            simulator's) or ``"pixels"`` (perceived); see `check_model_observation`.
    """

    name: str
    model: Any
    features: tuple[str, ...] = FEATURES
    observation: str = "state"

    def predict(self, X: np.ndarray) -> Distribution:
        """The predictive distribution of the effects of (K, 5) features.

        Raises:
            InputError: If the model was fitted on other features.
        """
        width = getattr(self.model, "n_features", len(FEATURES))
        if tuple(self.features) != FEATURES or width != len(FEATURES):
            raise InputError(
                f"model {self.name!r} was fitted on features {list(self.features)} ({width} "
                f"columns), but Push-T plans with {list(FEATURES)}; refit it on push_features."
            )
        with torch.no_grad():
            return self.model.predict(torch.as_tensor(X, dtype=torch.float64))


@dataclass
class QuasiStaticTee:
    """The analytic quasi-static model of a frictionless round pusher on the T (module doc).

    Attributes:
        sigma: (3,) standard deviation of its residuals (px, px, rad), set by `calibrate`.
        substeps: Integration steps per push.
        iterations: Projection iterations per step.
        name: A label for tables.
        tee: The T it pushes: its outline, centre of gravity and inertia.
        observation: Where the poses of the pushes `sigma` was calibrated on came from
            (``"state"`` or ``"pixels"``); None when it was not calibrated on recorded
            pushes (a hand-set `sigma`), which plans from either.
    """

    sigma: np.ndarray | None = None
    substeps: int = 40
    iterations: int = 3
    name: str = "analytic"
    tee: TeeGeometry = GYM_TEE
    observation: str | None = None

    def effects(self, X: np.ndarray) -> np.ndarray:
        """(K, 3) predicted pushing-frame effects of (K, 5) features."""
        X = np.asarray(X, dtype=float)
        pose = np.zeros((len(X), 3))  # the block relative to its start (centre of gravity, angle)
        direction = X[:, 2:4]
        rho2 = self.tee.inertia
        for i in range(1, self.substeps + 1):
            pusher = X[:, :2] + direction * (X[:, 4:5] * i / self.substeps)
            for _ in range(self.iterations):
                c, s = np.cos(pose[:, 2]), np.sin(pose[:, 2])
                rel = pusher - pose[:, :2]
                local = np.stack([c * rel[:, 0] + s * rel[:, 1], c * rel[:, 1] - s * rel[:, 0]], -1)
                d, near = distance_to_tee(local, self.tee)
                depth = AGENT_RADIUS - d
                hit = depth > 1e-9
                if not hit.any():
                    break
                n = (local - near) / np.maximum(d, 1e-9)[:, None]
                cross = near[:, 0] * n[:, 1] - near[:, 1] * n[:, 0]
                lam = np.where(hit, depth / (1 + cross**2 / rho2), 0.0)
                move = -lam[:, None] * n
                pose[:, 0] += c * move[:, 0] - s * move[:, 1]
                pose[:, 1] += s * move[:, 0] + c * move[:, 1]
                pose[:, 2] += -lam * cross / rho2
        yaw = np.arctan2(direction[:, 1], direction[:, 0])
        c, s = np.cos(yaw), np.sin(yaw)
        along = c * pose[:, 0] + s * pose[:, 1]
        across = -s * pose[:, 0] + c * pose[:, 1]
        return np.column_stack([across, along, pose[:, 2]])

    def calibrate(self, X: np.ndarray, Y: np.ndarray) -> QuasiStaticTee:
        """Set `sigma` to the residuals' standard deviation on (N, 5) features, (N, 3) effects."""
        resid = self.effects(X) - np.asarray(Y, dtype=float)
        self.sigma = np.sqrt((resid**2).mean(axis=0)) + 1e-6
        return self

    def predict(self, X: np.ndarray) -> Distribution:
        """A Normal over the effects of (K, 5) features (independent dimensions)."""
        if self.sigma is None:
            raise InputError("QuasiStaticTee has no residual scale; call calibrate first.")
        loc = torch.as_tensor(self.effects(X))
        scale = torch.as_tensor(np.broadcast_to(self.sigma, loc.shape).copy())
        return Independent(Normal(loc, scale), 1)


PushModel = LearnedModel | QuasiStaticTee
"""A Push-T push model: a fitted mixture (or single GP), or the calibrated analytic model."""

_POSES = {"state": "the simulator's state", "pixels": "poses perceived from pixels"}


class ObservationMismatchError(InputError):
    """A push model fitted on pushes recorded from one observation plans from the other."""


def check_model_observation(
    model: Any, observation: str, *, allow: bool = False, name: str = "observation"
) -> None:
    """Refuse to plan from `observation` with a model fitted on pushes recorded otherwise.

    A model fitted on state-recorded pushes has learned exact effects in gym-pusht's T frame;
    planning from perceived poses it meets the perception's noise and the perceived T's frame
    (and the reverse for a model fitted on perceived pushes), which it was never shown.

    Args:
        model: A push model; its ``observation`` attribute (``"state"``, ``"pixels"``, or
            None/absent: not fitted on recorded pushes, which plans from either) is read.
        observation: What the planner observes: ``"state"`` or ``"pixels"``.
        allow: Plan with it anyway (an explicit choice, e.g. to measure what the mismatch
            costs).
        name: The argument's name in the message.

    Raises:
        ObservationMismatchError: If the two differ and not `allow`.
    """
    fitted = getattr(model, "observation", None)
    if fitted is None or fitted == observation or allow:
        return
    label = getattr(model, "name", type(model).__name__)
    raise ObservationMismatchError(
        f"{name}={observation!r} plans from {_POSES.get(observation, repr(observation))}, but "
        f"model {label!r} was fitted on pushes recorded from {_POSES.get(fitted, repr(fitted))} "
        f"(its observation={fitted!r}); record its training pushes with "
        f"observation={observation!r} (record_chunk(..., observation={observation!r}); the "
        f"study's --observation {observation} does) and refit it, or pass "
        "allow_observation_mismatch=True to plan with it anyway."
    )


def predict_moments(model: Any, X: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The predictive mean and standard deviation of each effect, (K, 3) each."""
    if isinstance(model, QuasiStaticTee):
        if model.sigma is None:
            raise InputError("QuasiStaticTee has no residual scale; call calibrate first.")
        effects = model.effects(X)
        return effects, np.broadcast_to(model.sigma, effects.shape).copy()
    w, loc, scale = (t.double() for t in marginal_components(model.predict(X)))
    mean = (w[..., None] * loc).sum(1)
    var = (w[..., None] * (scale**2 + loc**2)).sum(1) - mean**2
    return mean.numpy(), var.clamp_min(0).sqrt().numpy()


def fit_learned(
    name: str,
    X: np.ndarray,
    Y: np.ndarray,
    *,
    experts: int,
    em: EMOptions,
    observation: str = "state",
) -> tuple[LearnedModel, float]:
    """Fit a mixture of `experts` GP experts by EM (1: the single GP); it and its EM objective.

    Args:
        name: The model's name.
        X: (N, 5) features.
        Y: (N, 3) effects.
        experts: Number of experts M.
        em: EM settings (their seed is the study's).
        observation: Where the pushes' poses came from (``"state"`` or ``"pixels"``:
            `probaff.experiments.pusht.data.dataset_observation`), kept on the model.
    """
    model = MixtureOfGPExperts(experts)  # gp=MIXTURE_GP: the length-scale prior on
    history = fit(
        model,
        torch.as_tensor(X, dtype=torch.float64),
        torch.as_tensor(Y, dtype=torch.float64),
        options=em,
    )
    score = getattr(history, "objective", getattr(history, "log_likelihood", math.nan))
    value = float(score[-1]) if isinstance(score, list | tuple) and score else math.nan
    return LearnedModel(name, model, observation=observation), value


def evaluate(model: Any, X: np.ndarray, Y: np.ndarray) -> dict[str, float]:
    """Held-out RMSE (px, px, rad), NLPD (nats, summed over dimensions) and 90 % coverage.

    Args:
        model: A `LearnedModel` or a calibrated `QuasiStaticTee`.
        X: (N, 5) test features.
        Y: (N, 3) test effects.
    """
    dist = model.predict(X)
    y = torch.as_tensor(Y, dtype=torch.float64)
    err, nl, cov = rmse(dist, y), nlpd(dist, y), interval_coverage(dist, y, level=0.9)
    return {
        "rmse_y": float(err[0]),
        "rmse_z": float(err[1]),
        "rmse_theta": float(err[2]),
        "nlpd": float(nl.sum()),
        "coverage90": float(cov.mean()),
    }
