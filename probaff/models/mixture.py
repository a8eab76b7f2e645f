"""Mixture of GP experts with a softmax gate, each on its own subset of feature columns."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import torch
from torch import Tensor
from torch.distributions import Normal

from probaff._checks import check_count
from probaff.errors import InputError, NotFittedError
from probaff.models.gate import GATE_KINDS, make_gate
from probaff.models.gated import ExpertList, GatedMixture, gated_probs, mixture_distribution
from probaff.models.gp_expert import GPExpert, noise_floor_vector
from probaff.models.tensors import as_matrix, training_rows

__all__ = ["MixtureOfGPExperts", "gated_probs", "mixture_distribution", "training_data"]

# Noise floor of `noise_floor="auto"`, as a fraction of each effect's standard deviation.
_AUTO_NOISE_FLOOR = 0.01

_NOT_FITTED = "MixtureOfGPExperts is not fitted; call probaff.models.fit_em(model, X, Y) first."


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
    x, y = training_rows(X, Y, "push")
    if n_experts > x.shape[0]:
        raise InputError(
            f"n_experts={n_experts} exceeds the {x.shape[0]} training samples; "
            "use fewer experts or more data."
        )
    return x, y


class MixtureOfGPExperts(GatedMixture[GPExpert]):
    r"""Mixture of `M` GP experts: :math:`p(e \mid f) = \sum_j g_j(f_g)\, p_j(e \mid f_e)`.

    The gate :math:`g` is a `SoftmaxGate` on the gate columns `f_g`; each expert :math:`p_j`
    is a `GPExpert` (E independent SE-ARD GPs) on the expert columns `f_e`. Columns are
    chosen by index or by the names of column groups, e.g.
    ``MixtureOfGPExperts(3, groups={"f_x": slice(0, 3), "f_o": slice(3, 40),
    "f_c": slice(40, 101)}, gate_features=("f_x",), expert_features=("f_o", "f_c"))``.
    The model is fitted with `probaff.models.em.fit_em`.

    Args:
        n_experts: Number of experts `M`.
        gate: Kind of gate: ``"linear"`` (the thesis's softmax on the gate features) or
            ``"fourier"`` (softmax on random Fourier features, for regimes that no
            hyperplane separates); see `probaff.models.gate.make_gate`.
        gate_l2: L2 penalty of the gate's weights, or ``"cv"`` (default) to choose it by
            inner 3-fold cross-validation at every fit of the gate.
        gp_max_iter: L-BFGS iterations per expert fit.
        lengthscale_prior: Give the experts' length scales the dimension-scaled log-normal
            prior (see `GPExpert`).
        noise_floor: Smallest observation-noise standard deviation of every expert, in
            effect units: ``"auto"`` (default) is 1 % of each effect's standard deviation
            over the training set; a scalar or one value per effect sets it (for data from
            a sensor, its measurement noise); ``None`` is no floor. See `GPExpert`.
        **columns: The column selection of `GatedMixture`: ``groups`` (named column groups),
            ``gate_features`` and ``expert_features``.

    Raises:
        InputError: If a selection names an unknown group or `n_experts` is not positive.
    """

    not_fitted_message = _NOT_FITTED

    def __init__(
        self,
        n_experts: int,
        *,
        gate: str = "linear",
        gate_l2: float | str = "cv",
        gp_max_iter: int = 50,
        lengthscale_prior: bool = False,
        noise_floor: float | Sequence[float] | str | None = "auto",
        **columns: Any,
    ) -> None:
        super().__init__(n_experts, gate_l2=gate_l2, **columns)
        check_count("gp_max_iter", gp_max_iter)
        if isinstance(noise_floor, str) and noise_floor != "auto":
            raise InputError(
                f"noise_floor must be 'auto', None, or standard deviations, got {noise_floor!r}."
            )
        if not isinstance(noise_floor, str):
            noise_floor_vector(
                noise_floor, 1 if noise_floor is None else torch.as_tensor(noise_floor).numel()
            )
        self.noise_floor = (
            noise_floor
            if noise_floor is None or isinstance(noise_floor, str)
            else [float(v) for v in torch.as_tensor(noise_floor).flatten()]
        )
        if gate not in GATE_KINDS:
            raise InputError(f"gate must be one of {list(GATE_KINDS)}, got {gate!r}.")
        self.gate_kind = gate
        self.gp_max_iter = int(gp_max_iter)
        self.lengthscale_prior = bool(lengthscale_prior)
        self.train_X: Tensor | None = None
        self.train_Y: Tensor | None = None
        self._train_weights: Tensor | None = None

    # ----------------------------------------------------------------- config
    def config(self) -> dict[str, Any]:
        """Constructor arguments as builtins; groups are resolved once `n_features` is known."""
        base = super().config()
        return {
            "n_experts": base["n_experts"],
            "groups": base["groups"],
            "gate_features": base["gate_features"],
            "expert_features": base["expert_features"],
            "gate": self.gate_kind,
            "gate_l2": base["gate_l2"],
            "gp_max_iter": self.gp_max_iter,
            "lengthscale_prior": self.lengthscale_prior,
            "noise_floor": self.noise_floor,
        }

    @property
    def is_fitted(self) -> bool:
        """Whether the experts hold training data and the gate has been fitted."""
        return (
            self.gate is not None
            and bool(self.gate.fitted)
            and all(e.is_fitted for e in self.experts)
        )

    @property
    def train_weights(self) -> Tensor:
        """Every expert's sample weights of the last fit, `(N, M)`.

        Raises:
            NotFittedError: Before the experts were given training data.
        """
        if self._train_weights is None:
            raise NotFittedError(_NOT_FITTED)
        return self._train_weights

    def build(self, n_features: int, n_outputs: int, noise_floor: Tensor | None = None) -> None:
        """Resolve the feature selections and create a fresh gate and fresh experts.

        Called by `fit_em` (so every fit starts from the same initial state) and `load`.

        Args:
            n_features: Columns `D` of the feature matrix.
            n_outputs: Effect dimensions `E`.
            noise_floor: The experts' noise floor in effect units, `(E,)`; defaults to the
                constructor's value (``"auto"`` then means no floor until `check_data`
                resolves it from the training data).
        """
        if noise_floor is None:
            noise_floor = (
                torch.zeros(n_outputs, dtype=torch.float64)
                if self.noise_floor is None or isinstance(self.noise_floor, str)
                else noise_floor_vector(self.noise_floor, n_outputs)
            )
        self.resolve_columns(n_features)
        self.n_outputs = int(n_outputs)
        self.gate = make_gate(
            self.gate_kind, len(self.gate_columns), self.n_experts, l2=self.gate_l2
        )
        self.experts = ExpertList(
            GPExpert(
                len(self.expert_columns),
                n_outputs,
                max_iter=self.gp_max_iter,
                lengthscale_prior=self.lengthscale_prior,
                noise_floor=noise_floor,
            )
            for _ in range(self.n_experts)
        )

    # ---------------------------------------------------------------- inputs
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
        self.build(x.shape[1], y.shape[1], self.resolve_noise_floor(y))
        return x, y

    def resolve_noise_floor(self, Y: Tensor) -> Tensor:
        """The experts' noise floor for training effects `Y: (N, E)`, in effect units, `(E,)`."""
        if self.noise_floor is None:
            return torch.zeros(Y.shape[1], dtype=torch.float64)
        if isinstance(self.noise_floor, str):
            return _AUTO_NOISE_FLOOR * Y.std(dim=0, correction=0)
        return noise_floor_vector(self.noise_floor, Y.shape[1])

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
            expert.fit(x_e, Y, weights[:, j], max_iter=max_iter)
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
            expert.condition(x_e, Y, weights[:, j])
        self._set_train_data(X, Y, weights)

    def _set_train_data(self, X: Tensor, Y: Tensor, weights: Tensor) -> None:
        self.train_X, self.train_Y, self._train_weights = X, Y, weights.clone()

    def fit_gate(self, X: Tensor, responsibilities: Tensor, *, reuse_choice: bool = False) -> None:
        """Refit the gate to soft targets (the gate's half of the M-step).

        Args:
            X: Features, `(N, D)`.
            responsibilities: Rows summing to 1, `(N, M)`.
            reuse_choice: Keep the gate's cross-validated penalty from its last fit.
        """
        self.built_gate().fit(X[:, self.gate_columns], responsibilities, reuse_choice=reuse_choice)

    # ------------------------------------------------------------ prediction
    def expert_predictions(self, X: Any, *, include_noise: bool = True) -> Normal:
        """Every expert's predictive distribution.

        Args:
            X: Features, `(N, D)`.
            include_noise: Include the observation noise.

        Returns:
            Normals with loc and scale `(N, M, E)`.
        """
        x = self.features(X)[:, self.expert_columns]
        preds = [e.predict(x, include_noise=include_noise) for e in self.experts]
        return Normal(
            torch.stack([p.loc for p in preds], dim=1), torch.stack([p.scale for p in preds], dim=1)
        )

    def log_joint(self, X: Any, Y: Any) -> Tensor:
        """`log p(m = j | f_i) + log p_j(e_i | f_i)` for every sample and expert.

        Args:
            X: Features, `(N, D)`.
            Y: Effects, `(N, E)`.

        Returns:
            Log joint densities, `(N, M)`.
        """
        x = self.features(X)
        y = as_matrix("effects Y", Y, n_rows=x.shape[0], n_cols=self.n_outputs)
        log_gate = self.built_gate().log_proba(x[:, self.gate_columns])
        log_lik = self.expert_predictions(x).log_prob(y[:, None, :]).sum(-1)
        return log_gate + log_lik

    def loo_log_joint(self, X: Tensor, Y: Tensor) -> Tensor:
        """Like `log_joint` on the training set, with leave-one-out expert densities.

        Args:
            X: The training features, `(N, D)`.
            Y: The training effects, `(N, E)`.

        Returns:
            Log joint densities `log p(m = j | f_i) + log p_j(e_i | f_i, D_-i)`, `(N, M)`.
        """
        log_gate = self.built_gate().log_proba(X[:, self.gate_columns])
        return log_gate + self.loo_log_lik(X, Y)

    def loo_log_lik(self, X: Tensor, Y: Tensor) -> Tensor:
        """Every expert's leave-one-out log density of every training sample.

        Expert `j`'s density of a sample it was trained on is its leave-one-out predictive
        density (`GPExpert.loo_predict`): the sample's own target is not used to predict it.
        A sample that expert `j` holds no weight of is scored by its ordinary predictive
        density, which is already out-of-sample. This removes the bias of in-sample GP
        densities towards the expert that already holds a sample, which otherwise locks EM
        into its initial assignment (Rasmussen & Ghahramani, 2002, score the assignment of
        a sample the same way).

        Args:
            X: The training features, `(N, D)`.
            Y: The training effects, `(N, E)`.

        Returns:
            `log p_j(e_i | f_i, D_-i)`, `(N, M)`.
        """
        self.check_fitted()
        if self._train_weights is None or self._train_weights.shape[0] != X.shape[0]:
            raise InputError("loo_log_lik needs the training set the mixture was fitted on.")
        pred = self.expert_predictions(X)
        loc, scale = pred.loc.clone(), pred.scale.clone()
        for j, expert in enumerate(self.experts):
            held = self.train_weights[:, j] > 0
            loo = expert.loo_predict()
            loc[held, j] = loo.loc
            scale[held, j] = loo.scale
        return Normal(loc, scale).log_prob(Y[:, None, :]).sum(-1)

    def lengthscales(self) -> list[Tensor]:
        """ARD length scales of every expert (standardised units; short means relevant).

        Returns:
            One `(E, D_e)` tensor per expert, columns ordered as `expert_columns`.
        """
        self.check_fitted()
        return [e.lengthscales for e in self.experts]
