"""L-BFGS: a closure-based minimiser for the gate, and a coroutine form for many problems.

`minimise` runs the gate's small convex problems: scipy's L-BFGS-B on CPU float64 tensors,
`torch.optim.LBFGS` elsewhere; both take a closure that returns the loss and sets every
parameter's ``grad``. `lbfgs_coroutine` is `torch.optim.LBFGS` with a strong-Wolfe line
search written as a coroutine that yields the points it wants evaluated, so that `lockstep`
can run many problems (the GP experts of a mixture) side by side with their evaluations
computed as one batch; `drive` runs one.
"""

from __future__ import annotations

from collections.abc import Callable, Generator, Sequence
from typing import Any, TypeAlias, TypeVar

import numpy as np
import torch
from scipy.optimize import minimize
from torch import Tensor

__all__ = [
    "Evaluation",
    "LBFGSCoroutine",
    "assign",
    "drive",
    "flat_grad",
    "flatten",
    "lbfgs_coroutine",
    "lockstep",
    "minimise",
]

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

    def fun(flat: np.ndarray) -> tuple[float, np.ndarray]:
        assign(params, flat)
        loss = float(closure())
        return loss, flat_grad(params)

    start = flatten(params)
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
    assign(params, result.x if np.all(np.isfinite(result.x)) else start)


def flatten(params: Sequence[Tensor]) -> np.ndarray:
    """The values of `params` as one float64 vector `(P,)` (a copy, on the host)."""
    return torch.cat([p.detach().reshape(-1) for p in params]).cpu().numpy().astype(np.float64)


def flat_grad(params: Sequence[Tensor]) -> np.ndarray:
    """The gradients of `params` as one float64 vector `(P,)` (zeros where a grad is None)."""
    grads = [p.grad if p.grad is not None else torch.zeros_like(p) for p in params]
    return torch.cat([g.detach().reshape(-1) for g in grads]).cpu().numpy().astype(np.float64)


def assign(params: Sequence[Tensor], flat: np.ndarray) -> None:
    """Copy the vector `flat` `(P,)` into `params` in place (in their order and shapes)."""
    values = torch.from_numpy(np.asarray(flat, dtype=np.float64))
    offset = 0
    with torch.no_grad():
        for p in params:
            n = p.numel()
            p.copy_(values[offset : offset + n].view_as(p))
            offset += n


# ---------------------------------------------------------------- the coroutine form
Evaluation: TypeAlias = tuple[float, np.ndarray]
"""A loss and its gradient, `(P,)`, at a point an `lbfgs_coroutine` asked for."""

LBFGSCoroutine: TypeAlias = Generator[np.ndarray, Evaluation, tuple[np.ndarray, float]]
"""Yields points `(P,)` to evaluate, is sent their `Evaluation`, returns the final point and
its loss."""


def lbfgs_coroutine(
    x0: np.ndarray,
    *,
    max_iter: int,
    tolerance_grad: float = 1e-7,
    tolerance_change: float = 1e-9,
    history_size: int = 100,
) -> LBFGSCoroutine:
    """`torch.optim.LBFGS` with a strong-Wolfe line search, as a coroutine over the points.

    The algorithm, its defaults (``lr = 1``, at most ``max_iter * 5 // 4`` evaluations) and
    its stopping rules are those of one ``step`` of ``torch.optim.LBFGS(...,
    line_search_fn="strong_wolfe")``; the caller evaluates the points it yields, so many
    problems can run side by side and have their evaluations computed as one batch
    (`lockstep`). The state is a handful of float64 vectors, so the optimiser's own cost is
    small next to torch's per-operation overhead. An exception thrown into the coroutine
    (``coroutine.throw``) ends it with that exception.

    Args:
        x0: Start, `(P,)` (copied).
        max_iter: Most iterations.
        tolerance_grad: Stop when the largest gradient entry is at most this.
        tolerance_change: Stop when the loss or the step changes less than this.
        history_size: Curvature pairs kept.

    Yields:
        The next point to evaluate, `(P,)` (a fresh array each time).

    Returns:
        The final point, `(P,)`, always one that was evaluated, and its loss.
    """
    max_eval = max_iter * 5 // 4
    x = np.array(x0, dtype=np.float64)
    loss, grad = yield x.copy()
    evals = 1
    if np.abs(grad).max() <= tolerance_grad:
        return x, loss
    dirs: list[np.ndarray] = []
    steps: list[np.ndarray] = []
    rho: list[float] = []
    h_diag = 1.0
    d, t, prev_grad = -grad, 1.0, grad
    for n_iter in range(1, max_iter + 1):
        if n_iter > 1:
            y, s = grad - prev_grad, d * t
            ys = float(y @ s)
            if ys > 1e-10:
                if len(dirs) == history_size:
                    del dirs[0], steps[0], rho[0]
                dirs.append(y)
                steps.append(s)
                rho.append(1.0 / ys)
                h_diag = ys / float(y @ y)
            d = _two_loop(grad, dirs, steps, rho, h_diag)
        prev_grad, prev_loss = grad, loss
        t = min(1.0, 1.0 / float(np.abs(grad).sum())) if n_iter == 1 else 1.0
        gtd = float(grad @ d)
        if gtd > -tolerance_change:
            break
        loss, grad, t, ls_evals = yield from _strong_wolfe(
            x, t, d, loss, grad, gtd, tolerance_change, max_eval - evals
        )
        x = x + t * d
        evals += ls_evals
        if (
            n_iter == max_iter
            or evals >= max_eval
            or np.abs(grad).max() <= tolerance_grad
            or np.abs(d * t).max() <= tolerance_change
            or abs(loss - prev_loss) < tolerance_change
        ):
            break
    return x, loss


