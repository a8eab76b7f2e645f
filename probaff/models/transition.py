r"""Chapter 6's modular transition models: one model per skill, with a backward component.

A `SkillTransitionModel` predicts the effect of ONE skill (push, pick or place) on one
object: the object's displacement in the action frame `Y (N, E)` given interaction features
`X (N, D)` (shape, relative pose, contact and action features). It is a multi-output ARD GP
(``kind="gp"``, the thesis's model) or a mixture of GP experts fitted by EM
(``kind="mixture"``). With its backward component (``backward=True``) it also models the
end-effector's deviation from its commanded path, the reaction `R (N, Er)`:

* the effect component predicts :math:`Y_0` from `X`;
* the reaction component predicts `R` from :math:`[X, Y]`, so at prediction time from
  :math:`[X, \bar Y_0]`;
* the corrected component predicts the final `Y` from :math:`[X, R]`, at prediction time
  from :math:`[X, \bar R]`, or from samples of `R` to carry its uncertainty into `Y`.

A predicted object trajectory becomes the action on the next object, so chains of objects
need no new model. `MonolithicTransitionModel` is the thesis's baseline: one GP on whole
scenes of a fixed number of objects, which cannot predict a scene of another size. Both are
fitted by `fit_transition`.
"""

from __future__ import annotations

import inspect
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any

import torch
from torch import Tensor
from torch.distributions import Distribution, Independent, MixtureSameFamily, Normal

from probaff._checks import check_count, check_positive
from probaff.errors import InputError, NotFittedError
from probaff.models._tensors import as_matrix
from probaff.models.em import EMHistory, fit_em
from probaff.models.gp_expert import GPExpert, exact_gp_settings
from probaff.models.mixture import MixtureOfGPExperts

__all__ = [
    "COMPONENTS",
    "KINDS",
    "SKILLS",
    "MonolithicTransitionModel",
    "SkillTransitionModel",
    "TransitionHistory",
    "fit_transition",
]

SKILLS: tuple[str, ...] = ("pick", "place", "push")
"""The skills a transition model can be trained for."""

KINDS: tuple[str, ...] = ("gp", "mixture")
"""Kinds of components: one multi-output ARD GP, or a mixture of GP experts."""

COMPONENTS: tuple[str, ...] = ("effect", "reaction", "corrected")
"""Component names: the effect `X -> Y`, the reaction `[X, Y] -> R` and the corrected
effect `[X, R] -> Y` (the last two only with a backward component)."""

# Noise floor of `noise_floor="auto"` as a fraction of each target's standard deviation
# (the value `MixtureOfGPExperts` uses).
_AUTO_NOISE_FLOOR = 0.01

# Experts of `kind="mixture"` when `n_experts` is not given (chapter 5's best M).
_DEFAULT_EXPERTS = 3

# Seed of the sampled prediction when no generator is given.
_DEFAULT_SEED = 0

# Rows per call to a component's `predict` in sampled predictions (an exact GP's prediction
# of n rows costs O(n^2) memory, so S * N rows at once would not scale).
_PREDICT_ROWS = 1024

# Options `fit_transition` passes on to `fit_em` for mixture components.
_EM_OPTIONS = frozenset(inspect.signature(fit_em).parameters) - {"model", "X", "Y"}

_MONOLITHIC_NOT_FITTED = (
    "this MonolithicTransitionModel is not fitted; call "
    "probaff.models.fit_transition(model, X, Y) first."
)

Component = GPExpert | MixtureOfGPExperts
"""A component of a transition model: one multi-output GP or a mixture of GP experts."""


# ------------------------------------------------------------------ helpers
def _check_skill(name: str, skill: Any) -> str:
    """`skill` if it is a known skill name, else `InputError` listing the known ones."""
    if not isinstance(skill, str) or skill not in SKILLS:
        known = ", ".join(repr(s) for s in SKILLS)
        raise InputError(f"unknown {name} {skill!r}; known skills: {known}.")
    return skill


def _check_asked_skill(own: str, skill: Any) -> None:
    """Refuse a prediction for another skill than the model's own (``None`` skips it)."""
    if skill is None:
        return
    asked = _check_skill("skill", skill)
    if asked != own:
        raise InputError(f"a {own} model cannot predict {asked}; use the {asked} model.")


