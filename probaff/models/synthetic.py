"""Synthetic regime-switching regression data with known expert assignments.

Used to test and benchmark mixtures of experts: every sample belongs to one of three
regimes chosen by its features, and each regime has its own function and noise level.
"""

from __future__ import annotations

import torch
from torch import Tensor

from probaff._checks import check_count
from probaff.errors import InputError

__all__ = ["piecewise_1d", "regime_features", "softmax_regimes"]

_NOISE_STD = (0.05, 0.1, 0.2)


def _uniform_features(
    n: int, d: int, half_width: float, seed: int
) -> tuple[int, torch.Generator, Tensor]:
    """The checked count, the seeded generator and features ``U(-w, w)^d`` `(n, d)`."""
    n = check_count("n", n)
    g = torch.Generator().manual_seed(seed)
    x = torch.rand(n, d, generator=g, dtype=torch.float64) * (2 * half_width) - half_width
    return n, g, x


def piecewise_1d(n: int, *, seed: int = 0) -> tuple[Tensor, Tensor, Tensor]:
    """Three regimes on `x ~ U(-3, 3)` split at -1 and 1, with 2-D outputs.

    Regime 0 is linear with noise std 0.05, regime 1 sinusoidal with 0.1, regime 2 linear
    with 0.2; the regimes' outputs are well separated.

    Args:
        n: Number of samples.
        seed: Seed of the inputs and of the noise.

    Returns:
        Inputs `(n, 1)`, 2-D outputs `(n, 2)` and the regime of every sample `(n,)` (long).
    """
    n, g, x = _uniform_features(n, 1, 3.0, seed)
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
    n = check_count("n", n)
    e = check_count("e", e)
    d = check_count("d", d)
    if d < 15:
        raise InputError(f"regime_features needs d >= 15 columns, got {d}.")
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


def softmax_regimes(n: int, *, seed: int = 0) -> tuple[Tensor, Tensor, Tensor]:
    r"""Three regimes drawn from a softmax gate on two inputs, overlapping in effect space.

    Features `x ~ U(-2, 2)^4`. The regime is drawn from
    :math:`\mathrm{softmax}(4\,(A x_{0:2} + c))` with the three gate directions 120 degrees
    apart, so the regions meet at the origin and their borders are soft. The outputs are

    * regime 0: :math:`(\sin 2x_2,\; 0.5\,x_3)`, noise std 0.05;
    * regime 1: :math:`(0.8\,x_3,\; \cos 2x_2)`, noise std 0.1;
    * regime 2: :math:`(-\sin 2x_2,\; -0.5\,x_3)`, noise std 0.15,

    all with the same range, so no clustering of the outputs alone can tell the regimes
    apart: only the gate inputs `x0, x1` decide them, and the experts need `x2, x3`.

    Args:
        n: Number of samples.
        seed: Random seed.

    Returns:
        Features `(n, 4)`, outputs `(n, 2)` and regime labels `(n,)` (long).
    """
    n, g, x = _uniform_features(n, 4, 2.0, seed)
    angles = torch.tensor([0.0, 2.0, 4.0], dtype=torch.float64) * torch.pi / 3
    directions = torch.stack([angles.cos(), angles.sin()], dim=1)
    probs = torch.softmax(40.0 * (x[:, :2] @ directions.T), dim=1)
    labels = torch.multinomial(probs, 1, generator=g)[:, 0]
    a, b = x[:, 2], x[:, 3]
    means = torch.stack(
        [
            torch.stack([torch.sin(2 * a), 0.5 * b], dim=1),
            torch.stack([0.8 * b, torch.cos(2 * a)], dim=1),
            torch.stack([-torch.sin(2 * a), -0.5 * b], dim=1),
        ],
        dim=1,
    )
    noise = torch.tensor([0.05, 0.1, 0.15], dtype=torch.float64)
    eps = torch.randn(n, 2, generator=g, dtype=torch.float64)
    rows = torch.arange(n)
    y = means[rows, labels] + noise[labels, None] * eps
    return x, y, labels
