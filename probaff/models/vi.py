r"""Stochastic variational inference for a mixture of sparse GP experts with Pyro.

The same generative model as `MixtureOfGPExperts`, trained by minibatch SVI instead of EM:
each expert is a gpytorch `ApproximateGP` (SVGP with learned inducing points and a
whitened Gaussian q(u)), and each sample's expert assignment is a discrete latent variable
that `TraceEnum_ELBO` sums out exactly. Both the expected log-likelihood and
:math:`\mathrm{KL}(q(u) \Vert p(u))` enter the ELBO in closed form, so the only
Monte Carlo noise is the minibatch.
"""

from __future__ import annotations

import math
from typing import Any

import gpytorch
import pyro
import pyro.distributions as dist
import torch
from gpytorch.means import ConstantMean
from gpytorch.variational import CholeskyVariationalDistribution, VariationalStrategy
from pyro.infer import config_enumerate
from pyro.ops.indexing import Vindex
from torch import Tensor
from torch.distributions import Normal

from probaff._checks import check_count
from probaff.errors import NotFittedError
from probaff.models._scaling import Standardizer
from probaff.models.gate import SoftmaxGate
from probaff.models.gated import ExpertList, GatedMixture
from probaff.models.kernels import ard_se_kernel
from probaff.models.mixture import MixtureOfGPExperts

__all__ = ["SVGPExpert", "VariationalMixtureOfGPExperts"]

_NOT_FITTED = (
    "VariationalMixtureOfGPExperts is not fitted; call probaff.models.fit_svi(model, X, Y) first."
)


class SVGPExpert(gpytorch.models.ApproximateGP):
    """`E` independent sparse variational GPs (SE-ARD kernels) sharing their inputs.

    Args:
        inducing: Initial inducing inputs (standardised), `(E, K, D)`.
    """

    def __init__(self, inducing: Tensor) -> None:
        n_outputs, n_inducing, n_features = inducing.shape
        batch = torch.Size([n_outputs])
        variational = CholeskyVariationalDistribution(n_inducing, batch_shape=batch)
        strategy = VariationalStrategy(self, inducing, variational, learn_inducing_locations=True)
        super().__init__(strategy)
        self.n_outputs = n_outputs
        self.mean_module = ConstantMean(batch_shape=batch)
        self.covar_module = ard_se_kernel(
            n_features, batch, lengthscale_bounds=(1e-3, 1e4), outputscale_bounds=(1e-4, 1e4)
        )
        self.covar_module.base_kernel.lengthscale = math.sqrt(n_features)
        self.covar_module.outputscale = 1.0

    def initialize_variational(self, values: Tensor, std: float = 0.1) -> None:
        r"""Centre q(u) on given function values at the inducing points.

        The whitened mean `v` solves the ridge problem
        :math:`\min_v \lVert L v - \text{values} \rVert^2 + 10^{-2} \lVert v \rVert^2`
        with :math:`L L^T = K_{uu}`, which stays moderate when inducing points nearly coincide.

        Args:
            values: Latent values minus the constant mean at the inducing points, `(E, K)`.
            std: Standard deviation of q(u) in whitened units.
        """
        strategy = self.variational_strategy
        with torch.no_grad():
            z = strategy.inducing_points
            k_uu = self.covar_module(z).to_dense()
            eye = torch.eye(z.shape[-2], dtype=z.dtype)
            chol = torch.linalg.cholesky(k_uu + 1e-6 * eye)
            gram = chol.transpose(-1, -2) @ chol + 1e-2 * eye
            rhs = chol.transpose(-1, -2) @ values[..., None]
            whitened = torch.linalg.solve(gram, rhs)[..., 0]
            variational = strategy._variational_distribution
            variational.variational_mean.copy_(whitened)
            variational.chol_variational_covar.copy_(std * eye.expand_as(k_uu))
            strategy.variational_params_initialized.fill_(1)

    def forward(self, x: Tensor) -> gpytorch.distributions.MultivariateNormal:
        """Prior over the `E` outputs at `x: (..., n, D)`, batch `(E,)`."""
        return gpytorch.distributions.MultivariateNormal(self.mean_module(x), self.covar_module(x))

    def kl_divergence(self) -> Tensor:
        r"""Closed-form :math:`\mathrm{KL}(q(u) \Vert p(u))` of every output, `(E,)`.

        With whitened inducing values, :math:`p(u) = \mathcal N(0, I)` and
        :math:`q(u) = \mathcal N(m, L L^T)`, so the KL is
        :math:`\tfrac12 (\lVert L \rVert_F^2 + \lVert m \rVert^2 - K
        - \sum_k \log L_{kk}^2)`: products with `L` and logs of its diagonal, no solve
        with it. It therefore stays exact however ill-conditioned `L` becomes, whereas the
        single-sample estimate :math:`\log q(u) - \log p(u)` at :math:`u = m + L\epsilon`
        needs :math:`L^{-1}(u - m)`, whose round-off grows with the condition number of
        `L`. Unconstrained Adam steps on the entries of `L` readily drive that condition
        number past :math:`10^{16}`, where the estimate becomes arbitrarily negative.
        """
        kl: Tensor = self.variational_strategy.kl_divergence()
        return kl

    def moments(self, x: Tensor) -> tuple[Tensor, Tensor]:
        """Mean and variance of q(f) at `x: (B, D)`, each `(B, E)`.

        The variance is clamped at 0: round-off in the sparse posterior can make it slightly
        negative, and a negative variance would inflate the expected log-likelihood.
        """
        q = self(x.expand(self.n_outputs, *x.shape[-2:]))
        return q.mean.transpose(-1, -2), q.variance.clamp_min(0.0).transpose(-1, -2)


