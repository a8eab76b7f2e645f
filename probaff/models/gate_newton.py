"""Newton's method for a gate's penalised soft-target multinomial logistic regression.

The gate's objective (`probaff.models.gate_penalty.penalised_objective`) is convex and smooth
with at most a few hundred parameters, so its exact Hessian is cheap: `N (M (P + 1))^2`
operations, against hundreds of L-BFGS evaluations when the smoothed lasso makes the
problem ill-conditioned (curvature ``l1 / eps`` next to zero weights, next to almost
none for large ones). This is scikit-learn's ``newton-cholesky`` solver of
`LogisticRegression` for soft targets and an elastic-net penalty: a damped Newton step
solved by Cholesky, then a backtracking (Armijo) line search.
"""

from __future__ import annotations

import torch
from torch import Tensor

from probaff.models.gate_penalty import (
    L1_SMOOTHING,
    Penalty,
    penalised_gradient,
    penalised_objective,
)

__all__ = ["NEWTON_MAX_PARAMETERS", "newton_fit"]

NEWTON_MAX_PARAMETERS = 1024
"""Most parameters `M (P + 1)` a gate is fitted by Newton's method (above: L-BFGS)."""

# Armijo's sufficient-decrease constant and the most step halvings of one line search.
_ARMIJO = 1e-4
_HALVINGS = 40
# Relative damping of the Hessian (the softmax is invariant to a shift shared by all
# experts, so the unpenalised intercepts alone leave it singular).
_DAMPING = 1e-10


def _objective(
    phi: Tensor, r: Tensor, s: Tensor, penalty: Penalty, v: Tensor
) -> tuple[Tensor, Tensor]:
    """Penalised loss and log-probabilities `(N, M)` at stacked parameters `v: (M, P + 1)`."""
    return penalised_objective(phi, r, s, penalty, v[:, :-1], v[:, -1])


def _hessian(phi1: Tensor, p: Tensor, mass: Tensor, penalty: Penalty, weight: Tensor) -> Tensor:
    r"""Hessian of the penalised loss in the row-major flattened `v`, `(M (P+1), M (P+1))`.

    The data part is :math:`\sum_i m_i (\mathrm{diag}(p_i) - p_i p_i^\top) \otimes
    \phi_i \phi_i^\top` for the row masses :math:`m_i = s_i \sum_j r_{ij}`; the penalty
    adds its diagonal on the weights (not the intercepts).
    """
    n, width = phi1.shape
    m = p.shape[1]
    scaled = (mass[:, None] * p)[:, :, None] * phi1[:, None, :]  # (N, M, P + 1)
    h = -(scaled.reshape(n, m * width).T @ (p[:, :, None] * phi1[:, None, :]).reshape(n, -1))
    blocks = torch.einsum("nja,nb->jab", scaled, phi1)  # (M, P + 1, P + 1)
    h4 = h.view(m, width, m, width)
    idx = torch.arange(m, device=phi1.device)
    h4[idx, :, idx, :] += blocks
    l2, l1 = penalty
    curvature = torch.full_like(weight, l2)
    if l1 > 0.0:
        eps2 = L1_SMOOTHING**2
        curvature = curvature + l1 * eps2 / (weight.square() + eps2).pow(1.5)
    diag = torch.cat([curvature, torch.zeros_like(weight[:, :1])], dim=1)  # (M, P + 1)
    h.diagonal().add_(diag.reshape(-1))
    return h


def _direction(h: Tensor, g: Tensor) -> Tensor | None:
    """The damped Newton direction ``-(H + d I)^{-1} g``; ``None`` if no damping helps."""
    scale = 1.0 + float(h.diagonal().abs().max())
    eye = torch.eye(h.shape[0], dtype=h.dtype, device=h.device)
    damping = _DAMPING
    for _ in range(6):
        chol, info = torch.linalg.cholesky_ex(h + (damping * scale) * eye)
        if int(info) == 0:
            return -torch.cholesky_solve(g[:, None], chol)[:, 0]
        damping *= 1e3
    return None


