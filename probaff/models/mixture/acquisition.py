r"""Where to observe next: the integrated variance reduction of a mixture of GP experts.

One more observation at a candidate input :math:`x` lowers each expert's posterior variance
at every other input :math:`r`. For expert :math:`j` (an exact GP per output :math:`e`, with
posterior covariance :math:`c_{je}` and noise variance :math:`\sigma^2_{je} / w`, where a
sample of responsibility :math:`w` has that noise, as in EM), the variance at :math:`r` after
observing :math:`x` with responsibility :math:`g_j(x)` (the gate's probability) falls by

.. math:: \Delta_{je}(r; x) = \frac{c_{je}(r, x)^2}{c_{je}(x, x) + \sigma^2_{je} / g_j(x)}.

`integrated_variance_reduction` averages this over a reference set :math:`R` of the inputs
the model will be asked about, each expert's share weighted by the gate's probability at
:math:`r`, and sums the outputs in their own units (times `output_weights`):

.. math:: \mathrm{IVR}(x) = \frac{1}{|R|} \sum_{r \in R} \sum_j g_j(r) \sum_e
   w_e\, s_e^2\, \Delta_{je}(r; x),

with :math:`s_e` the expert's output scale. This is Cohn's (1996) active-learning criterion
(ALC), the negative integrated posterior variance of BoTorch's ``qNegIntegratedPosterior
Variance`` for one point, applied expert by expert. Unlike the largest predictive variance,
which favours inputs at the edge of the data that nothing else resembles, it favours inputs
whose observation informs many of the inputs in `R`.

With ``measure="information"`` each term is instead the information (nats) the observation
gives about the expert's function value at :math:`r`,

.. math:: I_{je}(r; x) = -\tfrac12 \log\Big(1 - \frac{\Delta_{je}(r; x)}{c_{je}(r, r)}\Big),

which does not depend on the outputs' units, so an output of small variance (a turn beside
a displacement) counts as much as one of large variance; `output_weights` still weigh them.
"""

from __future__ import annotations

from typing import Any

import torch
from torch import Tensor

from probaff._checks import check_finite
from probaff.errors import InputError
from probaff.models.experts.gp_expert import GPExpert, exact_gp_settings
from probaff.models.tensors import as_matrix

__all__ = ["MEASURES", "integrated_variance_reduction"]

MEASURES = ("variance", "information")
"""What `integrated_variance_reduction` averages: variance removed, or information gained."""


def integrated_variance_reduction(
    model: Any,
    candidates: Any,
    reference: Any,
    *,
    output_weights: Any | None = None,
    measure: str = "variance",
) -> Tensor:
    """Each candidate's expected reduction of the predictive variance over `reference`.

    Args:
        model: A fitted `MixtureOfGPExperts` with exact GP experts.
        candidates: Inputs that could be observed next, `(C, D)`, in the model's feature frame.
        reference: Inputs the model will be asked about, `(R, D)`, same frame.
        output_weights: Non-negative weight of each output's term, `(E,)` (e.g. a turn's
            radius squared to count an angle as the arc it moves); None for ones.
        measure: ``"variance"`` (`IVR`, squared output units) or ``"information"`` (nats
            about the function values at `reference`; module doc).

    Returns:
        The score of every candidate (module doc), `(C,)`, averaged over `reference`.

    Raises:
        InputError: For inputs of the wrong width or with NaN/inf, negative or mis-sized
            output weights, an unknown measure, or a mixture with sparse experts.
        NotFittedError: If the mixture is not fitted.
    """
    if measure not in MEASURES:
        raise InputError(f"measure must be one of {list(MEASURES)}, got {measure!r}.")
    model.check_fitted()
    x_c = model.features(as_matrix("candidates", candidates, n_cols=model.n_features))
    x_r = model.features(as_matrix("reference", reference, n_cols=model.n_features))
    n_ref = x_r.shape[0]
    if n_ref == 0 or x_c.shape[0] == 0:
        raise InputError("candidates and reference need at least one row each.")
    e = model.n_outputs
    w = torch.ones(e, dtype=torch.float64, device=x_c.device)
    if output_weights is not None:
        w = torch.as_tensor(output_weights, dtype=torch.float64)
        check_finite("output_weights", w)
        if w.shape != (e,) or bool((w < 0).any()):
            raise InputError(
                f"output_weights must be {e} non-negative numbers (one per output), got shape "
                f"{tuple(w.shape)}; pass e.g. torch.ones({e})."
            )
        w = w.to(x_c.device)
    if not all(isinstance(expert, GPExpert) for expert in model.experts):
        raise InputError(
            "integrated_variance_reduction needs exact GP experts; fit the mixture with "
            "experts='exact'."
        )
    both = torch.cat([x_r, x_c])
    gate = model.built_gate().predict_proba(both[:, model.gate_columns])  # (R + C, M)
    x_e = both[:, model.expert_columns]
    total = torch.zeros(x_c.shape[0], dtype=torch.float64, device=x_c.device)
    for j, expert in enumerate(model.experts):
        expert.eval()
        with torch.no_grad(), exact_gp_settings(float(expert.jitter)):
            cov = expert.gp(expert.x_scaler(x_e)).covariance_matrix  # (E, R + C, R + C)
        cross = cov[:, :n_ref, n_ref:]  # (E, R, C)
        var_c = cov[:, n_ref:, n_ref:].diagonal(dim1=-2, dim2=-1)  # (E, C)
        g_c = gate[n_ref:, j].clamp_min(1e-12)
        denom = var_c + expert.likelihood.noise / g_c  # (E, C), standardised units
        reduction = cross**2 / denom[:, None, :]  # (E, R, C)
        if measure == "variance":
            scale = w * expert.y_scaler.std**2  # (E,): output units
        else:
            var_r = cov[:, :n_ref, :n_ref].diagonal(dim1=-2, dim2=-1)  # (E, R)
            ratio = (reduction / var_r.clamp_min(1e-300)[..., None]).clamp(0.0, 1.0 - 1e-12)
            reduction, scale = -0.5 * torch.log1p(-ratio), w
        total += torch.einsum("e,r,erc->c", scale, gate[:n_ref, j], reduction)
    return total / n_ref
