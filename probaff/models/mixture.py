"""Mixture of GP experts with a softmax gate, each on its own subset of feature columns."""

from __future__ import annotations

from typing import Any

import torch
from torch import Tensor
from torch.distributions import Categorical, Independent, MixtureSameFamily, Normal

from probaff._checks import check_positive
from probaff.errors import InputError, NotFittedError
from probaff.models._tensors import as_matrix
from probaff.models.columns import (
    FeatureGroups,
    FeatureSpec,
    check_mixture_args,
    resolve_features,
    resolve_groups,
)
from probaff.models.gate import SoftmaxGate
from probaff.models.gp_expert import GPExpert

__all__ = ["MixtureOfGPExperts", "mixture_distribution", "training_data"]

_NOT_FITTED = "MixtureOfGPExperts is not fitted; call probaff.models.fit_em(model, X, Y) first."


def _plain(spec: FeatureSpec) -> str | list[str] | list[int] | None:
    """A copy of a feature selection made only of builtins (for saving)."""
    if spec is None or isinstance(spec, str):
        return spec
    return [s if isinstance(s, str) else int(s) for s in spec]  # type: ignore[misc]


def training_data(X: Any, Y: Any, n_experts: int) -> tuple[Tensor, Tensor]:
    """Validate the training set of a mixture of `n_experts` experts.

    Args:
        X: Features, `(N, D)`.
        Y: Effects, `(N, E)`.
        n_experts: Number of experts `M`.

    Returns:
        `X` and `Y` as float64 tensors.

    Raises:
        InputError: For NaN/inf, empty or mismatched inputs, or more experts than samples.
    """
    x = as_matrix("features X", X)
    y = as_matrix("effects Y", Y)
    if y.shape[0] != x.shape[0]:
        raise InputError(
            f"features X has {x.shape[0]} samples but effects Y has {y.shape[0]}; "
            "they must have one row per push."
        )
    if n_experts > x.shape[0]:
        raise InputError(
            f"n_experts={n_experts} exceeds the {x.shape[0]} training samples; "
            "use fewer experts or more data."
        )
    return x, y


def mixture_distribution(probs: Tensor, components: Normal) -> MixtureSameFamily:
    """Per-sample mixture of independent normals.

    Args:
        probs: Mixture weights, rows summing to 1, `(N, M)`.
        components: Normals with loc and scale `(N, M, E)`.

    Returns:
        Batch shape `(N,)`, event shape `(E,)`.
    """
    return MixtureSameFamily(Categorical(probs=probs), Independent(components, 1))


