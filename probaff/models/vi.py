r"""Stochastic variational inference for a mixture of sparse GP experts with Pyro.

The same generative model as `MixtureOfGPExperts`, trained by minibatch SVI instead of EM:
each expert is a gpytorch `ApproximateGP` (SVGP with learned inducing points and a
whitened Gaussian q(u)), and each sample's expert assignment is a discrete latent variable
that `TraceEnum_ELBO` sums out exactly. Both the expected log-likelihood and
:math:`\mathrm{KL}(q(u) \Vert p(u))` enter the ELBO in closed form, so the only
Monte Carlo noise is the minibatch.
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any

import gpytorch
import pyro
import pyro.distributions as dist
import torch
from gpytorch.means import ConstantMean
from gpytorch.variational import CholeskyVariationalDistribution, VariationalStrategy
from pyro.infer import SVI, TraceEnum_ELBO, config_enumerate
from pyro.ops.indexing import Vindex
from torch import Tensor
from torch.distributions import MixtureSameFamily, Normal

from probaff._checks import check_count, check_positive, check_probability
from probaff.errors import InputError, NotFittedError
from probaff.models._scaling import Standardizer
from probaff.models._tensors import as_matrix
from probaff.models.columns import (
    FeatureGroups,
    FeatureSpec,
    check_mixture_args,
    resolve_features,
)
from probaff.models.em import fit_em
from probaff.models.gate import SoftmaxGate
from probaff.models.initialization import check_initialization, initial_responsibilities
from probaff.models.kernels import ard_se_kernel
from probaff.models.mixture import (
    MixtureOfGPExperts,
    gated_probs,
    mixture_distribution,
    training_data,
)

__all__ = ["SVGPExpert", "SVIHistory", "VariationalMixtureOfGPExperts", "fit_svi"]

_NOT_FITTED = (
    "VariationalMixtureOfGPExperts is not fitted; call probaff.models.vi.fit_svi(model, X, Y) "
    "first."
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

    def forward(self, x: Tensor) -> gpytorch.distributions.MultivariateNormal:  # type: ignore[override]
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


@contextlib.contextmanager
def _default_dtype(dtype: torch.dtype) -> Iterator[None]:
    """Pyro creates some tensors with the default dtype; match the model's within a block."""
    previous = torch.get_default_dtype()
    torch.set_default_dtype(dtype)
    try:
        yield
    finally:
        torch.set_default_dtype(previous)


@dataclass
class SVIHistory:
    """Record of one SVI fit.

    Attributes:
        loss: Negative ELBO estimate (per training sample) of every step.
    """

    loss: list[float] = field(default_factory=list)


