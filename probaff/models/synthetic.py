"""Synthetic regime-switching regression data with known expert assignments.

Used to test and benchmark mixtures of experts: every sample belongs to one of three
regimes chosen by its features, and each regime has its own function and noise level.
"""

from __future__ import annotations

import torch
from torch import Tensor

from probaff._checks import check_positive

__all__ = ["piecewise_1d", "regime_features"]

_NOISE_STD = (0.05, 0.1, 0.2)


def piecewise_1d(n: int, *, seed: int = 0) -> tuple[Tensor, Tensor, Tensor]:
    """Three regimes on `x ~ U(-3, 3)` split at -1 and 1, with 2-D outputs.

    Regime 0 is linear with noise std 0.05, regime 1 sinusoidal with 0.1, regime 2 linear
    with 0.2; the regimes' outputs are well separated.

    Args:
        n: Number of samples.
        seed: Random seed.

    Returns:
        Features `(n, 1)`, outputs `(n, 2)` and regime labels `(n,)` (long).
    """
    check_positive("n", n)
    g = torch.Generator().manual_seed(seed)
    x = torch.rand(n, 1, generator=g, dtype=torch.float64) * 6 - 3
    labels = torch.bucketize(x[:, 0], torch.tensor([-1.0, 1.0], dtype=torch.float64))
    eps = torch.randn(n, 2, generator=g, dtype=torch.float64)
    t = x[:, 0]
    regimes = (
        torch.stack([2.0 + 0.5 * t, -1.0 + 0.3 * t], dim=1),
        torch.stack([torch.sin(3 * t), 1.0 + 0.5 * torch.cos(2 * t)], dim=1),
        torch.stack([-2.5 + 0.3 * t, -0.5 * t], dim=1),
    )
    y = torch.zeros(n, 2, dtype=torch.float64)
    for k, (f, s) in enumerate(zip(regimes, _NOISE_STD, strict=True)):
        rows = labels == k
        y[rows] = f[rows] + s * eps[rows]
    return x, y, labels


def regime_features(n: int, d: int, e: int, *, seed: int = 0) -> tuple[Tensor, Tensor, Tensor]:
    """High-dimensional push-like data: the regime depends on columns 0-1 only.

    Features are standard normal. Regime `k` (from thresholds on `x0 + 0.5 x1`) has
    outputs `offset_k + sin(x[:, 3+4k : 7+4k]) @ W_k + noise_k`, so each regime depends
    on its own four columns and the other columns are irrelevant.

    Args:
        n: Number of samples.
        d: Number of feature columns (at least 15).
        e: Number of outputs.
        seed: Random seed.

    Returns:
        Features `(n, d)`, outputs `(n, e)` and regime labels `(n,)` (long).
    """
    check_positive("n", n)
    check_positive("e", e)
    if d < 15:
        raise ValueError(f"regime_features needs d >= 15 columns, got {d}.")
    g = torch.Generator().manual_seed(seed)
    x = torch.randn(n, d, generator=g, dtype=torch.float64)
    labels = torch.bucketize(x[:, 0] + 0.5 * x[:, 1], torch.tensor([-0.5, 0.5]).double())
    w = torch.randn(3, 4, e, generator=g, dtype=torch.float64)
    eps = torch.randn(n, e, generator=g, dtype=torch.float64)
    y = torch.zeros(n, e, dtype=torch.float64)
    for k, s in enumerate(_NOISE_STD):
        rows = labels == k
        z = x[rows, 3 + 4 * k : 7 + 4 * k]
        y[rows] = 3.0 * (k - 1) + torch.sin(z) @ w[k] + s * eps[rows]
    return x, y, labels
