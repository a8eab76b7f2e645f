"""Chapter 6's per-skill transition model, with its backward (reaction) component.

See `probaff.models.transitions.transition` for the model family and `fit_transition`.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import torch
from torch import Tensor
from torch.distributions import Distribution, Independent, Normal

from probaff._checks import check_count
from probaff.errors import InputError, NotFittedError
from probaff.models.experts.gp_expert import GPExpert
from probaff.models.mixture.em import fit_em
from probaff.models.mixture.model import MixtureOfGPExperts
from probaff.models.options import EMOptions, GPOptions
from probaff.models.tensors import as_matrix
from probaff.models.transitions.transition_base import (
    COMPONENTS,
    DEFAULT_EXPERTS,
    KINDS,
    Component,
    TransitionBase,
    TransitionHistory,
    check_asked_skill,
    check_generator,
    component_predict,
    gp_objective,
    predict_moments,
    sample_effects,
    training_pair,
)

__all__ = ["SkillTransitionModel"]


class SkillTransitionModel(TransitionBase):
    r"""Transition model of one skill: interaction features to the object's effect.

    Maps interaction features `X (N, D)` to the object's displacement in the action frame
    `Y (N, E)` (E = 6 in general; any E >= 1, the caller chooses the columns). With
    ``kind="gp"`` every component is one `GPExpert` (E independent SE-ARD GPs) of the
    settings `gp`, whose hyperparameters start by default at the thesis's values, signal
    variance :math:`\theta_0` = ``gp.outputscale`` = 0.1 and noise = ``gp.noise`` = 0.1
    (standardised units, `TRANSITION_GP`); with ``kind="mixture"`` every component is a
    `MixtureOfGPExperts` of `n_experts` experts, gate and experts on the same inputs, fitted
    by `fit_em`, whose experts take `gp`'s `max_iter`, `lengthscale_prior` and `noise_floor`
    and start from `GPOptions`' default start values.

    With ``backward=True`` (default) the model has three components (`COMPONENTS`):
    ``"effect"`` (`X -> Y`), ``"reaction"`` (`[X, Y] -> R`, the end-effector's deviation
    from its commanded path, `(N, Er)`) and ``"corrected"`` (`[X, R] -> Y`); each is
    trained on observed data. `predict` chains them: :math:`Y_0` from `X`, `R` from
    :math:`[X, \bar Y_0]`, `Y` from :math:`[X, \bar R]`. With ``backward=False`` the
    model is the effect component alone.

    Args:
        skill: The skill, one of `SKILLS`.
        kind: ``"gp"`` (the thesis) or ``"mixture"``.
        backward: Add the reaction and corrected components.
        n_experts: Experts per mixture component (``kind="mixture"`` only; 3 if ``None``).
        gp: The GP settings of every component (`TransitionBase`); None for
            `TRANSITION_GP`, e.g. ``gp=GPOptions(max_iter=20, lengthscale_prior=True,
            noise_floor="auto", outputscale=0.1)``.
        **unexpected: Refused (`TransitionBase`): the old flat keywords ``gp_max_iter``,
            ``lengthscale_prior``, ``noise_floor``, ``outputscale`` and ``noise`` with an
            `InputError` naming the ``gp=GPOptions(...)`` to give.

    Attributes:
        components: The fitted components by name (empty before `fit_transition`).
        n_features: Features `D` (``None`` before fitting).
        n_outputs: Effect dimensions `E` (``None`` before fitting).
        n_reaction: Reaction dimensions `Er` (``None`` before fitting or without the
            backward component).

    Raises:
        InputError: For an unknown skill or kind, a non-integer count, `n_experts` with
            ``kind="gp"``, a `gp` that is not a `GPOptions`, or an old flat GP keyword.
    """

    def __init__(
        self,
        skill: str,
        *,
        kind: str = "gp",
        backward: bool = True,
        n_experts: int | None = None,
        gp: GPOptions | None = None,
        **unexpected: Any,
    ) -> None:
        super().__init__(skill, gp=gp, **unexpected)
        if kind not in KINDS:
            raise InputError(f"unknown kind {kind!r}; known kinds: {', '.join(map(repr, KINDS))}.")
        self.kind = kind
        if kind == "gp":
            if n_experts is not None and check_count("n_experts", n_experts) != 1:
                raise InputError(
                    f"n_experts={n_experts} needs kind='mixture'; the 'gp' kind is one GP."
                )
            self.n_experts = 1
        else:
            self.n_experts = check_count(
                "n_experts", DEFAULT_EXPERTS if n_experts is None else n_experts
            )
        self.backward = bool(backward)
        self.n_reaction: int | None = None
        self.train_R: Tensor | None = None

    # ----------------------------------------------------------------- config
    def config(self) -> dict[str, Any]:
        """Constructor arguments: ``SkillTransitionModel(**model.config())`` rebuilds it."""
        return {
            "skill": self.skill,
            "kind": self.kind,
            "backward": self.backward,
            "n_experts": None if self.kind == "gp" else self.n_experts,
            "gp": self.gp,
        }

    @property
    def is_fitted(self) -> bool:
        """Whether every component holds training data."""
        names = COMPONENTS if self.backward else COMPONENTS[:1]
        return (
            self.train_X is not None
            and all(n in self.components for n in names)
            and all(self.component(n).is_fitted for n in names)
        )

    def check_fitted(self) -> None:
        """Raise `NotFittedError` unless the model has been fitted."""
        if not self.is_fitted:
            raise NotFittedError(
                f"this {self.skill} SkillTransitionModel is not fitted; call "
                "probaff.models.fit_transition(model, X, Y, R) first."
            )

    def component(self, name: str) -> Component:
        """The component called `name` (one of `COMPONENTS`).

        Raises:
            InputError: For a name the model does not have.
        """
        if name not in self.components:
            raise InputError(
                f"this model has no component {name!r}; it has {sorted(self.components)}."
            )
        comp = self.components[name]
        assert isinstance(comp, (GPExpert, MixtureOfGPExperts))
        return comp

    # ------------------------------------------------------------- building
    def build(self, n_features: int, n_outputs: int, n_reaction: int | None = None) -> None:
        """Create fresh, unfitted components for the data sizes.

        Called by `fit_transition` (every fit starts from the same state) and by `load`.
        GP components start at ``gp.outputscale`` and ``gp.noise``.

        Args:
            n_features: Features `D`.
            n_outputs: Effect dimensions `E`.
            n_reaction: Reaction dimensions `Er`; required with the backward component, and
                must be ``None`` without it.

        Raises:
            InputError: For non-integer sizes, or `n_reaction` not matching `backward`.
        """
        d = check_count("n_features", n_features)
        e = check_count("n_outputs", n_outputs)
        if self.backward:
            if n_reaction is None:
                raise InputError("n_reaction is required: the model has a backward component.")
            er: int | None = check_count("n_reaction", n_reaction)
        elif n_reaction is not None:
            raise InputError("n_reaction must be None: the model has no backward component.")
        else:
            er = None
        sizes = {"effect": (d, e)}
        if er is not None:
            sizes.update(reaction=(d + e, er), corrected=(d + er, e))
        self.components = torch.nn.ModuleDict(
            {name: self._new_component(*size) for name, size in sizes.items()}
        )
        self.n_features, self.n_outputs, self.n_reaction = d, e, er
        self.train_X = self.train_Y = self.train_R = None

    def _new_component(self, n_inputs: int, n_targets: int) -> Component:
        if self.kind == "gp":
            return GPExpert(n_inputs, n_targets, self.gp)
        # The mixture's experts keep GPOptions' initial variances (not the GP component's).
        gp = GPOptions(
            max_iter=self.gp.max_iter,
            lengthscale_prior=self.gp.lengthscale_prior,
            noise_floor=self.gp.noise_floor,
        )
        return MixtureOfGPExperts(self.n_experts, gp=gp)

    def check_data(self, X: Any, Y: Any, R: Any = None) -> tuple[Tensor, Tensor, Tensor | None]:
        """Validate a training set and (re)build the components for its sizes.

        Args:
            X: Features, `(N, D)`.
            Y: Effects in the action frame, `(N, E)`.
            R: Reactions, `(N, Er)`: required with the backward component, refused without.

        Returns:
            `X`, `Y` and `R` (or ``None``) as float64 tensors.

        Raises:
            InputError: For NaN/inf, empty or mismatched inputs, fewer than 2 samples, a
                missing or unexpected `R`, or more experts than samples.
        """
        x, y = training_pair(X, Y)
        n = x.shape[0]
        r: Tensor | None = None
        if self.backward:
            if R is None:
                raise InputError(
                    "reactions R are required: the model has a backward component "
                    "(backward=True); pass R (N, Er) or build the model with backward=False."
                )
            r = as_matrix("reactions R", R)
            if r.shape[0] != n:
                raise InputError(
                    f"reactions R has {r.shape[0]} samples but features X has {n}; "
                    "they must have one row per interaction."
                )
        elif R is not None:
            raise InputError(
                "reactions R were given but the model has no backward component "
                "(backward=False); pass R=None or build the model with backward=True."
            )
        if self.n_experts > n:
            raise InputError(
                f"n_experts={self.n_experts} exceeds the {n} training samples; "
                "use fewer experts or more data."
            )
        self.build(x.shape[1], y.shape[1], None if r is None else r.shape[1])
        return x, y, r

    def component_data(
        self, X: Tensor, Y: Tensor, R: Tensor | None
    ) -> Iterator[tuple[str, Tensor, Tensor]]:
        """Inputs and targets of every component on a training set.

        Args:
            X: Features, `(N, D)`.
            Y: Effects, `(N, E)`.
            R: Reactions, `(N, Er)`, or ``None`` without the backward component.

        Yields:
            `(name, inputs, targets)`: ``"effect"`` `(N, D) -> (N, E)`, then with the
            backward component ``"reaction"`` `(N, D + E) -> (N, Er)` and ``"corrected"``
            `(N, D + Er) -> (N, E)`.
        """
        yield "effect", X, Y
        if R is not None:
            yield "reaction", torch.cat([X, Y], dim=1), R
            yield "corrected", torch.cat([X, R], dim=1), Y

    def fit_components(
        self, X: Tensor, Y: Tensor, R: Tensor | None, options: EMOptions | None = None
    ) -> TransitionHistory:
        """Fit every component on its observed inputs and targets (called by `fit_transition`).

        Args:
            X: Features, `(N, D)`, as returned by `check_data`.
            Y: Effects, `(N, E)`.
            R: Reactions, `(N, Er)`, or ``None`` without the backward component.
            options: The EM settings of mixture components; None for `EMOptions()`.

        Returns:
            The history of the fit.
        """
        history = TransitionHistory(n_samples=int(X.shape[0]))
        for name, inputs, targets in self.component_data(X, Y, R):
            comp = self.component(name)
            if isinstance(comp, GPExpert):
                comp.fit(inputs, targets)  # its noise floor resolved from the targets
                history.objective[name] = gp_objective(comp)
            else:
                em = fit_em(comp, inputs, targets, options)
                history.em[name] = em
                history.objective[name] = em.best / X.shape[0]
        self.train_X, self.train_Y, self.train_R = X, Y, R
        return history

    def condition(
        self, X: Tensor, Y: Tensor, R: Tensor | None, weights: dict[str, Tensor] | None = None
    ) -> None:
        """Give every built component its training data without changing hyperparameters.

        Used by `load`, before the saved state dict is restored.

        Args:
            X: Features, `(N, D)`.
            Y: Effects, `(N, E)`.
            R: Reactions, `(N, Er)`, or ``None`` without the backward component.
            weights: Sample weights `(N, M)` of every mixture component, by name.

        Raises:
            InputError: If the weights of a mixture component are missing.
        """
        for name, inputs, targets in self.component_data(X, Y, R):
            comp = self.component(name)
            if isinstance(comp, GPExpert):
                comp.condition(inputs, targets)
            else:
                if weights is None or name not in weights:
                    raise InputError(
                        f"the sample weights of mixture component {name!r} are missing."
                    )
                comp.build(inputs.shape[1], targets.shape[1], n_samples=inputs.shape[0])
                comp.condition(inputs, targets, weights[name])
        self.train_X, self.train_Y, self.train_R = X, Y, R

    def component_weights(self) -> dict[str, Tensor]:
        """Sample weights `(N, M)` of every mixture component, by name (empty for GPs)."""
        return {
            name: comp.train_weights
            for name, comp in self.components.items()
            if isinstance(comp, MixtureOfGPExperts)
        }

    # ------------------------------------------------------------ prediction
    def _features(self, X: Any, skill: Any) -> Tensor:
        check_asked_skill(self.skill, skill)
        self.check_fitted()
        return as_matrix("features X", X, n_cols=self.n_features)

    def _reaction(self, x: Tensor) -> Distribution:
        y0 = component_predict(self.component("effect"), x).mean
        return component_predict(self.component("reaction"), torch.cat([x, y0], dim=1))

    def predict(
        self,
        X: Any,
        *,
        skill: str | None = None,
        n_samples: int | None = None,
        generator: torch.Generator | None = None,
    ) -> Distribution:
        r"""Predictive distribution of the effect `Y`.

        Without `n_samples`, the chain of means: :math:`Y_0` from `X`, `R` from
        :math:`[X, \bar Y_0]`, and the corrected component's prediction at
        :math:`[X, \bar R]` (without the backward component, the effect component's
        prediction). With `n_samples = S`, `S` draws :math:`R_s` of the reaction's
        predictive distribution at :math:`[X, \bar Y_0]` each give a prediction of `Y`
        from :math:`[X, R_s]`, with mean :math:`\mu_s` and variance :math:`v_s`; the
        result is the moment-matched independent normal with mean
        :math:`\frac1S \sum_s \mu_s` and variance
        :math:`\frac1S \sum_s v_s + \frac1S \sum_s (\mu_s - \bar\mu)^2` (the law of total
        variance), which carries the reaction's uncertainty into the effect.

        Args:
            X: Features, `(N, D)`.
            skill: The skill asked for; an error if it is not the model's (``None``: no
                check).
            n_samples: Number of reaction draws `S` (needs the backward component).
            generator: Source of the draws; a fresh generator seeded with 0 if ``None``,
                so that the result is deterministic.

        Returns:
            Batch shape `(N,)`, event shape `(E,)`: an `Independent` `Normal` for GP
            components and for sampled predictions, a `MixtureSameFamily` for mixture
            components.

        Raises:
            NotFittedError: If the model is not fitted.
            InputError: For malformed `X`, another or unknown skill, a non-integer
                `n_samples`, or `n_samples` without the backward component.
        """
        x = self._features(X, skill)
        if n_samples is not None:
            s = check_count("n_samples", n_samples)
            if not self.backward:
                raise InputError(
                    "n_samples draws the reaction, but this model has no backward component "
                    "(backward=False); predict without n_samples."
                )
            return self._sampled(x, s, check_generator(generator))
        if not self.backward:
            return component_predict(self.component("effect"), x)
        r = self._reaction(x).mean
        return component_predict(self.component("corrected"), torch.cat([x, r], dim=1))

    def _sampled(self, x: Tensor, n_samples: int, generator: torch.Generator) -> Independent:
        n, d = x.shape
        r = sample_effects(self._reaction(x), n_samples, generator)  # (S, N, Er)
        inputs = torch.cat([x.expand(n_samples, n, d), r], dim=2).reshape(n_samples * n, -1)
        mean, variance = predict_moments(self.component("corrected"), inputs)
        mu = mean.reshape(n_samples, n, -1)
        var = variance.reshape(n_samples, n, -1).mean(0) + mu.var(0, correction=0)
        return Independent(Normal(mu.mean(0), var.sqrt()), 1)

    def predict_reaction(self, X: Any, *, skill: str | None = None) -> Distribution:
        r"""Predictive distribution of the reaction `R` at :math:`[X, \bar Y_0]`.

        Args:
            X: Features, `(N, D)`.
            skill: The skill asked for (``None``: no check).

        Returns:
            Batch shape `(N,)`, event shape `(Er,)`.

        Raises:
            NotFittedError: If the model is not fitted.
            InputError: For malformed `X`, another or unknown skill, or a model without the
                backward component.
        """
        if not self.backward:
            raise InputError(
                "this model has no backward component (backward=False), so it does not "
                "predict reactions; build it with backward=True."
            )
        return self._reaction(self._features(X, skill))
