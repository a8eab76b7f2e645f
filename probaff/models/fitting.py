"""A registry of the fitting procedures of push models, looked up by name.

``get_fitter("em")(model, X, Y, **options)`` fits `model` in place and returns what the
fitter returns (`fit_em`: an `EMHistory`; `fit_svi`: an `SVIHistory`; ``"clustered"``: the
model; ``"transition"``: a `TransitionHistory`, reactions passed as ``R=``). New procedures
are added with `register_fitter`.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, TypeVar

from probaff.errors import InputError
from probaff.models.clustered import ClusteredGPModel
from probaff.models.em import fit_em
from probaff.models.svi import fit_svi
from probaff.models.transition import fit_transition

__all__ = ["FITTERS", "fit_clustered", "get_fitter", "register_fitter"]

Fitter = Callable[..., Any]
"""``fitter(model, X, Y, **options)``: fits `model` in place on features `(N, D)` and effects
`(N, E)`."""

F = TypeVar("F", bound=Fitter)

FITTERS: dict[str, Fitter] = {}
"""Fitter of every registered name."""


def register_fitter(name: str) -> Callable[[F], F]:
    """Decorator that registers a fitter under `name` (replacing any earlier one).

    Args:
        name: The name `get_fitter` will know it by.

    Returns:
        A decorator that registers its function and returns it unchanged.

    Raises:
        InputError: If `name` is not a non-empty string.
    """
    if not isinstance(name, str) or not name:
        raise InputError(f"a fitter's name must be a non-empty string, got {name!r}.")

    def register(fitter: F) -> F:
        FITTERS[name] = fitter
        return fitter

    return register


def get_fitter(name: str) -> Fitter:
    """The fitter registered under `name`.

    Args:
        name: ``"em"``, ``"svi"``, ``"clustered"``, ``"transition"`` or a name given to
            `register_fitter`.

    Returns:
        ``fitter(model, X, Y, **options)``.

    Raises:
        InputError: For an unknown name; the message lists the known ones.
    """
    try:
        return FITTERS[name]
    except (KeyError, TypeError):
        known = ", ".join(repr(k) for k in sorted(FITTERS))
        raise InputError(f"unknown fitter {name!r}; known fitters: {known}.") from None


def fit_clustered(model: ClusteredGPModel, X: Any, Y: Any) -> ClusteredGPModel:
    """Fit chapter 4's clustered model (`ClusteredGPModel.fit`).

    Args:
        model: The model to fit.
        X: Features, `(N, D)`.
        Y: Effects, `(N, E)`.

    Returns:
        The fitted model.

    Raises:
        InputError: If `model` is not a `ClusteredGPModel`, or as `ClusteredGPModel.fit`.
    """
    if not isinstance(model, ClusteredGPModel):
        raise InputError(
            f"the 'clustered' fitter fits a ClusteredGPModel, got {type(model).__name__}."
        )
    return model.fit(X, Y)


register_fitter("em")(fit_em)
register_fitter("svi")(fit_svi)
register_fitter("clustered")(fit_clustered)
register_fitter("transition")(fit_transition)
