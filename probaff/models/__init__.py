"""Probabilistic push-effect models: a mixture of Gaussian-process experts.

`MixtureOfGPExperts` is fitted by EM (`fit_em`) with exact GP experts (`GPExpert`) and a
softmax gate (`SoftmaxGate`); `VariationalMixtureOfGPExperts` is the same model with sparse
variational experts, fitted by Pyro SVI (`fit_svi`). `save` and `load` store a fitted
EM mixture in one file. `ClusteredGPModel` is chapter 4's baseline: GMM effect clusters, one
GP per cluster and an SVM gate.
"""

from probaff.errors import NotFittedError
from probaff.models.clustered import ClusteredGPModel
from probaff.models.em import EMHistory, fit_em
from probaff.models.gate import SoftmaxGate
from probaff.models.gp_expert import GPExpert
from probaff.models.mixture import MixtureOfGPExperts
from probaff.models.persistence import load, save
from probaff.models.vi import VariationalMixtureOfGPExperts, fit_svi

__all__ = [
    "ClusteredGPModel",
    "EMHistory",
    "GPExpert",
    "MixtureOfGPExperts",
    "NotFittedError",
    "SoftmaxGate",
    "VariationalMixtureOfGPExperts",
    "fit_em",
    "fit_svi",
    "load",
    "save",
]
