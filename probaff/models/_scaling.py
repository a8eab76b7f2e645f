"""Weighted per-column standardisation, used for GP inputs, GP outputs and gate inputs."""

from __future__ import annotations

import torch
from torch import Tensor

__all__ = ["Standardizer"]

# A column whose spread is below this is treated as constant and left unscaled.
_MIN_STD = 1e-12


class Standardizer(torch.nn.Module):
    """Affine map `z = (x - mean) / std` with weighted column moments.

    Attributes:
        mean: Column means, `(C,)`.
        std: Column standard deviations (1 for constant columns), `(C,)`.
    """

    mean: Tensor
    std: Tensor

    def __init__(self, n_columns: int) -> None:
        super().__init__()
        self.register_buffer("mean", torch.zeros(n_columns, dtype=torch.float64))
        self.register_buffer("std", torch.ones(n_columns, dtype=torch.float64))

    def fit(self, x: Tensor, weights: Tensor | None = None) -> Standardizer:
        """Set `mean` and `std` to the weighted column moments of `x`.

        Args:
            x: Data, `(N, C)`.
            weights: Non-negative sample weights with a positive sum, `(N,)`; uniform if ``None``.

        Returns:
            This standardizer.
        """
        w = torch.ones(x.shape[0], dtype=x.dtype, device=x.device) if weights is None else weights
        w = w / w.sum()
        mean = w @ x
        var = w @ (x - mean).square()
        std = var.sqrt()
        std = torch.where(std > _MIN_STD * (1.0 + mean.abs()), std, torch.ones_like(std))
        self.mean.copy_(mean)
        self.std.copy_(std)
        return self

    def forward(self, x: Tensor) -> Tensor:
        """Standardise `x`.

        Args:
            x: Data in original units, `(N, C)`.

        Returns:
            Standardised data, `(N, C)`.
        """
        return (x - self.mean) / self.std
