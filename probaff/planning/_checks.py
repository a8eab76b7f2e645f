"""Argument checks that every planning module shares: an instance of a type, a generator.

Covered by tests/planning/test_planning_transitions.py.
"""

from __future__ import annotations

from typing import Any, TypeVar

import numpy as np

from probaff.errors import InputError

__all__ = ["check_instance", "check_rng"]

T = TypeVar("T")


def check_instance(value: Any, kind: type[T], what: str) -> T:
    """`value`, or `InputError` ``"{what}, got {its type}."`` unless it is a `kind`.

    Args:
        value: What the caller was given.
        kind: The type it must be (a runtime-checkable protocol too).
        what: The requirement, e.g. ``"task must be an EdgeTask (load_edge_task())"``.

    Returns:
        `value`, unchanged.
    """
    if not isinstance(value, kind):
        raise InputError(f"{what}, got {type(value).__name__}.")
    return value


def check_rng(rng: Any) -> np.random.Generator:
    """`rng`, or `InputError` unless it is a ``numpy.random.Generator``."""
    return check_instance(
        rng,
        np.random.Generator,
        "rng must be a numpy.random.Generator (np.random.default_rng(seed))",
    )
