"""Probabilistic push-effect models: a mixture of Gaussian-process experts.

`MixtureOfGPExperts` is fitted by EM (`fit_em`, or `fit_em_path` for several sizes at once)
with exact GP experts (`GPExpert`) and a softmax gate (`SoftmaxGate`, or `FourierGate` for
regimes no hyperplane separates); `VariationalMixtureOfGPExperts` is the same model with sparse
variational experts, fitted by Pyro SVI (`fit_svi`). Both derive from `GatedMixture`.
`ClusteredGPModel` is chapter 4's baseline: GMM effect clusters, one GP per cluster and an SVM
gate. Every model is a `PushModel` (``predict(X)`` gives a distribution over effects); the
fitting procedures are registered by name in `FITTERS` (`get_fitter`, `register_fitter`), and
`save` and `load` store any fitted model in one file.
"""

from probaff.errors import NotFittedError
from probaff.models.clustered import ClusteredGPModel
from probaff.models.em import EMHistory, fit_em, fit_em_path
from probaff.models.fitting import FITTERS, get_fitter, register_fitter
from probaff.models.gate import FourierGate, SoftmaxGate, make_gate
from probaff.models.gated import GatedMixture
from probaff.models.gp_expert import GPExpert
from probaff.models.interface import PushModel
from probaff.models.mixture import MixtureOfGPExperts
from probaff.models.modular import (
    ChainPrediction,
    ChainScene,
    InteractionGeometry,
    ModularTransitionModel,
)
from probaff.models.persistence import load, save
from probaff.models.svi import SVIHistory, fit_svi
from probaff.models.transition import (
    MonolithicTransitionModel,
    SkillTransitionModel,
    TransitionHistory,
    fit_transition,
)
from probaff.models.vi import VariationalMixtureOfGPExperts

__all__ = [
    "FITTERS",
    "ChainPrediction",
    "ChainScene",
    "ClusteredGPModel",
    "EMHistory",
    "FourierGate",
    "GPExpert",
    "GatedMixture",
    "InteractionGeometry",
    "MixtureOfGPExperts",
    "ModularTransitionModel",
    "MonolithicTransitionModel",
    "NotFittedError",
    "PushModel",
    "SVIHistory",
    "SkillTransitionModel",
    "SoftmaxGate",
    "TransitionHistory",
    "VariationalMixtureOfGPExperts",
    "fit_em",
    "fit_em_path",
    "fit_svi",
    "fit_transition",
    "get_fitter",
    "load",
    "make_gate",
    "register_fitter",
    "save",
]
