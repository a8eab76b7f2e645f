"""Gates that share a mixture's rows among its experts, and the gated mixture they drive.

A gate is a multinomial logistic regression fitted to soft assignment targets (``gate``):
`SoftmaxGate` on the features themselves, `FourierGate` on random Fourier features for
regimes no hyperplane separates, both made by `make_gate`; their ridge and smoothed lasso
penalties and the strengths cross-validation tries are in ``gate_penalty``, and the Newton
solver of small problems in ``gate_newton``. `GatedMixture` (``gated``) is the base class of
the EM and variational mixtures: a gate, its experts, and the mixture distribution they
predict.
"""

from probaff.models.gates.gate import FourierGate, SoftmaxGate, make_gate
from probaff.models.gates.gated import GatedMixture

__all__ = ["FourierGate", "GatedMixture", "SoftmaxGate", "make_gate"]
