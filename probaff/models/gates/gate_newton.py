"""Newton's method for a gate's penalised soft-target multinomial logistic regression.

The gate's objective (`probaff.models.gates.gate_penalty.penalised_objective`) is convex and smooth
with at most a few hundred parameters, so its exact Hessian is cheap: `N (M (P + 1))^2`
operations, against hundreds of L-BFGS evaluations when the smoothed lasso makes the
problem ill-conditioned (curvature ``l1 / eps`` next to zero weights, next to almost
none for large ones). This is scikit-learn's ``newton-cholesky`` solver of
`LogisticRegression` for soft targets and an elastic-net penalty: a damped Newton step
solved by Cholesky, then a backtracking (Armijo) line search.

With a lasso, the quadratic model behind a Newton step holds only within about ``eps`` of
zero for each weight the lasso holds there, so from a start far from the optimum the line
search keeps shrinking the steps and the loss creeps. The first shrunken step therefore
switches to continuation in the smoothing: the fit is solved at a `_WIDENING` times wider
smoothing, where that region is as much wider, and then carried back to ``eps``. At a fixed
data gradient a weight held near zero sits at ``eps t / sqrt(1 - t^2)`` with ``t`` the data
gradient over ``-l1``, proportional to ``eps``, so such weights are rescaled between the
two (`_rescale_zeroed`) and the last stage starts close to its optimum.
"""

from __future__ import annotations

from typing import NamedTuple

import torch
from torch import Tensor

