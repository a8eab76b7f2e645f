"""The GP experts of a mixture: exact and sparse, with per-sample noise weights.

An expert models E outputs as independent Gaussian processes with an amplitude times SE-ARD
kernel (`ard_se_kernel`, in ``kernels``) and a Gaussian likelihood whose noise variance is
divided by each sample's weight (`WeightedGaussianLikelihood`, in ``likelihood``), so that a
mixture's responsibilities weight its rows. `WeightedExpert` (``expert_base``) holds what
every expert shares; `GPExpert` (``gp_expert``) is the exact one, fitted together with its
siblings as one batch in ``expert_batch`` with the closed-form marginal likelihood of
``gaussian_density``; `SparseGPExpert` (``sparse_expert``) is the inducing-point one for
large sets.
"""

from probaff.models.experts.expert_base import WeightedExpert
from probaff.models.experts.gp_expert import GPExpert
from probaff.models.experts.kernels import ard_se_kernel
from probaff.models.experts.likelihood import WeightedGaussianLikelihood
from probaff.models.experts.sparse_expert import SparseGPExpert

__all__ = [
    "GPExpert",
    "SparseGPExpert",
    "WeightedExpert",
    "WeightedGaussianLikelihood",
    "ard_se_kernel",
]
