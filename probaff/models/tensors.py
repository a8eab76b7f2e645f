"""Conversion of user arrays to validated float64 tensors, shared by every model module."""

from __future__ import annotations

from typing import Any, Self

import torch
from torch import Tensor

from probaff._checks import as_float_array, as_real_tensor, check_finite, check_shape
from probaff.errors import InputError

__all__ = [
    "DeviceCheckedModule",
    "as_matrix",
    "as_vector",
    "check_to_device",
    "resolve_device",
    "training_rows",
]

DeviceLike = str | torch.device | int


def resolve_device(name: str, device: DeviceLike | None) -> torch.device:
    """Return `device` as a `torch.device` that exists on this machine.

    Args:
        name: What `device` is, as the user knows it (e.g. ``"device"``).
        device: ``"cpu"``, ``"cuda"``, ``"cuda:1"``, ``"mps"``, a `torch.device`, a CUDA
            index, or None for the CPU.

    Returns:
        The device (``cuda`` gets its current index).

    Raises:
        InputError: For a malformed name or a device that this machine does not have.
    """
    if device is None:
        return torch.device("cpu")
    try:
        dev = torch.device("cuda", device) if isinstance(device, int) else torch.device(device)
    except (RuntimeError, TypeError, ValueError) as exc:
        raise InputError(
            f"{name} {device!r} is not a torch device; use 'cpu', 'cuda', 'cuda:0' or 'mps'."
        ) from exc
    if dev.type == "cuda":
        count = torch.cuda.device_count() if torch.cuda.is_available() else 0
        index = torch.cuda.current_device() if dev.index is None and count else dev.index or 0
        if index >= count:
            have = f"this machine has {count} CUDA device(s)" if count else "CUDA is unavailable"
            raise InputError(f"{name} {device!r} does not exist: {have}; use 'cpu'.")
        return torch.device("cuda", index)
    if dev.type == "mps" and not torch.backends.mps.is_available():
        raise InputError(f"{name} {device!r} does not exist: MPS is unavailable; use 'cpu'.")
    if dev.type not in ("cpu", "cuda", "mps", "meta"):
        raise InputError(f"{name} {device!r} is not supported; use 'cpu', 'cuda' or 'mps'.")
    return dev


def check_to_device(args: tuple[Any, ...], kwargs: dict[str, Any]) -> None:
    """Check the device among the arguments of a `torch.nn.Module.to` call.

    Args:
        args: The positional arguments (a device, dtype or tensor first).
        kwargs: The keyword arguments (``device=`` among them).

    Raises:
        InputError: For a malformed device or one that this machine does not have.
    """
    device = kwargs.get("device")
    first = args[0] if args else None
    if (
        device is None
        and isinstance(first, (str, torch.device, int))
        and not isinstance(first, bool)
    ):
        device = first
    if device is not None:
        resolve_device("device", device)


class DeviceCheckedModule(torch.nn.Module):
    """A `torch.nn.Module` whose `to` and `cuda` refuse a device this machine does not have."""

    def to(self, *args: Any, **kwargs: Any) -> Self:
        """`torch.nn.Module.to`, refusing a device that this machine does not have.

        Raises:
            InputError: For a malformed device or one that does not exist.
        """
        check_to_device(args, kwargs)
        return super().to(*args, **kwargs)

    def cuda(self, device: int | torch.device | None = None) -> Self:
        """`torch.nn.Module.cuda`, refusing a CUDA device that this machine does not have.

        Raises:
            InputError: On a machine without CUDA, or for a CUDA index it does not have.
        """
        resolve_device("device", "cuda" if device is None else device)
        return super().cuda(device)


def _as_float64(name: str, x: Any, device: torch.device | None) -> Tensor:
    if isinstance(x, Tensor):
        t = as_real_tensor(name, x)
        return t.to(dtype=torch.float64, device=t.device if device is None else device)
    return torch.as_tensor(as_float_array(name, x), device=device)


def _check_finite(name: str, t: Tensor) -> None:
    """`check_finite` without copying a finite tensor off its device."""
    if t.numel() and not bool(torch.isfinite(t).all()):
        check_finite(name, t)


def as_matrix(
    name: str,
    x: Any,
    *,
    n_rows: int | None = None,
    n_cols: int | None = None,
    device: torch.device | None = None,
) -> Tensor:
    """Return `x` as a finite float64 matrix with at least one row.

    Args:
        name: What `x` is, as the user knows it (e.g. ``"features X"``).
        x: Array-like or tensor, `(N, C)`.
        n_rows: Required number of rows, or ``None`` for any.
        n_cols: Required number of columns, or ``None`` for any.
        device: Device of the result; None keeps a tensor's own device (arrays go to
            the CPU).

    Returns:
        A detached float64 tensor, `(N, C)`.

    Raises:
        InputError: If `x` is not 2-D, has zero rows, the wrong size, or holds NaN/inf.
    """
    t = _as_float64(name, x, device)
    if t.dim() != 2:
        raise InputError(
            f"{name} must be a 2-D array (samples x columns), got {t.dim()} dimension(s); "
            "reshape a single column with .reshape(-1, 1)."
        )
    if t.shape[0] == 0:
        raise InputError(f"{name} has zero samples; at least one row is needed.")
    check_shape(name, t, (n_rows, n_cols))
    _check_finite(name, t)
    return t


def as_vector(name: str, x: Any, *, n: int, device: torch.device | None = None) -> Tensor:
    """Return `x` as a finite float64 vector of length `n`.

    Args:
        name: What `x` is.
        x: Array-like or tensor, `(n,)`.
        n: Required length.
        device: Device of the result; None keeps a tensor's own device (arrays go to
            the CPU).

    Returns:
        A detached float64 tensor, `(n,)`.

    Raises:
        InputError: If `x` has the wrong shape or holds NaN/inf.
    """
    t = _as_float64(name, x, device)
    check_shape(name, t, (n,))
    _check_finite(name, t)
    return t


def training_rows(X: Any, Y: Any, unit: str) -> tuple[Tensor, Tensor]:
    """Features `(N, D)` and effects `(N, E)` of a training set, with the same rows.

    Args:
        X: Features, `(N, D)`.
        Y: Effects, `(N, E)`.
        unit: What a row is (``"push"``, ``"interaction"``), for the message.

    Returns:
        `X` and `Y` as float64 tensors, both on the device of `X` when it is a tensor
        (else the CPU), so a fit runs where its data lives.

    Raises:
        InputError: For NaN/inf, empty or non-2-D inputs, or different numbers of rows.
    """
    x = as_matrix("features X", X)
    y = as_matrix("effects Y", Y, device=x.device)
    if y.shape[0] != x.shape[0]:
        raise InputError(
            f"features X has {x.shape[0]} samples but effects Y has {y.shape[0]}; "
            f"they must have one row per {unit}."
        )
    return x, y
