"""Least-squares template fits and their covariances, as Push-T perception makes them.

`fit_least_squares` and `fit_ramped` fit a residual (Levenberg-Marquardt, coarse to fine over
edge ramps); `laplace_cov` is a fit's Laplace covariance; `length_cov` the covariance of a T
outline's four lengths, with a block jackknife over its edges; `outline_cov` carries that
covariance into a pose fitted with the outline.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

__all__ = ["Fit", "fit_least_squares", "fit_ramped", "laplace_cov", "length_cov", "outline_cov"]


@dataclass
class Fit:
    """A least-squares fit: its parameters, cost, Jacobian and residual at the optimum."""

    x: np.ndarray
    cost: float
    jac: np.ndarray
    residual: np.ndarray


def fit_least_squares(
    fun: Callable[[np.ndarray], np.ndarray],
    x0: np.ndarray,
    scale: np.ndarray,
    max_nfev: int | None = None,
) -> Fit:
    """Levenberg-Marquardt from `x0` on the residual `fun` `(P,) -> (R,)`.

    Steps are scaled by `scale` `(P,)`, the Jacobian is taken by finite differences of
    relative step 1e-3, and `fun` is called at most `max_nfev` times (None: scipy's default).
    """
    res = least_squares(fun, x0, x_scale=scale, method="lm", max_nfev=max_nfev, diff_step=1e-3)
    return Fit(np.asarray(res.x, dtype=float), float(res.cost), res.jac, res.fun)


def fit_ramped(
    residual: Callable[[np.ndarray, float], np.ndarray],
    starts: Iterable[np.ndarray],
    scale: np.ndarray,
    ramps: Sequence[float],
    max_nfev: int,
) -> Fit:
    """The best of fits from `starts` at the widest ramp, refined through the narrower ones."""
    best: Fit | None = None
    first = functools.partial(_at_ramp, residual, ramps[0])
    for x0 in starts:
        fit = fit_least_squares(first, x0, scale, max_nfev=max_nfev)
        if best is None or fit.cost < best.cost:
            best = fit
    assert best is not None
    for ramp in ramps[1:]:
        best = fit_least_squares(functools.partial(_at_ramp, residual, ramp), best.x, scale)
    return best


def _at_ramp(
    residual: Callable[[np.ndarray, float], np.ndarray], ramp: float, p: np.ndarray
) -> np.ndarray:
    return residual(p, ramp)


def _central_jacobian(
    fun: Callable[[np.ndarray], np.ndarray], x: np.ndarray, steps: np.ndarray
) -> np.ndarray:
    """(R, P) central differences of `fun` `(P,) -> (R,)` at `x`, half-steps `steps` `(P,)`."""
    cols = [(fun(x + h) - fun(x - h)) / (2 * h.sum()) for h in np.diag(np.asarray(steps, float))]
    return np.column_stack(cols)


def laplace_cov(fit: Fit, n_params: int, prior: np.ndarray | None = None) -> np.ndarray:
    """Covariance ``(J^T J / s^2 + P)^-1`` of a least-squares fit, s^2 its residual variance.

    `prior`, the diagonal of `P` (one precision per parameter, 0 for none), bounds what the
    fit cannot pin down; without it the result is the Laplace ``s^2 (J^T J)^-1``.
    """
    n = fit.residual.size
    s2 = max(float(np.sum(fit.residual**2)) / max(n - n_params, 1), 1e-300)
    precision = fit.jac.T @ fit.jac / s2
    if prior is not None:
        precision = precision + np.diag(np.r_[prior, np.zeros(n_params - len(prior))])
    return np.asarray(np.linalg.pinv(precision), dtype=float)


def length_cov(
    residual: Callable[[np.ndarray], np.ndarray],
    fit: Fit,
    groups: np.ndarray,
    scale: np.ndarray,
) -> np.ndarray:
    """(4, 4) covariance of the outline's lengths ``fit.x[3:7]``: Laplace plus edge jackknife.

    Both are taken on `residual`, the fit's residual with edges ramped over a unit: the
    finest model draws the T on a screen of one world unit per pixel, so its residual is
    flat in a length between two whole units and says nothing of the lengths' spread. As for
    a block's pose (`probaff.experiments.pusht.perception`), the Laplace approximation
    counts every pixel as independent while one edge's pixels err together (the image
    samples an edge every 5.3 world units), so the fit is repeated without each edge's
    pixels and the spread of the lengths over those fits is added (the delete-one-group
    jackknife).

    Args:
        residual: The fit's residual of its parameters, ramped over a unit, `(R,)`.
        fit: The fit; its parameters ``[x, y, theta, 4 lengths, ...]``.
        groups: (R,) the outline edge each residual's pixel lies nearest
            (`probaff.experiments.pusht.template.edge_groups`).
        scale: The fit's parameter scales (the difference steps are half of them).
    """
    r0 = residual(fit.x)
    jac = _central_jacobian(residual, fit.x, 0.5 * scale)
    laplace = laplace_cov(Fit(fit.x, 0.5 * float(r0 @ r0), jac, r0), fit.x.size)[3:7, 3:7]
    subsets = []
    for g in range(int(groups.max()) + 1):
        keep = groups != g

        def res_g(p: np.ndarray, keep: np.ndarray = keep) -> np.ndarray:
            return keep * residual(p)

        subsets.append(fit_least_squares(res_g, fit.x, scale, max_nfev=12).x[3:7])
    dev = np.asarray(subsets) - np.mean(subsets, axis=0)
    return np.asarray(laplace + (len(dev) - 1) / len(dev) * dev.T @ dev, dtype=float)


def outline_cov(
    drawn: Callable[[np.ndarray, np.ndarray], np.ndarray],
    pose: np.ndarray,
    dims: np.ndarray,
    weight: np.ndarray,
    shape_cov: np.ndarray,
) -> np.ndarray:
    """(3, 3) the outline's covariance carried into a block pose fitted with that outline.

    At a least-squares optimum the pose moves with the lengths as ``S = -(J^T J)^-1 J^T D``
    (the implicit function theorem), J the residual's derivative in the pose and D in the
    four lengths; the term is ``S shape_cov S^T``. Both are central differences (one world
    unit, 0.01 rad) of `drawn`, which should be smooth at that scale (a ramp of a unit).

    Args:
        drawn: The T's drawn fraction `(P,)` at a pose `(3,)` with lengths `(4,)`.
        pose: (3,) the fitted pose.
        dims: (4,) the lengths the fit used.
        weight: (P,) the residual's pixel weights.
        shape_cov: (4, 4) the lengths' covariance.
    """
    w = weight[:, None]
    jac = w * _central_jacobian(lambda p: drawn(p, dims), pose, np.array([0.5, 0.5, 0.005]))
    d = w * _central_jacobian(lambda q: drawn(pose, q), dims, np.full(4, 0.5))
    sens = -np.linalg.pinv(jac.T @ jac) @ (jac.T @ d)
    return np.asarray(sens @ shape_cov @ sens.T, dtype=float)
