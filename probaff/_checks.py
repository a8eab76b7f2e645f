"""Input validation shared by every module: one place for shape, finiteness and range checks."""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any, TypeVar

import numpy as np
import torch

from probaff.errors import InputError

__all__ = [
    "as_bool_array",
    "as_float_array",
    "as_float_vectors",
    "as_real_array",
    "as_real_tensor",
    "check_array_fields",
    "check_bool",
    "check_box_sizes",
    "check_count",
    "check_finite",
    "check_number",
    "check_output_dir",
    "check_output_file",
    "check_positive",
    "check_probability",
    "check_rows",
    "check_shape",
    "default_or_instance",
    "real_float64",
    "real_number",
]

T = TypeVar("T")


def _as_array(x: Any) -> np.ndarray:
    if isinstance(x, torch.Tensor):
        return x.detach().cpu().numpy()
    return np.asarray(x)


def _is_complex(x: Any) -> bool:
    if isinstance(x, torch.Tensor):
        return x.is_complex()
    try:
        return np.asarray(x).dtype.kind == "c"
    except (TypeError, ValueError):
        return False


def _not_numeric(name: str, x: Any) -> InputError:
    """The error of an array argument that holds no real numbers (strings, None, ...)."""
    if _is_complex(x):  # scikit-learn's estimator checks ask for these words
        return InputError(
            f"{name} holds complex numbers (Complex data not supported): got "
            f"{_describe(x)}; give real numbers, e.g. its real part or magnitude."
        )
    return InputError(
        f"{name} must be a numeric array (numbers of one shape), got "
        f"{_describe(x)}; convert it to floats first."
    )


def real_float64(x: Any) -> np.ndarray | None:
    """`x` as a float64 array, or None where it is not an array of real numbers.

    The core of `as_float_array`, for callers that word their own error: None for strings
    that are not numbers, ``None`` (numpy would cast it to NaN), objects, complex numbers
    (numpy would keep their real parts with a warning) and ragged nested lists.

    Args:
        x: Array-like or tensor of any shape.

    Returns:
        `x` as a float64 array of the same shape (`x` itself when it already is one), or
        None.
    """
    if isinstance(x, torch.Tensor):
        x = x.detach().cpu().numpy()
    try:
        arr = x if isinstance(x, np.ndarray) else np.asarray(x)
        if arr.dtype.kind == "c" or (arr.dtype.kind == "O" and any(v is None for v in arr.flat)):
            return None
        return np.asarray(arr, dtype=np.float64)
    except (TypeError, ValueError):
        return None


def as_float_array(name: str, x: Any, *, copy: bool = False) -> np.ndarray:
    """Return `x` as a float64 numpy array, or raise `InputError` when it is not numeric.

    The one conversion of user arrays in probaff (`real_float64` with the argument's name in
    the error): non-numeric strings, ``None``, objects, complex numbers and ragged nested
    lists are refused instead of raising numpy's own error or casting silently.

    Args:
        name: What `x` is, as the user knows it (e.g. ``"points"``).
        x: Array-like or tensor of any shape.
        copy: Always return a new array (else `x` itself when it already is float64).

    Returns:
        `x` as a float64 array of the same shape.
    """
    arr = real_float64(x)
    if arr is None:
        raise _not_numeric(name, x)
    return arr.copy() if copy else arr


