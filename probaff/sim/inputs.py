"""Checks of the simulators' arguments, worded once for every module of `probaff.sim`.

Each raises `probaff.errors.InputError` naming the argument, what it must be and how to make
one, so that nothing malformed reaches numpy's or pymunk's own errors.

Covered by tests/sim/test_sim_bad_inputs.py.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, TypeVar

import numpy as np

from probaff._checks import check_finite, check_shape, real_float64
from probaff.errors import InputError
from probaff.sim.specs import ObjectSpec

__all__ = [
    "check_items",
    "check_objects",
    "check_rng",
    "check_type",
    "float_rows",
    "floats",
    "numeric_fields",
]

_T = TypeVar("_T")


def floats(name: str, value: object) -> np.ndarray:
    """`value` as a float64 array (any shape).

    Raises:
        InputError: Naming `name`, if it holds no numbers.
    """
    arr = real_float64(value)
    if arr is None:
        raise InputError(f"{name} must hold numbers, got {value!r}.")
    return arr


def float_rows(name: str, arr: np.ndarray, columns: int) -> np.ndarray:
    """`arr` as rows of `columns` finite numbers, `(N, columns)`; an empty array is no rows.

    Raises:
        InputError: Naming `name`, for another shape or a NaN or infinite value.
    """
    if arr.size == 0:
        arr = arr.reshape(0, columns)
    check_shape(name, arr, (None, columns))
    check_finite(name, arr)
    return arr


def check_type(name: str, value: object, cls: type[_T], how: str = "") -> _T:
    """`value`, which must be a `cls`.

    Args:
        name: The argument's name.
        value: The argument.
        cls: Its class.
        how: Where one comes from, e.g. ``"load_tabletop()"``, named in the message.

    Raises:
        InputError: ``"NAME must be a CLS (HOW), got TYPE."``.
    """
    if not isinstance(value, cls):
        where = f" ({how})" if how else ""
        raise InputError(f"{name} must be a {cls.__name__}{where}, got {type(value).__name__}.")
    return value


def check_rng(rng: object) -> np.random.Generator:
    """`rng`, which must be a `numpy.random.Generator`.

    Raises:
        InputError: For anything else, naming ``np.random.default_rng(seed)``.
    """
    if not isinstance(rng, np.random.Generator):
        raise InputError(
            f"rng must be a numpy.random.Generator (np.random.default_rng(seed)), got "
            f"{type(rng).__name__}."
        )
    return rng


def check_items(name: str, items: object, cls: type[_T], how: str) -> list[_T]:
    """`items` as a list: a non-empty list or tuple of `cls`.

    Args:
        name: The argument's name, e.g. ``"scenes"``.
        items: The argument.
        cls: The class of every item.
        how: Where an item comes from, named in the message.

    Raises:
        InputError: For anything but a non-empty list or tuple, or an item of another class
            (named by its index).
    """
    if not isinstance(items, (list, tuple)) or not items:
        raise InputError(
            f"{name} must be a non-empty list of {cls.__name__}, got {items!r}; wrap a single "
            f"{name.rstrip('s')} in a list."
        )
    return [check_type(f"{name}[{i}]", item, cls, how) for i, item in enumerate(items)]


def check_objects(owner: str, objects: object, how: str) -> tuple[ObjectSpec, ...]:
    """`objects` as a non-empty tuple of catalogue `ObjectSpec`.

    Args:
        owner: The class whose field they are, e.g. ``"SceneInstance"``.
        objects: The field's value.
        how: Where the specs come from, named in the message.

    Raises:
        InputError: For anything else.
    """
    specs = tuple(objects) if isinstance(objects, (tuple, list)) else ()
    if not specs or not all(isinstance(o, ObjectSpec) for o in specs):
        raise InputError(
            f"{owner}.objects must be a non-empty tuple of ObjectSpec (from {how}), got "
            f"{objects!r}."
        )
    return specs


def numeric_fields(owner: Any, names: Sequence[str]) -> None:
    """Replace the fields `names` of the frozen dataclass `owner` by float arrays.

    Raises:
        InputError: Naming the first field that holds no numbers.
    """
    kind = type(owner).__name__
    for name in names:
        value = real_float64(getattr(owner, name))
        if value is None:
            raise InputError(
                f"{kind}.{name} must be a numeric array, got {getattr(owner, name)!r}."
            )
        object.__setattr__(owner, name, value)
