"""Base class of the gated mixtures of GP experts and the mixture helpers they share.

`GatedMixture` holds what `MixtureOfGPExperts` (fitted by EM) and
`VariationalMixtureOfGPExperts` (fitted by SVI) have in common: the constructor's column
selection (``groups``, ``gate_features``, ``expert_features``, resolved to `gate_columns` and
`expert_columns`), the gate, the experts as a typed `ExpertList`, `gate_probs` and
`predict`. Subclasses supply `is_fitted` and `expert_predictions`.
"""

from __future__ import annotations

import abc
from collections.abc import Iterable, Iterator
from typing import Any, ClassVar, Generic, TypeVar, cast, overload

import torch
from torch import Tensor
from torch.distributions import Categorical, Independent, MixtureSameFamily, Normal

from probaff.errors import InputError, NotFittedError
from probaff.models.columns import (
    FeatureGroups,
    FeatureSpec,
    check_mixture_args,
    resolve_features,
    resolve_groups,
)
from probaff.models.gates.gate import SoftmaxGate
from probaff.models.tensors import DeviceCheckedModule, as_matrix

__all__ = [
    "ExpertList",
    "GatedMixture",
    "gated_probs",
    "mixture_distribution",
    "mixture_payload",
    "plain_spec",
]

ExpertT = TypeVar("ExpertT", bound=torch.nn.Module)


def mixture_distribution(probs: Tensor, components: Normal) -> MixtureSameFamily:
    """Per-sample mixture of independent normals.

    Args:
        probs: Mixture weights, rows summing to 1, `(N, M)`.
        components: Normals with loc and scale `(N, M, E)`.

    Returns:
        Batch shape `(N,)`, event shape `(E,)`.
    """
    return MixtureSameFamily(Categorical(probs=probs), Independent(components, 1))


def gated_probs(probs: Tensor, gating: str) -> Tensor:
    """Mixture weights for a gating mode: the gate's probabilities or their one-hot argmax.

    Args:
        probs: Gate probabilities, `(N, M)`.
        gating: ``"soft"`` (the probabilities) or ``"hard"`` (the most probable expert).

    Returns:
        Mixture weights, `(N, M)`.

    Raises:
        InputError: For an unknown `gating`.
    """
    if gating == "soft":
        return probs
    if gating == "hard":
        return torch.nn.functional.one_hot(probs.argmax(1), probs.shape[1]).to(probs.dtype)
    raise InputError(f"gating must be 'soft' or 'hard', got {gating!r}.")


def plain_spec(spec: FeatureSpec) -> str | list[str] | list[int] | None:
    """A copy of a feature selection made only of builtins (for saving).

    Args:
        spec: ``None``, a group name, group names or column indices.

    Returns:
        The same selection as ``None``, a string or a list.
    """
    if spec is None or isinstance(spec, str):
        return spec
    names = [s for s in spec if isinstance(s, str)]
    if len(names) == len(spec):
        return names
    return [int(s) for s in spec if not isinstance(s, str)]


def mixture_payload(model: GatedMixture[Any], **entries: Any) -> dict[str, Any]:
    """What `probaff.models.save` stores of a gated mixture, in the file's order.

    Args:
        model: A fitted mixture.
        **entries: The subclass's own entries, stored between the sizes and the state dict.

    Returns:
        ``config``, ``n_features``, ``n_outputs``, the `entries`, then ``state_dict``.
    """
    return {
        "config": model.config(),
        "n_features": model.n_features,
        "n_outputs": model.n_outputs,
        **entries,
        "state_dict": model.state_dict(),
    }