from probaff.models.gates.gate_penalty import (
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
# Continuation: the wider smoothing in multiples of `L1_SMOOTHING`, its stage's looser
# gradient tolerance (a multiple of the fit's), and the band (in multiples of a stage's
# smoothing) below which a weight counts as held at zero by the lasso.
_WIDENING = 100.0
_WIDE_TOLERANCE = 10.0
_ZERO_BAND = 5.0


class _Problem(NamedTuple):
    """One gate fit's data and penalty.

    The basis `phi` `(N, P)` and with a ones column `phi1` `(N, P + 1)`, the targets `r`
    `(N, M)`, the sample weights `s` `(N,)` and the row masses ``s_i sum_j r_ij`` `(N,)`.
    """

    phi: Tensor
    phi1: Tensor
    r: Tensor
    s: Tensor
    mass: Tensor
    penalty: Penalty


def _objective(problem: _Problem, v: Tensor, smoothing: float) -> tuple[Tensor, Tensor]:
    """Penalised loss and log-probabilities `(N, M)` at stacked parameters `v: (M, P + 1)`."""
    phi, r, s, penalty = problem.phi, problem.r, problem.s, problem.penalty
    return penalised_objective(phi, r, s, penalty, v[:, :-1], v[:, -1], smoothing=smoothing)


def _hessian(
    phi1: Tensor, p: Tensor, mass: Tensor, penalty: Penalty, weight: Tensor, smoothing: float
) -> Tensor:
    r"""Hessian of the penalised loss in the row-major flattened `v`, `(M (P+1), M (P+1))`.

    The data part is :math:`\sum_i m_i (\mathrm{diag}(p_i) - p_i p_i^\top) \otimes
    \phi_i \phi_i^\top` for the row masses :math:`m_i = s_i \sum_j r_{ij}`; the penalty
    adds its diagonal on the weights (not the intercepts), at lasso smoothing `smoothing`.
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
        eps2 = smoothing**2
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


def _stop_at_zero(v: Tensor, d: Tensor, smoothing: float) -> Tensor:
    """The direction `d` `(M, P + 1)` with each weight that would cross zero stopped at zero.

    Next to zero the smoothed lasso's curvature jumps (``l1 / eps``), so a Newton step
    computed from far away overshoots to the other side; as in orthant-wise L-BFGS
    (OWL-QN), such a weight lands on zero instead.
    """
    w, step = v[:, :-1], d[:, :-1]
    cross = (w.abs() > smoothing) & (w * (w + step) < 0.0)
    return torch.cat([torch.where(cross, -w, step), d[:, -1:]], dim=1)


def _line_search(
    problem: _Problem, v: Tensor, loss: Tensor, g: Tensor, d: Tensor, smoothing: float
) -> tuple[Tensor, Tensor, Tensor, float] | None:
    """Backtrack from the full step along `d` to Armijo's sufficient decrease.

    Returns:
        The new parameters, loss, log-probabilities and step length (1 for the full
        step), or ``None`` if `d` is no descent direction or no step along it decreases
        the loss enough.
    """
    slope = float(g @ d.reshape(-1))
    if not slope < 0.0:
        return None
    step = 1.0
    for _ in range(_HALVINGS):
        trial = v + step * d
        new_loss, log_p = _objective(problem, trial, smoothing)
        bound = float(loss) + _ARMIJO * step * slope
        if bool(torch.isfinite(new_loss)) and float(new_loss) <= bound:
            return trial, new_loss, log_p, step
        step *= 0.5
    return None


def _newton(
    problem: _Problem,
    v: Tensor,
    smoothing: float,
    *,
    max_iter: int,
    tolerance_grad: float,
    tolerance_change: float,
    stop_on_shrink: bool,
) -> tuple[Tensor, float, int, bool]:
    """Damped Newton steps from `v` `(M, P + 1)` at lasso smoothing `smoothing`.

    A step's small loss drop ends the fit only after a full step: a drop after the line
    search shrank the step says nothing of how far the optimum is.

    Returns:
        The last parameters and their loss, the Newton steps taken, and whether the fit
        stopped (with `stop_on_shrink`) at a step the line search had to shrink, before
        taking it.
    """
    phi, r, s, penalty = problem.phi, problem.r, problem.s, problem.penalty
    loss, log_p = _objective(problem, v, smoothing)
    steps = 0
    for steps in range(1, max_iter + 1):
        g_weight, g_bias = penalised_gradient(
            phi, r, s, penalty, v[:, :-1], log_p, smoothing=smoothing
        )
        g = torch.cat([g_weight, g_bias[:, None]], dim=1).reshape(-1)
        if float(g.abs().max()) <= tolerance_grad:
            return v, float(loss), steps - 1, False
        h = _hessian(problem.phi1, log_p.exp(), problem.mass, penalty, v[:, :-1], smoothing)
        d = _direction(h, g)
        if d is None:
            break
        d = d.view_as(v)
        candidates = [_stop_at_zero(v, d, smoothing), d] if penalty[1] > 0.0 else [d]
        found = None
        for direction in candidates:
            found = _line_search(problem, v, loss, g, direction, smoothing)
            if found is not None:
                break
        if found is None:
            break
        trial, new_loss, new_log_p, step = found
        if stop_on_shrink and step < 1.0:
            return v, float(loss), steps, True
        drop = float(loss - new_loss)
        v, loss, log_p = trial, new_loss, new_log_p
        if step == 1.0 and drop <= tolerance_change * max(abs(float(loss)), 1.0):
            break
    return v, float(loss), steps, False


def _rescale_zeroed(v: Tensor, smoothing: float, target: float) -> Tensor:
    """`v` `(M, P + 1)` with the weights held near zero at `smoothing` carried to `target`.

    Such a weight (under `_ZERO_BAND` times `smoothing` in size) is multiplied by
    ``target / smoothing``; the others and the intercepts are kept.
    """
    w = v[:, :-1]
    zeroed = w.abs() < _ZERO_BAND * smoothing
    scaled = torch.where(zeroed, w * (target / smoothing), w)
    return torch.cat([scaled, v[:, -1:]], dim=1)


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
        max_iter: Most Newton steps of each stage (the first, and with a lasso the two
            stages of the continuation).
        tolerance_grad: Stop when the largest gradient entry is at most this.
        tolerance_change: Stop when a full step lowers the loss by at most this times
            ``max(|loss|, 1)``.

    Returns:
        The Newton steps taken in all stages.
    """
    with torch.no_grad():
        phi1 = torch.cat([phi, torch.ones_like(phi[:, :1])], dim=1)  # (N, P + 1)
        problem = _Problem(phi, phi1, r, s, s * r.sum(-1), penalty)
        v = torch.cat([weight.detach(), bias.detach()[:, None]], dim=1)  # (M, P + 1)
        v, loss, steps, shrunk = _newton(
            problem,
            v,
            L1_SMOOTHING,
            max_iter=max_iter,
            tolerance_grad=tolerance_grad,
            tolerance_change=tolerance_change,
            stop_on_shrink=penalty[1] > 0.0,
        )
        if shrunk:  # continuation: a wider smoothing first, then back
            wide = _WIDENING * L1_SMOOTHING
            start, start_loss = v, loss
            v, _, wide_steps, _ = _newton(
                problem,
                _rescale_zeroed(v, L1_SMOOTHING, wide),
                wide,
                max_iter=max_iter,
                tolerance_grad=_WIDE_TOLERANCE * tolerance_grad,
                tolerance_change=tolerance_change,
                stop_on_shrink=False,
            )
            v, loss, last_steps, _ = _newton(
                problem,
                _rescale_zeroed(v, wide, L1_SMOOTHING),
                L1_SMOOTHING,
                max_iter=max_iter,
                tolerance_grad=tolerance_grad,
                tolerance_change=tolerance_change,
                stop_on_shrink=False,
            )
            steps += wide_steps + last_steps
            # the stages can run out of steps before they pass their start: keep the better
            if start_loss < loss:
                v = start
        weight.copy_(v[:, :-1])
        bias.copy_(v[:, -1])
    return steps