def _stop_at_zero(v: Tensor, d: Tensor) -> Tensor:
    """The direction `d` `(M, P + 1)` with each weight that would cross zero stopped at zero.

    Next to zero the smoothed lasso's curvature jumps (``l1 / eps``), so a Newton step
    computed from far away overshoots to the other side; as in orthant-wise L-BFGS
    (OWL-QN), such a weight lands on zero instead.
    """
    w, step = v[:, :-1], d[:, :-1]
    cross = (w.abs() > L1_SMOOTHING) & (w * (w + step) < 0.0)
    return torch.cat([torch.where(cross, -w, step), d[:, -1:]], dim=1)


def _line_search(
    phi: Tensor,
    r: Tensor,
    s: Tensor,
    penalty: Penalty,
    v: Tensor,
    loss: Tensor,
    g: Tensor,
    d: Tensor,
) -> tuple[Tensor, Tensor, Tensor] | None:
    """Backtrack from the full step along `d` to Armijo's sufficient decrease.

    Returns:
        The new parameters, loss and log-probabilities, or ``None`` if `d` is no descent
        direction or no step along it decreases the loss enough.
    """
    slope = float(g @ d.reshape(-1))
    if not slope < 0.0:
        return None
    step = 1.0
    for _ in range(_HALVINGS):
        trial = v + step * d
        new_loss, log_p = _objective(phi, r, s, penalty, trial)
        bound = float(loss) + _ARMIJO * step * slope
        if bool(torch.isfinite(new_loss)) and float(new_loss) <= bound:
            return trial, new_loss, log_p
        step *= 0.5
    return None


def newton_fit(
    phi: Tensor,
    r: Tensor,
    s: Tensor,
    penalty: Penalty,
    weight: Tensor,
    bias: Tensor,
    *,
    max_iter: int,
    tolerance_grad: float,
    tolerance_change: float,
) -> int:
    """Minimise the gate's penalised loss over `weight` and `bias` in place, from their values.

    Args:
        phi: Basis, `(N, P)`.
        r: Targets, rows summing to 1, `(N, M)`.
        s: Non-negative sample weights summing to 1, `(N,)`.
        penalty: Ridge and lasso strengths `(l2, l1)`.
        weight: `W`, `(M, P)`, updated in place.
        bias: `b`, `(M,)`, updated in place.
        max_iter: Most Newton steps.
        tolerance_grad: Stop when the largest gradient entry is at most this.
        tolerance_change: Stop when a step lowers the loss by at most this times
            ``max(|loss|, 1)``.

    Returns:
        The Newton steps taken.
    """
    with torch.no_grad():
        phi1 = torch.cat([phi, torch.ones_like(phi[:, :1])], dim=1)  # (N, P + 1)
        mass = s * r.sum(-1)  # (N,)
        v = torch.cat([weight.detach(), bias.detach()[:, None]], dim=1)  # (M, P + 1)
        loss, log_p = _objective(phi, r, s, penalty, v)
        steps = 0
        for steps in range(1, max_iter + 1):
            g_weight, g_bias = penalised_gradient(phi, r, s, penalty, v[:, :-1], log_p)
            g = torch.cat([g_weight, g_bias[:, None]], dim=1).reshape(-1)
            if float(g.abs().max()) <= tolerance_grad:
                steps -= 1
                break
            d = _direction(_hessian(phi1, log_p.exp(), mass, penalty, v[:, :-1]), g)
            if d is None:
                break
            d = d.view_as(v)
            candidates = [_stop_at_zero(v, d), d] if penalty[1] > 0.0 else [d]
            found = None
            for direction in candidates:
                found = _line_search(phi, r, s, penalty, v, loss, g, direction)
                if found is not None:
                    break
            if found is None:
                break
            trial, new_loss, new_log_p = found
            drop = float(loss - new_loss)
            v, loss, log_p = trial, new_loss, new_log_p
            if drop <= tolerance_change * max(abs(float(loss)), 1.0):
                break
        weight.copy_(v[:, :-1])
        bias.copy_(v[:, -1])
    return steps