class MixtureOfGPExperts(torch.nn.Module):
    r"""Mixture of `M` GP experts: :math:`p(e \mid f) = \sum_j g_j(f_g)\, p_j(e \mid f_e)`.

    The gate :math:`g` is a `SoftmaxGate` on the gate columns `f_g`; each expert :math:`p_j`
    is a `GPExpert` (E independent SE-ARD GPs) on the expert columns `f_e`. Columns are
    chosen by index or by the names of column groups, e.g.
    ``MixtureOfGPExperts(3, groups={"f_x": slice(0, 3), "f_o": slice(3, 40),
    "f_c": slice(40, 101)}, gate_features=("f_x",), expert_features=("f_o", "f_c"))``.
    The model is fitted with `probaff.models.em.fit_em`.

    Args:
        n_experts: Number of experts `M`.
        groups: Named column groups (slices or index lists of the feature matrix).
        gate_features: Gate columns: ``None`` (all), group name(s) or column indices.
        expert_features: Expert columns, shared by every expert, in the same forms.
        gate_l2: L2 penalty of the gate's weights.
        gp_max_iter: L-BFGS iterations per expert fit.
        lengthscale_prior: Give the experts' length scales the dimension-scaled log-normal
            prior (see `GPExpert`).

    Raises:
        InputError: If a selection names an unknown group or `n_experts` is not positive.
    """

    def __init__(
        self,
        n_experts: int,
        *,
        groups: FeatureGroups | None = None,
        gate_features: FeatureSpec = None,
        expert_features: FeatureSpec = None,
        gate_l2: float = 1e-3,
        gp_max_iter: int = 50,
        lengthscale_prior: bool = False,
    ) -> None:
        super().__init__()
        self.n_experts = check_mixture_args(n_experts, groups, gate_features, expert_features,
                                            gate_l2)
        check_positive("gp_max_iter", gp_max_iter)
        self.groups = dict(groups or {})
        self.gate_features = gate_features
        self.expert_features = expert_features
        self.gate_l2 = float(gate_l2)
        self.gp_max_iter = int(gp_max_iter)
        self.lengthscale_prior = bool(lengthscale_prior)
        self.n_features: int | None = None
        self.n_outputs: int | None = None
        self.gate_columns: list[int] = []
        self.expert_columns: list[int] = []
        self.gate: SoftmaxGate | None = None
        self.experts = torch.nn.ModuleList()
        self.train_X: Tensor | None = None
        self.train_Y: Tensor | None = None
        self.train_weights: Tensor | None = None

    # ----------------------------------------------------------------- config
    def config(self) -> dict[str, Any]:
        """Constructor arguments as builtins; groups are resolved once `n_features` is known."""
        groups: dict[str, Any] = (
            resolve_groups(self.groups, self.n_features)
            if self.n_features is not None
            else {k: v if isinstance(v, slice) else list(v) for k, v in self.groups.items()}
        )
        return {
            "n_experts": self.n_experts,
            "groups": groups,
            "gate_features": _plain(self.gate_features),
            "expert_features": _plain(self.expert_features),
            "gate_l2": self.gate_l2,
            "gp_max_iter": self.gp_max_iter,
            "lengthscale_prior": self.lengthscale_prior,
        }

    @property
    def is_fitted(self) -> bool:
        """Whether the experts hold training data and the gate has been fitted."""
        return (
            self.gate is not None
            and bool(self.gate.fitted)
            and all(e.is_fitted for e in self.experts)  # type: ignore[attr-defined]
        )

    def _built_gate(self) -> SoftmaxGate:
        if self.gate is None:
            raise NotFittedError(_NOT_FITTED)
        return self.gate

    def check_fitted(self) -> None:
        """Raise `NotFittedError` unless the mixture has been fitted."""
        if not self.is_fitted:
            raise NotFittedError(_NOT_FITTED)

    def build(self, n_features: int, n_outputs: int) -> None:
        """Resolve the feature selections and create a fresh gate and fresh experts.

        Called by `fit_em` (so every fit starts from the same initial state) and `load`.

        Args:
            n_features: Columns `D` of the feature matrix.
            n_outputs: Effect dimensions `E`.
        """
        self.gate_columns = resolve_features(
            "gate_features", self.gate_features, self.groups, n_features
        )
        self.expert_columns = resolve_features(
            "expert_features", self.expert_features, self.groups, n_features
        )
        self.n_features, self.n_outputs = int(n_features), int(n_outputs)
        self.gate = SoftmaxGate(len(self.gate_columns), self.n_experts, l2=self.gate_l2)
        self.experts = torch.nn.ModuleList(
            GPExpert(
                len(self.expert_columns),
                n_outputs,
                max_iter=self.gp_max_iter,
                lengthscale_prior=self.lengthscale_prior,
            )
            for _ in range(self.n_experts)
        )

    # ---------------------------------------------------------------- inputs
    def _features(self, X: Any) -> Tensor:
        if self.n_features is None:
            raise NotFittedError(_NOT_FITTED)
        return as_matrix("features X", X, n_cols=self.n_features)

    def check_data(self, X: Any, Y: Any) -> tuple[Tensor, Tensor]:
        """Validate a training set and (re)build the model for its sizes.

        Args:
            X: Features, `(N, D)`.
            Y: Effects, `(N, E)`.

        Returns:
            `X` and `Y` as float64 tensors.

        Raises:
            InputError: For NaN/inf, empty or mismatched inputs, or more experts than samples.
        """
        x, y = training_data(X, Y, self.n_experts)
        self.build(x.shape[1], y.shape[1])
        return x, y

    # --------------------------------------------------------------- fitting
    def fit_experts(
        self, X: Tensor, Y: Tensor, weights: Tensor, *, max_iter: int | None = None
    ) -> None:
        """Refit every expert on its weighted data (the experts' half of the M-step).

        Args:
            X: Features, `(N, D)`.
            Y: Effects, `(N, E)`.
            weights: Non-negative weight of each sample for each expert, `(N, M)`.
            max_iter: L-BFGS iterations per expert; defaults to `gp_max_iter`.
        """
        x_e = X[:, self.expert_columns]
        for j, expert in enumerate(self.experts):
            expert.fit(x_e, Y, weights[:, j], max_iter=max_iter)  # type: ignore[operator]
        self._set_train_data(X, Y, weights)

    def condition(self, X: Tensor, Y: Tensor, weights: Tensor) -> None:
        """Give every expert its weighted training data without changing hyperparameters.

        Args:
            X: Features, `(N, D)`.
            Y: Effects, `(N, E)`.
            weights: Non-negative weight of each sample for each expert, `(N, M)`.
        """
        x_e = X[:, self.expert_columns]
        for j, expert in enumerate(self.experts):
            expert.condition(x_e, Y, weights[:, j])  # type: ignore[operator]
        self._set_train_data(X, Y, weights)

    def _set_train_data(self, X: Tensor, Y: Tensor, weights: Tensor) -> None:
        self.train_X, self.train_Y, self.train_weights = X, Y, weights.clone()

    def fit_gate(self, X: Tensor, responsibilities: Tensor) -> None:
        """Refit the gate to soft targets (the gate's half of the M-step).

        Args:
            X: Features, `(N, D)`.
            responsibilities: Rows summing to 1, `(N, M)`.
        """
        self._built_gate().fit(X[:, self.gate_columns], responsibilities)

    # ------------------------------------------------------------ prediction
    def gate_probs(self, X: Any) -> Tensor:
        """Gate probabilities `p(m = j | f)`.

        Args:
            X: Features, `(N, D)`.

        Returns:
            Rows summing to 1, `(N, M)`.
        """
        self.check_fitted()
        x = self._features(X)
        return self._built_gate().predict_proba(x[:, self.gate_columns])

    def expert_predictions(self, X: Any, *, include_noise: bool = True) -> Normal:
        """Every expert's predictive distribution.

        Args:
            X: Features, `(N, D)`.
            include_noise: Include the observation noise.

        Returns:
            Normals with loc and scale `(N, M, E)`.
        """
        self.check_fitted()
        x = self._features(X)[:, self.expert_columns]
        preds = [e.predict(x, include_noise=include_noise) for e in self.experts]  # type: ignore[operator]
        return Normal(
            torch.stack([p.loc for p in preds], dim=1), torch.stack([p.scale for p in preds], dim=1)
        )

    def predict(self, X: Any) -> MixtureSameFamily:
        """Predictive distribution of the effects, one mixture per sample.

        Args:
            X: Features, `(N, D)`.

        Returns:
            Mixture over `M` of independent normals over `E`: batch shape `(N,)`,
            event shape `(E,)`, with `mean`, `variance`, `sample()` and `log_prob(Y)`.
        """
        return mixture_distribution(self.gate_probs(X), self.expert_predictions(X))

    def log_joint(self, X: Any, Y: Any) -> Tensor:
        """`log p(m = j | f_i) + log p_j(e_i | f_i)` for every sample and expert.

        Args:
            X: Features, `(N, D)`.
            Y: Effects, `(N, E)`.

        Returns:
            Log joint densities, `(N, M)`.
        """
        self.check_fitted()
        x = self._features(X)
        y = as_matrix("effects Y", Y, n_rows=x.shape[0], n_cols=self.n_outputs)
        log_gate = self._built_gate().log_proba(x[:, self.gate_columns])
        log_lik = self.expert_predictions(x).log_prob(y[:, None, :]).sum(-1)
        return log_gate + log_lik

    def lengthscales(self) -> list[Tensor]:
        """ARD length scales of every expert (standardised units; short means relevant).

        Returns:
            One `(E, D_e)` tensor per expert, columns ordered as `expert_columns`.
        """
        self.check_fitted()
        return [e.lengthscales for e in self.experts]  # type: ignore[attr-defined]
