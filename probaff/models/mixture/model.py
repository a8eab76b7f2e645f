"""Mixture of GP experts with a softmax gate, each on its own subset of feature columns."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from typing import Any

import torch
from torch import Tensor
from torch.distributions import Normal

from probaff._checks import check_count
from probaff.errors import InputError, NotFittedError
from probaff.models.experts.expert_base import (
    noise_floor_vector,
    out_of_sample,
    training_noise_floor,
)
from probaff.models.experts.expert_batch import (
    fit_exact_experts,
    predict_exact_experts,
    predict_exact_experts_out_of_sample,
)
from probaff.models.experts.gp_expert import GPExpert
from probaff.models.experts.sparse_expert import (
    DEFAULT_N_INDUCING,
    FitMemoryError,
    SparseGPExpert,
    available_memory_bytes,
    fit_memory_bytes,
)
from probaff.models.gates.gate import GATE_KINDS, make_gate
from probaff.models.gates.gate_penalty import check_strength
from probaff.models.gates.gated import ExpertList, GatedMixture, gated_probs, mixture_distribution
from probaff.models.mixture.point import (
    MIN_STACK_ROWS,
    POINT_KINDS,
    out_of_fold_gate,
    stacking_weights,
)
from probaff.models.options import (
    MIXTURE_GP,
    GPOptions,
    SparseGPOptions,
    check_hyper_rows,
    refuse_flat_gp_keywords,
)
from probaff.models.tensors import as_matrix, training_rows

__all__ = [
    "AUTO_SPARSE_ABOVE",
    "EXPERT_KINDS",
    "FLAT_GP_KEYWORDS",
    "AnyGPExpert",
    "MixtureOfGPExperts",
    "gated_probs",
    "mixture_distribution",
    "training_data",
]

_NOT_FITTED = "MixtureOfGPExperts is not fitted; call probaff.models.fit_em(model, X, Y) first."

EXPERT_KINDS = ("auto", "exact", "sparse")
"""The values of `MixtureOfGPExperts`'s ``experts=``."""

AUTO_SPARSE_ABOVE = 1500
"""``experts="auto"`` builds sparse experts when the training set has more rows than this.

Measured on `probaff.models.synthetic.regime_features` (D = 101, E = 6, one thread): one
expert's fit with 256 inducing points is slower than the exact one on 500 weighted samples
and faster on 1,000 (with the same held-out density), and an expert of a 3-expert mixture
holds about a third to a half of the rows once EM has separated the regimes."""

FLAT_GP_KEYWORDS = {
    "gp_max_iter": "max_iter",
    "lengthscale_prior": "lengthscale_prior",
    "noise_floor": "noise_floor",
}
"""The experts' settings a `MixtureOfGPExperts` once took one by one, each to its field of
`GPOptions`: the keywords it now refuses, the keys of files saved before ``gp``, and the
flat parameters of the scikit-learn estimator (`probaff.models.sklearn`), which scikit-learn's
`get_params` needs one by one (the transition models' old keywords extend them)."""


def _check_gp(gp: Any) -> GPOptions:
    """`gp`, or `MIXTURE_GP` for None; `InputError` for anything but a `GPOptions`.

    A `SparseGPOptions` is refused too: a mixture's sparse experts take `n_inducing` and
    `hyper_rows` from the mixture.
    """
    if gp is None:
        return MIXTURE_GP
    if type(gp) is not GPOptions:
        raise InputError(
            f"gp must be GPOptions (the experts' settings, e.g. GPOptions(max_iter=20, "
            f"lengthscale_prior=True, noise_floor='auto')) or None, got {type(gp).__name__}; "
            "give a mixture's sparse experts n_inducing and hyper_rows as its own arguments."
        )
    return gp


AnyGPExpert = GPExpert | SparseGPExpert
"""An expert of a `MixtureOfGPExperts`: exact (`GPExpert`) or sparse (`SparseGPExpert`)."""


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


