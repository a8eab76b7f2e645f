"""What every GP expert of a mixture shares, and the checks of a weighted training set.

Sizes, settings, the weighted likelihood, the standardisers, the jitter and the noise floor.

`probaff.models.experts.gp_expert.GPExpert` (exact) and
`probaff.models.experts.sparse_expert.SparseGPExpert` (inducing points) derive from
`WeightedExpert`; each adds its kernel, its `condition` and its hyperparameter search, which
`WeightedExpert.fit` runs after it.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, Self

import torch
from gpytorch.constraints import Interval
from gpytorch.priors import Prior
from torch import Tensor
from torch.distributions import Normal

from probaff._checks import check_count, check_finite
from probaff._threads import threads_by_rows
from probaff.errors import InputError
from probaff.models._scaling import Standardizer
from probaff.models.experts.kernels import lengthscale_prior
from probaff.models.experts.likelihood import WeightedGaussianLikelihood
from probaff.models.options import AUTO_NOISE_FLOOR, NOISE_BOUNDS, GPOptions
from probaff.models.tensors import DeviceCheckedModule, as_matrix, as_vector

__all__ = [
    "MIN_VARIANCE",
    "WeightedExpert",
    "noise_floor_vector",
    "out_of_sample",
    "training_noise_floor",
]

MIN_VARIANCE = 1e-12
"""Floor on every expert's predictive variances (in standardised output units)."""


def noise_floor_vector(
    noise_floor: float | Sequence[float] | Tensor | None, n_outputs: int
) -> Tensor:
    """A noise floor (standard deviations in output units) as one value per output.

    Args:
        noise_floor: ``None`` (no floor), a scalar, or one value per output.
        n_outputs: Number of outputs `E`.

    Returns:
        Non-negative standard deviations, `(E,)`, float64.

    Raises:
        InputError: For negative, NaN or infinite values, or the wrong number of values.
    """
    if noise_floor is None:
        return torch.zeros(n_outputs, dtype=torch.float64)
    floor = torch.as_tensor(noise_floor, dtype=torch.float64).flatten()
    check_finite("noise_floor", floor)
    if floor.numel() == 1:
        floor = floor.expand(n_outputs)
    if floor.numel() != n_outputs or bool((floor < 0).any()):
        raise InputError(
            f"noise_floor must be one non-negative standard deviation or {n_outputs} of them "
            f"(one per output), got {noise_floor!r}."
        )
    return floor.clone()


def training_noise_floor(
    noise_floor: float | Sequence[float] | str | None, targets: Tensor
) -> Tensor:
    """The noise floor of a `GPOptions` for training targets `(N, E)`, in their units.

    Args:
        noise_floor: ``GPOptions.noise_floor``: ``"auto"`` (`AUTO_NOISE_FLOOR` of each
            output's standard deviation over every row of `targets`), ``None`` (no floor),
            a scalar, or one value per output.
        targets: The training targets, `(N, E)`.

    Returns:
        Non-negative standard deviations, `(E,)`, float64.

    Raises:
        InputError: For negative, NaN or infinite values, or the wrong number of values.
    """
    if isinstance(noise_floor, str):  # "auto", the one text GPOptions accepts
        return AUTO_NOISE_FLOOR * targets.std(dim=0, correction=0)
    return noise_floor_vector(noise_floor, targets.shape[1])