def _check_noise_floor(noise_floor: Any) -> float | str | None:
    """The noise floor argument as ``"auto"``, ``None`` or a non-negative float."""
    if noise_floor is None or (isinstance(noise_floor, str) and noise_floor == "auto"):
        return noise_floor
    if isinstance(noise_floor, str):
        raise InputError(
            f"noise_floor must be 'auto', None or a standard deviation >= 0, got {noise_floor!r}."
        )
    check_positive("noise_floor", noise_floor, allow_zero=True)
    return float(noise_floor)


def _resolve_noise_floor(noise_floor: float | str | None, targets: Tensor) -> Tensor:
    """Noise floor of a GP component with training targets `(N, C)`, in their units, `(C,)`."""
    if noise_floor is None:
        return torch.zeros(targets.shape[1], dtype=torch.float64)
    if isinstance(noise_floor, str):
        return _AUTO_NOISE_FLOOR * targets.std(dim=0, correction=0)
    return torch.full((targets.shape[1],), noise_floor, dtype=torch.float64)


def _component_predict(component: Component, x: Tensor) -> Distribution:
    """Predictive distribution of a component at inputs `x: (N, C)`: batch `(N,)`, event `(E,)`."""
    if isinstance(component, GPExpert):
        return Independent(component.predict(x), 1)
    return component.predict(x)


def _predict_moments(component: Component, x: Tensor) -> tuple[Tensor, Tensor]:
    """Predictive mean and variance of a component at many inputs `x: (n, C)`, `(n, E)` each.

    The rows are predicted `_PREDICT_ROWS` at a time.
    """
    means, variances = [], []
    for rows in torch.split(x, _PREDICT_ROWS):
        pred = _component_predict(component, rows)
        means.append(pred.mean)
        variances.append(pred.variance)
    return torch.cat(means), torch.cat(variances)


def _sample(dist: Distribution, n_samples: int, generator: torch.Generator) -> Tensor:
    """Draw `n_samples` values from a component's prediction with `generator`.

    Args:
        dist: Independent normals (loc `(N, E)`), or a mixture of them (loc `(N, M, E)`).
        n_samples: Number of draws `S`.
        generator: Source of randomness.

    Returns:
        Samples, `(S, N, E)`.
    """
    if isinstance(dist, MixtureSameFamily):
        probs = dist.mixture_distribution.probs  # (N, M)
        normal = dist.component_distribution.base_dist  # type: ignore[attr-defined]
        pick = torch.multinomial(probs, n_samples, replacement=True, generator=generator)
        rows = torch.arange(probs.shape[0])[:, None]
        loc = normal.loc[rows, pick].transpose(0, 1)  # (S, N, E)
        scale = normal.scale[rows, pick].transpose(0, 1)
    else:
        normal = dist.base_dist  # type: ignore[attr-defined]
        loc = normal.loc.expand(n_samples, *normal.loc.shape)
        scale = normal.scale.expand_as(loc)
    eps = torch.randn(loc.shape, generator=generator, dtype=loc.dtype)
    return loc + scale * eps


def _gp_objective(expert: GPExpert) -> float:
    """Log marginal likelihood per sample, summed over the expert's outputs."""
    with torch.no_grad(), exact_gp_settings(float(expert.jitter)):
        return float(expert.marginal_log_likelihood().sum())


def _training_pair(X: Any, Y: Any) -> tuple[Tensor, Tensor]:
    """Validate features `(N, D)` and effects `(N, E)` of a training set with N >= 2."""
    x = as_matrix("features X", X)
    y = as_matrix("effects Y", Y)
    if y.shape[0] != x.shape[0]:
        raise InputError(
            f"features X has {x.shape[0]} samples but effects Y has {y.shape[0]}; "
            "they must have one row per interaction."
        )
    if x.shape[0] < 2:
        raise InputError(f"a transition model needs at least 2 training samples, got {x.shape[0]}.")
    return x, y


def _check_generator(generator: Any) -> torch.Generator:
    """`generator`, or a fresh one seeded with `_DEFAULT_SEED` when it is ``None``."""
    if generator is None:
        return torch.Generator().manual_seed(_DEFAULT_SEED)
    if not isinstance(generator, torch.Generator):
        raise InputError(
            f"generator must be a torch.Generator or None, got {type(generator).__name__}."
        )
    return generator


