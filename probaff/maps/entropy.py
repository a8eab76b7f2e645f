"""Entropy of binary marginals, per variable and summed over a map, batched."""

from __future__ import annotations

from typing import Any

import torch

from probaff._checks import as_real_tensor, check_probability
from probaff.errors import InputError

__all__ = ["map_entropy", "marginal_entropy"]


def marginal_entropy(marginals: Any) -> torch.Tensor:
    """Shannon entropy of each variable's marginal, in nats.

    Args:
        marginals: ``(..., V, 2)`` probabilities ``(P(x=0), P(x=1))``.

    Returns:
        ``(..., V)`` entropies ``-Σ_x P(x) log P(x)`` (``0 log 0 = 0``).

    Raises:
        InputError: If the last axis is not of size 2 or entries are not probabilities.
    """
    probs = as_real_tensor("marginals", marginals)
    if probs.dim() < 1 or probs.shape[-1] != 2:
        raise InputError(f"marginals must have shape (..., V, 2), got {tuple(probs.shape)}.")
    if not probs.is_floating_point():
        probs = probs.double()
    check_probability("marginals", probs)
    return -torch.special.xlogy(probs, probs).sum(dim=-1)


def map_entropy(marginals: Any) -> torch.Tensor:
    """Whole-map entropy: the sum of per-variable marginal entropies, in nats.

    Args:
        marginals: ``(..., V, 2)`` probabilities.

    Returns:
        ``(...)`` entropies, e.g. ``(B,)`` for a batch of conditioned maps.
    """
    return marginal_entropy(marginals).sum(dim=-1)
