"""Probabilistic push-effect models: a mixture of Gaussian-process experts.

`MixtureOfGPExperts` is fitted by EM (`fit_em`, or `fit_em_path` for several sizes at once)
with exact GP experts (`GPExpert`) and a softmax gate (`SoftmaxGate`, or `FourierGate` for
regimes no hyperplane separates); `VariationalMixtureOfGPExperts` is the same model with sparse
variational experts, fitted by Pyro SVI (`fit_svi`). `save` and `load` store a fitted
EM mixture in one file. `ClusteredGPModel` is chapter 4's baseline: GMM effect clusters, one
GP per cluster and an SVM gate.
"""

from probaff.errors import NotFittedError
from probaff.models.clustered import ClusteredGPModel
from probaff.models.em import EMHistory, fit_em, fit_em_path
from probaff.models.gate import FourierGate, SoftmaxGate, make_gate
from probaff.models.gp_expert import GPExpert
from probaff.models.mixture import MixtureOfGPExperts
from probaff.models.persistence import load, save
from probaff.models.vi import VariationalMixtureOfGPExperts, fit_svi

__all__ = [
    "ClusteredGPModel",
    "EMHistory",
    "FourierGate",
    "GPExpert",
    "MixtureOfGPExperts",
    "NotFittedError",
    "SoftmaxGate",
    "VariationalMixtureOfGPExperts",
    "fit_em",
    "fit_em_path",
    "fit_svi",
    "load",
    "make_gate",
    "save",
]
