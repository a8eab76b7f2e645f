"""What chapter 6's transition models share: skills, components, checks, sampling, history.

The constants and helpers of `SkillTransitionModel` and `MonolithicTransitionModel`
(`probaff.models.transitions.transition`): the skill and component names, the checks of their
arguments, the predictive distribution and draws of a component, and the record of a fit.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import torch
from torch import Tensor
from torch.distributions import Distribution, Independent, MixtureSameFamily, Normal

from probaff._checks import default_or_instance
from probaff.errors import InputError
from probaff.models.experts.gp_expert import GPExpert, exact_gp_settings
from probaff.models.mixture.em import EMHistory
from probaff.models.mixture.model import FLAT_GP_KEYWORDS, MixtureOfGPExperts
from probaff.models.options import GPOptions, refuse_flat_gp_keywords
from probaff.models.tensors import training_rows

__all__ = [
    "COMPONENTS",
    "DEFAULT_EXPERTS",
    "DEFAULT_SEED",
    "KINDS",
    "MONOLITHIC_NOT_FITTED",
    "PREDICT_ROWS",
    "SKILLS",
    "TRANSITION_FLAT_GP_KEYWORDS",
    "TRANSITION_GP",
    "Component",
    "TransitionBase",
    "TransitionHistory",
    "check_asked_skill",
    "check_generator",
    "check_skill",
    "check_transition_gp",
    "component_predict",
    "gp_objective",
    "predict_moments",
    "sample_effects",
    "training_pair",
]

SKILLS: tuple[str, ...] = ("pick", "place", "push")
"""The skills a transition model can be trained for."""

KINDS: tuple[str, ...] = ("gp", "mixture")
"""Kinds of components: one multi-output ARD GP, or a mixture of GP experts."""

COMPONENTS: tuple[str, ...] = ("effect", "reaction", "corrected")
"""Component names: the effect `X -> Y`, the reaction `[X, Y] -> R` and the corrected
effect `[X, R] -> Y` (the last two only with a backward component)."""

TRANSITION_GP = GPOptions(noise_floor="auto", outputscale=0.1)
"""The GP settings of a transition model given no ``gp``: the thesis's.

50 L-BFGS iterations per GP fit, no length-scale prior, a noise floor of 1 % of each target's
standard deviation over the component's training set (``"auto"``), and the GP components'
initial signal variance :math:`\\theta_0` = 0.1 and noise variance 0.1 (standardised units)."""

TRANSITION_FLAT_GP_KEYWORDS = {**FLAT_GP_KEYWORDS, "outputscale": "outputscale", "noise": "noise"}
"""The GP settings a transition model once took one by one, each to its field of `GPOptions`:
the mixture's (`FLAT_GP_KEYWORDS`) and the start values ``outputscale`` and ``noise``. The
keywords the constructors now refuse, and the keys of the files saved before ``gp``."""

# Experts of `kind="mixture"` when `n_experts` is not given (chapter 5's best M).
DEFAULT_EXPERTS = 3

# Seed of the sampled prediction when no generator is given.
DEFAULT_SEED = 0

# Rows per call to a component's `predict` in sampled predictions (an exact GP's prediction
# of n rows costs O(n^2) memory, so S * N rows at once would not scale).
PREDICT_ROWS = 1024

MONOLITHIC_NOT_FITTED = (
    "this MonolithicTransitionModel is not fitted; call "
    "probaff.models.fit_transition(model, X, Y) first."
)

Component = GPExpert | MixtureOfGPExperts
"""A component of a transition model: one multi-output GP or a mixture of GP experts."""


# ------------------------------------------------------------------ helpers
def check_skill(name: str, skill: Any) -> str:
    """`skill` if it is a known skill name, else `InputError` listing the known ones."""
    if not isinstance(skill, str) or skill not in SKILLS:
        known = ", ".join(repr(s) for s in SKILLS)
        raise InputError(f"unknown {name} {skill!r}; known skills: {known}.")
    return skill


def check_asked_skill(own: str, skill: Any) -> None:
    """Refuse a prediction for another skill than the model's own (``None`` skips it)."""
    if skill is None:
        return
    asked = check_skill("skill", skill)
    if asked != own:
        raise InputError(f"a {own} model cannot predict {asked}; use the {asked} model.")


def check_transition_gp(gp: Any) -> GPOptions:
    """`gp` if it is a transition model's GP settings; `InputError` for anything else.

    The components of a model have different numbers of outputs (a skill model's effect,
    reaction and corrected effect), so the noise floor must be ``"auto"``, None or one
    number; a per-output tuple is refused.
    """
    if type(gp) is not GPOptions:
        raise InputError(
            f"gp must be GPOptions (the GP settings, e.g. GPOptions(max_iter=20, "
            f"lengthscale_prior=True, noise_floor='auto', outputscale=0.1)), got "
            f"{type(gp).__name__}."
        )
    if isinstance(gp.noise_floor, tuple):
        raise InputError(
            f"a transition model's gp.noise_floor must be 'auto', None or one standard "
            f"deviation >= 0 (its components have different outputs), got {gp.noise_floor!r}."
        )
    return gp


