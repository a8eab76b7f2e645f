"""What the studies' figures share: checks of their inputs, a grid of axes, a titled save.

A figure of study results takes its records as lists of dicts (e.g. the rows of a summary
table), or the same values loaded back from JSON; `check_records` refuses an input that is
not such a list, or a record that lacks a key, and the value checks (`finite_array`,
`finite_number`, `half_width`, `nonempty_text`, `check_flag`, `check_unique`) refuse a
bad value with a message naming it, before anything is drawn.
"""

from __future__ import annotations

import math
import os
from collections.abc import Hashable, Mapping, Sequence
from typing import Any

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from probaff._checks import check_finite, check_positive, check_shape, real_float64
from probaff._io import atomic_save_figure
from probaff.errors import InputError

__all__ = [
    "axes_grid",
    "check_figure_path",
    "check_flag",
    "check_records",
    "check_unique",
    "finite_array",
    "finite_number",
    "half_width",
    "nonempty_text",
    "save_titled",
]


def check_records(
    name: str, records: Any, keys: Sequence[str], what: str
) -> list[Mapping[str, Any]]:
    """The records as a list, or `InputError` for an empty input or a record lacking keys.

    Args:
        name: The argument's name in messages (``"rows"``).
        records: A sequence of mappings.
        keys: The keys every record must hold.
        what: What a record is, in messages (``"success-rate rows"``).

    Returns:
        The records, as a list.

    Raises:
        InputError: If `records` is not a non-empty sequence of mappings with `keys`.
    """
    if isinstance(records, (str, bytes, Mapping)) or not isinstance(records, Sequence):
        raise InputError(f"{name} must be a sequence of {what}, got {type(records).__name__}.")
    if len(records) == 0:
        raise InputError(f"{name} is empty; give at least one of {what}.")
    out = []
    for i, rec in enumerate(records):
        if not isinstance(rec, Mapping):
            raise InputError(f"{name}[{i}] must be a dict ({what}), got {type(rec).__name__}.")
        missing = [k for k in keys if k not in rec]
        if missing:
            raise InputError(
                f"{name}[{i}] lacks key(s) {missing}; each must be one of {what} with keys "
                f"{list(keys)}."
            )
        out.append(rec)
    return out


def check_figure_path(path: Any) -> None:
    """`InputError` unless `path` is a non-empty file path (str or PathLike)."""
    if isinstance(path, bytes) or not isinstance(path, (str, os.PathLike)):
        raise InputError(f"path must be a file path (str or PathLike), got {type(path).__name__}.")
    if os.fspath(path) == "":
        raise InputError("path is empty; give the image file to write (e.g. 'figure.png').")


def finite_array(name: str, value: Any, shape: Sequence[int | None]) -> np.ndarray:
    """`value` as a finite float array of `shape` (``None``: any size, but not zero)."""
    if value is None:
        raise InputError(f"{name} is None; give an array of shape {tuple(shape)}.")
    arr = real_float64(value)
    if arr is None:
        raise InputError(f"{name} must be an array of numbers, got {value!r:.80}.")
    check_shape(name, arr, shape)
    if arr.size == 0:
        raise InputError(f"{name} is empty (shape {arr.shape}); give at least one entry.")
    check_finite(name, arr)
    return arr


def finite_number(name: str, value: Any) -> float:
    """`value` as a finite float."""
    if value is None or isinstance(value, (bool, np.bool_, str, bytes)):
        raise InputError(f"{name} must be a number, got {value!r}.")
    return float(finite_array(name, value, ()))


def half_width(name: str, value: Any) -> float:
    """A confidence-interval half-width: a finite number >= 0."""
    check_positive(name, value, allow_zero=True)
    return finite_number(name, value)


def nonempty_text(name: str, value: Any) -> str:
    """`value` if it is a non-empty string, else `InputError` naming `name`."""
    if not isinstance(value, str) or not value:
        raise InputError(f"{name} must be a non-empty string, got {value!r}.")
    return value


def check_flag(name: str, value: Any) -> bool:
    """`value` as a bool if it is one (numpy's included), else `InputError` naming `name`."""
    if not isinstance(value, (bool, np.bool_)):
        raise InputError(f"{name} must be true or false, got {value!r}.")
    return bool(value)


def check_unique(name: str, keys: Sequence[Hashable], what: str) -> None:
    """`InputError` naming the first record whose `key` repeats an earlier one."""
    seen: dict[Hashable, int] = {}
    for i, key in enumerate(keys):
        if key in seen:
            raise InputError(
                f"{name}[{i}] repeats {what} {key!r} of {name}[{seen[key]}]; give one row each."
            )
        seen[key] = i


def axes_grid(fig: Figure, n: int, cols: int) -> list[Axes]:
    """`n` axes in rows of at most `cols`; the unused cells of the last row are hidden."""
    rows = math.ceil(n / cols)
    axes = list(fig.subplots(rows, cols, squeeze=False).ravel())
    for ax in axes[n:]:
        ax.axis("off")
    return axes[:n]


def save_titled(fig: Figure, path: str | os.PathLike[str], title: str | None, default: str) -> str:
    """Title `fig` (`title`, else `default`), save it atomically as a PNG; the path."""
    fig.suptitle(title if title is not None else default, fontsize=10)
    atomic_save_figure(fig, path, dpi=120)
    return str(path)