class VariationalMixtureOfGPExperts(torch.nn.Module):
    r"""Mixture of `M` sparse GP experts with a softmax gate, fitted by `fit_svi`.

    Generative model, for sample `i`: :math:`m_i \sim \mathrm{Categorical}(\mathrm{softmax}
    (W f_{g,i} + b))`, :math:`e_i \sim \mathcal N(g_{m_i}(f_{e,i}), \mathrm{diag}\,
    \sigma^2_{m_i})` with :math:`g_j` an SVGP per expert and effect dimension. Inputs and
    effects are standardised; columns are chosen as in `MixtureOfGPExperts`.

    Args:
        n_experts: Number of experts `M`.
        groups: Named column groups.
        gate_features: Gate columns: ``None`` (all), group name(s) or column indices.
        expert_features: Expert columns, shared by every expert.
        n_inducing: Inducing points per expert (at most `N`).
        gate_l2: L2 penalty of the gate's weights (per sample, as in `SoftmaxGate`), or
            ``"cv"`` to choose it by cross-validation when the gate is initialised.
    """

    def __init__(
        self,
        n_experts: int,
        *,
        groups: FeatureGroups | None = None,
        gate_features: FeatureSpec = None,
        expert_features: FeatureSpec = None,
        n_inducing: int = 32,
        gate_l2: float | str = 1e-3,
    ) -> None:
        super().__init__()
        self.n_experts = check_mixture_args(n_experts, groups, gate_features, expert_features,
                                            gate_l2)
        check_count("n_inducing", n_inducing)
        self.groups = dict(groups or {})
        self.gate_features = gate_features
        self.expert_features = expert_features
        self.n_inducing = int(n_inducing)
        self.gate_l2: float | str = gate_l2 if isinstance(gate_l2, str) else float(gate_l2)
        self.n_features: int | None = None
        self.gate_columns: list[int] = []
        self.expert_columns: list[int] = []
        self.gate: SoftmaxGate | None = None
        self.experts = torch.nn.ModuleList()
        self.x_scaler: Standardizer | None = None
        self.y_scaler: Standardizer | None = None
        self.raw_noise = torch.nn.Parameter(torch.zeros(0, dtype=torch.float64))
        self.fitted = False

    # ----------------------------------------------------------------- setup
    def build(self, x: Tensor, y: Tensor, resp: Tensor,
              exact: MixtureOfGPExperts | None = None) -> None:
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
        self.n_features = d
        self.gate_columns = resolve_features("gate_features", self.gate_features, self.groups, d)
        self.expert_columns = resolve_features(
            "expert_features", self.expert_features, self.groups, d
        )
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
                noise.append(self._start_from(expert, exact.experts[j],
                                              x[top][:, self.expert_columns]))
            experts.append(expert)
        self.experts = torch.nn.ModuleList(experts)
        self.raw_noise = torch.nn.Parameter(torch.stack(noise).log())

    def _start_from(self, expert: SVGPExpert, source: Any, x_top: Tensor) -> Tensor:
        """Copy an exact expert into `expert`; return its noise in standardised units `(E,)`."""
        x_scaler, y_scaler = self._scalers()
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
            mean = (constant * source.y_scaler.std + source.y_scaler.mean - y_scaler.mean)
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
            mean, var = expert.moments(x_e)  # type: ignore[operator]
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
        gate = self._built_gate()
        n = x_g.shape[0]
        pyro.factor("gate.l2", -0.5 * gate.l2_ * n * gate.weight.square().sum())
        for j, expert in enumerate(self.experts):
            pyro.factor(f"expert{j}.kl", -expert.kl_divergence().sum())  # type: ignore[operator]
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
    def _built_gate(self) -> SoftmaxGate:
        if self.gate is None:
            raise NotFittedError(_NOT_FITTED)
        return self.gate

    def _scalers(self) -> tuple[Standardizer, Standardizer]:
        if self.x_scaler is None or self.y_scaler is None:
            raise NotFittedError(_NOT_FITTED)
        return self.x_scaler, self.y_scaler

    def _features(self, X: Any) -> Tensor:
        if not self.fitted or self.n_features is None:
            raise NotFittedError(_NOT_FITTED)
        return as_matrix("features X", X, n_cols=self.n_features)

    def gate_probs(self, X: Any) -> Tensor:
        """Gate probabilities `p(m = j | f)`, `(N, M)`."""
        x = self._features(X)
        return self._built_gate().predict_proba(x[:, self.gate_columns])

    def expert_predictions(self, X: Any) -> Normal:
        """Every expert's predictive distribution (noise included), loc and scale `(N, M, E)`."""
        x = self._features(X)
        x_scaler, y_scaler = self._scalers()
        z = x_scaler(x[:, self.expert_columns])
        self.eval()
        locs, scales = [], []
        with torch.no_grad():
            for j, expert in enumerate(self.experts):
                post = expert(z.expand(expert.n_outputs, *z.shape))  # type: ignore[operator]
                var = post.variance.T + self.noise[j]
                locs.append(post.mean.T * y_scaler.std + y_scaler.mean)
                scales.append(var.sqrt() * y_scaler.std)
        return Normal(torch.stack(locs, dim=1), torch.stack(scales, dim=1))

    def predict(self, X: Any, *, gating: str = "soft") -> MixtureSameFamily:
        """Predictive mixture per sample: batch shape `(N,)`, event shape `(E,)`.

        Args:
            X: Features, `(N, D)`.
            gating: ``"soft"`` (gate-weighted mixture) or ``"hard"`` (most probable expert).
        """
        return mixture_distribution(gated_probs(self.gate_probs(X), gating),
                                    self.expert_predictions(X))


