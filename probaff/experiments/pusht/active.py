"""Training pushes chosen by information gain: the push that teaches the model most, next.

The thesis chooses the action that most reduces uncertainty; here it is applied to the push
model's own training data. After `ActiveOptions.start` random pushes, the mixture of GP experts
is fitted (EM, `fit_learned`) and every next push is chosen from `ActiveOptions.pool` feasible
primitives sampled at the T's current pose, by one of three scores:

* ``"information"``: the push whose observation tells the most (nats) about the mixture's
  predictions of the pushes a planner asks about (`reduction_chooser`:
  `probaff.models.mixture.integrated_variance_reduction` with ``measure="information"``, over
  `ActiveOptions.reference` primitives drawn as the planner draws its candidates): the
  thesis's information gain, in which each effect counts whatever its units;
* ``"reduction"``: the same, but the predictive variance it removes (Cohn's criterion);
* ``"variance"``: the push whose predicted effect has the largest predictive variance
  (`predictive_spread`: the law of total variance over the experts, so both the experts' own
  uncertainty and their disagreement count). It favours pushes unlike any other, which a
  planner seldom needs.

The two variances count a turn as the arc it moves the T's corners through
(`_output_weights`). The model is refitted every
`ActiveOptions.refit_every` pushes. ``strategy="random"`` runs the same loop with random pushes
(`probaff.experiments.pusht.data`'s), the baseline.

Pushes are recorded as `probaff.experiments.pusht.data` records them (the same fields, resets
and limits), so `push_dataset` reads them; a collection of N pushes is the first N of any
longer one with the same seed and options (the refits happen at the same counts).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import torch

from probaff._checks import check_count
from probaff._threads import limit_threads
from probaff.errors import InputError
from probaff.experiments.pusht.data import Chooser, push_dataset, record_pushes, with_worker
from probaff.experiments.pusht.env import PushTWorker
from probaff.experiments.pusht.geometry import GYM_TEE
from probaff.experiments.pusht.models import (
    LearnedModel,
    PushModel,
    fit_learned,
    predict_moments,
    push_effects,
    push_features,
)
from probaff.experiments.pusht.primitives import (
    PrimitiveSettings,
    feasible_starts,
    push_frames,
    sample_primitives,
)
from probaff.models import EMOptions
from probaff.models.mixture import integrated_variance_reduction

__all__ = [
    "STRATEGIES",
    "ActiveOptions",
    "collect_pushes",
    "predictive_spread",
    "primitive_features",
    "record_chosen",
    "reduction_chooser",
    "variance_chooser",
]

STRATEGIES = ("information", "reduction", "variance", "random")
"""How training pushes are chosen: by the information they give or the variance they remove
at the planner's queries, by the model's predictive variance, or at random."""


@dataclass(frozen=True)
class ActiveOptions:
    """How training pushes are collected.

    Attributes:
        budget: Pushes recorded in all (a positive integer).
        strategy: ``"information"``, ``"reduction"``, ``"variance"`` (module doc) or
            ``"random"``.
        start: Random pushes before the first fit (at least 5, at most `budget`).
        refit_every: Pushes between two refits, k.
        pool: Candidate primitives scored per chosen push.
        experts: Experts M of the mixture fitted to choose.
        em: The EM fits made to choose (their seed is the collection's).
        reference: Primitives drawn per choice as the planner's queries (``"information"``,
            ``"reduction"``).

    Raises:
        InputError: For a budget, start, refit interval, pool or expert count that is not a
            positive integer, a start outside [5, budget], or an unknown strategy; a
            reference size that is not a positive integer.
    """

    budget: int
    strategy: str = "variance"
    start: int = 10
    refit_every: int = 10
    pool: int = 64
    experts: int = 2
    em: EMOptions = field(default=EMOptions(max_iter=5, n_restarts=1, split_merge=0))
    reference: int = 256

    def __post_init__(self) -> None:
        if isinstance(self.budget, bool) or not isinstance(self.budget, int) or self.budget < 1:
            raise InputError(
                f"the active-learning budget must be a positive integer (pushes to record), got "
                f"{self.budget!r}; pass e.g. ActiveOptions(budget=60)."
            )
        for name in ("start", "refit_every", "pool", "experts", "reference"):
            check_count(f"ActiveOptions.{name}", getattr(self, name))
        if not 5 <= self.start <= self.budget:
            raise InputError(
                f"ActiveOptions.start must be between 5 and the budget ({self.budget}) random "
                f"pushes before the first fit, got {self.start}."
            )
        if self.strategy not in STRATEGIES:
            raise InputError(
                f"ActiveOptions.strategy must be one of {list(STRATEGIES)}, got {self.strategy!r}."
            )


def primitive_features(prims: np.ndarray, settings: PrimitiveSettings) -> np.ndarray:
    """(K, 5) model features (`probaff.experiments.pusht.models.FEATURES`) of (K, 3) primitives.

    The block-frame start (px), the push's block-frame direction (cos, sin) and the target's
    travel (px), as the planner asks its model.
    """
    geo = push_frames(prims, settings)
    return np.column_stack([geo["start"], geo["direction"], settings.gap + prims[:, 2]])


def predictive_spread(
    model: PushModel, X: np.ndarray, radius: float = GYM_TEE.radius
) -> np.ndarray:
    """(K,) predictive variance (px^2) of the effects of (K, 5) features.

    ``var(dy_p) + var(dz_p) + (radius * sd(dtheta))^2``: the turn counted as the arc it moves
    the T's corners through, at their RMS `radius` (px).
    """
    _, std = predict_moments(model, X)
    return np.asarray((std**2 * _output_weights(radius)).sum(axis=1))


def _output_weights(radius: float = GYM_TEE.radius) -> np.ndarray:
    """(3,) weights of (dy_p, dz_p, dtheta) variances: a turn as the arc at `radius` (px)."""
    return np.array([1.0, 1.0, radius**2])


def _best_feasible(
    pool: int,
    settings: PrimitiveSettings,
    score: Callable[[np.random.Generator, np.ndarray], Any],
) -> Chooser:
    """A chooser of the best-scored of `pool` primitives feasible at the T's pose.

    `score(rng, features)` scores the (K, 5) features of the feasible ones (`argmax` is
    taken); where none is feasible the first primitive drawn is returned.
    """

    def choose(rng: np.random.Generator, pose: np.ndarray, agent: np.ndarray) -> np.ndarray:
        prims = sample_primitives(rng, pool, settings)
        ok = prims[feasible_starts(pose, prims, settings)]
        if len(ok) == 0:
            return np.asarray(prims[0])
        return np.asarray(ok[int(np.argmax(score(rng, primitive_features(ok, settings))))])

    return choose


def reduction_chooser(
    model: LearnedModel,
    pool: int,
    settings: PrimitiveSettings,
    reference: int = 256,
    measure: str = "variance",
) -> Chooser:
    """A chooser of the push whose observation most informs the planner's queries.

    Args:
        model: The current push model (a `LearnedModel` with exact GP experts).
        pool: Primitives sampled per choice; the feasible ones are scored.
        settings: The primitives' settings.
        reference: Primitives drawn per choice (`sample_primitives`, the planner's draw) at
            which the score is averaged.
        measure: ``"variance"`` (the variance removed, the turn as its arc) or
            ``"information"`` (nats, every effect alike).
    """
    weights = _output_weights() if measure == "variance" else None

    def score(rng: np.random.Generator, features: np.ndarray) -> np.ndarray:
        queries = primitive_features(sample_primitives(rng, reference, settings), settings)
        with torch.no_grad():
            gain = integrated_variance_reduction(
                model.model, features, queries, output_weights=weights, measure=measure
            )
        return gain.cpu().numpy()

    return _best_feasible(pool, settings, score)


def variance_chooser(model: PushModel, pool: int, settings: PrimitiveSettings) -> Chooser:
    """A chooser (`probaff.experiments.pusht.data.Chooser`) of the push of largest variance.

    Args:
        model: The current push model.
        pool: Primitives sampled per choice; the feasible ones are scored.
        settings: The primitives' settings.
    """
    return _best_feasible(pool, settings, lambda rng, features: predictive_spread(model, features))


def _fit(rows: dict[str, list[Any]], options: ActiveOptions, seed: int) -> LearnedModel:
    ds = push_dataset([rows], seed)
    em = dataclasses.replace(options.em, seed=seed)
    with limit_threads(1):
        model, _ = fit_learned(
            "moe", push_features(ds), push_effects(ds), experts=options.experts, em=em
        )
    return model


def record_chosen(
    w: PushTWorker,
    seed: int,
    options: ActiveOptions,
    settings: PrimitiveSettings,
) -> dict[str, Any]:
    """Record `options.budget` pushes chosen by `options.strategy` (see the module doc).

    Args:
        w: The Push-T worker.
        seed: Seeds the resets, the candidates and the fits.
        options: Budget, strategy and refits.
        settings: The primitives' settings.

    Returns:
        `probaff.experiments.pusht.data.record_chunk`'s lists, and ``refits``: the pushes
        recorded at each refit.
    """
    rng = np.random.default_rng(np.random.SeedSequence(int(seed), spawn_key=(2,)))
    rows = dict(record_pushes(w, rng, options.start, settings))
    refits: list[int] = []
    while len(rows["before"]) < options.budget:
        n = min(options.refit_every, options.budget - len(rows["before"]))
        choose: Chooser | None = None
        if options.strategy != "random":
            refits.append(len(rows["before"]))
            model = _fit(rows, options, seed)
            if options.strategy == "variance":
                choose = variance_chooser(model, options.pool, settings)
            else:
                measure = "variance" if options.strategy == "reduction" else "information"
                choose = reduction_chooser(
                    model, options.pool, settings, options.reference, measure
                )
        more = record_pushes(w, rng, n, settings, choose)
        rows = {k: rows[k] + more[k] for k in rows}
    return {**rows, "refits": refits}


def collect_pushes(
    seed: int, options: ActiveOptions, settings: PrimitiveSettings, python: str | None
) -> dict[str, Any]:
    """`record_chosen` on this process's worker (restarted once if it dies)."""
    return dict(with_worker(python, record_chosen, seed, options, settings))
