"""SVI steps of a variational mixture whose gate and hyperparameters stay where they are.

When `probaff.models.fit_svi` starts from an exact mixture (its default), the gate, the
kernels, the means, the noise and the inducing inputs are kept and only every q(u) moves.
Each expert's factor of :math:`K_{uu}` and the gate's log-probabilities of the training rows
are then fixed, so they are computed once, and a minibatch step (the ELBO it records, the
assignment posterior, the natural-gradient targets) is a few products with the minibatch's
whitened projections :math:`A = L^{-1} K_{uf}` instead of a pass through gpytorch's
variational strategy and Pyro's enumeration. The numbers are those of
`VariationalMixtureOfGPExperts.model` under `pyro.infer.TraceEnum_ELBO` and of
`VariationalMixtureOfGPExperts.update_variational`.
"""

from __future__ import annotations

import torch
from torch import Tensor

from probaff.models.vi import VariationalMixtureOfGPExperts, expected_log_density

__all__ = ["FixedHyperparameterSVI"]


class FixedHyperparameterSVI:
    """Minibatch steps on every q(u) of a built mixture whose other parameters are held.

    Args:
        model: A built `VariationalMixtureOfGPExperts`.
        x_g: Gate features (raw), `(N, D_g)`.
        x_e: Standardised expert inputs, `(N, D_e)`.
        y: Standardised effects, `(N, E)`.
    """

    def __init__(
        self, model: VariationalMixtureOfGPExperts, x_g: Tensor, x_e: Tensor, y: Tensor
    ) -> None:
        self.model, self.x_e, self.y = model, x_e, y
        with torch.no_grad():
            gate = model.built_gate()
            self.log_gate = gate.logits(x_g).log_softmax(-1)  # (N, M)
            penalty = gate.l2_ if model.gate_penalty is None else model.gate_penalty
            self.gate_term = float(0.5 * penalty * x_g.shape[0] * gate.weight.square().sum())
            self.noise = model.noise.detach()  # (M, E)
        self.factors = [expert.inducing_factor() for expert in model.experts]  # (E, K, K) each

    def step(self, idx: Tensor, *, scale: float, step: float) -> float:
        """Move every q(u) a natural-gradient step on the minibatch `idx`, `(B,)`.

        The assignments are held at their posterior given the current q(u), as in
        `VariationalMixtureOfGPExperts.update_variational`.

        Args:
            idx: Rows of the minibatch, `(B,)`.
            scale: `N / B`.
            step: Natural-gradient step size in `(0, 1]`.

        Returns:
            The negative ELBO estimate of the minibatch before the step (nats, for all `N`
            rows, as `TraceEnum_ELBO.loss` gives it).
        """
        x, y = self.x_e[idx], self.y[idx]
        experts = list(self.model.experts)
        with torch.no_grad():
            proj = [e.projection(x, c) for e, c in zip(experts, self.factors, strict=True)]
            ell = torch.stack(
                [
                    expected_log_density(y, *e.projected_moments(x, a), self.noise[j])
                    for j, (e, a) in enumerate(zip(experts, proj, strict=True))
                ],
                dim=-1,
            )  # (B, M)
            joint = self.log_gate[idx] + ell
            kl = sum(float(e.kl_divergence().sum()) for e in experts)
            data = scale * float(torch.logsumexp(joint, dim=-1).sum())
            resp = torch.softmax(joint, dim=-1)
            for j, (expert, a) in enumerate(zip(experts, proj, strict=True)):
                precision, shift = expert.projected_target(a, y, resp[:, j], self.noise[j])
                eye = torch.eye(a.shape[-2], dtype=a.dtype, device=a.device)
                expert.natural_step(eye + scale * precision, scale * shift, step)
        return -(data - kl - self.gate_term)