def _start(model: VariationalMixtureOfGPExperts, x: Tensor, y: Tensor,
           init: str | Tensor | MixtureOfGPExperts, *,
           n_init: int, seed: int, init_rows: int
           ) -> tuple[Tensor, MixtureOfGPExperts | None]:
    """Starting responsibilities `(N, M)` of `fit_svi`, and the exact mixture behind them."""
    m = model.n_experts
    if isinstance(init, MixtureOfGPExperts):
        if init.n_experts != m or not init.is_fitted:
            raise InputError(
                f"init must be a fitted MixtureOfGPExperts with {m} experts; fit it with "
                "probaff.models.fit_em first."
            )
        return torch.softmax(init.log_joint(x, y), dim=1), init
    if isinstance(init, Tensor):
        resp = as_matrix("init responsibilities", init, n_rows=x.shape[0], n_cols=m)
        check_probability("init responsibilities", resp)
        return resp / resp.sum(1, keepdim=True).clamp_min(1e-300), None
    check_initialization(init)
    gate_cols = resolve_features("gate_features", model.gate_features, model.groups, x.shape[1])
    if init in ("effects", "joint"):
        return initial_responsibilities(init, x[:, gate_cols], y, m, n_init=n_init,
                                        seed=seed), None
    rows = torch.randperm(x.shape[0], generator=torch.Generator().manual_seed(seed))[:init_rows]
    exact = MixtureOfGPExperts(m, groups=model.groups, gate_features=model.gate_features,
                               expert_features=model.expert_features, lengthscale_prior=True)
    fit_em(exact, x[rows], y[rows], init=init, n_init=n_init, seed=seed)
    return torch.softmax(exact.log_joint(x, y), dim=1), exact


def fit_svi(
    model: VariationalMixtureOfGPExperts,
    X: Any,
    Y: Any,
    *,
    n_steps: int = 1500,
    batch_size: int = 64,
    lr: float = 0.02,
    n_init: int = 5,
    seed: int = 0,
    init: str | Tensor | MixtureOfGPExperts = "auto",
    init_rows: int = 400,
) -> SVIHistory:
    """Fit a variational mixture of GP experts by minibatch SVI.

    The model is initialised from responsibilities (`init`), then trained with
    `pyro.infer.SVI` on `TraceEnum_ELBO`, which sums out every sample's expert assignment;
    Adam with step size `lr`. Parameters live in a private Pyro parameter-store scope, and
    the global random state is left untouched.

    Initialisations are those of `probaff.models.fit_em`: ``"effects"`` and ``"joint"``
    take the responsibilities of that Gaussian mixture; ``"grow"`` and ``"auto"`` fit an
    exact mixture by EM with that `init` on at most `init_rows` rows (a seeded random
    subset) and start from its responsibilities on every row and from its experts (their
    hyperparameters, and q(u) on their predictive means); a fitted `MixtureOfGPExperts`
    with the same experts and expert columns is such a start already made; a tensor
    `(N, M)` gives the responsibilities directly.

    Args:
        model: The mixture to fit (rebuilt for the data).
        X: Features, `(N, D)`.
        Y: Effects, `(N, E)`.
        n_steps: SVI steps.
        batch_size: Minibatch size (capped at `N`).
        lr: Adam step size.
        n_init: Restarts of the initial Gaussian mixture.
        seed: Seed of the initialisation and the minibatches.
        init: ``"auto"`` (default), ``"grow"``, ``"effects"``, ``"joint"``, a fitted
            `MixtureOfGPExperts`, or responsibilities `(N, M)`.
        init_rows: Rows of the exact EM fit behind ``"grow"`` and ``"auto"``.

    Returns:
        The per-step losses.

    Raises:
        InputError: For NaN/inf, empty or mismatched inputs, more experts than samples, an
            unknown `init`, or a non-integer count.
    """
    check_count("n_steps", n_steps)
    check_count("batch_size", batch_size)
    check_positive("lr", lr)
    n_init = check_count("n_init", n_init)
    init_rows = check_count("init_rows", init_rows)
    x, y = training_data(X, Y, model.n_experts)
    resp, exact = _start(model, x, y, init, n_init=n_init, seed=seed, init_rows=init_rows)
    model.fitted = False
    model.build(x, y, resp, exact)
    x_scaler, y_scaler = model._scalers()
    x_g = x[:, model.gate_columns]
    x_e = x_scaler(x[:, model.expert_columns])
    t = y_scaler(y)
    n = x.shape[0]
    b = min(int(batch_size), n)
    history = SVIHistory()
    generator = torch.Generator().manual_seed(seed)
    model.train()
    with torch.random.fork_rng(), pyro.get_param_store().scope(), _default_dtype(torch.float64):
        torch.manual_seed(seed)
        svi = SVI(
            model.model,
            model.guide,
            pyro.optim.Adam({"lr": float(lr)}),
            loss=TraceEnum_ELBO(max_plate_nesting=1),
        )
        for _ in range(int(n_steps)):
            idx = torch.randperm(n, generator=generator)[:b]
            history.loss.append(svi.step(x_g, x_e, t, idx) / n)
    model.eval()
    model.fitted = True
    return history
