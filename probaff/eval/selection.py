"""Choosing the number of experts of a mixture by cross-validated NLPD.

The thesis picked the number of experts by hand; here each candidate M is fitted on K-1 folds
and scored on the held-out fold, and the M with the lowest mean negative log predictive
density wins (RMSE is reported alongside).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import torch
from sklearn.model_selection import KFold

from probaff._checks import check_count
from probaff.errors import InputError
from probaff.eval.metrics import nlpd, rmse
from probaff.models import MixtureOfGPExperts, fit_em
from probaff.models.tensors import as_matrix

__all__ = ["ExpertSelection", "select_n_experts"]


@dataclass(frozen=True)
class ExpertSelection:
    """Outcome of `select_n_experts`.

    Attributes:
        best: The chosen number of experts.
        nlpd: Candidate M -> mean held-out NLPD (summed over effect dimensions).
        rmse: Candidate M -> (E,) mean held-out RMSE.
    """

    best: int
    nlpd: dict[int, float]
    rmse: dict[int, list[float]]


def _default_model(m: int) -> MixtureOfGPExperts:
    return MixtureOfGPExperts(m)  # the experts' default settings, MIXTURE_GP (prior on)


def _default_fit(model: Any, X: torch.Tensor, Y: torch.Tensor, seed: int) -> None:
    fit_em(model, X, Y, seed=seed)


def select_n_experts(
    X: Any,
    Y: Any,
    candidates: Sequence[int] = (1, 2, 3, 4, 5, 6),
    folds: int = 3,
    seed: int = 0,
    make_model: Callable[[int], Any] = _default_model,
    fit: Callable[[Any, torch.Tensor, torch.Tensor, int], None] = _default_fit,
) -> ExpertSelection:
    """Pick the number of experts by K-fold cross-validated NLPD.

    Args:
        X: Features, (N, D).
        Y: Effects, (N, E).
        candidates: Numbers of experts to try (positive integers).
        folds: K (an integer in ``[2, N]``).
        seed: Seed of the folds and the fits (an integer >= 0).
        make_model: ``make_model(M)`` returns an unfitted model with a ``predict`` method
            returning a distribution over (N, E); default an EM mixture with the length-scale
            prior.
        fit: ``fit(model, X_train, Y_train, seed)``; default `fit_em`.

    Returns:
        The selection and the scores of every candidate.

    Raises:
        InputError: For fewer than 2 folds, a fold count, seed or candidate that is not an
            integer, no candidates, or a candidate larger than a training fold.
    """
    x = as_matrix("features X", X)
    y = as_matrix("effects Y", Y, n_rows=x.shape[0])
    folds = check_count("folds", folds, minimum=2)
    if folds > x.shape[0]:
        raise InputError(f"folds must lie in [2, {x.shape[0]}], got {folds}.")
    seed = check_count("seed", seed, minimum=0)
    if not candidates:
        raise InputError("give at least one candidate number of experts.")
    candidates = [check_count(f"candidates[{i}]", m) for i, m in enumerate(candidates)]
    splits = list(KFold(folds, shuffle=True, random_state=seed).split(x.numpy()))
    smallest = min(len(tr) for tr, _ in splits)
    if max(candidates) > smallest:
        raise InputError(
            f"{max(candidates)} experts exceed the {smallest} samples of a training fold; "
            "use fewer experts or fewer folds."
        )
    scores: dict[int, float] = {}
    errors: dict[int, list[float]] = {}
    for m in candidates:
        nl, rm = [], []
        for train, test in splits:
            model = make_model(m)
            fit(model, x[train], y[train], seed)
            pred = model.predict(x[test])
            nl.append(float(nlpd(pred, y[test]).sum()))
            rm.append(rmse(pred, y[test]).numpy())
        scores[m] = float(np.mean(nl))
        errors[m] = np.mean(rm, axis=0).tolist()
    best = min(scores, key=lambda m: scores[m])
    return ExpertSelection(best=best, nlpd=scores, rmse=errors)
