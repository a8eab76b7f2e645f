"""One GP expert: E independent SE-ARD Gaussian processes with per-sample noise weights."""

from __future__ import annotations

import contextlib
import math
import warnings
from collections.abc import Generator, Iterator
from typing import Any, Self, TypeAlias

import gpytorch
import numpy as np
import torch
from gpytorch.distributions import MultivariateNormal
from gpytorch.means import ConstantMean
from gpytorch.priors import Prior
from linear_operator.utils.errors import NanError, NotPSDError
from torch import Tensor
from torch.distributions import Normal

from probaff.errors import NotFittedError
from probaff.models.experts.expert_base import MIN_VARIANCE, WeightedExpert, noise_floor_vector
from probaff.models.experts.gaussian_density import gaussian_log_density, loo_moments, psd_cholesky
from probaff.models.experts.kernels import ard_se_kernel
from probaff.models.experts.likelihood import WeightedGaussianLikelihood
from probaff.models.lbfgs import Evaluation, assign, drive, flat_grad, flatten, lbfgs_coroutine
from probaff.models.options import OUTPUTSCALE_BOUNDS, GPOptions, resolve_options
from probaff.models.tensors import as_matrix

__all__ = ["FitRequest", "GPExpert", "exact_gp_settings", "noise_floor_vector"]

FitRequest: TypeAlias = tuple[float, np.ndarray]
"""An evaluation `GPExpert.optimisation` asks for: a fallback jitter and flat parameters."""

# Diagonal jitter levels tried in turn when a kernel matrix is numerically singular.
_JITTERS = (1e-8, 1e-6, 1e-4, 1e-2)
# Box constraints (standardised units) that keep every hyperparameter finite and positive.
_LENGTHSCALE_BOUNDS = (1e-3, 1e4)


@contextlib.contextmanager
def exact_gp_settings(jitter: float = _JITTERS[0]) -> Iterator[None]:
    """Force exact Cholesky-based GP algebra with `jitter` as the first fallback jitter.

    Args:
        jitter: Diagonal jitter added when a Cholesky factorisation fails.
    """
    with (
        gpytorch.settings.max_cholesky_size(10**9),
        gpytorch.settings.fast_computations(
            covar_root_decomposition=False, log_prob=False, solves=False
        ),
        gpytorch.settings.cholesky_jitter(float_value=jitter, double_value=jitter),
        gpytorch.settings.cholesky_max_tries(3),
        gpytorch.settings.fast_pred_var(False),
        gpytorch.settings.debug(False),
    ):
        yield


class _BatchedExactGP(gpytorch.models.ExactGP):
    """`E` independent exact GPs sharing their inputs (gpytorch batch shape `(E,)`)."""

    def __init__(
        self,
        n_features: int,
        n_outputs: int,
        likelihood: WeightedGaussianLikelihood,
        lengthscale_prior: Prior | None,
    ) -> None:
        super().__init__(None, None, likelihood)
        batch = torch.Size([n_outputs])
        self.n_outputs = n_outputs
        self.mean_module = ConstantMean(batch_shape=batch)
        self.covar_module = ard_se_kernel(
            n_features,
            batch,
            lengthscale_bounds=_LENGTHSCALE_BOUNDS,
            outputscale_bounds=OUTPUTSCALE_BOUNDS,
            lengthscale_prior=lengthscale_prior,
        )

    def forward(self, x: Tensor) -> MultivariateNormal:
        """Prior over the `E` outputs at `x: (n, D)` (or `(E, n, D)`), batch `(E,)`."""
        x = x.expand(self.n_outputs, *x.shape[-2:])
        return MultivariateNormal(self.mean_module(x), self.covar_module(x))


