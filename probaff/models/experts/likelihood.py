r"""Gaussian likelihood whose per-sample noise variance is :math:`\sigma^2 / w_i`.

This is the observation model of one expert in the M-step of EM for a mixture of GP
experts: sample `i` enters expert `j` with weight :math:`w_i = r_{ij}` (its responsibility),
so the training covariance becomes :math:`K + \sigma^2 W^{-1}`.
"""

from __future__ import annotations

import math
from typing import Any

import torch
from gpytorch.constraints import GreaterThan, Interval
from gpytorch.likelihoods.gaussian_likelihood import _GaussianLikelihoodBase
from gpytorch.likelihoods.noise_models import Noise
from gpytorch.mlls import AddedLossTerm
from linear_operator.operators import DiagLinearOperator
from torch import Tensor

__all__ = ["WeightCorrection", "WeightedGaussianLikelihood", "WeightedNoise", "weight_correction"]

_SCALAR = torch.Size()


class WeightedNoise(Noise):
    r"""Diagonal noise :math:`\sigma^2 / w_i` with a learnable :math:`\sigma^2` per batch member.

    The weights of the training set are stored in the buffer `weights`. The noise model
    recognises the training set by its size, like gpytorch's fixed-noise model: on a set
    of another size every weight is 1 (the noise of a new observation). Pass ``weights=``
    explicitly to override this.

    Args:
        batch_shape: Batch shape of :math:`\sigma^2` (one noise level per output).
        noise_constraint: Constraint on :math:`\sigma^2`; defaults to ``GreaterThan(1e-6)``.
    """

    weights: Tensor

    def __init__(
        self, batch_shape: torch.Size = _SCALAR, noise_constraint: Interval | None = None
    ) -> None:
        super().__init__()
        self.register_parameter(
            "raw_noise", torch.nn.Parameter(torch.zeros(*batch_shape, 1, dtype=torch.float64))
        )
        self.register_constraint(
            "raw_noise", GreaterThan(1e-6) if noise_constraint is None else noise_constraint
        )
        self.register_buffer("weights", torch.ones(0, dtype=torch.float64), persistent=False)
        self.register_buffer("floor", torch.zeros(*batch_shape, 1, dtype=torch.float64))

    @property
    def noise(self) -> Tensor:
        r"""Noise variance :math:`\sigma^2_{\text{free}} + \sigma^2_{\text{floor}}`, `(*b, 1)`.

        The learnable part is kept inside the constraint; the buffer `floor` (a variance,
        `(*batch_shape, 1)`, zero by default) is added on top, so no fit can take the noise
        below it.
        """
        return self.raw_noise_constraint.transform(self.raw_noise) + self.floor

    @noise.setter
    def noise(self, value: Tensor | float) -> None:
        value = torch.as_tensor(value, dtype=self.raw_noise.dtype, device=self.raw_noise.device)
        value = value.expand_as(self.raw_noise)
        c = self.raw_noise_constraint
        lo, hi = float(c.lower_bound.max()), float(c.upper_bound.min())
        free = (value - self.floor).clamp_min(1.01 * lo + 1e-300)
        if math.isfinite(hi):
            free = free.clamp_max(0.99 * hi)
        self.initialize(raw_noise=self.raw_noise_constraint.inverse_transform(free))

    def forward(
        self,
        *params: Any,
        shape: torch.Size | None = None,
        weights: Tensor | None = None,
        **kwargs: Any,
    ) -> DiagLinearOperator:
        """Return the noise covariance of `n` observations.

        Args:
            *params: Inputs the likelihood was called with (used for the shape only).
            shape: `(*batch, n)` of the function values.
            weights: Explicit weights, `(n,)`; see the class docstring for the default.
            **kwargs: Ignored.

        Returns:
            Diagonal operator, `(*batch, n, n)`.
        """
        if shape is None:
            p = params[0] if torch.is_tensor(params[0]) else params[0][0]
            shape = p.shape if p.dim() == 1 else p.shape[:-1]
        n = shape[-1]
        if weights is None:
            weights = self.weights if self.weights.numel() == n else None
        diag = self.noise if weights is None else self.noise / weights
        batch = torch.broadcast_shapes(self.noise.shape[:-1], torch.Size(shape[:-1]))
        return DiagLinearOperator(diag.expand(*batch, n))


def weight_correction(weights: Tensor, noise: Tensor) -> Tensor:
    r"""The `WeightCorrection` term for sample weights and noise variances.

    Args:
        weights: Positive sample weights :math:`w_i`, `(n,)`.
        noise: Noise variances :math:`\sigma^2`, `(*batch)`.

    Returns:
        :math:`\tfrac12 \sum_i [(1 - w_i) \log(2\pi\sigma^2) - \log w_i]`, `(*batch)`.
    """
    return 0.5 * ((1.0 - weights).sum() * torch.log(2 * math.pi * noise) - weights.log().sum())


class WeightCorrection(AddedLossTerm):
    r"""Loss term making the marginal likelihood under :math:`K + \sigma^2 W^{-1}` a weighted one.

    With noise :math:`\sigma^2 / w_i`, each sample still adds :math:`-\tfrac12 \log \sigma^2`
    to the log marginal likelihood however small its weight, which biases the noise level
    towards zero (by the factor :math:`\sum_i w_i / N` when the kernel is negligible). Adding

    .. math:: \tfrac12 \sum_i \left[(1 - w_i) \log(2\pi\sigma^2) - \log w_i\right]

    makes the objective equal the weighted log likelihood
    :math:`\sum_i w_i \log \mathcal N(y_i; \mu, \sigma^2)` in the noise-dominated limit,
    and makes a sample's contribution vanish continuously as its weight goes to 0. The
    term is exactly 0 for unit weights.

    Args:
        noise_model: The noise model whose :math:`\sigma^2` and training weights are used.
    """

    def __init__(self, noise_model: WeightedNoise) -> None:
        self.noise_model = noise_model

    def loss(self, *params: Any) -> Tensor:
        """Return the correction per batch member, `(*batch_shape,)`."""
        return weight_correction(self.noise_model.weights, self.noise_model.noise[..., 0])


class WeightedGaussianLikelihood(_GaussianLikelihoodBase):
    r"""Gaussian likelihood with per-sample noise :math:`\sigma^2 / w_i`.

    It registers a `WeightCorrection` loss term, so gpytorch's
    ``ExactMarginalLogLikelihood`` maximises the weighted marginal likelihood.

    Args:
        batch_shape: Batch shape of :math:`\sigma^2`.
        noise_constraint: Constraint on :math:`\sigma^2`; defaults to ``GreaterThan(1e-6)``.
    """

    noise_covar: WeightedNoise

    def __init__(
        self, batch_shape: torch.Size = _SCALAR, noise_constraint: Interval | None = None
    ) -> None:
        super().__init__(noise_covar=WeightedNoise(batch_shape, noise_constraint))
        self.register_added_loss_term("weight_correction")
        self.update_added_loss_term("weight_correction", WeightCorrection(self.noise_covar))

    @property
    def noise(self) -> Tensor:
        r""":math:`\sigma^2`, `(*batch_shape, 1)`."""
        return self.noise_covar.noise

    @noise.setter
    def noise(self, value: Tensor | float) -> None:
        self.noise_covar.noise = value

    @property
    def weights(self) -> Tensor:
        """Weights of the training samples, `(n,)`."""
        return self.noise_covar.weights

    @weights.setter
    def weights(self, value: Tensor) -> None:
        self.noise_covar.weights = value.to(self.noise_covar.raw_noise)