# ------------------------------------------------------------------ history
@dataclass
class TransitionHistory:
    """Record of one `fit_transition`.

    Attributes:
        objective: Training objective per sample of every fitted component, by name (see
            `COMPONENTS`): for a GP its log marginal likelihood summed over outputs
            (`GPExpert.marginal_log_likelihood`), for a mixture its EM objective
            (`EMHistory.best`) over the number of samples.
        em: The `EMHistory` of every mixture component (empty for GP components).
        n_samples: Number of training samples `N`.
    """

    objective: dict[str, float] = field(default_factory=dict)
    em: dict[str, EMHistory] = field(default_factory=dict)
    n_samples: int = 0


# ------------------------------------------------------------- skill model
class _TransitionBase(torch.nn.Module):
    """What both transition models hold: the skill, the GP settings and the training data."""

    def __init__(
        self,
        skill: str,
        *,
        gp_max_iter: int,
        lengthscale_prior: bool,
        noise_floor: float | str | None,
        outputscale: float,
        noise: float,
    ) -> None:
        super().__init__()
        self.skill = _check_skill("skill", skill)
        self.gp_max_iter = check_count("gp_max_iter", gp_max_iter)
        self.lengthscale_prior = bool(lengthscale_prior)
        self.noise_floor = _check_noise_floor(noise_floor)
        # GPExpert validates the start values; build one now so that errors come early.
        GPExpert(1, 1, outputscale=outputscale, noise=noise)
        self.outputscale = float(outputscale)
        self.noise = float(noise)
        self.components = torch.nn.ModuleDict()
        self.n_features: int | None = None
        self.n_outputs: int | None = None
        self.train_X: Tensor | None = None
        self.train_Y: Tensor | None = None

    def _gp_config(self) -> dict[str, Any]:
        """The GP settings as constructor arguments."""
        return {
            "gp_max_iter": self.gp_max_iter,
            "lengthscale_prior": self.lengthscale_prior,
            "noise_floor": self.noise_floor,
            "outputscale": self.outputscale,
            "noise": self.noise,
        }


