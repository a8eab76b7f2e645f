r"""Stochastic variational inference for a mixture of sparse GP experts with Pyro.

The same generative model as `MixtureOfGPExperts`, trained by minibatch SVI instead of EM:
each expert is a gpytorch `ApproximateGP` (SVGP with inducing points and a whitened
Gaussian q(u)), and each sample's expert assignment is a discrete latent variable that
`TraceEnum_ELBO` sums out exactly. Both the expected log-likelihood and
:math:`\mathrm{KL}(q(u) \Vert p(u))` enter the ELBO in closed form, so the only
Monte Carlo noise is the minibatch. Since the likelihood is Gaussian, q(u) has a closed-form
optimum given the assignments; it is set there at the start and moved towards it by
natural-gradient steps (`SVGPExpert.natural_step`) rather than by Adam steps on its mean and
Cholesky factor, which drift away from that optimum under minibatch noise.
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
from probaff.models.experts.gp_expert import GPExpert
from probaff.models.experts.kernels import ard_se_kernel
from probaff.models.gates.gate import SoftmaxGate
from probaff.models.gates.gated import ExpertList, GatedMixture
from probaff.models.mixture.model import MixtureOfGPExperts

__all__ = ["SVGPExpert", "VariationalMixtureOfGPExperts", "WhitenedQ", "expected_log_density"]

# Smallest noise variance of every expert (standardised units).
_NOISE_FLOOR = 1e-6
# Rows per block when q(u)'s statistics are summed over many samples.
_CHUNK = 4096
# Most candidate samples of the greedy choice of inducing inputs.
_CANDIDATES = 8192

_NOT_FITTED = (
    "VariationalMixtureOfGPExperts is not fitted; call probaff.models.fit_svi(model, X, Y) first."
)


def expected_log_density(y: Tensor, mean: Tensor, var: Tensor, noise: Tensor) -> Tensor:
    r""":math:`\sum_e \mathbb E_{f \sim \mathcal N(\mu, v)} \log \mathcal N(y_e; f_e, \sigma_e^2)`.

    Args:
        y: Effects, `(B, E)`.
        mean: Mean :math:`\mu` of q(f), `(B, E)`.
        var: Variance `v` of q(f), `(B, E)`.
        noise: Noise variances :math:`\sigma^2`, `(E,)`.

    Returns:
        `(B,)`.
    """
    ll = -0.5 * (torch.log(2 * math.pi * noise) + ((y - mean).square() + var) / noise)
    return ll.sum(-1)


class WhitenedQ:
    r"""One expert's whitened q(u) = N(m, S) in natural parameters, with what a step reads.

    Args:
        precision: :math:`\Lambda = S^{-1}`, `(E, K, K)`.
        shift: :math:`\eta = \Lambda m`, `(E, K)`.

    Attributes:
        precision: :math:`\Lambda`, `(E, K, K)`.
        shift: :math:`\eta`, `(E, K)`.
        mean: `m`, `(E, K)`.
        root: :math:`R = L_\Lambda^{-1}`, lower triangular with :math:`S = R^T R`, `(E, K, K)`.
        kl: :math:`\mathrm{KL}(q(u) \Vert \mathcal N(0, I))` summed over the outputs (nats).
    """

    def __init__(self, precision: Tensor, shift: Tensor) -> None:
        self.precision, self.shift = precision, shift
        chol = torch.linalg.cholesky(0.5 * (precision + precision.mT))
        eye = torch.eye(chol.shape[-1], dtype=chol.dtype, device=chol.device)
        self.root = torch.linalg.solve_triangular(chol, eye, upper=False)
        self.mean = torch.cholesky_solve(shift[..., None], chol)[..., 0]
        log_det_precision = 2.0 * chol.diagonal(dim1=-2, dim2=-1).log().sum()
        trace = self.root.square().sum()
        size = chol.shape[-1] * chol.shape[0]
        self.kl = 0.5 * float(trace + self.mean.square().sum() - size + log_det_precision)

    @classmethod
    def of(cls, expert: SVGPExpert) -> WhitenedQ:
        """The natural parameters of `expert`'s current q(u)."""
        variational = expert.variational_strategy._variational_distribution
        with torch.no_grad():
            precision = torch.cholesky_inverse(variational.chol_variational_covar.tril())
            shift = (precision @ variational.variational_mean[..., None])[..., 0]
        return cls(precision, shift)

    def store(self, expert: SVGPExpert) -> None:
        """Write this q(u) into `expert`'s variational distribution (mean and factor)."""
        variational = expert.variational_strategy._variational_distribution
        with torch.no_grad():
            variational.variational_mean.copy_(self.mean)
            covar = self.root.mT @ self.root
            variational.chol_variational_covar.copy_(torch.linalg.cholesky(covar))
            expert.variational_strategy.variational_params_initialized.fill_(1)

    def moved(self, precision: Tensor, shift: Tensor, step: float) -> WhitenedQ:
        r"""This q(u) moved a natural-gradient step towards target natural parameters.

        :math:`\theta \leftarrow (1 - \gamma)\theta + \gamma \theta^\star`, as in
        `SVGPExpert.natural_step`; `step` is :math:`\gamma` in `(0, 1]`.
        """
        if step >= 1.0:
            return WhitenedQ(precision, shift)
        return WhitenedQ(
            (1.0 - step) * self.precision + step * precision,
            (1.0 - step) * self.shift + step * shift,
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

    def place_inducing(self, x: Tensor, weights: Tensor) -> None:
        r"""Choose the inducing inputs among `x` by weighted greedy pivoted Cholesky.

        For each output, every step takes the sample with the largest
        :math:`w_i\,(k(x_i, x_i) - Q_{ii})`: its weight times its prior variance left
        unexplained by the points already chosen (:math:`Q = K_{xu} K_{uu}^{-1} K_{ux}`),
        under the expert's current kernel. The points chosen thus cover the samples the
        expert is responsible for, not only the most responsible ones, and never repeat
        while a sample with positive weight and residual variance remains. Above 8,192
        samples, the candidates are the 8,192 with the largest weights.

        Args:
            x: Standardised expert inputs, `(N, D)`, with `N` at least the inducing size `K`.
            weights: Non-negative sample weights, `(N,)`.
        """
        strategy = self.variational_strategy
        if x.shape[0] > _CANDIDATES:  # the greedy factor is (E, K, N): cap N
            top = torch.argsort(weights, descending=True, stable=True)[:_CANDIDATES]
            x, weights = x[top], weights[top]
        k, n = strategy.inducing_points.shape[-2], x.shape[0]
        rows = torch.arange(self.n_outputs, device=x.device)
        with torch.no_grad():
            xs = x.expand(self.n_outputs, n, x.shape[1])
            resid = self.covar_module(xs, diag=True).clone()  # (E, N)
            factor = torch.zeros(self.n_outputs, k, n, dtype=x.dtype, device=x.device)
            chosen = torch.zeros(self.n_outputs, k, dtype=torch.long, device=x.device)
            score_w = weights.clamp_min(0.0) + 1e-12
            for t in range(k):
                idx = (score_w * resid.clamp_min(0.0)).argmax(-1)  # (E,)
                chosen[:, t] = idx
                col = self.covar_module(x[idx][:, None, :], xs).to_dense()[:, 0, :]
                col = col - (factor[:, :t, :] * factor[rows, :t, idx][..., None]).sum(-2)
                pivot = resid[rows, idx].clamp_min(1e-12).sqrt()
                factor[:, t, :] = col / pivot[:, None]
                resid = resid - factor[:, t, :].square()
                resid[rows, idx] = 0.0
            strategy.inducing_points.copy_(x[chosen])

    def inducing_factor(self) -> Tensor:
        """Lower Cholesky factor `L` of :math:`K_{uu}` plus the strategy's jitter, `(E, K, K)`."""
        strategy = self.variational_strategy
        with torch.no_grad():
            z = strategy.inducing_points
            eye = torch.eye(z.shape[-2], dtype=z.dtype, device=z.device)
            k_uu = self.covar_module(z).to_dense() + float(strategy.jitter_val) * eye
            return torch.linalg.cholesky(k_uu)

    def projection(self, x: Tensor, chol: Tensor) -> Tensor:
        r"""The whitened projection :math:`A = L^{-1} K_{uf}` of inputs `x: (B, D)`, `(E, K, B)`.

        Args:
            x: Standardised expert inputs, `(B, D)`.
            chol: `inducing_factor()`.
        """
        z = self.variational_strategy.inducing_points
        with torch.no_grad():
            k_uf = self.covar_module(z, x.expand(self.n_outputs, *x.shape)).to_dense()
            return torch.linalg.solve_triangular(chol, k_uf, upper=False)

    def natural_target(
        self, x: Tensor, y: Tensor, weights: Tensor, noise: Tensor, scale: float = 1.0
    ) -> tuple[Tensor, Tensor]:
        r"""Natural parameters of the optimal whitened q(u) given weighted samples.

        The expected log-likelihood of samples with per-sample noise
        :math:`\sigma^2 / w_i` is quadratic in the whitened inducing values `v`
        (:math:`u = L v`, :math:`L L^T = K_{uu}`), so for fixed hyperparameters the best
        Gaussian q(v) has precision :math:`\Lambda = I + s\,\sigma^{-2} A W A^T` and
        precision-times-mean :math:`\eta = s\,\sigma^{-2} A W (y - \mu)`, with
        :math:`A = L^{-1} K_{uf}` and `s` the minibatch's scale `N / B` (Titsias, 2009;
        Hensman et al., 2013). Its predictive mean is the sparse (DTC) posterior mean of
        the weighted GP, which equals the exact one when the inducing inputs are the
        training inputs.

        Args:
            x: Standardised expert inputs, `(B, D)`.
            y: Standardised effects, `(B, E)`.
            weights: Non-negative sample weights, `(B,)`.
            noise: Noise variances (standardised units), `(E,)`.
            scale: Factor `s` on the samples' statistics.

        Returns:
            :math:`\Lambda`, `(E, K, K)`, and :math:`\eta`, `(E, K)`.
        """
        chol = self.inducing_factor()
        parts = [
            self.projected_target(self.projection(x[rows], chol), y[rows], weights[rows], noise)
            for rows in torch.arange(x.shape[0], device=x.device).split(_CHUNK)
        ]
        precision = torch.eye(chol.shape[-1], dtype=chol.dtype, device=chol.device)
        precision = precision + scale * sum(part[0] for part in parts)
        return precision, scale * sum(part[1] for part in parts)  # type: ignore[return-value]

    def projected_target(
        self, a: Tensor, y: Tensor, weights: Tensor, noise: Tensor
    ) -> tuple[Tensor, Tensor]:
        r"""The samples' parts of `natural_target`, from their projection `a: (E, K, B)`.

        They are :math:`\sigma^{-2} A W A^T`, `(E, K, K)`, and
        :math:`\sigma^{-2} A W (y - \mu)`, `(E, K)`.

        Args:
            a: `projection` of the samples' inputs, `(E, K, B)`.
            y: Standardised effects, `(B, E)`.
            weights: Non-negative sample weights, `(B,)`.
            noise: Noise variances (standardised units), `(E,)`.
        """
        with torch.no_grad():
            beta = weights.clamp_min(0.0)[None, :] / noise[:, None]  # (E, B)
            resid = y.T - self.mean_module.constant[:, None]  # (E, B)
            return (a * beta[:, None, :]) @ a.mT, (a @ (beta * resid)[..., None])[..., 0]

    def projected_moments(
        self, x: Tensor, a: Tensor, q: tuple[Tensor, Tensor] | None = None
    ) -> tuple[Tensor, Tensor]:
        r"""`moments` from the inputs' `projection` `a: (E, K, B)`: mean and variance `(B, E)`.

        The same numbers as gpytorch's whitened `VariationalStrategy` gives
        (:math:`\mu + A^T m` and :math:`k(x, x) + \text{jitter} + a^T (S - I) a`), without
        recomputing :math:`K_{uu}` and its factor for every batch.

        Args:
            x: Standardised expert inputs, `(B, D)`.
            a: Their `projection`, `(E, K, B)`.
            q: The whitened q(u) as its mean `m` `(E, K)` and a root `R` `(E, K, K)` of its
                covariance, :math:`S = R^T R`; None for the expert's own q(u).
        """
        strategy = self.variational_strategy
        variational = strategy._variational_distribution
        with torch.no_grad():
            if q is None:
                q = (variational.variational_mean, variational.chol_variational_covar.tril().mT)
            mean_u, root = q
            prior = self.covar_module(x.expand(self.n_outputs, *x.shape), diag=True)  # (E, B)
            mean = self.mean_module.constant[:, None] + (mean_u[:, None, :] @ a)[:, 0, :]
            var = prior + float(strategy.jitter_val) + (root @ a).square().sum(-2)
            var = var - a.square().sum(-2)
            return mean.T, var.clamp_min(0.0).T

    def natural_step(self, precision: Tensor, shift: Tensor, step: float) -> None:
        r"""Move q(u) a natural-gradient step of size `step` towards a target.

        In natural parameters, :math:`\theta \leftarrow (1 - \gamma)\,\theta + \gamma\,
        \theta^\star`, the natural-gradient step of the ELBO in q(u) for a conjugate
        likelihood (Hensman et al., 2013); :math:`\gamma = 1` jumps to the target. The
        result (`WhitenedQ`) is stored as mean and Cholesky factor, so it is always a valid
        Gaussian.

        Args:
            precision: Target precision :math:`\Lambda^\star`, `(E, K, K)`.
            shift: Target precision-times-mean :math:`\eta^\star`, `(E, K)`.
            step: :math:`\gamma` in `(0, 1]`.
        """
        with torch.no_grad():
            if step < 1.0:
                q = WhitenedQ.of(self).moved(precision, shift, step)
            else:
                q = WhitenedQ(precision, shift)
        q.store(self)

    def set_optimal_variational(self, x: Tensor, y: Tensor, weights: Tensor, noise: Tensor) -> None:
        r"""Set q(u) to the optimum of the collapsed bound for the current hyperparameters.

        With per-sample noise :math:`\sigma^2 / w_i` (as in the weighted exact expert),
        Titsias (2009) gives :math:`q(u) = \mathcal N(\sigma^{-2} K_{uu} \Sigma K_{uf} W
        (y - \mu), K_{uu} \Sigma K_{uu})` with :math:`\Sigma = (K_{uu} + \sigma^{-2}
        K_{uf} W K_{fu})^{-1}`; whitened, see `natural_target`.

        Args:
            x: Standardised expert inputs, `(N, D)`.
            y: Standardised effects, `(N, E)`.
            weights: Non-negative sample weights, `(N,)`.
            noise: Noise variances (standardised units), `(E,)`.
        """
        self.natural_step(*self.natural_target(x, y, weights, noise), 1.0)

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
        n_inducing: Inducing points per expert (capped at `N` by the fit). An expert's
            sparse posterior matches the exact one only when its inducing points can cover
            the samples it is responsible for: on chapter 5's pushes (214 training rows,
            21 expert features) 32 points cost 0.36 nats per point at M = 3 against the
            exact experts, 96 points 0.03.
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
        n_inducing: int = 128,
        gate_l2: float | str = 1e-3,
        **columns: Any,
    ) -> None:
        super().__init__(n_experts, gate_l2=gate_l2, **columns)
        check_count("n_inducing", n_inducing)
        self.n_inducing = int(n_inducing)
        self.x_scaler: Standardizer | None = None
        self.y_scaler: Standardizer | None = None
        self.raw_noise = torch.nn.Parameter(torch.zeros(0, dtype=torch.float64))
        self.gate_penalty: float | None = None
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
        r"""Create gate, experts and noise, initialised from responsibilities.

        Every expert's hyperparameters start either from exact expert `j` of `exact` (a
        fitted mixture with the same experts and expert columns; converted to this model's
        standardisation, noise included) or, without it, from defaults: length scales
        :math:`\sqrt D`, unit amplitude, the constant mean at the weighted effect mean and
        the noise at a tenth of the weighted effect variance. Its inducing inputs are chosen
        among the samples by `SVGPExpert.place_inducing` with weights `resp[:, j]`, and q(u)
        is set to the optimum of the collapsed bound given those weights and
        hyperparameters (`SVGPExpert.set_optimal_variational`), so at the start each
        expert predicts as the sparse posterior of a GP with these hyperparameters
        trained on the weighted samples. The gate is a copy of `exact`'s when that is a
        linear gate on the same columns, else fitted to `resp`.

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
        self.gate_penalty = None
        if exact is None or not self._copy_gate(exact):
            self.gate.fit(x[:, self.gate_columns], resp)
        z, t = self.x_scaler(x[:, self.expert_columns]), self.y_scaler(y)
        k = min(self.n_inducing, n)
        experts, noise = [], []
        for j in range(self.n_experts):
            r = resp[:, j]
            expert = SVGPExpert(z[:k].expand(e, k, z.shape[1]).clone()).double()
            if exact is None:
                w = r / r.sum().clamp_min(1e-12)
                mean = w @ t
                expert.mean_module.constant.data.copy_(mean)
                noise.append((0.1 * (w @ (t - mean).square())).clamp_min(1e-4))
            else:
                noise.append(self._start_from(expert, exact.experts[j]))
            expert.place_inducing(z, r)
            expert.set_optimal_variational(z, t, r, noise[-1])
            experts.append(expert)
        self.experts = ExpertList(experts)
        self.raw_noise = torch.nn.Parameter((torch.stack(noise) - _NOISE_FLOOR).log())

    def _copy_gate(self, source: MixtureOfGPExperts) -> bool:
        """Copy `source`'s gate into this model's if it is a linear gate on the same columns."""
        gate, own = source.built_gate(), self.built_gate()
        if type(gate) is not SoftmaxGate or list(source.gate_columns) != self.gate_columns:
            return False
        with torch.no_grad():
            own.scaler.load_state_dict(gate.scaler.state_dict())
            own.weight.copy_(gate.weight)
            own.bias.copy_(gate.bias)
            own.fitted.fill_(True)
        self.gate_penalty = gate.l2_
        return True

    def _start_from(self, expert: SVGPExpert, source: Any) -> Tensor:
        """Copy an EM expert's hyperparameters; return its noise in standardised units `(E,)`.

        `source` is a `GPExpert` or a `SparseGPExpert`.
        """
        exact = isinstance(source, GPExpert)
        source_kernel = source.gp.covar_module if exact else source.covar_module
        source_constant = source.gp.mean_module.constant if exact else source.constant
        x_scaler, y_scaler = self.scalers()
        x_ratio = source.x_scaler.std / x_scaler.std[None, :]  # (1, D) per input
        y_ratio = (source.y_scaler.std / y_scaler.std).square()  # (E,)
        kernel = expert.covar_module
        e, d = source.n_outputs, source.n_features
        with torch.no_grad():
            lengthscale = (source.lengthscales * x_ratio).clamp(1e-3 * 1.01, 1e4 * 0.99)
            kernel.base_kernel.lengthscale = lengthscale.reshape(e, 1, d)
            outputscale = source_kernel.outputscale.detach() * y_ratio
            kernel.outputscale = outputscale.clamp(1e-4 * 1.01, 1e4 * 0.99)
            constant = source_constant.detach()
            mean = constant * source.y_scaler.std + source.y_scaler.mean - y_scaler.mean
            mean = mean / y_scaler.std
            expert.mean_module.constant.data.copy_(mean)
        return (source.noise / y_scaler.std.square()).clamp_min(2 * _NOISE_FLOOR)

    @property
    def noise(self) -> Tensor:
        """Observation noise variances (standardised units), `(M, E)`."""
        return self.raw_noise.exp() + _NOISE_FLOOR

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
        noise = self.noise
        out = [
            expected_log_density(y, *expert.moments(x_e), noise[j])
            for j, expert in enumerate(self.experts)
        ]
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
        penalty = gate.l2_ if self.gate_penalty is None else self.gate_penalty
        pyro.factor("gate.l2", -0.5 * penalty * n * gate.weight.square().sum())
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

    def responsibilities(self, x_g: Tensor, x_e: Tensor, y: Tensor) -> Tensor:
        r"""The assignment posterior that the ELBO's enumeration uses, `(B, M)`.

        :math:`q(m_i = j) \propto g_j(x_i) \exp \ell_{ij}` with :math:`\ell_{ij}` the
        expected log-likelihood (`expected_log_lik`); the ELBO's gradient in
        :math:`\ell_{ij}` is exactly this weight.

        Args:
            x_g: Gate features (raw), `(B, D_g)`.
            x_e: Standardised expert inputs, `(B, D_e)`.
            y: Standardised effects, `(B, E)`.
        """
        with torch.no_grad():
            logits = self.built_gate().logits(x_g)
            return torch.softmax(logits.log_softmax(-1) + self.expected_log_lik(x_e, y), -1)

    def update_variational(
        self, x_g: Tensor, x_e: Tensor, y: Tensor, *, scale: float = 1.0, step: float = 1.0
    ) -> None:
        """Natural-gradient step of every expert's q(u) on a (mini)batch.

        The assignments are held at their posterior (`responsibilities`) and every q(u)
        moves a step `step` towards its optimum given them (`SVGPExpert.natural_step`);
        with the full training set, ``scale=1`` and ``step=1`` this is the exact
        coordinate-ascent update of q(u), which never lowers the ELBO.

        Args:
            x_g: Gate features (raw), `(B, D_g)`.
            x_e: Standardised expert inputs, `(B, D_e)`.
            y: Standardised effects, `(B, E)`.
            scale: `N / B` for a minibatch of `B` of `N` samples.
            step: Step size in `(0, 1]`.
        """
        resp = torch.cat(
            [
                self.responsibilities(x_g[rows], x_e[rows], y[rows])
                for rows in torch.arange(x_e.shape[0], device=x_e.device).split(_CHUNK)
            ]
        )
        noise = self.noise.detach()
        for j, expert in enumerate(self.experts):
            target = expert.natural_target(x_e, y, resp[:, j], noise[j], scale)
            expert.natural_step(*target, step)

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
