"""The mixture of GP experts and its fit by expectation-maximisation, and chapter 4's baseline.

`MixtureOfGPExperts` (``model``) is a gate over exact or sparse GP experts, each on its own
feature columns, whose point prediction may be stacked with one GP (``point``). `fit_em` and
`fit_em_path` (``em``) fit it by EM for one or several sizes, with restarts that cannot lose:
``em_starts`` screens and finishes the starts of one size, ``em_run`` runs EM from given
responsibilities and records it (`EMHistory`); the named starting responsibilities are
`probaff.models.initialization`'s, shared with the variational fit. `ClusteredGPModel`
(``clustered``) is chapter 4's hierarchical alternative: GMM effect clusters, one GP per
cluster and an SVM gate. `integrated_variance_reduction` (``acquisition``) ranks inputs to
observe next by how much they would lower the mixture's predictive variance elsewhere.
"""

from probaff.models.mixture.acquisition import integrated_variance_reduction
from probaff.models.mixture.clustered import ClusteredGPModel
from probaff.models.mixture.em import EMHistory, fit_em, fit_em_path
from probaff.models.mixture.model import MixtureOfGPExperts

__all__ = [
    "ClusteredGPModel",
    "EMHistory",
    "MixtureOfGPExperts",
    "fit_em",
    "fit_em_path",
    "integrated_variance_reduction",
]
