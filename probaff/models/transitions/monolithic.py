"""The thesis's monolithic baseline: one GP on whole scenes of a fixed number of objects.

See `probaff.models.transitions.transition` for the model family and `fit_transition`.
"""

from __future__ import annotations

from typing import Any

import torch
from torch import Tensor
from torch.distributions import Independent

from probaff._checks import check_count
from probaff.errors import InputError, NotFittedError
from probaff.models.experts.gp_expert import GPExpert
from probaff.models.options import GPOptions
from probaff.models.tensors import as_matrix
from probaff.models.transitions.transition_base import (
    MONOLITHIC_NOT_FITTED,
    TransitionBase,
    TransitionHistory,
    check_asked_skill,
    gp_objective,
    training_pair,
)

__all__ = ["MonolithicTransitionModel"]


class MonolithicTransitionModel(TransitionBase):
    r"""The thesis's monolithic baseline: one GP from a whole scene to every object's effect.

    Trained on scenes of exactly `n_objects` objects: scene features `X (N, D)` map to the
    effects of all objects at once, `Y (N, n_objects * E)` (object `k`'s effect in columns
    `k E .. (k + 1) E - 1`), with one `GPExpert` of `n_objects * E` outputs. It has no
    backward component, and it cannot predict a scene with another number of objects (whose
    features have another width), which the modular `SkillTransitionModel` chains can.

    Args:
        n_objects: Objects per scene.
        skill: The skill, one of `SKILLS`.
        gp: The GP's settings (`TransitionBase`); None for `TRANSITION_GP`.
        **unexpected: Refused (`TransitionBase`): the old flat keywords ``gp_max_iter``,
            ``lengthscale_prior``, ``noise_floor``, ``outputscale`` and ``noise`` with an
            `InputError` naming the ``gp=GPOptions(...)`` to give.

    Attributes:
        components: ``{"effect": GPExpert}`` once fitted.
        n_features: Scene features `D` (``None`` before fitting).
        n_outputs: Effect columns `n_objects * E` (``None`` before fitting).

    Raises:
        InputError: For an unknown skill, a non-integer count, a `gp` that is not a
            `GPOptions`, or an old flat GP keyword.
    """

    def __init__(
        self,
        n_objects: int = 2,
        *,
        skill: str = "push",
        gp: GPOptions | None = None,
        **unexpected: Any,
    ) -> None:
        super().__init__(skill, gp=gp, **unexpected)
        self.n_objects = check_count("n_objects", n_objects)

    def config(self) -> dict[str, Any]:
        """Constructor arguments: ``MonolithicTransitionModel(**model.config())`` rebuilds it."""
        return {
            "n_objects": self.n_objects,
            "skill": self.skill,
            "gp": self.gp,
        }

    @property
    def effect_size(self) -> int | None:
        """Effect dimensions `E` of one object (``None`` before fitting)."""
        return None if self.n_outputs is None else self.n_outputs // self.n_objects

    @property
    def expert(self) -> GPExpert:
        """The scene GP.

        Raises:
            NotFittedError: Before the model was built.
        """
        if "effect" not in self.components:
            raise NotFittedError(MONOLITHIC_NOT_FITTED)
        comp = self.components["effect"]
        assert isinstance(comp, GPExpert)
        return comp

    @property
    def is_fitted(self) -> bool:
        """Whether the scene GP holds training data."""
        return "effect" in self.components and self.expert.is_fitted and self.train_X is not None

    def check_fitted(self) -> None:
        """Raise `NotFittedError` unless the model has been fitted."""
        if not self.is_fitted:
            raise NotFittedError(MONOLITHIC_NOT_FITTED)

    def build(self, n_features: int, n_outputs: int) -> None:
        """Create a fresh, unfitted scene GP for the data sizes.

        Args:
            n_features: Scene features `D`.
            n_outputs: Effect columns, a multiple of `n_objects`.

        Raises:
            InputError: For non-integer sizes or effect columns not divisible by
                `n_objects`.
        """
        d = check_count("n_features", n_features)
        e = check_count("n_outputs", n_outputs)
        if e % self.n_objects:
            raise InputError(
                f"effects Y has {e} columns, which is not n_objects={self.n_objects} times an "
                "object's effect size; give every object's effect, object after object."
            )
        self.components = torch.nn.ModuleDict({"effect": GPExpert(d, e, self.gp)})
        self.n_features, self.n_outputs = d, e
        self.train_X = self.train_Y = None

    def check_data(self, X: Any, Y: Any) -> tuple[Tensor, Tensor]:
        """Validate a training set of whole scenes and (re)build the GP for its sizes.

        Args:
            X: Scene features, `(N, D)`.
            Y: Effects of every object, `(N, n_objects * E)`.

        Returns:
            `X` and `Y` as float64 tensors.

        Raises:
            InputError: For NaN/inf, empty or mismatched inputs, fewer than 2 samples or
                effect columns not divisible by `n_objects`.
        """
        x, y = training_pair(X, Y)
        self.build(x.shape[1], y.shape[1])
        return x, y

    def fit_components(self, X: Tensor, Y: Tensor) -> TransitionHistory:
        """Fit the scene GP (called by `fit_transition`).

        Args:
            X: Scene features, `(N, D)`, as returned by `check_data`.
            Y: Effects of every object, `(N, n_objects * E)`.

        Returns:
            The history of the fit.
        """
        expert = self.expert
        expert.fit(X, Y)  # its noise floor resolved from the targets
        self.train_X, self.train_Y = X, Y
        return TransitionHistory(
            objective={"effect": gp_objective(expert)}, n_samples=int(X.shape[0])
        )

    def condition(self, X: Tensor, Y: Tensor) -> None:
        """Give the built GP its training data without changing hyperparameters (for `load`).

        Args:
            X: Scene features, `(N, D)`.
            Y: Effects of every object, `(N, n_objects * E)`.
        """
        self.expert.condition(X, Y)
        self.train_X, self.train_Y = X, Y

    def predict(self, X: Any, *, skill: str | None = None) -> Independent:
        """Predictive distribution of every object's effect in a scene.

        Args:
            X: Scene features, `(N, D)`, of scenes of `n_objects` objects.
            skill: The skill asked for (``None``: no check).

        Returns:
            Independent normals, batch shape `(N,)`, event shape `(n_objects * E,)`.

        Raises:
            NotFittedError: If the model is not fitted.
            InputError: For another or unknown skill, NaN/inf, or a feature width other
                than the training scenes' (a scene of another size).
        """
        check_asked_skill(self.skill, skill)
        self.check_fitted()
        x = as_matrix("features X", X)
        if x.shape[1] != self.n_features:
            raise InputError(
                f"features X has {x.shape[1]} columns but this monolithic model was trained on "
                f"scenes of {self.n_objects} objects with {self.n_features} features; it cannot "
                "predict a scene of another size. Use a SkillTransitionModel per object instead."
            )
        return Independent(self.expert.predict(x), 1)