class ExpertList(torch.nn.ModuleList, Generic[ExpertT]):
    """A `torch.nn.ModuleList` whose items are typed as the experts they hold.

    Indexing and iteration give `ExpertT` (e.g. `GPExpert`), so the experts' methods type-check;
    the state-dict keys are those of a plain `ModuleList` (``experts.0.…``).

    Args:
        experts: The experts, in order.
    """

    def __init__(self, experts: Iterable[ExpertT] | None = None) -> None:
        super().__init__(experts)

    @overload
    def __getitem__(self, idx: slice) -> ExpertList[ExpertT]: ...

    @overload
    def __getitem__(self, idx: int) -> ExpertT: ...

    def __getitem__(self, idx: int | slice) -> ExpertT | ExpertList[ExpertT]:
        if isinstance(idx, slice):
            return ExpertList(cast("list[ExpertT]", list(self._modules.values())[idx]))
        return cast(ExpertT, super().__getitem__(idx))

    def __iter__(self) -> Iterator[ExpertT]:
        return iter(cast("list[ExpertT]", list(self._modules.values())))


class GatedMixture(DeviceCheckedModule, Generic[ExpertT], metaclass=abc.ABCMeta):
    r"""A softmax-gated mixture of `M` experts, the base of the mixtures of GP experts.

    :math:`p(e \mid f) = \sum_j g_j(f_g)\, p_j(e \mid f_e)`.
    The gate sees the gate columns `f_g`, every expert the expert columns `f_e`; columns are
    chosen by index or by the names of column groups (see `probaff.models.columns`).
    Subclasses create `gate` and `experts` when they are fitted, and implement `is_fitted`
    and `expert_predictions`; `gate_probs` and `predict` are built on them.

    `to` and `cuda` refuse a device that this machine does not have. A fit runs on the device
    of its training data, so after ``model.to(device)`` fit with data on that device;
    predictions move their inputs to the mixture's device.

    Args:
        n_experts: Number of experts `M`.
        groups: Named column groups (slices or index lists of the feature matrix).
        gate_features: Gate columns: ``None`` (all), group name(s) or column indices.
        expert_features: Expert columns, shared by every expert, in the same forms.
        gate_l2: L2 penalty of the gate's weights, or ``"cv"`` to choose it by
            cross-validation.

    Raises:
        InputError: If a selection names an unknown group, `n_experts` is not positive or
            `gate_l2` is neither ``"cv"`` nor a number >= 0.
    """

    not_fitted_message: ClassVar[str] = "the mixture is not fitted."
    """Message of the `NotFittedError` that an unfitted mixture raises."""

    def __init__(
        self,
        n_experts: int,
        *,
        groups: FeatureGroups | None = None,
        gate_features: FeatureSpec = None,
        expert_features: FeatureSpec = None,
        gate_l2: float | str = "cv",
    ) -> None:
        super().__init__()
        self.n_experts = check_mixture_args(
            n_experts, groups, gate_features, expert_features, gate_l2
        )
        self.groups = dict(groups or {})
        self.gate_features = gate_features
        self.expert_features = expert_features
        self.gate_l2: float | str = gate_l2 if isinstance(gate_l2, str) else float(gate_l2)
        self.n_features: int | None = None
        self.n_outputs: int | None = None
        self.gate_columns: list[int] = []
        self.expert_columns: list[int] = []
        self.gate: SoftmaxGate | None = None
        self.experts: ExpertList[ExpertT] = ExpertList()

    # ----------------------------------------------------------------- config
    def config(self) -> dict[str, Any]:
        """The shared constructor arguments as builtins.

        Groups are resolved to column indices once `n_features` is known. Subclasses add
        their own arguments, so that ``type(model)(**model.config())`` rebuilds the model.

        Returns:
            ``n_experts``, ``groups``, ``gate_features``, ``expert_features``, ``gate_l2``.
        """
        groups: dict[str, Any] = (
            resolve_groups(self.groups, self.n_features)
            if self.n_features is not None
            else {k: v if isinstance(v, slice) else list(v) for k, v in self.groups.items()}
        )
        return {
            "n_experts": self.n_experts,
            "groups": groups,
            "gate_features": plain_spec(self.gate_features),
            "expert_features": plain_spec(self.expert_features),
            "gate_l2": self.gate_l2,
        }

    def resolve_columns(self, n_features: int) -> None:
        """Set `n_features`, `gate_columns` and `expert_columns` for `D = n_features` columns.

        Args:
            n_features: Columns `D` of the feature matrix.

        Raises:
            InputError: For an unknown group, an index out of range or a repeated column.
        """
        self.gate_columns = resolve_features(
            "gate_features", self.gate_features, self.groups, n_features
        )
        self.expert_columns = resolve_features(
            "expert_features", self.expert_features, self.groups, n_features
        )
        self.n_features = int(n_features)

    # ---------------------------------------------------------------- device
    @property
    def device(self) -> torch.device:
        """Where the mixture's gate and experts live (the CPU before they are built)."""
        for param in self.parameters():
            return param.device
        for buffer in self.buffers():
            return buffer.device
        return torch.device("cpu")

    # ---------------------------------------------------------------- fitted
    @property
    @abc.abstractmethod
    def is_fitted(self) -> bool:
        """Whether the mixture has been fitted (implemented by subclasses)."""

    def check_fitted(self) -> None:
        """Raise `NotFittedError` unless the mixture has been fitted."""
        if not self.is_fitted:
            raise NotFittedError(self.not_fitted_message)

    def built_gate(self) -> SoftmaxGate:
        """The gate, once it has been created.

        Raises:
            NotFittedError: Before the mixture was built.
        """
        if self.gate is None:
            raise NotFittedError(self.not_fitted_message)
        return self.gate

    _built_gate = built_gate

    def features(self, X: Any) -> Tensor:
        """Validate a feature matrix for this fitted mixture.

        Args:
            X: Features, `(N, D)`.

        Returns:
            `X` as a float64 tensor on the mixture's device, `(N, D)`.

        Raises:
            NotFittedError: If the mixture is not fitted.
            InputError: For NaN/inf or a wrong number of columns.
        """
        self.check_fitted()
        if self.n_features is None:
            raise NotFittedError(self.not_fitted_message)
        return as_matrix("features X", X, n_cols=self.n_features, device=self.device)

    # ------------------------------------------------------------ prediction
    def gate_probs(self, X: Any) -> Tensor:
        """Gate probabilities `p(m = j | f)`.

        Args:
            X: Features, `(N, D)`.

        Returns:
            Rows summing to 1, `(N, M)`.
        """
        x = self.features(X)
        return self.built_gate().predict_proba(x[:, self.gate_columns])

    @abc.abstractmethod
    def expert_predictions(self, X: Any) -> Normal:
        """Every expert's predictive distribution, noise included (implemented by subclasses).

        Args:
            X: Features, `(N, D)`.

        Returns:
            Normals with loc and scale `(N, M, E)`.
        """

    def predict(self, X: Any, *, gating: str = "soft") -> MixtureSameFamily:
        """Predictive distribution of the effects, one mixture per sample.

        Args:
            X: Features, `(N, D)`.
            gating: ``"soft"`` (default) weights every expert by its gate probability (the
                model's predictive distribution); ``"hard"`` uses only the most probable
                expert of each sample (a one-component mixture, for comparison with models
                that pick one expert).

        Returns:
            Mixture over `M` of independent normals over `E`: batch shape `(N,)`,
            event shape `(E,)`, with `mean`, `variance`, `sample()` and `log_prob(Y)`.

        Raises:
            NotFittedError: If the mixture is not fitted.
            InputError: For an unknown `gating` or malformed `X`.
        """
        return mixture_distribution(
            gated_probs(self.gate_probs(X), gating), self.expert_predictions(X)
        )

    def predict_point(self, X: Any, *, mean: Tensor | None = None) -> Tensor:
        """The point prediction of the effects: here the predictive mean.

        `probaff.models.MixtureOfGPExperts` can stack it with a single GP (``point=``).

        Args:
            X: Features, `(N, D)`.
            mean: ``predict(X).mean``, when the caller has it already.

        Returns:
            `(N, E)` effects, in output units.
        """
        return self.predict(X).mean if mean is None else mean
