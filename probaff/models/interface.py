"""The interface every push-effect model offers: a predictive distribution over effects."""

from __future__ import annotations

from typing import Any, Protocol, runtime_checkable

from torch.distributions import Distribution

__all__ = ["PushModel"]


@runtime_checkable
class PushModel(Protocol):
    """A fitted model of push effects `e` given features `f`.

    Implemented by `MixtureOfGPExperts`, `VariationalMixtureOfGPExperts` and
    `ClusteredGPModel`; ``isinstance(model, PushModel)`` checks that the members exist.

    Attributes:
        n_outputs: Effect dimensions `E` (``None`` before the model is fitted).
    """

    @property
    def n_outputs(self) -> int | None:
        """Effect dimensions `E`; ``None`` before the model is fitted."""
        ...

    def predict(self, X: Any) -> Distribution:
        """Predictive distribution of the effects.

        Args:
            X: Features, `(N, D)`.

        Returns:
            Batch shape `(N,)`, event shape `(E,)`, with `mean`, `variance` and `log_prob`.
        """
        ...
