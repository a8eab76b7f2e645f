"""Penalties of a gate's weights: ridge, smoothed lasso, and the candidates cross-validation tries.

`SoftmaxGate` minimises a soft-target cross-entropy plus `penalty_value` of its weights at
strengths `(l2, l1)`; with ``"cv"`` strengths it tries `penalty_candidates` along the warm-started
`penalty_paths`.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import torch
from torch import Tensor

from probaff._checks import check_positive
from probaff.errors import InputError

__all__ = [
    "DEFAULT_L1_GRID",
    "DEFAULT_L2_GRID",
    "L1_SMOOTHING",
    "Penalty",
    "check_grid",
    "check_strength",
    "log_softmax_last",
    "penalised_gradient",
    "penalised_loss",
    "penalised_objective",
    "penalty_candidates",
    "penalty_grad",
    "penalty_paths",
    "penalty_value",
    "strength_grid",
]

DEFAULT_L2_GRID: tuple[float, ...] = (1e1, 1e0, 1e-1, 1e-2, 1e-3, 1e-4)
"""Penalties tried by ``l2="cv"`` unless `l2_grid` is given (strongest first)."""

DEFAULT_L1_GRID: tuple[float, ...] = (1e-1, 3e-2, 1e-2, 3e-3, 1e-3)
"""Lasso penalties tried by ``l1="cv"`` unless `l1_grid` is given (strongest first)."""

L1_SMOOTHING = 1e-4
"""Smoothing `eps` of the lasso, sum_k sqrt(w_k^2 + eps^2) - eps, in logit units per
standardised feature: weights below it are shrunk like a ridge, so L-BFGS stays usable."""

Penalty = tuple[float, float]
"""Strengths `(l2, l1)` of the ridge and the lasso penalty of a gate's weights."""


def penalty_value(weight: Tensor, penalty: Penalty, *, smoothing: float = L1_SMOOTHING) -> Tensor:
    r"""The smoothed elastic-net penalty of `weight` `(M, P)` at strengths `penalty`.

    :math:`\tfrac{\lambda_2}{2} \lVert W \rVert^2 + \lambda_1 \sum_k
    (\sqrt{W_k^2 + \epsilon^2} - \epsilon)` with :math:`\epsilon` = `smoothing`
    (the gate's objective uses `L1_SMOOTHING`; a solver may pass a wider one on its way there).
    """
    l2, l1 = penalty
    value = 0.5 * l2 * weight.square().sum()
    if l1 > 0.0:
        smooth = (weight.square() + smoothing**2).sqrt() - smoothing
        value = value + l1 * smooth.sum()
    return value


def penalty_grad(weight: Tensor, penalty: Penalty, *, smoothing: float = L1_SMOOTHING) -> Tensor:
    """Gradient of `penalty_value` with respect to `weight` (same shape)."""
    l2, l1 = penalty
    grad = l2 * weight
    if l1 > 0.0:
        grad = grad + l1 * weight / (weight.square() + smoothing**2).sqrt()
    return grad


def log_softmax_last(logits: Tensor) -> Tensor:
    """`log_softmax` over the last, short axis, `(..., M)` (faster than the fused kernel)."""
    shifted = logits - logits.amax(-1, keepdim=True)
    return shifted - shifted.exp().sum(-1, keepdim=True).log()


def penalised_objective(
    phi: Tensor,
    r: Tensor,
    s: Tensor,
    penalty: Penalty,
    weight: Tensor,
    bias: Tensor,
    *,
    smoothing: float = L1_SMOOTHING,
) -> tuple[Tensor, Tensor]:
    """The fitting objective of `SoftmaxGate` at `weight` `(M, P)` and `bias` `(M,)`.

    The weighted cross-entropy of targets `r` `(N, M)` under the softmax of the basis `phi`
    `(N, P)`, with sample weights `s` `(N,)` that sum to 1, plus `penalty_value` of `weight`
    (lasso smoothing `smoothing`).

    Returns:
        The loss (a scalar tensor) and the gate's log-probabilities `(N, M)`.
    """
    log_p = log_softmax_last(torch.addmm(bias, phi, weight.T))
    value = penalty_value(weight, penalty, smoothing=smoothing)
    return -(s * (r * log_p).sum(-1)).sum() + value, log_p