class SkillTransitionModel(_TransitionBase):
    r"""Transition model of one skill: interaction features to the object's effect.

    Maps interaction features `X (N, D)` to the object's displacement in the action frame
    `Y (N, E)` (E = 6 in general; any E >= 1, the caller chooses the columns). With
    ``kind="gp"`` every component is one `GPExpert` (E independent SE-ARD GPs) whose
    hyperparameters start at the thesis's values, signal variance
    :math:`\theta_0` = `outputscale` = 0.1 and noise = 0.1 (standardised units); with
    ``kind="mixture"`` every component is a `MixtureOfGPExperts` of `n_experts` experts,
    gate and experts on the same inputs, fitted by `fit_em` (from `GPExpert`'s default
    start values).

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
        gp_max_iter: L-BFGS iterations of each GP fit.
        lengthscale_prior: Put `GPExpert`'s dimension-scaled prior on the length scales.
        noise_floor: Smallest observation-noise standard deviation of every component, in
            its targets' units: ``"auto"`` (default; 1 % of each target's standard
            deviation over the training set), ``None`` (no floor) or one number >= 0.
        outputscale: Initial signal variance :math:`\theta_0` of the GP components.
        noise: Initial noise variance of the GP components.

    Attributes:
        components: The fitted components by name (empty before `fit_transition`).
        n_features: Features `D` (``None`` before fitting).
        n_outputs: Effect dimensions `E` (``None`` before fitting).
        n_reaction: Reaction dimensions `Er` (``None`` before fitting or without the
            backward component).

    Raises:
        InputError: For an unknown skill or kind, a non-integer count, `n_experts` with
            ``kind="gp"``, or a malformed noise floor or start value.
    """

    def __init__(
        self,
        skill: str,
        *,
        kind: str = "gp",
        backward: bool = True,
        n_experts: int | None = None,
        gp_max_iter: int = 50,
        lengthscale_prior: bool = False,
        noise_floor: float | str | None = "auto",
        outputscale: float = 0.1,
        noise: float = 0.1,
    ) -> None:
        super().__init__(
            skill,
            gp_max_iter=gp_max_iter,
            lengthscale_prior=lengthscale_prior,
            noise_floor=noise_floor,
            outputscale=outputscale,
            noise=noise,
        )
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
                "n_experts", _DEFAULT_EXPERTS if n_experts is None else n_experts
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
            **self._gp_config(),
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
        GP components start at `outputscale` and `noise`.

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
            return GPExpert(
                n_inputs,
                n_targets,
                max_iter=self.gp_max_iter,
                lengthscale_prior=self.lengthscale_prior,
                outputscale=self.outputscale,
                noise=self.noise,
            )
        return MixtureOfGPExperts(
            self.n_experts,
            gp_max_iter=self.gp_max_iter,
            lengthscale_prior=self.lengthscale_prior,
            noise_floor=self.noise_floor,
        )

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
        x, y = _training_pair(X, Y)
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
        self, X: Tensor, Y: Tensor, R: Tensor | None, **options: Any
    ) -> TransitionHistory:
        """Fit every component on its observed inputs and targets (called by `fit_transition`).

        Args:
            X: Features, `(N, D)`, as returned by `check_data`.
            Y: Effects, `(N, E)`.
            R: Reactions, `(N, Er)`, or ``None`` without the backward component.
            **options: Passed to `fit_em` for mixture components.

        Returns:
            The history of the fit.
        """
        history = TransitionHistory(n_samples=int(X.shape[0]))
        for name, inputs, targets in self.component_data(X, Y, R):
            comp = self.component(name)
            if isinstance(comp, GPExpert):
                comp.noise_floor.copy_(_resolve_noise_floor(self.noise_floor, targets))
                comp.fit(inputs, targets)
                history.objective[name] = _gp_objective(comp)
            else:
                em = fit_em(comp, inputs, targets, **options)
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
                comp.build(inputs.shape[1], targets.shape[1])
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
        _check_asked_skill(self.skill, skill)
        self.check_fitted()
        return as_matrix("features X", X, n_cols=self.n_features)

    def _reaction(self, x: Tensor) -> Distribution:
        y0 = _component_predict(self.component("effect"), x).mean
        return _component_predict(self.component("reaction"), torch.cat([x, y0], dim=1))

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
            return self._sampled(x, s, _check_generator(generator))
        if not self.backward:
            return _component_predict(self.component("effect"), x)
        r = self._reaction(x).mean
        return _component_predict(self.component("corrected"), torch.cat([x, r], dim=1))

    def _sampled(self, x: Tensor, n_samples: int, generator: torch.Generator) -> Independent:
        n, d = x.shape
        r = _sample(self._reaction(x), n_samples, generator)  # (S, N, Er)
        inputs = torch.cat([x.expand(n_samples, n, d), r], dim=2).reshape(n_samples * n, -1)
        mean, variance = _predict_moments(self.component("corrected"), inputs)
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


