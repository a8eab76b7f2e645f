"""Loopy belief propagation specialised to a regular H x W Ising grid.

The same damped, parallel log-domain updates as `probaff.maps.bp`, but messages are kept in
four dense arrays, one per travel direction, so gathers and segment sums become slices of
``(B, H, W)`` tensors: no index arrays are stored or read. Message ``down[b, r, c]`` travels
from cell ``(r, c)`` to ``(r + 1, c)``, ``up[b, r, c]`` from ``(r + 1, c)`` to ``(r, c)``,
``right[b, r, c]`` from ``(r, c)`` to ``(r, c + 1)`` and ``left[b, r, c]`` from
``(r, c + 1)`` to ``(r, c)``.

Memory: fields, beliefs, four message arrays and two scratch arrays hold about 8 values per
cell and batch entry (32 bytes in float32) while iterating; they are released before the
``(B, H, W, 2)`` result (2 values per cell) is built.
"""

from __future__ import annotations

from typing import Any

import torch

from probaff._checks import as_real_tensor, check_finite, check_shape
from probaff.errors import InputError
from probaff.maps._kernels import (
    check_log_potentials,
    clamp_fields,
    damped_update_,
    ising_messages_,
    marginals_from_fields,
)
from probaff.maps.bp import BeliefPropagationResult
from probaff.maps.evidence import as_evidence
from probaff.maps.options import MAX_COUPLING, BPOptions, resolve_bp_options

__all__ = ["GRID_BYTES_PER_CELL", "grid_belief_propagation"]

GRID_BYTES_PER_CELL = {torch.float32: 8 * 4, torch.float64: 8 * 8}
"""Peak working-set bytes per cell and batch entry while iterating."""


def _tanh_coupling(name: str, value: Any, shape: tuple[int, int]) -> torch.Tensor:
    """``tanh(J)`` as a 0-dim tensor (one coupling for all edges) or an array of `shape`."""
    t = as_real_tensor(name, value).to(torch.float64)
    if t.dim() != 0:
        check_shape(name, t, shape)
    check_finite(name, t)
    if t.numel() and float(t.abs().max()) > MAX_COUPLING:
        raise InputError(
            f"{name} holds |J| = {float(t.abs().max()):.4g}; belief propagation accepts "
            f"|J| <= {MAX_COUPLING}."
        )
    return torch.tanh(t)


def _grid_beliefs(
    out: torch.Tensor,
    h: torch.Tensor,
    down: torch.Tensor,
    up: torch.Tensor,
    right: torch.Tensor,
    left: torch.Tensor,
) -> None:
    """Belief half log-odds ``(B, H, W)``: fields plus the messages arriving at each cell."""
    out.copy_(h)
    out[:, 1:, :].add_(down)
    out[:, :-1, :].add_(up)
    out[:, :, 1:].add_(right)
    out[:, :, :-1].add_(left)


def _grid_fields(
    unary_log: Any, coupling: float | tuple[Any, Any], evidence: Any, dtype: torch.dtype
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, bool]:
    """Check a grid problem; clamped fields ``(B, H, W)``, tanh couplings, and batchedness.

    Returns:
        The half log-odds fields with evidence clamped ``(B, H, W)``, ``tanh(J)`` of the
        vertical ``(H - 1, W)`` and horizontal ``(H, W - 1)`` edges (`dtype`, on the device
        of `unary_log`), and whether the evidence was batched.
    """
    unary = as_real_tensor("unary_log", unary_log)
    device = unary.device
    check_shape("unary_log", unary, (None, None, 2))
    if bool(check_log_potentials(unary).any()):
        raise InputError("unary_log gives zero potential to both states of some cell.")
    height, width = int(unary.shape[0]), int(unary.shape[1])
    if isinstance(coupling, tuple):
        if len(coupling) != 2:
            raise InputError(
                f"coupling must be one J or a (vertical, horizontal) pair, got a tuple of "
                f"{len(coupling)}; e.g. coupling=0.4 or coupling=(J_v, J_h)."
            )
        vertical, horizontal = coupling
    else:
        vertical = horizontal = coupling
    tk_v = _tanh_coupling("vertical coupling", vertical, (height - 1, width))
    tk_h = _tanh_coupling("horizontal coupling", horizontal, (height, width - 1))
    tk_v, tk_h = tk_v.to(dtype=dtype, device=device), tk_h.to(dtype=dtype, device=device)
    ev, batched = as_evidence(evidence, (height, width))
    fields = (unary[..., 1].to(dtype) - unary[..., 0].to(dtype)) / 2.0
    return clamp_fields(fields, ev.to(device)), tk_v, tk_h, batched


