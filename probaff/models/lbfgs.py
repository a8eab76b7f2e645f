"""L-BFGS for the small convex problems of the gate, on any device.

scipy's L-BFGS-B on CPU float64 tensors, `torch.optim.LBFGS` elsewhere; both take a
closure that returns the loss and sets every parameter's ``grad``.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
import torch
from scipy.optimize import minimize
from torch import Tensor

__all__ = ["minimise"]

# Most curvature pairs of scipy's L-BFGS-B (its compact form costs O(m^2) per iteration).
_SCIPY_HISTORY = 10


def minimise(
    params: Sequence[Tensor],
    closure: Callable[[], Tensor],
    *,
    max_iter: int,
    tolerance_grad: float,
    tolerance_change: float,
    history_size: int = 100,
) -> None:
    """Minimise a loss over `params` in place with L-BFGS.

    On the CPU (float64) this is scipy's compiled L-BFGS-B: a gate's cross-validation
    problems are small, so the per-iteration overhead of `torch.optim.LBFGS` would dominate
    them. Elsewhere it is `torch.optim.LBFGS` with a
    strong-Wolfe line search, on the parameters' device. The gate's objectives are convex,
    so both reach the same minimum within the tolerances.

    Args:
        params: Tensors to optimise.
        closure: Returns the loss at the current `params` after setting their ``grad``.
        max_iter: Most L-BFGS iterations.
        tolerance_grad: Stop when the largest gradient entry is below this.
        tolerance_change: Stop when the loss changes less than this (relative to its size
            when that is above 1) or, on other devices, the step is shorter than this.
        history_size: Curvature pairs kept by L-BFGS.
    """
    if all(p.device.type == "cpu" and p.dtype == torch.float64 for p in params):
        _scipy(params, closure, max_iter, tolerance_grad, tolerance_change, history_size)
        return
    optimiser = torch.optim.LBFGS(
        params,
        lr=1.0,
        max_iter=max_iter,
        history_size=history_size,
        line_search_fn="strong_wolfe",
        tolerance_grad=tolerance_grad,
        tolerance_change=tolerance_change,
    )
    optimiser.step(closure)


def _scipy(
    params: Sequence[Tensor],
    closure: Callable[[], Tensor],
    max_iter: int,
    tolerance_grad: float,
    tolerance_change: float,
    history_size: int,
) -> None:
    """`minimise` by `scipy.optimize.minimize(method="L-BFGS-B")` on float64 CPU tensors."""
    views = [p.detach().view(-1) for p in params]
    sizes = [v.numel() for v in views]

    def fun(flat: np.ndarray) -> tuple[float, np.ndarray]:
        with torch.no_grad():
            for view, part in zip(views, torch.from_numpy(flat).split(sizes), strict=True):
                view.copy_(part)
        loss = float(closure())
        grads = [p.grad if p.grad is not None else torch.zeros_like(p) for p in params]
        return loss, torch.cat([g.reshape(-1) for g in grads]).numpy().copy()

    start = torch.cat(views).numpy().copy()
    result = minimize(
        fun,
        start,
        jac=True,
        method="L-BFGS-B",
        options={
            "maxiter": max_iter,
            "maxfun": max(2 * max_iter, 20),
            "maxcor": min(history_size, _SCIPY_HISTORY),
            "gtol": tolerance_grad,
            "ftol": tolerance_change,
        },
    )
    best = result.x if np.all(np.isfinite(result.x)) else start
    with torch.no_grad():
        for view, part in zip(views, torch.from_numpy(np.asarray(best)).split(sizes), strict=True):
            view.copy_(part)