def as_real_array(name: str, x: Any) -> np.ndarray:
    """Return `x` as a numpy array of real numbers of its own kind, or raise `InputError`.

    The counterpart of `as_float_array` for arguments whose dtype carries meaning (integer
    indices, masks): bools stay bool, integers other than uint8 become int64 and floats keep
    their precision (a Python list of floats gives float64). A tensor is moved to the CPU.
    Strings, ``None``, objects, complex numbers and ragged nested lists are refused with the
    argument's name instead of numpy's own error (or its silent cast of complex numbers).

    Args:
        name: What `x` is, as the user knows it (e.g. ``"distances"``).
        x: Array-like or tensor of any shape.

    Returns:
        An array of `x`'s shape (`x` itself, or a view of a CPU tensor, where the dtype
        allows).
    """
    if isinstance(x, torch.Tensor):
        x = as_real_tensor(name, x).cpu().numpy()
    try:
        arr = x if isinstance(x, np.ndarray) else np.asarray(x)
    except (TypeError, ValueError):
        raise _not_numeric(name, x) from None
    if arr.dtype.kind not in "biuf":
        raise _not_numeric(name, x)
    if arr.dtype.kind in "iu" and arr.dtype != np.uint8:
        arr = arr.astype(np.int64, copy=False)
    return arr


def as_real_tensor(name: str, x: Any) -> torch.Tensor:
    """Return `x` as a detached real tensor of its own kind, or raise `InputError`.

    The tensor form of `as_real_array`, for arguments whose dtype carries meaning (integer
    indices, float32 potentials): a tensor keeps its dtype and device; any other array-like
    goes through `as_real_array`, so bools stay bool, integers become int64 and floats
    float64 (a Python list of floats too, where ``torch.as_tensor`` would give float32).
    Complex tensors are refused, where torch would drop their imaginary parts with a warning.

    Args:
        name: What `x` is, as the user knows it (e.g. ``"unary_log"``).
        x: Array-like or tensor of any shape.

    Returns:
        A detached tensor of `x`'s shape (sharing memory with a tensor or numpy array `x`
        where the dtype allows).
    """
    if isinstance(x, torch.Tensor):
        if x.is_complex():
            raise _not_numeric(name, x)
        return x.detach()
    arr = as_real_array(name, x)
    if any(stride < 0 for stride in arr.strides):  # torch cannot view reversed axes
        arr = arr.copy()
    return torch.as_tensor(arr)


def as_float_vectors(
    name: str, x: Any, width: int, what: str, *, finite: bool = True
) -> np.ndarray:
    """Return `x` as float64 vectors of `width` numbers, `(..., width)`, finite by default.

    Args:
        name: What `x` is, as the user knows it (e.g. ``"poses"``).
        x: Array-like or tensor, `(..., width)`.
        width: The length of the last axis.
        what: What the vectors are, for the message (e.g. ``"pairs of numbers"``).
        finite: Refuse NaN and infinite values; False lets them through (where NaN means
            "not seen" and propagates).

    Raises:
        InputError: Naming `name`, for anything but real numbers with a last axis of `width`,
            or (with `finite`) NaN or infinite values.
    """
    arr = real_float64(x)
    if arr is None or arr.ndim == 0 or arr.shape[-1] != width:
        raise InputError(f"{name} must be (..., {width}) {what}, got {x!r:.80}.")
    if finite:
        check_finite(name, arr)
    return arr


def as_bool_array(name: str, x: Any) -> np.ndarray:
    """Return `x` as a bool numpy array, or raise `InputError` unless it holds only 0 and 1.

    Bools pass as they are; real numbers must be exactly 0 or 1. NaN, 0.5, strings and
    complex numbers are refused, where numpy's cast to bool would call each of them True.

    Args:
        name: What `x` is, as the user knows it (e.g. ``"occupancy"``).
        x: Array-like or tensor of any shape.

    Returns:
        `x` as a bool array of the same shape.
    """
    arr = as_real_array(name, x)
    if arr.dtype == np.bool_:
        return arr
    outside = ~np.isin(arr, (0, 1))  # NaN is in neither
    if outside.any():
        raise InputError(
            f"{name} must be bool or 0/1 values, got {arr[outside].ravel()[0].item()!r} (dtype "
            f"{arr.dtype}); give a boolean mask."
        )
    return arr.astype(bool)


