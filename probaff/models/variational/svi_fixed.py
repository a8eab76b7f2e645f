r"""SVI steps of a variational mixture whose gate and hyperparameters stay where they are.

When `probaff.models.fit_svi` starts from an exact mixture (its default), the gate, the
kernels, the means, the noise and the inducing inputs are kept and only every q(u) moves.
Each expert's factor of :math:`K_{uu}` and the gate's log-probabilities of the training rows
are then fixed, so they are computed once, and a minibatch step (the ELBO it records, the
assignment posterior, the natural-gradient targets) is a few products with the minibatch's
whitened projections :math:`A = L^{-1} K_{uf}` instead of a pass through gpytorch's
variational strategy and Pyro's enumeration. Every q(u) is held in natural parameters
(`probaff.models.variational.vi.WhitenedQ`: precision and precision-times-mean), which the
natural-gradient step mixes linearly, so a step costs one Cholesky factor and one
triangular inverse of the precision per expert and output; `store` writes the mean and
covariance factor back into the model. The numbers are those of
`VariationalMixtureOfGPExperts.model` under `pyro.infer.TraceEnum_ELBO` and of
`VariationalMixtureOfGPExperts.update_variational`.
"""

from __future__ import annotations

import torch
from torch import Tensor

from probaff.models.variational.vi import (
    SVGPExpert,
    VariationalMixtureOfGPExperts,
    WhitenedQ,
    expected_log_density,
)

__all__ = ["FixedHyperparameterSVI"]

# Most bytes of whitened projections of all training rows kept between steps (above: each
# minibatch's projection is computed when it is drawn).
_PROJECTION_CACHE_BYTES = 256 * 2**20


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
        self.experts: list[SVGPExpert] = list(model.experts)
        with torch.no_grad():
            gate = model.built_gate()
            self.log_gate = gate.logits(x_g).log_softmax(-1)  # (N, M)
            penalty = gate.l2_ if model.gate_penalty is None else model.gate_penalty
            self.gate_term = float(0.5 * penalty * x_g.shape[0] * gate.weight.square().sum())
            self.noise = model.noise.detach()  # (M, E)
        self.factors = [expert.inducing_factor() for expert in self.experts]  # (E, K, K) each
        self.q = [WhitenedQ.of(expert) for expert in self.experts]
        size = sum(f.shape[0] * f.shape[1] for f in self.factors) * x_e.shape[0]
        self.projections: list[Tensor] | None = None
        if size * x_e.element_size() <= _PROJECTION_CACHE_BYTES:
            self.projections = [
                e.projection(x_e, c) for e, c in zip(self.experts, self.factors, strict=True)
            ]  # (E, K, N) each

    def _projections(self, idx: Tensor) -> list[Tensor]:
        """Every expert's whitened projection of the minibatch `idx`, `(E, K, B)` each."""
        if self.projections is not None:
            return [a[..., idx] for a in self.projections]
        x = self.x_e[idx]
        return [e.projection(x, c) for e, c in zip(self.experts, self.factors, strict=True)]

    def step(self, idx: Tensor, *, scale: float, step: float) -> float:
        """Move every q(u) a natural-gradient step on the minibatch `idx`, `(B,)`.

        The assignments are held at their posterior given the current q(u), as in
        `VariationalMixtureOfGPExperts.update_variational`. The model's q(u) are updated by
        `store`.

        Args:
            idx: Rows of the minibatch, `(B,)`.
            scale: `N / B`.
            step: Natural-gradient step size in `(0, 1]`.

        Returns:
            The negative ELBO estimate of the minibatch before the step (nats, for all `N`
            rows, as `TraceEnum_ELBO.loss` gives it).
        """
        x, y = self.x_e[idx], self.y[idx]
        with torch.no_grad():
            proj = self._projections(idx)
            ell = torch.stack(
                [
                    expected_log_density(y, *e.projected_moments(x, a, (q.mean, q.root)), noise)
                    for e, a, q, noise in zip(self.experts, proj, self.q, self.noise, strict=True)
                ],
                dim=-1,
            )  # (B, M)
            joint = self.log_gate[idx] + ell
            kl = sum(q.kl for q in self.q)
            data = scale * float(torch.logsumexp(joint, dim=-1).sum())
            resp = torch.softmax(joint, dim=-1)
            for j, (expert, a) in enumerate(zip(self.experts, proj, strict=True)):
                precision, shift = expert.projected_target(a, y, resp[:, j], self.noise[j])
                eye = torch.eye(a.shape[-2], dtype=a.dtype, device=a.device)
                self.q[j] = self.q[j].moved(eye + scale * precision, scale * shift, step)
        return -(data - kl - self.gate_term)

    def store(self) -> None:
        """Write every q(u) into its expert's variational distribution (mean and factor)."""
        for expert, q in zip(self.experts, self.q, strict=True):
            q.store(expert)