class MixtureOfGPExperts(GatedMixture[AnyGPExpert]):
    r"""Mixture of `M` GP experts: :math:`p(e \mid f) = \sum_j g_j(f_g)\, p_j(e \mid f_e)`.

    The gate :math:`g` is a `SoftmaxGate` on the gate columns `f_g`; each expert :math:`p_j`
    is a `GPExpert` (E independent SE-ARD GPs) or a `SparseGPExpert` (the same with `m`
    inducing points per output, see `experts`) on the expert columns `f_e`. Columns are
    chosen by index or by the names of column groups: on chapter 5's features
    (`probaff.features.chapter5_features`, whose ``groups`` are these),
    ``MixtureOfGPExperts(3, groups={"f_o": slice(0, 8), "f_c": slice(8, 21),
    "f_x": slice(21, 101)}, gate_features=("f_x",), expert_features=("f_o", "f_c"))`` gates on
    the objects' profiles and gives the experts the poses and contacts. The model is fitted
    with `probaff.models.mixture.em.fit_em`.

    Args:
        n_experts: Number of experts `M`.
        gate: Kind of gate: ``"linear"`` (the thesis's softmax on the gate features) or
            ``"fourier"`` (softmax on random Fourier features, for regimes that no
            hyperplane separates); see `probaff.models.gates.gate.make_gate`.
        gate_l2: L2 penalty of the gate's weights, or ``"cv"`` (default) to choose it by
            inner 3-fold cross-validation at every fit of the gate.
        gate_l1: L1 (lasso) penalty of the gate's weights, or ``"cv"`` (default): with both
            ``"cv"``, each fit of the gate chooses by the same cross-validation among the
            ridge penalties and the lasso penalties (`SoftmaxGate`), so a gate on many
            features can keep the few that separate the experts. On
            `probaff.models.synthetic.regime_features` (D = 101, two columns set the
            regime, M = 3) the lasso raised the gate's held-out accuracy from 63 % to 91 %
            at N = 250 and from 81 % to 95 % at N = 500. 0 is the ridge alone.
        gp: The experts' settings, whole (`GPOptions`: ``max_iter``, L-BFGS iterations per
            expert fit; ``lengthscale_prior``, the dimension-scaled log-normal prior on the
            length scales or its width; ``noise_floor``, the smallest observation-noise
            standard deviation of every expert in effect units: ``"auto"`` is 1 % of each
            effect's standard deviation over the mixture's training set, a scalar or one
            value per effect sets it (for data from a sensor, its measurement noise), None
            is no floor; ``outputscale`` and ``noise``, the initial variances). None for
            `MIXTURE_GP`, ``GPOptions(lengthscale_prior=True, noise_floor="auto")`` (50
            iterations), which differs from a single `GPExpert`'s `GPOptions()` (no prior, no
            floor): to change one setting, replace it in the default, e.g.
            ``gp=dataclasses.replace(MIXTURE_GP, max_iter=20)``. Sparse experts get these
            settings with `n_inducing` and `hyper_rows`.
        experts: ``"exact"`` (`GPExpert`: :math:`O(N^3)` time and :math:`O(N^2)` memory per
            M-step), ``"sparse"`` (`SparseGPExpert`: the weighted collapsed bound with
            `n_inducing` inducing points, :math:`O(N m^2)` time and :math:`O(N m)` memory),
            or ``"auto"`` (default): sparse when the training set has more than
            `AUTO_SPARSE_ABOVE` rows, exact otherwise, resolved when the model is fitted.
        n_inducing: Inducing points per output of sparse experts; None for
            ``min(DEFAULT_N_INDUCING, N)``. A value above the `N` training rows is refused
            when the model is fitted.
        hyper_rows: Sparse experts holding more samples than this choose their inducing
            inputs and hyperparameters on a uniform random subset of this many, then condition
            on all of them (`probaff.models.options.SparseGPOptions`); None uses every sample.
        point: What `predict_point` returns: ``"mean"`` (default), the mixture's predictive
            mean; ``"stacked"``, the mean stacked per output with one GP fitted on every
            row, by weights chosen on out-of-sample predictions of the training rows
            (`probaff.models.mixture.point`, which gives the measurements behind the default), for
            data where the experts extrapolate worse than one GP. `predict` is the same for
            both.
        **columns: The column selection of `GatedMixture`: ``groups`` (named column groups),
            ``gate_features`` and ``expert_features``.

    Raises:
        InputError: If a selection names an unknown group, `n_experts` is not positive,
            `gp` is not a `GPOptions` (or one of the old keywords ``gp_max_iter``,
            ``lengthscale_prior``, ``noise_floor`` is given), `experts` is not a known kind,
            `n_inducing` or `hyper_rows` is not a positive integer, `hyper_rows` is below
            the inducing points (`probaff.models.options.check_hyper_rows`), or `point` is
            not a known kind.

    Example:
        Three regimes that inputs 0 and 1 decide
        (`probaff.models.synthetic.softmax_regimes`), the gate on those two columns:

        >>> from probaff.models import MixtureOfGPExperts, fit_em
        >>> from probaff.models.synthetic import softmax_regimes
        >>> x, y, _ = softmax_regimes(60, seed=0)  # (60, 4) features, (60, 2) effects
        >>> model = MixtureOfGPExperts(3, gate_features=[0, 1])  # gp=MIXTURE_GP
        >>> _ = fit_em(model, x, y, init="joint", n_restarts=1, split_merge=0, max_iter=3)
        >>> pred = model.predict(x[:4])  # a torch MixtureSameFamily per row
        >>> tuple(pred.batch_shape), tuple(pred.event_shape)
        ((4,), (2,))
        >>> tuple(model.predict_point(x[:4]).shape)  # the point to score by squared error
        (4, 2)
    """

    not_fitted_message = _NOT_FITTED

    def __init__(
        self,
        n_experts: int,
        *,
        gate: str = "linear",
        gate_l2: float | str = "cv",
        gate_l1: float | str = "cv",
        gp: GPOptions | None = None,
        experts: str = "auto",
        n_inducing: int | None = None,
        hyper_rows: int | None = 2048,
        point: str = "mean",
        **columns: Any,
    ) -> None:
        what = "MixtureOfGPExperts takes its experts' settings"
        refuse_flat_gp_keywords(what, columns, FLAT_GP_KEYWORDS)
        super().__init__(n_experts, gate_l2=gate_l2, **columns)
        self.gate_l1: float | str = check_strength("gate_l1", gate_l1)
        self.gp = _check_gp(gp)
        if gate not in GATE_KINDS:
            raise InputError(f"gate must be one of {list(GATE_KINDS)}, got {gate!r}.")
        self.gate_kind = gate
        if not isinstance(experts, str) or experts not in EXPERT_KINDS:
            raise InputError(
                f"experts must be one of {list(EXPERT_KINDS)}, got {experts!r}; use 'sparse' "
                f"for large training sets, 'exact' for small ones, or 'auto' to choose by size."
            )
        self.expert_kind = experts
        self.n_inducing = None if n_inducing is None else check_count("n_inducing", n_inducing)
        self.hyper_rows = check_hyper_rows(hyper_rows, self.n_inducing)
        if not isinstance(point, str) or point not in POINT_KINDS:
            raise InputError(
                f"point must be one of {list(POINT_KINDS)}, got {point!r}; 'stacked' for the "
                "squared-error point prediction, 'mean' for the mixture's predictive mean."
            )
        self.point = point
        self._expert_options: GPOptions = self.gp
        self.point_expert: AnyGPExpert | None = None
        self.register_buffer("point_weights", None)
        self.point_weights: Tensor | None
        self.built_expert_kind: str | None = None
        self.train_X: Tensor | None = None
        self.train_Y: Tensor | None = None
        self._train_weights: Tensor | None = None

    # ----------------------------------------------------------------- config
    def config(self) -> dict[str, Any]:
        """Constructor arguments: ``MixtureOfGPExperts(**model.config())`` rebuilds the model.

        Builtins, except ``gp``, the experts' `GPOptions` whole (`save` stores its fields);
        groups are resolved once `n_features` is known.
        """
        base = super().config()
        return {
            "n_experts": base["n_experts"],
            "groups": base["groups"],
            "gate_features": base["gate_features"],
            "expert_features": base["expert_features"],
            "gate": self.gate_kind,
            "gate_l2": base["gate_l2"],
            "gate_l1": self.gate_l1,
            "gp": self.gp,
            "experts": self.expert_kind,
            "n_inducing": self.n_inducing,
            "hyper_rows": self.hyper_rows,
            "point": self.point,
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

    def build(
        self,
        n_features: int,
        n_outputs: int,
        noise_floor: Tensor | None = None,
        *,
        n_samples: int | None = None,
    ) -> None:
        """Resolve the feature selections and create a fresh gate and fresh experts.

        Called by `fit_em` (so every fit starts from the same initial state) and `load`.

        Args:
            n_features: Columns `D` of the feature matrix.
            n_outputs: Effect dimensions `E`.
            noise_floor: The experts' noise floor in effect units, `(E,)`; defaults to
                ``gp.noise_floor`` (``"auto"`` then means no floor until `check_data`
                resolves it from the training data).
            n_samples: Training rows `N`: resolves ``experts="auto"`` (see
                `resolve_expert_kind`) and is checked against `n_inducing` and the memory
                available. None keeps the kind of the last build (exact if none).

        Raises:
            InputError: If `n_inducing` exceeds `n_samples`.
            FitMemoryError: If the fit would not fit in the memory available (see
                `check_fit_memory`).
        """
        if noise_floor is None:
            floor = self.gp.noise_floor  # "auto" is resolved by `check_data`
            noise_floor = noise_floor_vector(None if isinstance(floor, str) else floor, n_outputs)
        kind = self.resolve_expert_kind(n_samples)
        self.resolve_columns(n_features)
        if n_samples is not None:
            self.check_fit_memory(kind, n_samples, n_outputs)
        self.n_outputs = int(n_outputs)
        self.gate = make_gate(
            self.gate_kind, len(self.gate_columns), self.n_experts, l2=self.gate_l2, l1=self.gate_l1
        )
        self.built_expert_kind = kind
        self._expert_options = self.expert_options(kind, noise_floor)
        self.experts = ExpertList(self.new_expert() for _ in range(self.n_experts))
        self.point_expert = None
        self.point_weights = None

    def expert_options(self, kind: str, noise_floor: Tensor) -> GPOptions:
        """The settings every expert of a build gets: `gp` with its noise floor resolved.

        Args:
            kind: ``"exact"`` or ``"sparse"``.
            noise_floor: The noise floor in effect units, `(E,)`.

        Returns:
            ``gp`` with `noise_floor` in place of its own; for sparse experts, as a
            `SparseGPOptions` with the mixture's `n_inducing` and `hyper_rows`.
        """
        floor = tuple(float(v) for v in noise_floor.flatten())
        options = dataclasses.replace(self.gp, noise_floor=floor)
        if kind != "sparse":
            return options
        shared = {f.name: getattr(options, f.name) for f in dataclasses.fields(GPOptions)}
        return SparseGPOptions(**shared, n_inducing=self.n_inducing, hyper_rows=self.hyper_rows)

    def new_expert(self) -> AnyGPExpert:
        """A fresh, unfitted expert of the kind and settings of the last `build`."""
        d_e, n_outputs = len(self.expert_columns), self.n_outputs
        assert n_outputs is not None, "build the mixture first"
        options = self._expert_options
        if self.built_expert_kind == "sparse":
            assert isinstance(options, SparseGPOptions)
            return SparseGPExpert(d_e, n_outputs, options)
        return GPExpert(d_e, n_outputs, options)

    def resolve_expert_kind(self, n_samples: int | None) -> str:
        """The kind of expert (``"exact"`` or ``"sparse"``) a fit on `n_samples` rows builds.

        ``experts="auto"`` is sparse above `AUTO_SPARSE_ABOVE` rows. Without `n_samples`,
        the kind of the last build is kept (exact before any).

        Args:
            n_samples: Training rows `N`, or None.

        Returns:
            ``"exact"`` or ``"sparse"``.

        Raises:
            InputError: If `n_inducing` exceeds `n_samples`.
        """
        if n_samples is not None and self.n_inducing is not None and self.n_inducing > n_samples:
            raise InputError(
                f"n_inducing={self.n_inducing} exceeds the {n_samples} training rows; use "
                f"n_inducing <= {n_samples}, or None for min({DEFAULT_N_INDUCING}, N)."
            )
        if self.expert_kind != "auto":
            return self.expert_kind
        if n_samples is None:
            return self.built_expert_kind or "exact"
        return "sparse" if n_samples > AUTO_SPARSE_ABOVE else "exact"

    def check_fit_memory(self, kind: str, n_samples: int, n_outputs: int) -> None:
        """Refuse, before anything is allocated, a fit that would not fit in memory.

        The estimate is `probaff.models.experts.sparse_expert.fit_memory_bytes` for `M` experts;
        the memory available is read from the operating system (no check where it cannot
        be read).

        Args:
            kind: ``"exact"`` or ``"sparse"``.
            n_samples: Training rows `N`.
            n_outputs: Effect dimensions `E`.

        Raises:
            FitMemoryError: If the estimate exceeds the memory available.
        """
        m = min(self.n_inducing or DEFAULT_N_INDUCING, n_samples)
        d, rows = len(self.expert_columns), self.hyper_rows

        def need_of(kind: str) -> int:
            return fit_memory_bytes(
                kind, n_samples, n_outputs, self.n_experts, m, n_features=d, hyper_rows=rows
            )

        need = need_of(kind)
        free = available_memory_bytes()
        if free is None or need <= free:
            return
        gib = 2.0**30
        if kind == "exact":
            hint = f"use experts='sparse' (about {need_of('sparse') / gib:.2g} GiB) or fewer rows"
        else:
            hint = "use a smaller n_inducing or fewer training rows"
        raise FitMemoryError(
            f"fitting {self.n_experts} {kind} experts on {n_samples} rows with {n_outputs} "
            f"outputs needs about {need / gib:.3g} GiB, but only {free / gib:.3g} GiB of memory "
            f"is available; {hint}."
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
        self.build(x.shape[1], y.shape[1], self.resolve_noise_floor(y), n_samples=x.shape[0])
        return x, y

    def resolve_noise_floor(self, Y: Tensor) -> Tensor:
        """The experts' noise floor for training effects `Y: (N, E)`, in effect units, `(E,)`.

        ``gp.noise_floor="auto"`` is 1 % of each effect's standard deviation over every row
        of `Y` (`probaff.models.experts.expert_base.training_noise_floor`).
        """
        return training_noise_floor(self.gp.noise_floor, Y)

    # --------------------------------------------------------------- fitting
    def fit_experts(
        self,
        X: Tensor,
        Y: Tensor,
        weights: Tensor,
        *,
        max_iter: int | None = None,
        only: Sequence[int] | None = None,
    ) -> None:
        """Refit every expert on its weighted data (the experts' half of the M-step).

        Exact experts are fitted together: each runs its own L-BFGS, and their evaluations
        are computed as one batch (`probaff.models.experts.expert_batch.fit_exact_experts`), which
        gives the fits of one expert at a time up to rounding. The mixture moves to the
        device of `X` first.

        Args:
            X: Features, `(N, D)`.
            Y: Effects, `(N, E)`.
            weights: Non-negative weight of each sample for each expert, `(N, M)`.
            max_iter: L-BFGS iterations per expert; defaults to ``gp.max_iter``.
            only: Refit these experts only; the others keep their hyperparameters and are
                conditioned on their column of `weights` (a partial M-step). None: all.
        """
        self.to(X.device)  # the mixture fits where its data lives
        x_e = X[:, self.expert_columns]
        chosen = list(range(self.n_experts)) if only is None else sorted(set(only))
        held = [j for j in range(self.n_experts) if j not in chosen]
        fitted = [self.experts[j] for j in chosen]
        if all(isinstance(e, GPExpert) for e in fitted):  # exact experts: one batched fit
            exact = [e for e in fitted if isinstance(e, GPExpert)]
            fit_exact_experts(exact, x_e, Y, weights[:, chosen], max_iter=max_iter)
        else:
            for j in chosen:
                self.experts[j].fit(x_e, Y, weights[:, j], max_iter=max_iter)
        for j in held:
            self.experts[j].condition(x_e, Y, weights[:, j])
        self._set_train_data(X, Y, weights)

    def condition(self, X: Tensor, Y: Tensor, weights: Tensor) -> None:
        """Give every expert its weighted training data without changing hyperparameters.

        Args:
            X: Features, `(N, D)`.
            Y: Effects, `(N, E)`.
            weights: Non-negative weight of each sample for each expert, `(N, M)`.
        """
        self.to(X.device)  # the mixture lives where its data lives
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
        """Every expert's predictive distribution (exact experts computed as one batch).

        Args:
            X: Features, `(N, D)`.
            include_noise: Include the observation noise.

        Returns:
            Normals with loc and scale `(N, M, E)`.
        """
        x = self.features(X)[:, self.expert_columns]
        exact = [e for e in self.experts if isinstance(e, GPExpert)]
        if len(exact) == len(self.experts):  # exact experts: one batched prediction
            return predict_exact_experts(exact, x, include_noise=include_noise)
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
        y = as_matrix("effects Y", Y, n_rows=x.shape[0], n_cols=self.n_outputs, device=x.device)
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
        density (`GPExpert.loo_predict`, or `SparseGPExpert.loo_predict`: the exact
        leave-one-out of the sparse model with its inducing inputs and hyperparameters
        held fixed, :math:`O(N m^2)`): the sample's own target is not used to predict it.
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
        return self.loo_expert_predictions(X).log_prob(Y[:, None, :]).sum(-1)

    def loo_expert_predictions(self, X: Tensor) -> Normal:
        """Every expert's out-of-sample predictive distribution of every training row.

        Leave-one-out where the expert holds the row, its ordinary prediction elsewhere (see
        `loo_log_lik`).

        Args:
            X: The training features, `(N, D)`.

        Returns:
            Normals with loc and scale `(N, M, E)`, noise included.
        """
        self.check_fitted()
        if self._train_weights is None or self._train_weights.shape[0] != X.shape[0]:
            raise InputError("loo_log_lik needs the training set the mixture was fitted on.")
        x_e = self.features(X)[:, self.expert_columns]
        held = self.train_weights > 0
        exact = [e for e in self.experts if isinstance(e, GPExpert)]
        if len(exact) == len(self.experts):  # one batched prediction, one factor per expert
            return predict_exact_experts_out_of_sample(exact, x_e, held)
        return out_of_sample(list(self.experts), x_e, held)  # sparse experts, one at a time

    # ------------------------------------------------------------ point prediction
    def fit_point(self, single: AnyGPExpert, X: Tensor, Y: Tensor, *, seed: int = 0) -> None:
        """Stack the mixture's mean with one GP fitted on every row (``point="stacked"``).

        Chooses the weights of `predict_point` (`probaff.models.mixture.point`); with
        ``point="mean"``, one expert, or fewer than `MIN_STACK_ROWS` rows, the point is the
        mixture's mean and nothing is stored.

        Args:
            single: A GP expert of this mixture's kind, fitted and conditioned on every
                training row with weight 1 (the `M = 1` fit).
            X: The training features, `(N, D)`.
            Y: The training effects, `(N, E)`.
            seed: Seed of the gate's cross-fitting folds.
        """
        self.point_expert, self.point_weights = None, None
        if self.point != "stacked" or self.n_experts == 1 or X.shape[0] < MIN_STACK_ROWS:
            return
        x_gate = X[:, self.gate_columns]
        loo = self.loo_expert_predictions(X)  # once: both the E-step's terms and the means
        log_joint = self.built_gate().log_proba(x_gate) + loo.log_prob(Y[:, None, :]).sum(-1)
        resp = torch.softmax(log_joint, dim=1)
        gate = out_of_fold_gate(self.built_gate(), x_gate, resp, seed)
        mixture_mean = (gate[..., None] * loo.loc).sum(1)
        single_mean = single.loo_predict().loc
        self.point_weights = stacking_weights(mixture_mean, single_mean, Y)
        self.point_expert = single

    def prepare_point(self) -> None:
        """Create the stacked point's single GP on the training rows, to load a saved state.

        Raises:
            NotFittedError: If the mixture holds no training data.
        """
        if self.train_X is None or self.train_Y is None:
            raise NotFittedError(_NOT_FITTED)
        single = self.new_expert()
        weights = torch.ones_like(self.train_Y[:, 0])
        single.condition(self.train_X[:, self.expert_columns], self.train_Y, weights)
        self.point_expert = single
        self.point_weights = torch.zeros_like(self.train_Y[0])

    def _load_from_state_dict(
        self, state_dict: Mapping[str, Any], prefix: str, *args: Any, **kwargs: Any
    ) -> None:
        # A saved stacked point: create its single GP first, so that its state loads too.
        if prefix + "point_weights" in state_dict and self.point_expert is None:
            self.prepare_point()
        super()._load_from_state_dict(state_dict, prefix, *args, **kwargs)

    def predict_point(self, X: Any, *, mean: Tensor | None = None) -> Tensor:
        """The point prediction of the effects (see ``point``): stacked, or the mean.

        Args:
            X: Features, `(N, D)`.
            mean: ``predict(X).mean``, when the caller has it already.

        Returns:
            `(N, E)` effects, in output units.
        """
        if mean is None:
            mean = self.predict(X).mean
        if self.point_expert is None or self.point_weights is None:
            return mean
        x_e = self.features(X)[:, self.expert_columns]
        single = self.point_expert.predict(x_e).loc
        return self.point_weights * mean + (1.0 - self.point_weights) * single

    def lengthscales(self) -> list[Tensor]:
        """ARD length scales of every expert (standardised units; short means relevant).

        Returns:
            One `(E, D_e)` tensor per expert, columns ordered as `expert_columns`.
        """
        self.check_fitted()
        return [e.lengthscales for e in self.experts]