class GPExpert(WeightedExpert):
    r"""Multi-output GP regressor with SE-ARD kernels and per-sample noise weights.

    Each of the `E` outputs is an independent exact GP (constant mean, amplitude times an
    ARD squared-exponential kernel, Gaussian noise) with its own hyperparameters, batched
    with gpytorch. Inputs and outputs are standardised with the weighted moments of the
    training data. Sample `i` with weight :math:`w_i > 0` has noise variance
    :math:`\sigma^2 / w_i`; samples with weight exactly 0 are removed before the GP is built,
    so they have no effect at all. Hyperparameters maximise the weighted exact marginal
    likelihood (see `WeightCorrection`) with L-BFGS, warm-started from their current values.

    With `lengthscale_prior`, each length scale gets the log-normal prior
    :math:`\log \ell_d \sim \mathcal N(\sqrt 2 + \tfrac12 \log D, 1)` whose median grows
    as :math:`\sqrt D` (Hvarfner et al., 2024; see
    `probaff.models.experts.kernels.lengthscale_prior` for the choice of its width), and the
    fit maximises the weighted marginal likelihood plus the log prior. This curbs the
    overfitting of ML-II when the number of samples is not much larger than `D`.

    Args:
        n_features: Number of input features `D`.
        n_outputs: Number of outputs `E`.
        options: The GP's settings (`GPOptions`: `max_iter`, L-BFGS iterations per call to
            `fit`; `lengthscale_prior`, the dimension-scaled log-normal prior on the length
            scales; `noise_floor`, the smallest observation-noise standard deviation in
            output units, one value or one per output `(E,)`, added as its square to the
            learned noise variance so that experts whose samples have (nearly) identical
            targets, such as the exact zeros of an object that did not move, keep a finite
            noise level; `outputscale` and `noise`, the initial signal and noise variances
            in standardised units); None for `GPOptions()`.
        **overrides: Fields of `GPOptions` that replace those of `options`, e.g.
            ``GPExpert(3, 2, max_iter=20, lengthscale_prior=True)``.

    Attributes:
        gp: The batched gpytorch model.
        likelihood: Its weighted Gaussian likelihood.
    """

    def __init__(
        self,
        n_features: int,
        n_outputs: int,
        options: GPOptions | None = None,
        **overrides: Any,
    ) -> None:
        resolved = resolve_options(GPOptions, options, overrides)
        super().__init__(n_features, n_outputs, resolved, _JITTERS[0])
        self.initial_outputscale = resolved.outputscale
        self.initial_noise = resolved.noise
        self.gp = _BatchedExactGP(
            self.n_features, self.n_outputs, self.likelihood, self.kernel_prior()
        )
        self.to(torch.float64)
        self.reset_hyperparameters()
        self.eval()

    # ------------------------------------------------------------------ setup
    def reset_hyperparameters(self) -> None:
        """Set length scales to sqrt(D), amplitudes and noise to their initial values, means to 0.

        The initial amplitude and noise are the constructor's `outputscale` (1 by default)
        and `noise` (0.1 by default). All in standardised units.
        """
        kernel = self.gp.covar_module
        kernel.base_kernel.lengthscale = torch.full_like(
            kernel.base_kernel.lengthscale, math.sqrt(self.n_features)
        )
        kernel.outputscale = torch.full_like(kernel.outputscale, self.initial_outputscale)
        self.likelihood.noise = self.initial_noise
        self.gp.mean_module.constant.data.zero_()

    @property
    def is_fitted(self) -> bool:
        """Whether training data has been set with `fit` or `condition`."""
        return self.gp.train_targets is not None

    @property
    def n_train(self) -> int:
        """Number of training samples with non-zero weight held by the GP."""
        return 0 if self.gp.train_targets is None else int(self.gp.train_targets.shape[-1])

    def condition(self, X: Any, Y: Any, weights: Any | None = None) -> Self:
        """Set the training data without changing the hyperparameters.

        The arguments, result and errors are those of `WeightedExpert.condition`.
        """
        x, y, _ = self.weighted_rows(X, Y, weights)
        self.gp.set_train_data(self.x_scaler(x), self.y_scaler(y).T.contiguous(), strict=False)
        return self

    # ---------------------------------------------------------------- fitting
    def _fit_hyperparameters(self, max_iter: int) -> None:
        """`fit`'s search: `optimise`, with a warning if every jitter level failed."""
        if not self.optimise(max_iter):
            warnings.warn(
                "GP hyperparameter optimisation failed at every jitter level; the previous "
                "hyperparameters are kept.",
                RuntimeWarning,
                stacklevel=3,  # the caller of `fit`, as when `fit` itself warned
            )

    def optimise(self, max_iter: int) -> bool:
        """Maximise the weighted marginal likelihood from the current hyperparameters.

        L-BFGS runs with the expert's first jitter; if the covariance cannot be factorised
        or anything becomes non-finite, the hyperparameters are restored and the next,
        larger jitter is tried (`optimisation` is this fit as a coroutine).

        Args:
            max_iter: L-BFGS iterations.

        Returns:
            Whether a jitter level succeeded; if none did, the hyperparameters are those
            before the call and the jitter is the largest level.
        """
        return drive(self.optimisation(max_iter), self.evaluate, (NotPSDError, NanError))

    def optimisation(self, max_iter: int) -> Generator[FitRequest, Evaluation, bool]:
        """`optimise` as a coroutine that leaves the evaluations to its caller.

        It yields ``(jitter, x)``, a fallback jitter and the flat trainable parameters `x`
        `(P,)` (in the order of `trainable`) to evaluate, and is sent ``(loss, grad)``: minus
        the sum over outputs of `marginal_log_likelihood` at that jitter and its gradient
        `(P,)`, as `evaluate` computes them; ``NotPSDError`` or ``NanError`` thrown into it
        abandon that jitter level. `probaff.models.experts.expert_batch` runs many side by side
        and evaluates them as one batch.

        Returns:
            Whether a jitter level succeeded (see `optimise`).
        """
        params = self.trainable()
        start = flatten(params)
        for jitter in _JITTERS:
            self.train()
            try:
                run = lbfgs_coroutine(
                    start, max_iter=max_iter, tolerance_grad=1e-6, tolerance_change=1e-9
                )
                x = next(run)
                while True:
                    x = run.send((yield jitter, x))
            except StopIteration as stop:
                x, loss = stop.value
                if math.isfinite(loss) and bool(np.isfinite(x).all()):
                    assign(params, x)
                    self.jitter.fill_(jitter)
                    return True
            except (NotPSDError, NanError):
                pass
            finally:
                self.eval()
        assign(params, start)
        self.jitter.fill_(_JITTERS[-1])
        return False

    def named_trainable(self) -> list[tuple[str, torch.nn.Parameter]]:
        """`trainable` with each parameter's name, in the order of `optimisation`'s vectors."""
        return [(name, p) for name, p in self.named_parameters() if p.requires_grad]

    def trainable(self) -> list[torch.nn.Parameter]:
        """The parameters the fit optimises, in the order of `optimisation`'s vectors."""
        return [p for _, p in self.named_trainable()]

    def evaluate(self, request: FitRequest) -> Evaluation:
        """The loss and gradient `optimisation` asks for, ``(jitter, x)``, on this expert alone."""
        jitter, x = request
        params = self.trainable()
        assign(params, x)
        with exact_gp_settings(jitter):
            for p in params:
                p.grad = None
            loss = -self.marginal_log_likelihood(jitter).sum()
            loss.backward()
        return float(loss.detach()), flat_grad(params)

    def marginal_log_likelihood(self, jitter: float | None = None) -> Tensor:
        r"""Weighted log marginal likelihood (plus log prior) per output, divided by `n`.

        The value of gpytorch's ``ExactMarginalLogLikelihood(likelihood, gp)`` on the
        training data: :math:`\log \mathcal N(y; m, K + \sigma^2 W^{-1})`, plus the
        likelihood's added loss terms (`WeightCorrection`) and the log priors, over the
        number of training samples. Its gradient comes from the closed form of
        `gaussian_log_density` instead of back-propagation through a Cholesky
        factorisation, which makes each L-BFGS evaluation about twice as fast.

        The result and errors are those of `WeightedExpert.marginal_log_likelihood`.

        Args:
            jitter: First diagonal jitter tried when the kernel matrix is singular;
                defaults to the expert's current jitter.
        """
        if not self.is_fitted:
            raise NotFittedError("GPExpert has no training data; call fit first.")
        x, y = self.gp.train_inputs[0], self.gp.train_targets  # (n, D), (E, n)
        n = y.shape[-1]
        k = self.gp.covar_module(x.expand(self.n_outputs, n, x.shape[-1])).to_dense()
        noise = self.likelihood.noise_covar(x, shape=torch.Size([self.n_outputs, n]))
        cov = k + noise.to_dense()
        mean = self.gp.mean_module.constant[:, None]
        res = gaussian_log_density(cov, y - mean, float(self.jitter) if jitter is None else jitter)
        for term in self.gp.added_loss_terms():
            res = res + term.loss()
        for _, module, prior, closure, _ in self.gp.named_priors():
            log_p = prior.log_prob(closure(module))
            res = res + log_p.reshape(self.n_outputs, -1).sum(-1)
        return res / n

    # ------------------------------------------------------------- prediction
    def predict(self, X: Any, *, include_noise: bool = True) -> Normal:
        """Predictive distribution of the outputs at `X`.

        The arguments, result and errors are those of `WeightedExpert.predict`.
        """
        if not self.is_fitted:
            raise NotFittedError("GPExpert has no training data; call fit first.")
        x = as_matrix("features X", X, n_cols=self.n_features, device=self.device)
        self.eval()
        with torch.no_grad(), exact_gp_settings(float(self.jitter)):
            post = self.gp(self.x_scaler(x))
            var = post.variance  # (E, N)
            if include_noise:
                var = var + self.likelihood.noise  # (E, 1)
        return self.output_normal(post.mean, var)

    def loo_predict(self) -> Normal:
        r"""Leave-one-out predictive distribution of every training sample.

        For sample `i` of the training set, the distribution of a new observation at
        :math:`x_i` (noise of weight 1) given every *other* training sample, from the
        closed form of Rasmussen & Williams (2006, eq. 5.12): with
        :math:`A = K + \sigma^2 W^{-1}` and :math:`\alpha = A^{-1}(y - m)`,
        :math:`\mu_{-i} = y_i - \alpha_i / [A^{-1}]_{ii}` and the latent variance
        :math:`1/[A^{-1}]_{ii} - \sigma^2 / w_i`. It costs one Cholesky factorisation. The
        result and errors are those of `WeightedExpert.loo_predict`, and one more:

        Raises:
            NotPSDError: If the training covariance cannot be factorised even with jitter
                (the policy of the marginal likelihood: as it is, then with the expert's
                jitter times 1, 10, 100).
        """
        if not self.is_fitted:
            raise NotFittedError("GPExpert has no training data; call fit first.")
        x = self.gp.train_inputs[0]
        y = self.gp.train_targets  # (E, n), standardised
        n = y.shape[-1]
        self.eval()
        with torch.no_grad(), exact_gp_settings(float(self.jitter)):
            k = self.gp.covar_module(x.expand(self.n_outputs, n, x.shape[-1])).to_dense()
            noise = self.likelihood.noise  # (E, 1)
            own = noise / self.likelihood.weights  # (E, n)
            chol = psd_cholesky(k + torch.diag_embed(own), float(self.jitter))
            resid = y - self.gp.mean_module.constant[:, None]
            alpha = torch.cholesky_solve(resid[..., None], chol)[..., 0]
            mean, latent = loo_moments(chol, y, alpha, own)  # (E, n) each
            var = latent.clamp_min(MIN_VARIANCE) + noise
        return self.output_normal(mean, var)

    # ------------------------------------------------------------ relevances
    @property
    def lengthscales(self) -> Tensor:
        """ARD length scales in standardised feature units, `(E, D)`; short means relevant."""
        return self.gp.covar_module.base_kernel.lengthscale.detach().reshape(
            self.n_outputs, self.n_features
        )