def grid_belief_propagation(
    unary_log: Any,
    coupling: float | tuple[Any, Any],
    evidence: Any = None,
    *,
    options: BPOptions | None = None,
    **overrides: Any,
) -> BeliefPropagationResult:
    """Loopy BP on an H x W grid with Ising factors ``exp(J s_i s_j)`` between 4-neighbours.

    Gives the same result as `probaff.maps.bp.loopy_belief_propagation` on the equivalent
    edge list. A zero coupling removes an edge, so masked (non-rectangular) layouts work too.

    Args:
        unary_log: ``(H, W, 2)`` log unary potentials (``-inf`` marks an impossible state).
        coupling: One ``J`` for every edge, or ``(vertical, horizontal)`` arrays of shapes
            ``(H - 1, W)`` (between ``(r, c)`` and ``(r + 1, c)``) and ``(H, W - 1)``
            (between ``(r, c)`` and ``(r, c + 1)``); ``|J| <= MAX_COUPLING``.
        evidence: None, ``(H, W)`` or ``(B, H, W)`` values in {-1 (free), 0, 1}.
        options: Solver settings; None for `BPOptions()`.
        **overrides: ``damping``, ``tol``, ``max_iterations`` or ``dtype``: override that
            field of `options` when given (not None).

    Returns:
        Result whose ``marginals`` are ``(H, W, 2)``, or ``(B, H, W, 2)`` for batched
        evidence.

    Raises:
        InputError: On malformed potentials, couplings, evidence or solver options.
    """
    opts = resolve_bp_options(options, **overrides)
    damping, tol, dtype = opts.damping, opts.tol, opts.dtype
    h, tk_v, tk_h, batched = _grid_fields(unary_log, coupling, evidence, dtype)
    height, width, device = int(h.shape[1]), int(h.shape[2]), h.device
    batch = h.shape[0]
    down = torch.zeros(batch, height - 1, width, dtype=dtype, device=device)
    up = torch.zeros_like(down)
    right = torch.zeros(batch, height, width - 1, dtype=dtype, device=device)
    left = torch.zeros_like(right)
    # Vertical and horizontal proposals depend on disjoint message arrays, so the two axes
    # are updated one after the other through one pair of scratch buffers.
    scratch_size = max(down.numel(), right.numel())
    scratch = (
        torch.empty(scratch_size, dtype=dtype, device=device),
        torch.empty(scratch_size, dtype=dtype, device=device),
    )
    beliefs = torch.empty_like(h)
    axes = (
        (down, up, tk_v, (slice(None), slice(None, -1)), (slice(None), slice(1, None))),
        (
            right,
            left,
            tk_h,
            (slice(None), slice(None), slice(None, -1)),
            (slice(None), slice(None), slice(1, None)),
        ),
    )

    has_edges = down.numel() + right.numel() > 0
    iterations, delta, converged = 0, 0.0, not has_edges
    while not converged and iterations < opts.max_iterations:
        _grid_beliefs(beliefs, h, down, up, right, left)
        delta = 0.0
        for forward, backward, tk, first, second in axes:
            # forward: first cell -> second cell of each pair; backward: the reverse.
            new_forward = scratch[0][: forward.numel()].view(forward.shape)
            new_backward = scratch[1][: backward.numel()].view(backward.shape)
            torch.sub(beliefs[first], backward, out=new_forward)
            torch.sub(beliefs[second], forward, out=new_backward)
            ising_messages_(new_forward, tk)
            ising_messages_(new_backward, tk)
            delta = max(
                delta,
                damped_update_(forward, new_forward, damping),
                damped_update_(backward, new_backward, damping),
            )
        iterations += 1
        converged = delta < tol
    _grid_beliefs(beliefs, h, down, up, right, left)
    del h, down, up, right, left, scratch, axes
    marginals = marginals_from_fields(beliefs)
    return BeliefPropagationResult(
        marginals=marginals if batched else marginals[0],
        converged=bool(converged),
        iterations=iterations,
        max_delta=float(delta),
    )
