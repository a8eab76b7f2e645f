"""Numerical kernels shared by the generic and the grid belief propagation solvers.

Both solvers work on binary pairwise models in Ising form,
``P(s) ∝ exp(Σ_i h_i s_i + Σ_(i,j) K_ij s_i s_j)`` with ``s = 2x - 1``. A log-domain
message ``log m_(i→j)(x_j)`` is kept only through its half log-ratio
``ν_(i→j) = (log m(1) - log m(0)) / 2`` (the other degree of freedom is a normaliser), and
the sum-product update becomes ``ν_(i→j) = atanh(tanh(K_ij) · tanh(η_i - ν_(j→i)))`` with
``η_i = h_i + Σ_k ν_(k→i)`` the half log-odds of the belief of ``i``. Clamped variables have
``h_i = ±inf``, which the update handles exactly (``tanh(±inf) = ±1``).

In float32 the update loses precision when ``tanh(K)`` approaches 1: about ``3e-4`` in a
message at ``|K| = 5``, ``1e-7`` at the default ``K = 0.4``; use float64 for strong couplings.
Solver options are validated by `probaff.maps.options.BPOptions`, not here.
"""

from __future__ import annotations

import math

import torch

from probaff.errors import InputError

__all__ = [
    "check_log_potentials",
    "clamp_fields",
    "damped_update_",
    "ising_messages_",
    "marginals_from_fields",
]


def check_log_potentials(unary: torch.Tensor) -> torch.Tensor:
    """Refuse NaN or ``+inf`` log unary potentials; mark variables with no possible state.

    Args:
        unary: ``(*event_shape, 2)`` log unary potentials.

    Returns:
        ``event_shape`` bool mask of the variables whose two states both have log potential
        ``-inf`` (an infeasible model; the caller says where).

    Raises:
        InputError: If an entry is NaN or ``+inf``.
    """
    if bool(torch.isnan(unary).any()) or bool((unary == float("inf")).any()):
        raise InputError("unary_log contains NaN or +inf; log potentials must be < +inf.")
    return torch.isinf(unary).all(dim=-1)


def clamp_fields(fields: torch.Tensor, evidence: torch.Tensor) -> torch.Tensor:
    """Apply evidence to half log-odds fields.

    Args:
        fields: ``event_shape`` fields ``h``.
        evidence: ``(B, *event_shape)`` int8 values in {-1, 0, 1}.

    Returns:
        ``(B, *event_shape)`` fields, ``+inf`` where clamped to 1 and ``-inf`` where clamped
        to 0; a read-only broadcast view of `fields` when nothing is clamped.
    """
    ev = evidence.to(fields.device)
    if not bool((ev >= 0).any()):
        return fields.expand(ev.shape)  # nothing clamped: a broadcast view, no copy
    inf = torch.tensor(math.inf, dtype=fields.dtype, device=fields.device)
    out = torch.where(ev == 1, inf, fields.expand(ev.shape))
    return torch.where(ev == 0, -inf, out)


def ising_messages_(cavity: torch.Tensor, tanh_coupling: torch.Tensor | float) -> torch.Tensor:
    """Turn cavity half log-odds into outgoing half log-ratio messages, in place.

    Args:
        cavity: Any shape; ``η_i - ν_(j→i)`` for each directed edge ``i → j``.
        tanh_coupling: ``tanh(K)`` broadcastable to `cavity`.

    Returns:
        `cavity`, overwritten with ``atanh(tanh(K) · tanh(cavity))``.
    """
    return cavity.tanh_().mul_(tanh_coupling).atanh_()


def damped_update_(messages: torch.Tensor, proposals: torch.Tensor, damping: float) -> float:
    """Move `messages` towards `proposals`; both are updated in place.

    Args:
        messages: Current messages, any shape.
        proposals: Undamped new messages, same shape; overwritten with the residual.
        damping: Weight of the old message, ``m ← damping · m + (1 - damping) · proposal``.

    Returns:
        The largest absolute residual ``|proposal - message|`` (0 for empty tensors).
    """
    if proposals.numel() == 0:
        return 0.0
    residual = proposals.sub_(messages)
    low, high = torch.aminmax(residual)
    messages.add_(residual, alpha=1.0 - damping)
    return max(-float(low), float(high))


def marginals_from_fields(fields: torch.Tensor) -> torch.Tensor:
    """Marginals from belief half log-odds.

    Args:
        fields: ``(...)`` half log-odds ``η`` (``±inf`` allowed).

    Returns:
        ``(..., 2)`` probabilities ``(P(x=0), P(x=1)) = (σ(-2η), σ(2η))``.
    """
    out = fields.new_empty((*fields.shape, 2))
    doubled = fields * 2.0
    torch.sigmoid(doubled, out=out[..., 1])
    torch.sigmoid(doubled.neg_(), out=out[..., 0])
    return out