def _two_loop(
    grad: np.ndarray, dirs: list[np.ndarray], steps: list[np.ndarray], rho: list[float], h: float
) -> np.ndarray:
    """The L-BFGS direction ``-H grad`` from the curvature pairs, `(P,)`."""
    q = -grad
    alpha = [0.0] * len(dirs)
    for i in range(len(dirs) - 1, -1, -1):
        alpha[i] = float(steps[i] @ q) * rho[i]
        q = q - alpha[i] * dirs[i]
    r = q * h
    for i in range(len(dirs)):
        beta = float(dirs[i] @ r) * rho[i]
        r = r + (alpha[i] - beta) * steps[i]
    return r


def _cubic_minimum(
    x1: float,
    f1: float,
    g1: float,
    x2: float,
    f2: float,
    g2: float,
    bounds: tuple[float, float] | None = None,
) -> float:
    """Minimiser of the cubic through two points' values and slopes, clipped to `bounds`."""
    lo, hi = bounds if bounds is not None else (min(x1, x2), max(x1, x2))
    with np.errstate(all="ignore"):
        d1 = np.float64(g1) + g2 - 3 * (np.float64(f1) - f2) / (np.float64(x1) - x2)
        d2_square = d1**2 - np.float64(g1) * g2
        if d2_square >= 0:
            d2 = np.sqrt(d2_square)
            if x1 <= x2:
                pos = x2 - (x2 - x1) * ((g2 + d2 - d1) / (g2 - g1 + 2 * d2))
            else:
                pos = x1 - (x1 - x2) * ((g1 + d2 - d1) / (g1 - g2 + 2 * d2))
            return float(min(max(pos, lo), hi))
    return (lo + hi) / 2.0


