"""Chapter 6's transition models over scenes: per skill, monolithic, chained and stepped.

`SkillTransitionModel` (``skill_transition``, one model per skill with a backward component)
and `MonolithicTransitionModel` (``monolithic``, one GP on whole scenes) share
``transition_base`` and are fitted by `fit_transition` (``transition``, with its
`TransitionHistory`); both take their GP settings as one `GPOptions` (``gp=``, by default
`TRANSITION_GP`). `ModularTransitionModel` (``modular``) chains per-skill predictions
over scenes of n objects (`ChainScene` and `ChainPrediction`, from ``chain``), and
`SteppedPushModel` (``stepped_transition``) rolls a forward and a backward push model out
step by step.
"""

from probaff.models.transitions.chain import ChainPrediction, ChainScene
from probaff.models.transitions.modular import InteractionGeometry, ModularTransitionModel
from probaff.models.transitions.stepped_transition import SteppedPushModel
from probaff.models.transitions.transition import (
    MonolithicTransitionModel,
    SkillTransitionModel,
    TransitionHistory,
    fit_transition,
)
from probaff.models.transitions.transition_base import TRANSITION_GP

__all__ = [
    "TRANSITION_GP",
    "ChainPrediction",
    "ChainScene",
    "InteractionGeometry",
    "ModularTransitionModel",
    "MonolithicTransitionModel",
    "SkillTransitionModel",
    "SteppedPushModel",
    "TransitionHistory",
    "fit_transition",
]
