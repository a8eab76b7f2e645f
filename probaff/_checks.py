"""Input validation shared by every module: one place for shape, finiteness and range checks."""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import torch

from probaff.errors import InputError

__all__ = [
    "check_count",
    "check_finite",
    "check_output_dir",
    "check_positive",
    "check_probability",
    "check_shape",
]


def _as_array(x: Any) -> np.ndarray:
    if isinstance(x, torch.Tensor):
        return x.detach().cpu().numpy()
    return np.asarray(x)


def check_finite(name: str, x: Any) -> None:
    """Raise `InputError` if `x` holds NaN or infinite values.

    Args:
        name: What `x` is, as the user knows it (e.g. ``"features"``).
        x: Array-like or tensor of any shape.
    """
    arr = _as_array(x)
    if arr.size and not np.all(np.isfinite(arr)):
        bad = int(np.size(arr) - np.count_nonzero(np.isfinite(arr)))
        raise InputError(
            f"{name} contains {bad} NaN or infinite value(s); clean or impute them before "
            "passing them to probaff."
        )


def check_shape(name: str, x: Any, shape: Sequence[int | None]) -> None:
    """Raise `InputError` unless `x` has `shape` (``None`` matches any size).

    Args:
        name: What `x` is.
        x: Array-like or tensor.
        shape: Expected shape; ``None`` entries are wildcards.
    """
    actual = tuple(x.shape) if isinstance(x, torch.Tensor) else tuple(_as_array(x).shape)
    ok = len(actual) == len(shape) and all(
        e is None or e == a for e, a in zip(shape, actual, strict=True)
    )
    if not ok:
        want = "(" + ", ".join("*" if e is None else str(e) for e in shape) + ")"
        raise InputError(f"{name} has shape {actual}, expected {want}.")


def check_positive(name: str, value: float, *, allow_zero: bool = False) -> None:
    """Raise `InputError` unless `value` is a finite number > 0 (or >= 0 if `allow_zero`).

    Args:
        name: What `value` is.
        value: The scalar to check.
        allow_zero: Accept exactly zero.
    """
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise InputError(f"{name} must be a number, got {value!r}.") from None
    if not math.isfinite(v) or v < 0 or (v == 0 and not allow_zero):
        bound = ">= 0" if allow_zero else "> 0"
        raise InputError(f"{name} must be a finite number {bound}, got {value!r}.")


def check_count(name: str, value: Any, *, minimum: int = 1) -> int:
    """Return `value` as an `int`, or raise `InputError` unless it is an integer >= `minimum`.

    Every count argument in probaff (iterations, restarts, samples, experts, workers, ...)
    goes through this one check. Integral numbers of another type (``numpy.int64``,
    ``3.0``) are accepted; booleans, fractions (``0.5``), NaN, infinities and strings are
    not.

    Args:
        name: The argument's name, as the user wrote it.
        value: The count to check.
        minimum: Smallest allowed value (``1`` for "positive", ``0`` for "non-negative").

    Returns:
        `value` as a builtin `int`.
    """
    bound = "a positive integer" if minimum == 1 else f"an integer >= {minimum}"
    if isinstance(value, (bool, str, bytes)):
        raise InputError(f"{name} must be {bound}, got {value!r}.")
    try:
        as_float = float(value)
    except (TypeError, ValueError):
        raise InputError(f"{name} must be {bound}, got {value!r}.") from None
    if not math.isfinite(as_float) or as_float != int(as_float) or int(as_float) < minimum:
        raise InputError(f"{name} must be {bound}, got {value!r}.")
    return int(as_float)


def check_probability(name: str, x: Any) -> None:
    """Raise `InputError` unless every entry of `x` is a finite probability in [0, 1].

    Args:
        name: What `x` is.
        x: Array-like or tensor of any shape.
    """
    check_finite(name, x)
    arr = _as_array(x)
    if arr.size and (arr.min() < 0 or arr.max() > 1):
        raise InputError(
            f"{name} must lie in [0, 1]; got values in [{arr.min():.4g}, {arr.max():.4g}]."
        )


def check_output_dir(name: str, path: Any) -> Path:
    """Return `path` as a `Path`, or raise `InputError` unless it is, or can become, a folder.

    Catches, before any work starts, an output path that is a regular file, lies under one
    (``/etc/passwd/x``), or lies in a folder that cannot be written; the folder itself is not
    created.

    Args:
        name: The argument's name, as the user wrote it (e.g. ``"--out"``).
        path: The output folder.

    Returns:
        `path` as a `Path`.
    """
    try:
        p = Path(os.fspath(path))
    except TypeError:
        raise InputError(f"{name} must be a folder path, got {path!r}.") from None
    if str(p) == "":
        raise InputError(f"{name} is empty; give the output folder's path.")
    if p.exists():
        if not p.is_dir():
            raise InputError(
                f"{name} {p} is a file, not a folder; choose a folder path for the output."
            )
        existing = p
    else:
        existing = next(
            (a for a in p.absolute().parents if a.exists() or a.is_symlink()), Path(p.anchor or ".")
        )
        if not existing.is_dir():
            raise InputError(
                f"{name} {p} lies under {existing}, which is a file, not a folder; choose an "
                "output path whose parents are folders (or do not exist yet)."
            )
    if not os.access(existing, os.W_OK | os.X_OK):
        raise InputError(
            f"{name} {p}: the folder {existing} is not writable; choose an output path you "
            "may write to."
        )
    return p