def _strong_wolfe(
    x: np.ndarray,
    t: float,
    d: np.ndarray,
    f: float,
    g: np.ndarray,
    gtd: float,
    tolerance_change: float,
    max_ls: int,
    c1: float = 1e-4,
    c2: float = 0.9,
) -> Generator[np.ndarray, Evaluation, tuple[float, np.ndarray, float, int]]:
    """The strong-Wolfe line search of `torch.optim.LBFGS` along `d`; yields ``x + t d``.

    Returns:
        The accepted point's loss and gradient, its step `t`, and the evaluations made.
    """
    d_norm = float(np.abs(d).max())
    f_new, g_new = yield x + t * d
    evals = 1
    gtd_new = float(g_new @ d)
    t_prev, f_prev, g_prev, gtd_prev = 0.0, f, g, gtd
    done = False
    ls_iter = 0
    bracket: list[float] = []
    bracket_f: list[float] = []
    bracket_g: list[np.ndarray] = []
    bracket_gtd: list[float] = []
    while ls_iter < max_ls:
        if f_new > f + c1 * t * gtd or (ls_iter > 1 and f_new >= f_prev):
            bracket, bracket_f, bracket_g = [t_prev, t], [f_prev, f_new], [g_prev, g_new]
            bracket_gtd = [gtd_prev, gtd_new]
            break
        if abs(gtd_new) <= -c2 * gtd:
            bracket, bracket_f, bracket_g = [t], [f_new], [g_new]
            done = True
            break
        if gtd_new >= 0:
            bracket, bracket_f, bracket_g = [t_prev, t], [f_prev, f_new], [g_prev, g_new]
            bracket_gtd = [gtd_prev, gtd_new]
            break
        step = _cubic_minimum(
            t_prev, f_prev, gtd_prev, t, f_new, gtd_new, bounds=(t + 0.01 * (t - t_prev), t * 10)
        )
        t_prev, f_prev, g_prev, gtd_prev, t = t, f_new, g_new, gtd_new, step
        f_new, g_new = yield x + t * d
        evals += 1
        gtd_new = float(g_new @ d)
        ls_iter += 1
    if ls_iter == max_ls:
        bracket, bracket_f, bracket_g = [0.0, t], [f, f_new], [g, g_new]
    low, high = (0, 1) if bracket_f[0] <= bracket_f[-1] else (1, 0)
    insufficient = False
    while not done and ls_iter < max_ls:
        if abs(bracket[1] - bracket[0]) * d_norm < tolerance_change:
            break
        t = _cubic_minimum(
            bracket[0], bracket_f[0], bracket_gtd[0], bracket[1], bracket_f[1], bracket_gtd[1]
        )
        # Too close to an end of the bracket: move a tenth of its length inside.
        eps = 0.1 * (max(bracket) - min(bracket))
        if min(max(bracket) - t, t - min(bracket)) < eps:
            if insufficient or t >= max(bracket) or t <= min(bracket):
                if abs(t - max(bracket)) < abs(t - min(bracket)):
                    t = max(bracket) - eps
                else:
                    t = min(bracket) + eps
                insufficient = False
            else:
                insufficient = True
        else:
            insufficient = False
        f_new, g_new = yield x + t * d
        evals += 1
        gtd_new = float(g_new @ d)
        ls_iter += 1
        if f_new > f + c1 * t * gtd or f_new >= bracket_f[low]:
            bracket[high], bracket_f[high], bracket_g[high] = t, f_new, g_new
            bracket_gtd[high] = gtd_new
            low, high = (0, 1) if bracket_f[0] <= bracket_f[1] else (1, 0)
        else:
            if abs(gtd_new) <= -c2 * gtd:
                done = True
            elif gtd_new * (bracket[high] - bracket[low]) >= 0:
                bracket[high], bracket_f[high] = bracket[low], bracket_f[low]
                bracket_g[high], bracket_gtd[high] = bracket_g[low], bracket_gtd[low]
            bracket[low], bracket_f[low], bracket_g[low] = t, f_new, g_new
            bracket_gtd[low] = gtd_new
    return bracket_f[low], bracket_g[low], bracket[low], evals


Request = TypeVar("Request")
Reply = TypeVar("Reply")
Result = TypeVar("Result")


def drive(
    coroutine: Generator[Request, Reply, Result],
    evaluate: Callable[[Request], Reply],
    failures: tuple[type[BaseException], ...] = (),
) -> Result:
    """Run `coroutine` to its end, answering each request with `evaluate`.

    An exception of a type in `failures` raised by `evaluate` is thrown into the coroutine.
    """
    return lockstep([coroutine], lambda batch: _answer(batch, evaluate, failures))[0]


def _answer(
    batch: dict[int, Request],
    evaluate: Callable[[Request], Reply],
    failures: tuple[type[BaseException], ...],
) -> dict[int, Reply | BaseException]:
    out: dict[int, Reply | BaseException] = {}
    for i, request in batch.items():
        try:
            out[i] = evaluate(request)
        except failures as exc:
            out[i] = exc
    return out


def lockstep(
    coroutines: Sequence[Generator[Request, Reply, Result]],
    evaluate: Callable[[dict[int, Request]], dict[int, Reply | BaseException]],
) -> list[Result]:
    """Run coroutines side by side, answering each round of their requests as one batch.

    Every round, each unfinished coroutine has one pending request; ``evaluate`` gets them
    all, keyed by the coroutine's index in order, and returns a reply or an exception for
    each (an exception is thrown into its coroutine). The result does not depend on
    anything but the coroutines and `evaluate`.

    Returns:
        Each coroutine's return value, in order.
    """
    results: list[Any] = [None] * len(coroutines)
    pending: dict[int, Request] = {}
    for i, coroutine in enumerate(coroutines):
        _advance(coroutine, i, None, pending, results)
    while pending:
        replies = evaluate(dict(pending))
        batch, pending = pending, {}
        for i in batch:
            _advance(coroutines[i], i, replies[i], pending, results)
    return results


def _advance(
    coroutine: Generator[Any, Any, Any],
    i: int,
    reply: Any,
    pending: dict[int, Any],
    results: list[Any],
) -> None:
    """Send `reply` (or throw it, if an exception) and record the next request or result."""
    try:
        if isinstance(reply, BaseException):
            pending[i] = coroutine.throw(reply)
        elif reply is None:
            pending[i] = next(coroutine)
        else:
            pending[i] = coroutine.send(reply)
    except StopIteration as stop:
        results[i] = stop.value
