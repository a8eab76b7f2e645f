r"""The squared-error point prediction of a mixture of GP experts, stacked with one GP.

A mixture's predictive mean is the point that minimises the expected squared error *under
the mixture*. On held-out data it can still lose to a single GP fitted on every row: each
expert sees only its share of the rows, so where the gate is unsure, or where one output
does not follow the partition that the others chose, the experts' means are worse than one
GP's (on the demo's 64 training pushes, even the best expert per held-out push predicts
o2's displacement along the push with 4.57 cm RMSE against the single GP's 4.17 cm).

`MixtureOfGPExperts(point="stacked")` therefore predicts, per output `e`,

.. math:: \hat y_e(f) = \alpha_e\, \mu^{mix}_e(f) + (1 - \alpha_e)\, \mu^{GP}_e(f),

the mixture's mean stacked with the mean of one GP fitted on every row (Wolpert, 1992;
Breiman, 1996): `alpha_e` in [0, 1] minimises the squared error of this combination on the
training rows, each predicted out of sample. The single GP's prediction of row `i` is its
leave-one-out mean; the mixture's is `sum_j g_j(f_i) mu_j^{-i}(f_i)` with each expert's
leave-one-out mean (the EM E-step's) and the gate's probabilities from `GATE_FOLDS`-fold
cross-fitting (the gate refitted on the other folds' responsibilities with its chosen
penalty). An in-sample gate knows which regime each training row fell in from its target,
so it would credit the mixture with more than it achieves on new rows.

The predictive distribution (`predict`) is not changed: only `predict_point`. A lower
squared error is not what a planner needs: on the planning study's 100 push-to-edge episodes
(`inference/planning.py`), A* over the stacked point succeeded 87 times, against 92 over the
mixture's mean (the single GP's: 90), so the planners keep stepping with the mean.

Why it is an option (``point="stacked"``) and not the default: the leave-one-out
predictions that choose the weights are pessimistic for an expert that holds few rows (its
rows' neighbours leave with them), so where such experts carry the held-out error the
weights side with the single GP wrongly. On the Engel data (2 folds of 100 rows,
``benchmarks/mixture_peers.py``), one fold's stacked point scored SRMSE 0.82 against the
mean's 0.48 (single GP 0.85). On chapter 5's pushes it scored 0.729 against the mean's
0.765 and the single GP's 0.738 (5 folds, ``benchmarks/mixture_ablation.py``).
"""

from __future__ import annotations

import copy

import torch
from torch import Tensor

__all__ = ["GATE_FOLDS", "MIN_STACK_ROWS", "POINT_KINDS", "out_of_fold_gate", "stacking_weights"]

POINT_KINDS = ("stacked", "mean")
"""The values of `MixtureOfGPExperts`'s ``point=``."""

GATE_FOLDS = 5
"""Folds of the gate's cross-fitting for the stacking weights."""

MIN_STACK_ROWS = 2 * GATE_FOLDS
"""Fewest training rows that get stacking weights; smaller fits predict the mixture's mean."""


def out_of_fold_gate(gate: torch.nn.Module, x_gate: Tensor, resp: Tensor, seed: int) -> Tensor:
    """Gate probabilities of every training row from a gate fitted without its fold.

    Args:
        gate: The fitted `SoftmaxGate` (left untouched; copies are refitted with its penalty).
        x_gate: Gate features of the training rows, `(N, D_g)`.
        resp: The responsibilities the gate was fitted to, `(N, M)`.
        seed: Seed of the random assignment of rows to folds.

    Returns:
        Rows summing to 1, `(N, M)`.
    """
    n = x_gate.shape[0]
    order = torch.randperm(n, generator=torch.Generator().manual_seed(seed))
    fold = torch.empty(n, dtype=torch.long)
    fold[order] = torch.arange(n) % GATE_FOLDS
    fold = fold.to(x_gate.device)
    probs = torch.empty_like(resp)
    for k in range(GATE_FOLDS):
        out = fold == k
        part = copy.deepcopy(gate)
        part.fit(x_gate[~out], resp[~out], reuse_choice=True)  # type: ignore[operator]
        probs[out] = part.predict_proba(x_gate[out])  # type: ignore[operator]
    return probs


def stacking_weights(mixture_mean: Tensor, single_mean: Tensor, Y: Tensor) -> Tensor:
    """Least-squares weights of two out-of-sample predictions, per output, in [0, 1].

    Args:
        mixture_mean: The mixture's out-of-sample means of the training rows, `(N, E)`.
        single_mean: The single GP's leave-one-out means of the same rows, `(N, E)`.
        Y: The training targets, `(N, E)`.

    Returns:
        `alpha` `(E,)`: the weight of the mixture's mean in each output's point prediction
        (1 where both predictions coincide).
    """
    diff = mixture_mean - single_mean
    num = ((Y - single_mean) * diff).sum(0)
    den = (diff * diff).sum(0)
    alpha = torch.where(den > 0, num / den.clamp_min(torch.finfo(den.dtype).tiny), 1.0)
    return alpha.clamp(0.0, 1.0)
