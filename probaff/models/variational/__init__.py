"""The mixture of GP experts with sparse variational experts, fitted by Pyro SVI.

`VariationalMixtureOfGPExperts` (``vi``) is the gated mixture of
`probaff.models.MixtureOfGPExperts` with sparse variational GP experts (whitened inducing
points) and Pyro programs that sum out each sample's expert; `fit_svi` (``svi``) fits it by
minibatch stochastic variational inference and records the run (`SVIHistory`), and
``svi_fixed`` takes SVI steps with the gate and the hyperparameters held where they are.
"""

from probaff.models.variational.svi import SVIHistory, fit_svi
from probaff.models.variational.vi import VariationalMixtureOfGPExperts

__all__ = ["SVIHistory", "VariationalMixtureOfGPExperts", "fit_svi"]