def _describe(x: Any) -> str:
    """A short description of a value that is not a numeric array, for error messages."""
    if isinstance(x, torch.Tensor):
        return f"a tensor of dtype {x.dtype}"
    if isinstance(x, np.ndarray):
        return f"an array of dtype {x.dtype}"
    if isinstance(x, (list, tuple)) and x:
        inner = {type(v).__name__ for v in x}
        return f"a {type(x).__name__} of {', '.join(sorted(inner))}"
    return repr(x)[:60]


def check_finite(name: str, x: Any) -> None:
    """Raise `InputError` if `x` holds NaN or infinite values.

    Args:
        name: What `x` is, as the user knows it (e.g. ``"features"``).
        x: Array-like or tensor of any shape; one that holds anything but real numbers
            (strings, None, complex numbers, a ragged list) is refused too.
    """
    try:
        arr = _as_array(x)
    except ValueError:  # a ragged nested list
        raise _not_numeric(name, x) from None
    if arr.dtype.kind not in "biuf":
        raise _not_numeric(name, x)
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
    if isinstance(x, torch.Tensor):
        actual = tuple(x.shape)
    else:
        try:
            actual = tuple(_as_array(x).shape)
        except ValueError:  # a ragged nested list
            raise InputError(
                f"{name} is a ragged nested list (rows of different lengths); give an array "
                "whose rows all have the same length."
            ) from None
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
    if isinstance(value, (bool, np.bool_)):  # True is not a number here, though float(True) is
        raise InputError(f"{name} must be a number, got {value!r}.")
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise InputError(f"{name} must be a number, got {value!r}.") from None
    if not math.isfinite(v) or v < 0 or (v == 0 and not allow_zero):
        bound = ">= 0" if allow_zero else "> 0"
        raise InputError(f"{name} must be a finite number {bound}, got {value!r}.")


def real_number(value: Any) -> float:
    """`value` as a `float` if it is a real number (a bool or a string is not), else NaN.

    The test behind `check_number`, for callers that word their own error.
    """
    ok = isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(
        value, (bool, np.bool_)
    )
    return float(value) if ok else math.nan


def check_number(name: str, value: Any, *, bound: str = "", unit: str = "") -> float:
    """Return `value` as a `float`, or raise `InputError` unless it is a finite real number.

    Stricter than `check_positive`: a string (``"0.02"``, ``"two cm"``) or a bool is refused
    even where `float` would take it, since such a value in a record (a dataset's ``meta``)
    is a mistake, not a number.

    Args:
        name: What `value` is, as the user knows it (e.g. ``"meta['push_height']"``).
        value: The scalar to check.
        bound: ``""`` (any finite number), ``"> 0"`` or ``">= 0"``.
        unit: The unit named in the message (e.g. ``"m"``), if any.

    Returns:
        `value` as a builtin `float`.
    """
    want = "a finite number" + (f" {bound}" if bound else "") + (f" ({unit})" if unit else "")
    v = real_number(value)
    if not math.isfinite(v) or (bound == "> 0" and v <= 0) or (bound == ">= 0" and v < 0):
        raise InputError(f"{name} must be {want}, got {value!r}.")
    return v


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


def check_array_fields(owner: object, label: str, shapes: Mapping[str, Sequence[int]]) -> None:
    """Set the named fields of a frozen dataclass to float arrays of the shapes given.

    Args:
        owner: The dataclass instance, in its ``__post_init__``.
        label: How errors name it, e.g. ``"PushBatch"`` (a field is ``"PushBatch.poses"``).
        shapes: Field name -> its expected shape.

    Raises:
        InputError: Naming the field, for another shape or a NaN or infinite value.
    """
    for name, shape in shapes.items():
        arr = np.asarray(getattr(owner, name), dtype=float)
        check_shape(f"{label}.{name}", arr, shape)
        check_finite(f"{label}.{name}", arr)
        object.__setattr__(owner, name, arr)


