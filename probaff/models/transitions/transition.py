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

import dataclasses
from typing import Any

from probaff._threads import threads_by_rows
from probaff.errors import InputError
from probaff.models.options import EMOptions, GPOptions, resolve_options
from probaff.models.registry import Codec, ModelKind, register_model_kind
from probaff.models.transitions.monolithic import MonolithicTransitionModel
from probaff.models.transitions.skill_transition import SkillTransitionModel
from probaff.models.transitions.transition_base import (
    COMPONENTS,
    KINDS,
    SKILLS,
    TRANSITION_FLAT_GP_KEYWORDS,
    TRANSITION_GP,
    TransitionHistory,
)

__all__ = [
    "COMPONENTS",
    "KINDS",
    "SKILLS",
    "MonolithicTransitionModel",
    "SkillTransitionModel",
    "TransitionHistory",
    "fit_transition",
]


@threads_by_rows("X")
def fit_transition(
    model: SkillTransitionModel | MonolithicTransitionModel,
    X: Any,
    Y: Any,
    R: Any = None,
    options: EMOptions | None = None,
    **overrides: Any,
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
        options: For ``kind="mixture"``, the `EMOptions` of its components' `fit_em`; GP
            components take none.
        **overrides: Fields of `EMOptions` that replace those of `options` (e.g. ``seed``,
            ``max_iter``, ``n_restarts``).

    Returns:
        The history of the fit.

    Raises:
        InputError: For a model of another class, malformed data (NaN/inf, wrong or
            mismatched shapes, fewer than 2 samples), a missing or unexpected `R`, or
            unknown options.
    """
    given = sorted(overrides) + (["options"] if options is not None else [])
    if isinstance(model, MonolithicTransitionModel):
        if R is not None:
            raise InputError("a MonolithicTransitionModel has no backward component; pass R=None.")
        if given:
            raise InputError(
                f"a MonolithicTransitionModel takes no fitting options, got {given}; "
                "give its GP settings as gp=GPOptions(...) in its constructor."
            )
        x, y = model.check_data(X, Y)
        return model.fit_components(x, y)
    if not isinstance(model, SkillTransitionModel):
        raise InputError(
            "fit_transition fits a SkillTransitionModel or a MonolithicTransitionModel, "
            f"got {type(model).__name__}."
        )
    if given and model.kind == "gp":
        raise InputError(
            f"the options {given} are fit_em's, for kind='mixture'; a 'gp' model "
            "takes none (give its GP settings as gp=GPOptions(...) in its constructor)."
        )
    opts = resolve_options(EMOptions, options, overrides)
    x, y, r = model.check_data(X, Y, R)
    return model.fit_components(x, y, r, opts)


# ---------------------------------------- the "transition" and "monolithic" kinds
def _saved_settings(model: SkillTransitionModel | MonolithicTransitionModel) -> dict[str, Any]:
    """A model's constructor arguments to save: its `GPOptions` as its fields (builtins)."""
    return {**model.config(), "gp": dataclasses.asdict(model.gp)}


def _saved_config(config: dict[str, Any]) -> dict[str, Any]:
    """A saved transition model's constructor arguments, its GP settings as one `GPOptions`.

    Files written since the settings were one `GPOptions` hold its fields under ``gp``;
    older files hold the flat keys ``gp_max_iter``, ``lengthscale_prior``, ``noise_floor``,
    ``outputscale`` and ``noise`` (`TRANSITION_FLAT_GP_KEYWORDS`; a missing one takes
    `TRANSITION_GP`'s value).
    """
    out = dict(config)
    flat = {new: out.pop(old) for old, new in TRANSITION_FLAT_GP_KEYWORDS.items() if old in out}
    saved = out.get("gp")
    if saved is None:
        out["gp"] = dataclasses.replace(TRANSITION_GP, **flat)
    elif isinstance(saved, dict) and not flat:
        out["gp"] = GPOptions(**saved)
    else:
        raise InputError(
            f"a saved transition model's gp must hold GPOptions' fields, got {saved!r}."
        )
    return out


def _dump_skill(model: SkillTransitionModel) -> dict[str, Any]:
    return {
        "config": _saved_settings(model),
        "sizes": [model.n_features, model.n_outputs, model.n_reaction],
        "X": model.train_X,
        "Y": model.train_Y,
        "R": model.train_R,
        "weights": model.component_weights(),
        "state_dict": model.state_dict(),
    }


def _restore_skill(payload: dict[str, Any]) -> SkillTransitionModel:
    model = SkillTransitionModel(**_saved_config(payload["config"]))
    model.build(*payload["sizes"])
    model.condition(payload["X"], payload["Y"], payload["R"], payload["weights"])
    model.load_state_dict(payload["state_dict"])
    return model


def _dump_monolithic(model: MonolithicTransitionModel) -> dict[str, Any]:
    return {
        "config": _saved_settings(model),
        "sizes": [model.n_features, model.n_outputs],
        "X": model.train_X,
        "Y": model.train_Y,
        "state_dict": model.state_dict(),
    }


def _restore_monolithic(payload: dict[str, Any]) -> MonolithicTransitionModel:
    model = MonolithicTransitionModel(**_saved_config(payload["config"]))
    model.build(*payload["sizes"])
    model.condition(payload["X"], payload["Y"])
    model.load_state_dict(payload["state_dict"])
    return model


_SKILL_CODEC = Codec(
    "probaff.models.SkillTransitionModel/1",
    _dump_skill,
    _restore_skill,
    ("config", "sizes", "X", "Y", "R", "weights", "state_dict"),
)
_MONOLITHIC_CODEC = Codec(
    "probaff.models.MonolithicTransitionModel/1",
    _dump_monolithic,
    _restore_monolithic,
    ("config", "sizes", "X", "Y", "state_dict"),
)
register_model_kind(
    ModelKind("transition", SkillTransitionModel, fit_transition, EMOptions, _SKILL_CODEC)
)
register_model_kind(
    ModelKind("monolithic", MonolithicTransitionModel, fit_transition, None, _MONOLITHIC_CODEC)
)
