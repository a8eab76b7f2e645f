"""Conversion of user arrays to validated float64 tensors, shared by every model module."""

from __future__ import annotations

from typing import Any

import torch
from torch import Tensor

from probaff._checks import as_float_array, check_finite, check_shape
from probaff.errors import InputError

__all__ = ["as_matrix", "as_vector", "training_rows"]


def _as_float64(name: str, x: Any) -> Tensor:
    if isinstance(x, Tensor):
        return x.detach().to(dtype=torch.float64, device="cpu")
    return torch.as_tensor(as_float_array(name, x))


def as_matrix(name: str, x: Any, *, n_rows: int | None = None, n_cols: int | None = None) -> Tensor:
    """Return `x` as a finite float64 matrix with at least one row.

    Args:
        name: What `x` is, as the user knows it (e.g. ``"features X"``).
        x: Array-like or tensor, `(N, C)`.
        n_rows: Required number of rows, or ``None`` for any.
        n_cols: Required number of columns, or ``None`` for any.

    Returns:
        A detached CPU float64 tensor, `(N, C)`.

    Raises:
        InputError: If `x` is not 2-D, has zero rows, the wrong size, or holds NaN/inf.
    """
    t = _as_float64(name, x)
    if t.dim() != 2:
        raise InputError(
            f"{name} must be a 2-D array (samples x columns), got {t.dim()} dimension(s); "
            "reshape a single column with .reshape(-1, 1)."
        )
    if t.shape[0] == 0:
        raise InputError(f"{name} has zero samples; at least one row is needed.")
    check_shape(name, t, (n_rows, n_cols))
    check_finite(name, t)
    return t


def as_vector(name: str, x: Any, *, n: int) -> Tensor:
    """Return `x` as a finite float64 vector of length `n`.

    Args:
        name: What `x` is.
        x: Array-like or tensor, `(n,)`.
        n: Required length.

    Returns:
        A detached CPU float64 tensor, `(n,)`.

    Raises:
        InputError: If `x` has the wrong shape or holds NaN/inf.
    """
    t = _as_float64(name, x)
    check_shape(name, t, (n,))
    check_finite(name, t)
    return t


def training_rows(X: Any, Y: Any, unit: str) -> tuple[Tensor, Tensor]:
    """Features `(N, D)` and effects `(N, E)` of a training set, with the same rows.

    Args:
        X: Features, `(N, D)`.
        Y: Effects, `(N, E)`.
        unit: What a row is (``"push"``, ``"interaction"``), for the message.

    Returns:
        `X` and `Y` as float64 tensors.

    Raises:
        InputError: For NaN/inf, empty or non-2-D inputs, or different numbers of rows.
    """
    x = as_matrix("features X", X)
    y = as_matrix("effects Y", Y)
    if y.shape[0] != x.shape[0]:
        raise InputError(
            f"features X has {x.shape[0]} samples but effects Y has {y.shape[0]}; "
            f"they must have one row per {unit}."
        )
    return x, y
