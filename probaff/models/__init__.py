"""Probabilistic push-effect models: a mixture of Gaussian-process experts, and their registry.

`MixtureOfGPExperts` is fitted by EM (`fit_em`, or `fit_em_path` for several sizes at once)
with exact GP experts (`GPExpert`) and a softmax gate (`SoftmaxGate`, or `FourierGate` for
regimes no hyperplane separates); `VariationalMixtureOfGPExperts` is the same model with sparse
variational experts, fitted by Pyro SVI (`fit_svi`). Both derive from `GatedMixture`.
`ClusteredGPModel` is chapter 4's baseline: GMM effect clusters, one GP per cluster and an SVM
gate. Chapter 6's transition models (`SkillTransitionModel`, `MonolithicTransitionModel`) are
fitted by `fit_transition` and chained by `ModularTransitionModel`. Every push model is a
`PushModel` (``predict(X)`` gives a distribution over effects).

Fits take typed options (`EMOptions`, `SVIOptions`, `GPOptions`), with single fields as
keyword overrides; a mixture takes its experts' settings as one `GPOptions` (``gp=``, by
default `MIXTURE_GP`), and so does a transition model (by default `TRANSITION_GP`). Every
kind of model is a `ModelKind` in one registry (`model_kind`, `model_kinds`,
`register_model_kind`): its class, fitter, options, save format and builder
(`ModelSettings`); `fit` fits any registered model, and `save` and `load` store any
registered model in one file.

`MixtureOfGPExpertsRegressor` (`probaff.models.sklearn`) is the EM mixture as a scikit-learn
regressor, for `cross_val_score`, `GridSearchCV` and `Pipeline`; `mean_log_predictive_density`
scores its whole predictive distribution there.

The code is grouped by idea, as GPyTorch groups its own: ``experts`` (the exact and sparse GP
experts, their kernel and weighted likelihood), ``gates`` (the softmax and Fourier gates and
the `GatedMixture` base), ``mixture`` (`MixtureOfGPExperts`, its EM fit and the clustered
baseline), ``variational`` (the variational mixture and its SVI fit) and ``transitions``
(chapter 6's transition models); options, the registry, persistence, the scikit-learn
estimator and the shared tensor, column and optimiser helpers stay at this level.
"""

from probaff.errors import NotFittedError
from probaff.models.experts import GPExpert, SparseGPExpert
from probaff.models.gates import FourierGate, GatedMixture, SoftmaxGate, make_gate
from probaff.models.interface import PushModel, point_prediction
from probaff.models.mixture import (
    ClusteredGPModel,
    EMHistory,
    MixtureOfGPExperts,
    fit_em,
    fit_em_path,
)
from probaff.models.options import MIXTURE_GP, EMOptions, GPOptions, SparseGPOptions, SVIOptions
from probaff.models.persistence import load, save
from probaff.models.registry import (
    Codec,
    ModelKind,
    ModelSettings,
    fit,
    model_kind,
    model_kinds,
    register_model_kind,
    unregister_model_kind,
)
from probaff.models.sklearn import MixtureOfGPExpertsRegressor, mean_log_predictive_density
from probaff.models.transitions import (
    TRANSITION_GP,
    ChainPrediction,
    ChainScene,
    InteractionGeometry,
    ModularTransitionModel,
    MonolithicTransitionModel,
    SkillTransitionModel,
    TransitionHistory,
    fit_transition,
)
from probaff.models.variational import SVIHistory, VariationalMixtureOfGPExperts, fit_svi

__all__ = [
    "MIXTURE_GP",
    "TRANSITION_GP",
    "ChainPrediction",
    "ChainScene",
    "ClusteredGPModel",
    "Codec",
    "EMHistory",
    "EMOptions",
    "FourierGate",
    "GPExpert",
    "GPOptions",
    "GatedMixture",
    "InteractionGeometry",
    "MixtureOfGPExperts",
    "MixtureOfGPExpertsRegressor",
    "ModelKind",
    "ModelSettings",
    "ModularTransitionModel",
    "MonolithicTransitionModel",
    "NotFittedError",
    "PushModel",
    "SVIHistory",
    "SVIOptions",
    "SkillTransitionModel",
    "SoftmaxGate",
    "SparseGPExpert",
    "SparseGPOptions",
    "TransitionHistory",
    "VariationalMixtureOfGPExperts",
    "fit",
    "fit_em",
    "fit_em_path",
    "fit_svi",
    "fit_transition",
    "load",
    "make_gate",
    "mean_log_predictive_density",
    "model_kind",
    "model_kinds",
    "point_prediction",
    "register_model_kind",
    "save",
    "unregister_model_kind",
]