def component_predict(component: Component, x: Tensor) -> Distribution:
    """Predictive distribution of a component at inputs `x: (N, C)`: batch `(N,)`, event `(E,)`."""
    if isinstance(component, GPExpert):
        return Independent(component.predict(x), 1)
    return component.predict(x)


def predict_moments(component: Component, x: Tensor) -> tuple[Tensor, Tensor]:
    """Predictive mean and variance of a component at many inputs `x: (n, C)`, `(n, E)` each.

    The rows are predicted `PREDICT_ROWS` at a time.
    """
    means, variances = [], []
    for rows in torch.split(x, PREDICT_ROWS):
        pred = component_predict(component, rows)
        means.append(pred.mean)
        variances.append(pred.variance)
    return torch.cat(means), torch.cat(variances)


def sample_effects(dist: Distribution, n_samples: int, generator: torch.Generator) -> Tensor:
    """Draw `n_samples` values from a component's prediction with `generator`.

    Mixtures draw the expert of each sample first, then its normal; the same generator
    state gives the same draws.

    Args:
        dist: Independent normals (batch `(N,)`, event `(E,)`), or a mixture of them (loc
            `(N, M, E)`), as the transition models predict.
        n_samples: Number of draws `S`.
        generator: Source of randomness.

    Returns:
        Samples, `(S, N, E)`.

    Raises:
        InputError: For a distribution of another kind.
    """
    if isinstance(dist, MixtureSameFamily):
        comp = dist.component_distribution
        normal = comp.base_dist if isinstance(comp, Independent) else comp
        if not (isinstance(comp, Independent) and isinstance(normal, Normal)):
            raise InputError(f"cannot sample a mixture of {type(comp).__name__} components.")
        probs = dist.mixture_distribution.probs  # (N, M)
        pick = torch.multinomial(probs, n_samples, replacement=True, generator=generator)
        rows = torch.arange(probs.shape[0])[:, None]
        loc = normal.loc[rows, pick].transpose(0, 1)  # (S, N, E)
        scale = normal.scale[rows, pick].transpose(0, 1)
    elif isinstance(dist, Independent) and isinstance(dist.base_dist, Normal):
        normal = dist.base_dist
        loc = normal.loc.expand(n_samples, *normal.loc.shape)
        scale = normal.scale.expand_as(loc)
    else:
        raise InputError(
            f"only independent normals or mixtures of them can be sampled; got a "
            f"{type(dist).__name__}."
        )
    eps = torch.randn(loc.shape, generator=generator, dtype=loc.dtype)
    return loc + scale * eps


def gp_objective(expert: GPExpert) -> float:
    """Log marginal likelihood per sample, summed over the expert's outputs."""
    with torch.no_grad(), exact_gp_settings(float(expert.jitter)):
        return float(expert.marginal_log_likelihood().sum())


def training_pair(X: Any, Y: Any) -> tuple[Tensor, Tensor]:
    """Validate features `(N, D)` and effects `(N, E)` of a training set with N >= 2."""
    x, y = training_rows(X, Y, "interaction")
    if x.shape[0] < 2:
        raise InputError(f"a transition model needs at least 2 training samples, got {x.shape[0]}.")
    return x, y


def check_generator(generator: Any) -> torch.Generator:
    """`generator`, or a fresh one seeded with `DEFAULT_SEED` when it is ``None``."""
    return default_or_instance(
        "generator",
        generator,
        torch.Generator,
        lambda: torch.Generator().manual_seed(DEFAULT_SEED),
        "a torch.Generator",
    )


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


class TransitionBase(torch.nn.Module):
    """What both transition models hold: the skill, the GP settings and the training data.

    Args:
        skill: The skill, one of `SKILLS`.
        gp: The GP settings of every component (checked by `check_transition_gp`); None
            for `TRANSITION_GP`. A GP component is one `GPExpert` of these settings: `max_iter`
            L-BFGS iterations per fit, the length-scale prior (`lengthscale_prior`), the
            noise floor in its targets' units (`noise_floor`: ``"auto"``, 1 % of each
            target's standard deviation over its training set, None or one number >= 0)
            and the start values `outputscale` and `noise`.
        **unexpected: Refused: the old flat keywords (`TRANSITION_FLAT_GP_KEYWORDS`) with
            an `InputError` naming the ``gp=GPOptions(...)`` to give, any other with a
            `TypeError`.

    Attributes:
        gp: The GP settings.

    Raises:
        InputError: For an unknown skill, a `gp` that is not a `GPOptions` (or one with a
            noise floor per output), or one of the old flat keywords.
        TypeError: For any other unknown keyword.
    """

    def __init__(self, skill: str, *, gp: GPOptions | None = None, **unexpected: Any) -> None:
        name = type(self).__name__
        what = f"{name} takes its GP settings"
        refuse_flat_gp_keywords(what, unexpected, TRANSITION_FLAT_GP_KEYWORDS)
        if unexpected:
            raise TypeError(f"{name}() got unexpected keyword argument(s) {sorted(unexpected)}.")
        super().__init__()
        self.skill = check_skill("skill", skill)
        self.gp = TRANSITION_GP if gp is None else check_transition_gp(gp)
        self.components = torch.nn.ModuleDict()
        self.n_features: int | None = None
        self.n_outputs: int | None = None
        self.train_X: Tensor | None = None
        self.train_Y: Tensor | None = None