class WeightedExpert(DeviceCheckedModule):
    r"""Base of the GP experts: `E` outputs of `D` features with per-sample noise weights.

    Sample `i` of weight :math:`w_i > 0` has noise variance :math:`\sigma^2 / w_i`
    (`WeightedGaussianLikelihood`, batched over the outputs); samples of weight 0 are
    dropped. Inputs and outputs are standardised with the weighted moments of the training
    data, and the noise standard deviation of every output is at least its `noise_floor`
    (output units; ``noise_floor="auto"`` is resolved from the targets of every fit or
    conditioning, see `training_noise_floor`). Subclasses register their kernel after
    calling this constructor, then move to float64 and reset their hyperparameters.

    Args:
        n_features: Number of input features `D`.
        n_outputs: Number of outputs `E`.
        options: The resolved settings (`GPOptions` or a subclass).
        jitter: The first diagonal jitter tried (relative; the subclass's first level).

    Attributes:
        options: The settings.
        max_iter: L-BFGS iterations per `fit` (``options.max_iter``).
        lengthscale_prior: Whether the log length-scale prior is on.
        likelihood: The weighted Gaussian likelihood, batch shape `(E,)`.
        x_scaler: Standardiser of the features (weighted moments of the training set).
        y_scaler: Standardiser of the outputs.
    """

    jitter: Tensor
    noise_floor: Tensor

    def __init__(self, n_features: int, n_outputs: int, options: GPOptions, jitter: float) -> None:
        super().__init__()
        self.n_features = check_count("n_features", n_features)
        self.n_outputs = check_count("n_outputs", n_outputs)
        self.options = options
        self.max_iter = options.max_iter
        self.lengthscale_prior = options.lengthscale_prior
        self.likelihood = WeightedGaussianLikelihood(
            batch_shape=torch.Size([self.n_outputs]), noise_constraint=Interval(*NOISE_BOUNDS)
        )
        self.x_scaler = Standardizer(self.n_features)
        self.y_scaler = Standardizer(self.n_outputs)
        self.register_buffer("jitter", torch.tensor(jitter, dtype=torch.float64))
        floor = options.noise_floor
        self.auto_noise_floor = isinstance(floor, str)  # "auto": set from the data it is given
        floor = None if isinstance(floor, str) else floor
        self.register_buffer("noise_floor", noise_floor_vector(floor, self.n_outputs))

    def kernel_prior(self) -> Prior | None:
        """The log length-scale prior of the kernel (`lengthscale_prior`), or None when off."""
        if self.lengthscale_prior is False:
            return None
        width = None if self.lengthscale_prior is True else float(self.lengthscale_prior)
        return lengthscale_prior(self.n_features, width)

    @property
    def device(self) -> torch.device:
        """The device of the expert's parameters, where it fits and predicts."""
        return self.jitter.device

    def weighted_rows(self, X: Any, Y: Any, weights: Any | None) -> tuple[Tensor, Tensor, Tensor]:
        """Validate a weighted training set and set the scalers, noise floor and weights.

        Rows of weight 0 are dropped; the standardisers take the weighted moments of the
        rest, the likelihood their weights and the noise floor (in standardised units). A
        ``noise_floor="auto"`` is resolved first, from every row of `Y`.

        Args:
            X: Features, `(N, D)`.
            Y: Targets, `(N, E)`.
            weights: Non-negative sample weights, `(N,)`; all 1 if ``None``.

        Returns:
            The kept rows' features `(n, D)`, targets `(n, E)` and weights `(n,)`, in input
            units, on the expert's device.

        Raises:
            InputError: On malformed inputs or if every weight is zero.
        """
        device = self.device
        x = as_matrix("features X", X, n_cols=self.n_features, device=device)
        y = as_matrix("targets Y", Y, n_rows=x.shape[0], n_cols=self.n_outputs, device=device)
        if weights is None:
            w = torch.ones(x.shape[0], dtype=torch.float64, device=device)
        else:
            w = as_vector("weights", weights, n=x.shape[0], device=device)
            if bool((w < 0).any()):
                raise InputError("weights must be >= 0.")
        keep = w > 0
        if not bool(keep.any()):
            raise InputError("every weight is zero; at least one sample must have weight > 0.")
        if self.auto_noise_floor:
            self.noise_floor.copy_(training_noise_floor("auto", y))
        x, y, w = x[keep], y[keep], w[keep]
        self.x_scaler.fit(x, w)
        self.y_scaler.fit(y, w)
        floor = (self.noise_floor / self.y_scaler.std).square()
        self.likelihood.noise_covar.floor.copy_(floor[:, None])
        self.likelihood.weights = w
        return x, y, w

    def condition(self, X: Any, Y: Any, weights: Any | None = None) -> Self:
        """Set the training data without changing the hyperparameters (each subclass's own).

        Args:
            X: Features, `(N, D)`.
            Y: Targets, `(N, E)`.
            weights: Non-negative sample weights, `(N,)`; all 1 if ``None``.

        Returns:
            This expert.

        Raises:
            InputError: On malformed inputs or if every weight is zero.
        """
        raise NotImplementedError

    @threads_by_rows("X")
    def fit(
        self, X: Any, Y: Any, weights: Any | None = None, *, max_iter: int | None = None
    ) -> Self:
        """Set the training data (`condition`) and fit the hyperparameters to it.

        `GPExpert` maximises the weighted marginal likelihood; `SparseGPExpert` chooses its
        inducing inputs, then maximises its bound. Both warm-start from the current
        hyperparameters.

        Args:
            X: Features, `(N, D)`.
            Y: Targets, `(N, E)`.
            weights: Non-negative sample weights, `(N,)`; all 1 if ``None``.
            max_iter: L-BFGS iterations; defaults to the constructor's `max_iter`.

        Returns:
            This expert.
        """
        self.condition(X, Y, weights)
        self._fit_hyperparameters(self.max_iter if max_iter is None else int(max_iter))
        return self

    def _fit_hyperparameters(self, max_iter: int) -> None:
        """The search `fit` runs on the data `condition` set (each subclass's own)."""
        raise NotImplementedError

    def predict(self, X: Any, *, include_noise: bool = True) -> Normal:
        """Predictive distribution of the outputs at `X` (each subclass's own).

        Args:
            X: Features, `(N, D)`.
            include_noise: Add the observation noise variance (weight 1) to the latent one.

        Returns:
            Independent normals with loc and scale `(N, E)`.

        Raises:
            NotFittedError: If the expert has no training data yet.
        """
        raise NotImplementedError

    def output_normal(self, mean: Tensor, var: Tensor) -> Normal:
        """Standardised predictive moments as independent normals in output units.

        Args:
            mean: Means, `(E, n)`, in standardised output units.
            var: Variances, `(E, n)`, in standardised output units; floored at
                `MIN_VARIANCE`.

        Returns:
            Independent normals with loc and scale `(n, E)`, in output units.
        """
        var = var.clamp_min(MIN_VARIANCE)
        loc = mean.T * self.y_scaler.std + self.y_scaler.mean
        return Normal(loc, var.T.sqrt() * self.y_scaler.std)

    def loo_predict(self) -> Normal:
        """Leave-one-out predictive distribution of every training row (each subclass's own).

        Returns:
            Independent normals with loc and scale `(n_train, E)`, in output units, one row
            per training sample with non-zero weight, in the order given to `fit`.

        Raises:
            NotFittedError: If the expert has no training data yet.
        """
        raise NotImplementedError

    def marginal_log_likelihood(self, jitter: float | None = None) -> Tensor:
        """The hyperparameters' objective per output, divided by `n` (each subclass's own).

        Args:
            jitter: Diagonal jitter of the training factorisation (each subclass says how it
                is used); defaults to the expert's current jitter.

        Returns:
            One value per output, `(E,)`, differentiable in the hyperparameters.

        Raises:
            NotFittedError: If the expert has no training data yet.
        """
        raise NotImplementedError

    def log_prob(self, X: Any, Y: Any) -> Tensor:
        """Predictive log density of each row of `Y` (noise included, summed over outputs).

        Args:
            X: Features, `(N, D)`.
            Y: Targets, `(N, E)`.

        Returns:
            Log densities, `(N,)`.
        """
        pred = self.predict(X)
        y = as_matrix(
            "targets Y", Y, n_rows=pred.loc.shape[0], n_cols=self.n_outputs, device=self.device
        )
        return pred.log_prob(y).sum(-1)

    @property
    def noise(self) -> Tensor:
        """Observation noise variances in output units, `(E,)`."""
        return self.likelihood.noise.detach()[..., 0] * self.y_scaler.std.square()


def out_of_sample(experts: Sequence[WeightedExpert], X: Tensor, held: Tensor) -> Normal:
    """Every expert's predictive distribution of every training row without that row.

    Where expert `j` holds row `i` (``held[i, j]``) it is its `loo_predict` normal;
    elsewhere its `predict` (noise included), which is already out of sample. One expert
    at a time; `probaff.models.experts.expert_batch.predict_exact_experts_out_of_sample` batches
    exact experts.

    Args:
        experts: `M` fitted experts with the same `E`.
        X: Expert features of the training rows, `(N, D)`, on the experts' device.
        held: Whether each expert holds each row (its training rows, in order), `(N, M)`.

    Returns:
        Normals with loc and scale `(N, M, E)`, in output units.
    """
    loc = X.new_empty(X.shape[0], len(experts), experts[0].n_outputs)
    scale = torch.empty_like(loc)
    for j, expert in enumerate(experts):
        own = held[:, j]
        loo = expert.loo_predict()
        loc[own, j], scale[own, j] = loo.loc, loo.scale
        if not bool(own.all()):
            pred = expert.predict(X[~own])
            loc[~own, j], scale[~own, j] = pred.loc, pred.scale
    return Normal(loc, scale)