class VariationalMixtureOfGPExperts(GatedMixture[SVGPExpert]):
    r"""Mixture of `M` sparse GP experts with a softmax gate, fitted by `fit_svi`.

    Generative model, for sample `i`: :math:`m_i \sim \mathrm{Categorical}(\mathrm{softmax}
    (W f_{g,i} + b))`, :math:`e_i \sim \mathcal N(g_{m_i}(f_{e,i}), \mathrm{diag}\,
    \sigma^2_{m_i})` with :math:`g_j` an SVGP per expert and effect dimension. Inputs and
    effects are standardised; columns are chosen as in `MixtureOfGPExperts`.

    Args:
        n_experts: Number of experts `M`.
        n_inducing: Inducing points per expert (at most `N`).
        gate_l2: L2 penalty of the gate's weights (per sample, as in `SoftmaxGate`), or
            ``"cv"`` to choose it by cross-validation when the gate is initialised.
        **columns: The column selection of `GatedMixture`: ``groups``, ``gate_features``
            and ``expert_features``.
    """

    not_fitted_message = _NOT_FITTED

    def __init__(
        self,
        n_experts: int,
        *,
        n_inducing: int = 32,
        gate_l2: float | str = 1e-3,
        **columns: Any,
    ) -> None:
        super().__init__(n_experts, gate_l2=gate_l2, **columns)
        check_count("n_inducing", n_inducing)
        self.n_inducing = int(n_inducing)
        self.x_scaler: Standardizer | None = None
        self.y_scaler: Standardizer | None = None
        self.raw_noise = torch.nn.Parameter(torch.zeros(0, dtype=torch.float64))
        self.fitted = False

    # ----------------------------------------------------------------- setup
    def config(self) -> dict[str, Any]:
        """Constructor arguments as builtins; groups are resolved once `n_features` is known."""
        return {**super().config(), "n_inducing": self.n_inducing}

    @property
    def is_fitted(self) -> bool:
        """Whether `fit_svi` has completed on this model (or it was loaded fitted)."""
        return bool(self.fitted) and self.gate is not None and len(self.experts) > 0

    def build_empty(self, n_features: int, n_outputs: int, n_inducing: int) -> None:
        """Create gate, experts, noise and scalers of the given sizes, with placeholder values.

        Used by `probaff.models.load`, which then loads a saved state dict into them.

        Args:
            n_features: Columns `D` of the feature matrix.
            n_outputs: Effect dimensions `E`.
            n_inducing: Inducing points per expert `K` (at most the training-set size).
        """
        self.resolve_columns(n_features)
        self.n_outputs = int(n_outputs)
        d_e = len(self.expert_columns)
        self.x_scaler = Standardizer(d_e)
        self.y_scaler = Standardizer(self.n_outputs)
        self.gate = SoftmaxGate(len(self.gate_columns), self.n_experts, l2=self.gate_l2)
        inducing = torch.zeros(self.n_outputs, int(n_inducing), d_e, dtype=torch.float64)
        self.experts = ExpertList(
            SVGPExpert(inducing.clone()).double() for _ in range(self.n_experts)
        )
        self.raw_noise = torch.nn.Parameter(
            torch.zeros(self.n_experts, self.n_outputs, dtype=torch.float64)
        )

    @property
    def inducing_size(self) -> int:
        """Inducing points per expert of the built model `K` (0 before it is built)."""
        if len(self.experts) == 0:
            return 0
        return int(self.experts[0].variational_strategy.inducing_points.shape[-2])

    def build(
        self, x: Tensor, y: Tensor, resp: Tensor, exact: MixtureOfGPExperts | None = None
    ) -> None:
        """Create gate, experts and noise, initialised from responsibilities.

        The gate is fitted to `resp`; expert `j` places its inducing points on the
        samples it is most responsible for, its constant mean at their weighted effect
        mean, and its noise at a tenth of their weighted effect variance. With `exact`, a
        fitted exact mixture with the same experts and expert columns, every expert instead
        starts from exact expert `j`: its hyperparameters (converted to this model's
        standardisation), and q(u) centred on its predictive mean at the inducing points.

        Args:
            x: Features, `(N, D)`.
            y: Effects, `(N, E)`.
            resp: Initial responsibilities, `(N, M)`.
            exact: A fitted `MixtureOfGPExperts` to start the experts from.
        """
        n, d = x.shape
        e = y.shape[1]
        self.resolve_columns(d)
        self.n_outputs = int(e)
        self.x_scaler = Standardizer(len(self.expert_columns)).fit(x[:, self.expert_columns])
        self.y_scaler = Standardizer(e).fit(y)
        self.gate = SoftmaxGate(len(self.gate_columns), self.n_experts, l2=self.gate_l2)
        self.gate.fit(x[:, self.gate_columns], resp)
        z, t = self.x_scaler(x[:, self.expert_columns]), self.y_scaler(y)
        k = min(self.n_inducing, n)
        experts, noise = [], []
        for j in range(self.n_experts):
            r = resp[:, j]
            top = torch.argsort(r, descending=True, stable=True)[:k]
            expert = SVGPExpert(z[top].expand(e, k, z.shape[1]).clone()).double()
            w = r / r.sum().clamp_min(1e-12)
            mean = w @ t
            if exact is None:
                expert.mean_module.constant.data.copy_(mean)
                expert.initialize_variational(t[top].T - mean[:, None])
                noise.append((0.1 * (w @ (t - mean).square())).clamp_min(1e-4))
            else:
                noise.append(
                    self._start_from(expert, exact.experts[j], x[top][:, self.expert_columns])
                )
            experts.append(expert)
        self.experts = ExpertList(experts)
        self.raw_noise = torch.nn.Parameter(torch.stack(noise).log())

    def _start_from(self, expert: SVGPExpert, source: Any, x_top: Tensor) -> Tensor:
        """Copy an exact expert into `expert`; return its noise in standardised units `(E,)`."""
        x_scaler, y_scaler = self.scalers()
        x_ratio = source.x_scaler.std / x_scaler.std[None, :]  # (1, D) per input
        y_ratio = (source.y_scaler.std / y_scaler.std).square()  # (E,)
        kernel = expert.covar_module
        e, d = source.n_outputs, source.n_features
        with torch.no_grad():
            lengthscale = (source.lengthscales * x_ratio).clamp(1e-3 * 1.01, 1e4 * 0.99)
            kernel.base_kernel.lengthscale = lengthscale.reshape(e, 1, d)
            outputscale = source.gp.covar_module.outputscale.detach() * y_ratio
            kernel.outputscale = outputscale.clamp(1e-4 * 1.01, 1e4 * 0.99)
            constant = source.gp.mean_module.constant.detach()
            mean = constant * source.y_scaler.std + source.y_scaler.mean - y_scaler.mean
            mean = mean / y_scaler.std
            expert.mean_module.constant.data.copy_(mean)
            values = y_scaler(source.predict(x_top, include_noise=False).loc).T
            expert.initialize_variational(values - mean[:, None])
        return (source.noise / y_scaler.std.square()).clamp_min(1e-6)

    @property
    def noise(self) -> Tensor:
        """Observation noise variances (standardised units), `(M, E)`."""
        return self.raw_noise.exp() + 1e-6

    # -------------------------------------------------------- pyro programs
    def expected_log_lik(self, x_e: Tensor, y: Tensor) -> Tensor:
        r"""Expected log-likelihood of each sample under each expert.

        :math:`\ell_{ij} = \mathbb E_{q(f_j)} \log \mathcal N(e_i; f_j(x_i), \sigma_j^2)`,
        in closed form. Since :math:`\log \sum_j g_{ij} e^{a_j}` is convex in `a`,
        :math:`\log \sum_j g_{ij} e^{\ell_{ij}}` lower-bounds
        :math:`\mathbb E_{q(f)} \log \sum_j g_{ij}\, p(e_i \mid f_j)`, so the ELBO stays a
        bound without Monte Carlo noise from `f`.

        Args:
            x_e: Standardised expert inputs, `(B, D)`.
            y: Standardised effects, `(B, E)`.

        Returns:
            `(B, M)`.
        """
        out = []
        for j, expert in enumerate(self.experts):
            mean, var = expert.moments(x_e)
            noise = self.noise[j]
            ll = -0.5 * (torch.log(2 * math.pi * noise) + ((y - mean).square() + var) / noise)
            out.append(ll.sum(-1))
        return torch.stack(out, dim=-1)

    @config_enumerate
    def model(self, x_g: Tensor, x_e: Tensor, y: Tensor, idx: Tensor) -> None:
        """Pyro model on standardised data; `idx` are the minibatch rows, `(B,)`.

        Global factors: the gate's L2 penalty and every expert's closed-form KL. In the
        subsampled plate (scaled by `N / B`): each sample's expected log-likelihood under
        its expert `m`, which `TraceEnum_ELBO` enumerates.
        """
        pyro.module("mixture", self)
        gate = self.built_gate()
        n = x_g.shape[0]
        pyro.factor("gate.l2", -0.5 * gate.l2_ * n * gate.weight.square().sum())
        for j, expert in enumerate(self.experts):
            pyro.factor(f"expert{j}.kl", -expert.kl_divergence().sum())
        with pyro.plate("data", n, subsample=idx):
            ell = self.expected_log_lik(x_e[idx], y[idx])
            m = pyro.sample("m", dist.Categorical(logits=gate.logits(x_g[idx])))
            pyro.factor("e", Vindex(ell)[..., m])

    def guide(self, x_g: Tensor, x_e: Tensor, y: Tensor, idx: Tensor) -> None:
        """Pyro guide without sample sites.

        q(u) enters the ELBO through `SVGPExpert.kl_divergence` and q(f) through
        `expected_log_lik`, both in the model; the assignments are enumerated there.
        """

    # ------------------------------------------------------------ prediction
    def scalers(self) -> tuple[Standardizer, Standardizer]:
        """The standardisers of the expert inputs `(D_e,)` and of the effects `(E,)`.

        Raises:
            NotFittedError: Before the model was built by `fit_svi` (or `load`).
        """
        if self.x_scaler is None or self.y_scaler is None:
            raise NotFittedError(_NOT_FITTED)
        return self.x_scaler, self.y_scaler

    _scalers = scalers

    def expert_predictions(self, X: Any) -> Normal:
        """Every expert's predictive distribution (noise included), loc and scale `(N, M, E)`."""
        x = self.features(X)
        x_scaler, y_scaler = self.scalers()
        z = x_scaler(x[:, self.expert_columns])
        self.eval()
        locs, scales = [], []
        with torch.no_grad():
            for j, expert in enumerate(self.experts):
                post = expert(z.expand(expert.n_outputs, *z.shape))
                var = post.variance.T + self.noise[j]
                locs.append(post.mean.T * y_scaler.std + y_scaler.mean)
                scales.append(var.sqrt() * y_scaler.std)
        return Normal(torch.stack(locs, dim=1), torch.stack(scales, dim=1))
