"""A feature matrix with named column groups."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from probaff.errors import InputError

__all__ = ["FeatureSet"]


@dataclass(frozen=True)
class FeatureSet:
    """Features of N samples with named column groups.

    Attributes:
        values: (N, D) float64 feature matrix.
        groups: Group name -> column slice, e.g. ``{"f_o": slice(0, 8), ...}``; the slices
            tile ``range(D)`` in order.
        names: (D,) column names.
    """

    values: np.ndarray
    groups: dict[str, slice]
    names: tuple[str, ...]

    def __post_init__(self) -> None:
        if self.values.ndim != 2 or self.values.shape[1] != len(self.names):
            raise InputError(
                f"feature values have shape {self.values.shape}, expected (N, {len(self.names)})."
            )

    @property
    def dim(self) -> int:
        """Number of columns D."""
        return self.values.shape[1]

    def __len__(self) -> int:
        return self.values.shape[0]

    def columns(self, *groups: str) -> np.ndarray:
        """Column indices of the named groups, in the order given.

        Raises:
            InputError: For an unknown group name, listing the known ones.
        """
        unknown = [g for g in groups if g not in self.groups]
        if unknown:
            raise InputError(
                f"unknown feature group(s) {unknown}; this feature set has {list(self.groups)}."
            )
        return np.concatenate([np.arange(self.dim)[self.groups[g]] for g in groups])

    def select(self, *groups: str) -> np.ndarray:
        """(N, d) values of the named groups, concatenated in the order given."""
        return self.values[:, self.columns(*groups)]

    def rows(self, index: Sequence[int] | np.ndarray) -> FeatureSet:
        """The features of a subset of samples."""
        return FeatureSet(self.values[np.asarray(index)], dict(self.groups), self.names)