def penalised_gradient(
    phi: Tensor,
    r: Tensor,
    s: Tensor,
    penalty: Penalty,
    weight: Tensor,
    log_p: Tensor,
    *,
    smoothing: float = L1_SMOOTHING,
) -> tuple[Tensor, Tensor]:
    """Gradient of `penalised_objective` in closed form, from its log-probabilities `log_p`.

    Returns:
        The gradients with respect to `weight` `(M, P)` and to the bias `(M,)`.
    """
    mass = s[:, None] * r.sum(-1, keepdim=True)  # (N, 1)
    residual = log_p.exp() * mass - s[:, None] * r  # d loss / d logits, (N, M)
    return penalty_grad(weight, penalty, smoothing=smoothing) + residual.T @ phi, residual.sum(0)


def penalised_loss(
    phi: Tensor, r: Tensor, s: Tensor, penalty: Penalty, weight: Tensor, bias: Tensor
) -> float:
    """`penalised_objective`'s loss as a float."""
    return float(penalised_objective(phi, r, s, penalty, weight, bias)[0])


def check_strength(name: str, value: Any) -> float | str:
    """A penalty strength: a number >= 0 as a float, or ``"cv"``."""
    if isinstance(value, str):
        if value != "cv":
            raise InputError(
                f"{name} must be a number >= 0 or the string 'cv' (choose it by "
                f"cross-validation), got {value!r}."
            )
        return value
    check_positive(name, value, allow_zero=True)
    return float(value)


def check_grid(name: str, grid: Any, *, allow_zero: bool) -> tuple[float, ...]:
    """`grid` as floats: a non-empty sequence of numbers >= 0 (> 0 unless `allow_zero`)."""
    if isinstance(grid, (str, bytes)) or not isinstance(grid, Sequence):
        raise InputError(f"{name} must be a sequence of numbers, got {grid!r}.")
    if len(grid) == 0:
        raise InputError(f"{name} is empty; give at least one value.")
    for value in grid:
        check_positive(f"every entry of {name}", value, allow_zero=allow_zero)
    return tuple(float(v) for v in grid)


def strength_grid(
    name: str, strength: float | str, grid: Sequence[float] | None, default: tuple[float, ...]
) -> tuple[float, ...]:
    """The strengths cross-validation tries for penalty `name`, strongest first."""
    if grid is not None and strength != "cv":
        raise InputError(
            f"{name}_grid is only used when {name}='cv', but {name}={strength!r}; pass "
            f"{name}='cv' or drop {name}_grid."
        )
    values = default if grid is None else check_grid(f"{name}_grid", grid, allow_zero=True)
    return tuple(sorted(values, reverse=True))


def penalty_candidates(
    l2: float | str, l1: float | str, l2_grid: tuple[float, ...], l1_grid: tuple[float, ...]
) -> tuple[Penalty, ...]:
    """Every `(l2, l1)` pair a fit tries: the ridge path, then the lasso path."""
    if isinstance(l2, float) and isinstance(l1, float):
        return ((l2, l1),)
    ridge = [(v, 0.0 if l1 == "cv" else float(l1)) for v in l2_grid] if l2 == "cv" else []
    lasso = [(0.0 if l2 == "cv" else float(l2), v) for v in l1_grid] if l1 == "cv" else []
    return tuple(ridge + lasso)


def penalty_paths(grid: Sequence[Penalty]) -> list[tuple[int, int]]:
    """`(start, stop)` of each warm-started path in `grid`.

    A new path starts where the varied penalty switches from ridge to lasso.
    """
    starts = [0] + [i for i in range(1, len(grid)) if (grid[i][1] > 0.0) != (grid[i - 1][1] > 0.0)]
    return list(zip(starts, [*starts[1:], len(grid)], strict=True))