def check_rows(
    name: str, x: Any, columns: int, empty_message: str, *, copy: bool = False
) -> np.ndarray:
    """Return `x` as `N >= 1` rows of `columns` finite floats, `(N, columns)`.

    Args:
        name: What `x` is.
        x: Array-like `(N, columns)`.
        columns: How many numbers a row holds.
        empty_message: The message of the error for no rows at all.
        copy: Always return a new array (see `as_float_array`).

    Raises:
        InputError: Naming `name`, for another shape or a NaN or infinite value; with
            `empty_message` for no rows.
    """
    arr = as_float_array(name, x, copy=copy)
    check_shape(name, arr, (None, columns))
    if arr.shape[0] == 0:
        raise InputError(empty_message)
    check_finite(name, arr)
    return arr


def check_bool(name: str, value: Any) -> bool:
    """Return `value` if it is a bool, else raise `InputError` naming `name`.

    Strict: 0, 1, strings and numpy booleans are refused, since a switch given as anything
    but True or False is a mistake.
    """
    if not isinstance(value, bool):
        raise InputError(f"{name} must be True or False, got {value!r}.")
    return value


def check_box_sizes(name: str, sizes: Any, empty_message: str, *, copy: bool = False) -> np.ndarray:
    """Return box extents `(N, 3)`, `N >= 1`, as floats that are finite and > 0.

    Args:
        name: What `sizes` is.
        sizes: Array-like `(N, 3)`: each box's extents along its own x, y, z (m).
        empty_message: The message of the error for no boxes at all.
        copy: Always return a new array (see `as_float_array`).

    Raises:
        InputError: Naming `name`, for another shape, no boxes, or an extent that is not a
            finite number > 0.
    """
    arr = check_rows(name, sizes, 3, empty_message, copy=copy)
    if np.any(arr <= 0):
        raise InputError(f"{name} must be > 0 along every axis; got a zero or negative extent.")
    return arr


def default_or_instance(
    name: str, value: object, kind: type[T], default: Callable[[], T], what: str
) -> T:
    """`value` when it is a `kind`, `default()` when it is None.

    Args:
        name: What `value` is, as the user wrote it.
        value: The argument.
        kind: The type it must have.
        default: Makes the value of None (called only then).
        what: How the message names `kind`, e.g. ``"a BPOptions"``.

    Raises:
        InputError: ``"{name} must be {what} or None, got {type}."`` for anything else.
    """
    if value is None:
        return default()
    if not isinstance(value, kind):
        raise InputError(f"{name} must be {what} or None, got {type(value).__name__}.")
    return value


def _check_parents(name: str, p: Path, exists: bool) -> None:
    """Raise `InputError` unless the nearest existing folder at or above `p` is writable.

    Args:
        name: The argument's name.
        p: The output path.
        exists: Whether `p` itself exists (and is then the folder to check).
    """
    if exists:
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
    if p.exists() and not p.is_dir():
        raise InputError(
            f"{name} {p} is a file, not a folder; choose a folder path for the output."
        )
    _check_parents(name, p, p.exists())
    return p


def check_output_file(name: str, path: Any) -> Path:
    """Return `path` as a `Path`, or raise `InputError` unless a file can be written there.

    The file counterpart of `check_output_dir`: catches an output path that is a folder, lies
    under a regular file (``/etc/passwd/model.pt``), or lies in a folder that cannot be
    written. Missing parent folders are allowed (writers create them); nothing is created.

    Args:
        name: The argument's name, as the user wrote it (e.g. ``"path"``).
        path: The output file.

    Returns:
        `path` as a `Path`.
    """
    try:
        raw = os.fspath(path)
    except TypeError:
        raise InputError(f"{name} must be a file path, got {path!r}.") from None
    if isinstance(raw, bytes) or raw == "":
        raise InputError(f"{name} must be a non-empty file path (str or Path), got {path!r}.")
    p = Path(raw)
    if p.is_dir():
        raise InputError(
            f"{name} {p} is a folder, not a file; give a file path inside it "
            f"(e.g. {p / 'out.bin'})."
        )
    _check_parents(name, p, False)
    return p
