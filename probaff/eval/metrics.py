"""Prediction metrics: RMSE per dimension, NLPD, and central-interval coverage.

All accept a predictive `torch.distributions.Distribution` over effects of shape (N, E): a
`Normal`, an `Independent` Normal, or a `MixtureSameFamily` whose components are (possibly
`Independent`) Normals over the E dimensions.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
import torch
from torch.distributions import Distribution, Independent, MixtureSameFamily, Normal

from probaff._checks import (
    as_float_array,
    as_real_tensor,
    check_count,
    check_finite,
    check_shape,
    real_number,
)
from probaff.errors import InputError

__all__ = [
    "corrected_halfwidth",
    "interval_coverage",
    "marginal_components",
    "mean_and_halfwidth",
    "mean_halfwidth",
    "nlpd",
    "rmse",
    "wilson_interval",
]


def marginal_components(dist: Distribution) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Per-dimension mixture parameters of a predictive distribution.

    Args:
        dist: Predictive distribution with batch shape (N,) and event shape (E,), or a
            `Normal` of shape (N, E).

    Returns:
        ``(weights (N, M), loc (N, M, E), scale (N, M, E))``; M = 1 for a single Normal.
    """
    if isinstance(dist, MixtureSameFamily):
        comp = dist.component_distribution
        base = comp.base_dist if isinstance(comp, Independent) else comp
        if not isinstance(base, Normal):
            raise InputError("mixture components must be Normal distributions.")
        return dist.mixture_distribution.probs, base.loc, base.scale
    base = dist.base_dist if isinstance(dist, Independent) else dist
    if not isinstance(base, Normal):
        raise InputError(f"cannot score a {type(dist).__name__}; expected Normal or a mixture.")
    return (
        torch.ones(base.loc.shape[0], 1, dtype=base.loc.dtype),
        base.loc[:, None],
        base.scale[:, None],
    )


def _check_targets(dist: Distribution, y: torch.Tensor) -> torch.Tensor:
    y = as_real_tensor("targets", y).to(torch.float64)
    _, loc, _ = marginal_components(dist)
    check_shape("targets", y, (loc.shape[0], loc.shape[2]))
    check_finite("targets", y)
    return y


def rmse(pred: Distribution | torch.Tensor, y: torch.Tensor) -> torch.Tensor:
    """Root mean squared error of a point prediction, per effect dimension.

    Args:
        pred: Predictive distribution over (N, E), scored by its mean; or the (N, E) point
            prediction itself (e.g. `MixtureOfGPExperts.predict_point`).
        y: (N, E) observed effects.

    Returns:
        (E,) RMSE.
    """
    if isinstance(pred, Distribution):
        y = _check_targets(pred, y)
        w, loc, _ = marginal_components(pred)
        mean = (w[..., None] * loc).sum(1)
    else:
        mean = as_real_tensor("point prediction", pred).to(torch.float64)
        check_finite("point prediction", mean)
        y = as_real_tensor("targets", y).to(torch.float64)
        check_shape("targets", y, tuple(mean.shape))
        check_finite("targets", y)
    return ((mean.double() - y) ** 2).mean(0).sqrt()


def nlpd(dist: Distribution, y: torch.Tensor) -> torch.Tensor:
    """Negative log predictive density per dimension, averaged over samples.

    The per-dimension marginal densities are used, so the values of different dimensions
    can be compared and summed into a joint NLPD under the model's factorisation.

    Args:
        dist: Predictive distribution over (N, E).
        y: (N, E) observed effects.

    Returns:
        (E,) mean NLPD (nats).
    """
    y = _check_targets(dist, y)
    w, loc, scale = marginal_components(dist)
    comp = Normal(loc.double(), scale.double()).log_prob(y[:, None, :])  # (N, M, E)
    lp = torch.logsumexp(torch.log(w.double().clamp_min(1e-300))[..., None] + comp, dim=1)
    return -lp.mean(0)


def interval_coverage(
    dist: Distribution, y: torch.Tensor, level: float = 0.9, iterations: int = 60
) -> torch.Tensor:
    """Fraction of observations inside the central `level` interval, per dimension.

    The interval of each 1-D marginal mixture is found by bisection on its CDF.

    Args:
        dist: Predictive distribution over (N, E).
        y: (N, E) observed effects.
        level: Central probability mass of the interval, in (0, 1).
        iterations: Bisection steps (a positive integer).

    Returns:
        (E,) coverage in [0, 1]; a calibrated model gives about `level`.

    Raises:
        InputError: For `level` outside (0, 1), `iterations` that is not a positive integer,
            or mismatched targets.
    """
    iterations = check_count("iterations", iterations)
    level = _check_level("level", level)
    y = _check_targets(dist, y)
    w, loc, scale = (t.double() for t in marginal_components(dist))
    lo_q, hi_q = (1 - level) / 2, (1 + level) / 2

    def cdf(x: torch.Tensor) -> torch.Tensor:
        z = (x[:, None, :] - loc) / scale
        return (w[..., None] * 0.5 * (1 + torch.erf(z / math.sqrt(2)))).sum(1)

    def quantile(q: float) -> torch.Tensor:
        lo = (loc - 10 * scale).amin(1)
        hi = (loc + 10 * scale).amax(1)
        for _ in range(iterations):
            mid = 0.5 * (lo + hi)
            below = cdf(mid) < q
            lo, hi = torch.where(below, mid, lo), torch.where(below, hi, mid)
        return 0.5 * (lo + hi)

    inside = (y >= quantile(lo_q)) & (y <= quantile(hi_q))
    return inside.double().mean(0)


