"""Evidence batches: which variables are clamped to 0 or 1 in each conditioned copy of a map.

An evidence batch is a ``(B, V)`` integer tensor with `FREE` (-1) for unobserved variables
and 0 or 1 for clamped ones. Clamping a variable replaces its unary factor by the indicator
of the observed value, so evidence overrides the classifier.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import torch

from probaff._checks import as_real_array, as_real_tensor, check_count, check_finite
from probaff.errors import InputError

__all__ = ["FREE", "as_evidence", "make_evidence", "single_variable_evidence"]

FREE = -1
"""Evidence value of a variable that is not clamped."""


def as_evidence(evidence: Any, event_shape: tuple[int, ...]) -> tuple[torch.Tensor, bool]:
    """Validate an evidence array and give it one leading batch axis.

    Args:
        evidence: ``event_shape`` (one assignment) or ``(B, *event_shape)`` values in
            {-1, 0, 1}; None means a single, unconditioned copy.
        event_shape: Shape of one assignment, ``(V,)`` for a graph or ``(H, W)`` for a grid.

    Returns:
        ``(B, *event_shape)`` int8 tensor and whether the input had a batch axis.

    Raises:
        InputError: On a shape that does not end in `event_shape`, or values other than
            -1, 0 and 1.
    """
    if evidence is None:
        return torch.full((1, *event_shape), FREE, dtype=torch.int8), False
    ev = as_real_tensor("evidence", evidence).cpu()
    n = len(event_shape)
    if ev.dim() not in (n, n + 1) or tuple(ev.shape[ev.dim() - n :]) != tuple(event_shape):
        raise InputError(
            f"evidence has shape {tuple(ev.shape)}, expected {tuple(event_shape)} or "
            f"(B, {', '.join(str(s) for s in event_shape)}): one column per variable of the "
            "model, -1 for free and 0/1 for clamped variables."
        )
    if ev.is_floating_point():
        check_finite("evidence", ev)
    if ev.dtype == torch.bool:
        raise InputError("evidence must hold -1 (free), 0 or 1, not booleans.")
    valid = (ev == FREE) | (ev == 0) | (ev == 1)
    if not bool(valid.all()):
        bad = ev[~valid].reshape(-1)[:5].tolist()
        raise InputError(
            f"evidence values must be -1 (free), 0 or 1; got {bad} (first offending entries)."
        )
    batched = ev.dim() == n + 1
    ev = ev.to(torch.int8)
    return (ev if batched else ev.unsqueeze(0)).contiguous(), batched


def _is_index(value: Any) -> bool:
    """Whether `value` is an integer (a Python or numpy int, not a bool)."""
    return isinstance(value, (int, np.integer)) and not isinstance(value, (bool, np.bool_))


def make_evidence(num_variables: int, assignments: Sequence[Mapping[int, int]]) -> torch.Tensor:
    """Build an evidence batch from ``{variable: value}`` mappings.

    Args:
        num_variables: Number of variables ``V`` of the model (an integer >= 0).
        assignments: One mapping per batch row; values must be 0 or 1.

    Returns:
        ``(B, V)`` int8 tensor, `FREE` where a row does not mention a variable.

    Raises:
        InputError: If `num_variables` is not an integer >= 0, a variable index does not
            exist or a value is not 0/1.
    """
    num_variables = check_count("num_variables", num_variables, minimum=0)
    if isinstance(assignments, (str, bytes, Mapping)) or not isinstance(assignments, Sequence):
        raise InputError(
            f"assignments must be a list of {{variable: value}} mappings, got "
            f"{type(assignments).__name__}; e.g. [{{0: 1}}, {{3: 0}}]."
        )
    out = torch.full((len(assignments), num_variables), FREE, dtype=torch.int8)
    for row, assignment in enumerate(assignments):
        if not isinstance(assignment, Mapping):
            raise InputError(
                f"assignments[{row}] must be a {{variable: value}} mapping, got "
                f"{type(assignment).__name__}."
            )
        for var, value in assignment.items():
            if not _is_index(var):
                raise InputError(
                    f"evidence row {row} names variable {var!r}; variables are integer indices."
                )
            v = int(var)
            if not 0 <= v < num_variables:
                raise InputError(
                    f"evidence row {row} clamps variable {var}, but the model has "
                    f"{num_variables} variables (indices 0..{num_variables - 1})."
                )
            if value not in (0, 1):
                raise InputError(f"evidence row {row} sets variable {v} to {value!r}; use 0 or 1.")
            out[row, v] = int(value)
    return out


def single_variable_evidence(
    num_variables: int, variables: Sequence[int] | np.ndarray | None = None
) -> torch.Tensor:
    """Every candidate observation of one variable: each clamped to 1, then to 0.

    Args:
        num_variables: Number of variables ``V`` (an integer >= 0).
        variables: ``(n,)`` candidate variables; all ``V`` when None.

    Returns:
        ``(2 n, V)`` int8 tensor; row ``2k`` clamps ``variables[k]`` to 1 and row
        ``2k + 1`` clamps it to 0.

    Raises:
        InputError: If `num_variables` is not an integer >= 0, or a candidate variable does
            not exist.
    """
    num_variables = check_count("num_variables", num_variables, minimum=0)
    if variables is None:
        cand = np.arange(num_variables)
    else:
        given = as_real_array("variables", variables).reshape(-1)
        if given.size and given.dtype.kind not in "iu":  # [] is no candidate
            raise InputError(
                f"variables must be integer variable indices, got dtype {given.dtype}; e.g. "
                "variables=[0, 3, 7]."
            )
        cand = given.astype(np.int64)
    if cand.size and (cand.min() < 0 or cand.max() >= num_variables):
        bad = cand[(cand < 0) | (cand >= num_variables)][:5].tolist()
        raise InputError(
            f"candidate variables {bad} do not exist; the model has {num_variables} "
            f"variables (indices 0..{num_variables - 1})."
        )
    idx = torch.as_tensor(cand, dtype=torch.int64)
    out = torch.full((2 * idx.numel(), num_variables), FREE, dtype=torch.int8)
    rows = torch.arange(idx.numel())
    out[2 * rows, idx] = 1
    out[2 * rows + 1, idx] = 0
    return out