# -------------------------------------------------------- monolithic model
class MonolithicTransitionModel(_TransitionBase):
    r"""The thesis's monolithic baseline: one GP from a whole scene to every object's effect.

    Trained on scenes of exactly `n_objects` objects: scene features `X (N, D)` map to the
    effects of all objects at once, `Y (N, n_objects * E)` (object `k`'s effect in columns
    `k E .. (k + 1) E - 1`), with one `GPExpert` of `n_objects * E` outputs. It has no
    backward component, and it cannot predict a scene with another number of objects (whose
    features have another width), which the modular `SkillTransitionModel` chains can.

    Args:
        n_objects: Objects per scene.
        skill: The skill, one of `SKILLS`.
        gp_max_iter: L-BFGS iterations of the GP fit.
        lengthscale_prior: Put `GPExpert`'s dimension-scaled prior on the length scales.
        noise_floor: As `SkillTransitionModel`.
        outputscale: Initial signal variance :math:`\theta_0`.
        noise: Initial noise variance.

    Attributes:
        components: ``{"effect": GPExpert}`` once fitted.
        n_features: Scene features `D` (``None`` before fitting).
        n_outputs: Effect columns `n_objects * E` (``None`` before fitting).

    Raises:
        InputError: For an unknown skill, a non-integer count, or a malformed noise floor
            or start value.
    """

    def __init__(
        self,
        n_objects: int = 2,
        *,
        skill: str = "push",
        gp_max_iter: int = 50,
        lengthscale_prior: bool = False,
        noise_floor: float | str | None = "auto",
        outputscale: float = 0.1,
        noise: float = 0.1,
    ) -> None:
        super().__init__(
            skill,
            gp_max_iter=gp_max_iter,
            lengthscale_prior=lengthscale_prior,
            noise_floor=noise_floor,
            outputscale=outputscale,
            noise=noise,
        )
        self.n_objects = check_count("n_objects", n_objects)

    def config(self) -> dict[str, Any]:
        """Constructor arguments: ``MonolithicTransitionModel(**model.config())`` rebuilds it."""
        return {
            "n_objects": self.n_objects,
            "skill": self.skill,
            **self._gp_config(),
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
            raise NotFittedError(_MONOLITHIC_NOT_FITTED)
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
            raise NotFittedError(_MONOLITHIC_NOT_FITTED)

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
        self.components = torch.nn.ModuleDict(
            {
                "effect": GPExpert(
                    d,
                    e,
                    max_iter=self.gp_max_iter,
                    lengthscale_prior=self.lengthscale_prior,
                    outputscale=self.outputscale,
                    noise=self.noise,
                )
            }
        )
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
        x, y = _training_pair(X, Y)
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
        expert.noise_floor.copy_(_resolve_noise_floor(self.noise_floor, Y))
        expert.fit(X, Y)
        self.train_X, self.train_Y = X, Y
        return TransitionHistory(
            objective={"effect": _gp_objective(expert)}, n_samples=int(X.shape[0])
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
        _check_asked_skill(self.skill, skill)
        self.check_fitted()
        x = as_matrix("features X", X)
        if x.shape[1] != self.n_features:
            raise InputError(
                f"features X has {x.shape[1]} columns but this monolithic model was trained on "
                f"scenes of {self.n_objects} objects with {self.n_features} features; it cannot "
                "predict a scene of another size. Use a SkillTransitionModel per object instead."
            )
        return Independent(self.expert.predict(x), 1)


# ----------------------------------------------------------------- fitting
def fit_transition(
    model: SkillTransitionModel | MonolithicTransitionModel,
    X: Any,
    Y: Any,
    R: Any = None,
    **options: Any,
) -> TransitionHistory:
    """Fit a transition model in place, every component on its observed data.

    A `SkillTransitionModel`'s effect component learns `X -> Y`; with its backward
    component, the reaction component learns the observed `[X, Y] -> R` and the corrected
    component the observed `[X, R] -> Y`. A `MonolithicTransitionModel` learns whole scenes
    `X -> Y` (no reactions). Every fit starts from freshly built components, so it is
    deterministic.

    Args:
        model: The model to fit.
        X: Features, `(N, D)`, N >= 2.
        Y: Effects in the action frame, `(N, E)` (monolithic: `(N, n_objects * E)`).
        R: Reactions (end-effector deviations), `(N, Er)`: required for a model with a
            backward component, refused otherwise.
        **options: For ``kind="mixture"``, options of `fit_em` (e.g. ``seed``,
            ``max_iter``, ``n_restarts``); GP components take none.

    Returns:
        The history of the fit.

    Raises:
        InputError: For a model of another class, malformed data (NaN/inf, wrong or
            mismatched shapes, fewer than 2 samples), a missing or unexpected `R`, or
            unknown options.
    """
    if isinstance(model, MonolithicTransitionModel):
        if R is not None:
            raise InputError("a MonolithicTransitionModel has no backward component; pass R=None.")
        if options:
            raise InputError(
                f"a MonolithicTransitionModel takes no fitting options, got {sorted(options)}; "
                "set gp_max_iter in its constructor."
            )
        x, y = model.check_data(X, Y)
        return model.fit_components(x, y)
    if not isinstance(model, SkillTransitionModel):
        raise InputError(
            "fit_transition fits a SkillTransitionModel or a MonolithicTransitionModel, "
            f"got {type(model).__name__}."
        )
    if options and model.kind == "gp":
        raise InputError(
            f"the options {sorted(options)} are fit_em's, for kind='mixture'; a 'gp' model "
            "takes none (set gp_max_iter in its constructor)."
        )
    unknown = sorted(set(options) - _EM_OPTIONS)
    if unknown:
        raise InputError(
            f"unknown fitting option(s) {unknown}; fit_em takes {sorted(_EM_OPTIONS)}."
        )
    x, y, r = model.check_data(X, Y, R)
    return model.fit_components(x, y, r, **options)