def wilson_interval(successes: int, trials: int, confidence: float = 0.95) -> tuple[float, float]:
    """Wilson score interval of a success rate.

    Args:
        successes: Successful trials (an integer in [0, trials]).
        trials: Trials (a positive integer).
        confidence: Two-sided confidence level in (0, 1).

    Returns:
        ``(low, high)`` bounds of the rate, in [0, 1].

    Raises:
        InputError: For counts that are not integers, ``successes > trials`` or a level
            outside (0, 1).
    """
    from scipy.stats import norm

    n = check_count("trials", trials)
    k = check_count("successes", successes, minimum=0)
    if k > n:
        raise InputError(f"successes ({k}) cannot exceed trials ({n}).")
    z = float(norm.ppf(0.5 + _check_level("confidence", confidence) / 2))
    p = k / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return max(0.0, centre - half), min(1.0, centre + half)


def _check_level(name: str, value: Any) -> float:
    """`value` as a float in (0, 1) (a two-sided level), or `InputError` naming `name`."""
    level = real_number(value)  # NaN for anything but a real number
    if not 0 < level < 1:
        raise InputError(f"{name} must lie in (0, 1), got {value!r}.")
    return level


def _t_quantile(confidence: float, dof: int) -> float:
    """The two-sided Student-t quantile of `confidence` with `dof` degrees of freedom."""
    from scipy.stats import t

    return float(t.ppf(0.5 + _check_level("confidence", confidence) / 2, dof))


def _values(values: Sequence[float] | np.ndarray) -> np.ndarray:
    """`values` as a float64 vector (NaN kept), or `InputError` naming ``values``."""
    v = as_float_array("values", values)
    check_shape("values", v, (None,))
    return v


def _sample_sd(v: np.ndarray) -> float:
    return float(np.sqrt(((v - v.mean()) ** 2).sum() / (len(v) - 1)))


def corrected_halfwidth(
    values: Sequence[float] | np.ndarray, test_to_train: float, confidence: float = 0.95
) -> float:
    """Half-width of Nadeau and Bengio's corrected resampled t interval of the mean of `values`.

    The J scores of repeated cross-validation (R repeats of K folds, J = R K) share training
    rows, so they are correlated and the plain t interval `mean_halfwidth` is too narrow.
    Nadeau and Bengio (2003, "Inference for the generalization error") correct the variance
    of the mean from ``sd^2 / J`` to ``sd^2 (1 / J + n_test / n_train)``; Bouckaert and Frank
    (2004) apply it to repeated K-fold, where ``n_test / n_train = 1 / (K - 1)``.

    Args:
        values: One paired difference per (repeat, fold), `(J,)`.
        test_to_train: Held-out rows over training rows of one split, ``1 / (K - 1)`` for
            K-fold; 0 gives the plain t interval.
        confidence: Two-sided confidence level in (0, 1).

    Returns:
        ``t_{(1 + confidence) / 2, J - 1} * sd * sqrt(1 / J + test_to_train)`` (0 for fewer
        than two values); NaN values propagate.

    Raises:
        InputError: For `values` that are not a 1-D array of numbers, a level outside (0, 1)
            or a negative or non-finite `test_to_train`.
    """
    ratio = real_number(test_to_train)
    if not math.isfinite(ratio) or ratio < 0:
        raise InputError(
            f"test_to_train must be a finite ratio >= 0 (1 / (K - 1) for K folds), "
            f"got {test_to_train!r}."
        )
    v = _values(values)
    q = _t_quantile(confidence, max(len(v) - 1, 1))
    if len(v) < 2:
        return 0.0
    return q * _sample_sd(v) * math.sqrt(1 / len(v) + ratio)


def mean_halfwidth(values: Sequence[float] | np.ndarray, confidence: float = 0.95) -> float:
    """Half-width of the Student-t interval of the mean of `values` (0 for fewer than two).

    Args:
        values: Independent observations, e.g. one score per trial.
        confidence: Two-sided confidence level in (0, 1).

    Returns:
        ``t_{(1 + confidence) / 2, n - 1} * sd / sqrt(n)``; NaN values propagate.

    Raises:
        InputError: For `values` that are not a 1-D array of numbers, or a level outside
            (0, 1).
    """
    return corrected_halfwidth(values, 0.0, confidence)


def mean_and_halfwidth(values: Sequence[float], confidence: float = 0.95) -> tuple[float, float]:
    """The mean of `values` and its `mean_halfwidth`, as a table reports a score over trials.

    Args:
        values: Independent observations, e.g. one score per trial.
        confidence: Two-sided confidence level in (0, 1).

    Returns:
        ``(mean, half-width)``; the half-width is 0 for a single value, and no values give
        ``(nan, 0.0)``: a table's cell without trials.

    Raises:
        InputError: For `values` that are not a 1-D array of numbers, or a level outside
            (0, 1).
    """
    v = _values(values)
    mean = float(v.mean()) if v.size else math.nan
    return mean, mean_halfwidth(v, confidence)
