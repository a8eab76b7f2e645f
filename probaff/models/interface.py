"""The interface every push-effect model offers: a predictive distribution over effects."""

from __future__ import annotations

from typing import Any, Protocol, runtime_checkable

from torch import Tensor
from torch.distributions import Distribution

__all__ = ["PushModel", "point_prediction"]


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


def point_prediction(model: PushModel, X: Any, *, mean: Tensor | None = None) -> Tensor:
    """A push model's point prediction of the effects.

    The model's ``predict_point`` where it has one (a `MixtureOfGPExperts` with
    ``point="stacked"`` stacks its mean with a single GP), else its predictive mean.

    Args:
        model: A fitted push model.
        X: Features, `(N, D)`.
        mean: ``model.predict(X).mean`` when the caller has it already (saves a prediction).

    Returns:
        `(N, E)` effects.
    """
    predict_point = getattr(model, "predict_point", None)
    if callable(predict_point):
        out: Tensor = predict_point(X, mean=mean)
        return out
    return model.predict(X).mean if mean is None else mean
