"""The kernel every GP expert uses: an amplitude times an SE-ARD kernel, batched over outputs."""

from __future__ import annotations

import torch
from gpytorch.constraints import Interval
from gpytorch.kernels import RBFKernel, ScaleKernel
from gpytorch.priors import Prior

__all__ = ["ard_se_kernel"]


def ard_se_kernel(
    n_features: int,
    batch: torch.Size,
    *,
    lengthscale_bounds: tuple[float, float],
    outputscale_bounds: tuple[float, float],
    lengthscale_prior: Prior | None = None,
) -> ScaleKernel:
    """``theta0 exp(-1/2 sum_d (x_d - x'_d)^2 / l_d^2)`` with one length scale per feature.

    Args:
        n_features: Number of input features D (one length scale each).
        batch: Batch shape, one independent kernel per output: ``(E,)``.
        lengthscale_bounds: Interval constraint of the length scales.
        outputscale_bounds: Interval constraint of the amplitude theta0.
        lengthscale_prior: Optional prior on the length scales.

    Returns:
        The gpytorch kernel.
    """
    return ScaleKernel(
        RBFKernel(
            ard_num_dims=n_features,
            batch_shape=batch,
            lengthscale_prior=lengthscale_prior,
            lengthscale_constraint=Interval(*lengthscale_bounds),
        ),
        batch_shape=batch,
        outputscale_constraint=Interval(*outputscale_bounds),
    )
