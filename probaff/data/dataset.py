"""What every dataset kind shares: named arrays, one row per sample, checked on construction.

A dataset kind (`probaff.data.schema.PushDataset`, `probaff.data.skill_schema.SkillDataset`)
declares its arrays and their dtypes, the optional groups stored all together or not at all, and
its own shape checks; this base checks names, dtypes, groups and row counts, and joins shards.

Covered by tests/data/test_data.py.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, ClassVar, TypeVar

import numpy as np

from probaff.errors import DatasetError

__all__ = ["ArrayDataset"]

_D = TypeVar("_D", bound="ArrayDataset")


@dataclass
class ArrayDataset:
    """Samples of one scene template, in memory: named arrays whose first axis is the row.

    Subclasses set the class attributes below and extend `validate` with their shape checks.

    Attributes:
        arrays: Named arrays (see the subclass's schema).
        object_names: Vocabulary of ``arrays["object_ids"]`` (negative ids are empty slots).
        meta: Scene name, seed, world settings and generation options.
    """

    KIND: ClassVar[str] = "array"
    """The dataset kind, in messages."""
    REQUIRED: ClassVar[dict[str, str]] = {"object_ids": "int16"}
    """The required arrays and their dtypes."""
    OPTIONAL: ClassVar[dict[str, str]] = {}
    """The optional arrays and their dtypes."""
    GROUPS: ClassVar[dict[str, tuple[str, ...]]] = {}
    """Optional arrays stored all together or not at all, by the group's name."""
    ROWS: ClassVar[str] = "object_ids"
    """The array whose length is the number of rows."""

    arrays: dict[str, np.ndarray]
    object_names: list[str]
    meta: dict[str, Any] = field(default_factory=dict)

    def validate(self) -> None:
        """Check names, dtypes, the all-or-none groups and that every array has the same rows.

        Raises:
            DatasetError: Naming the offending array.
        """
        arrays = self.arrays
        missing = set(self.REQUIRED) - set(arrays)
        if missing:
            raise DatasetError(f"{self.KIND} dataset is missing arrays {sorted(missing)}.")
        known = {**self.REQUIRED, **self.OPTIONAL}
        unknown = set(arrays) - set(known)
        if unknown:
            raise DatasetError(f"{self.KIND} dataset has unknown arrays {sorted(unknown)}.")
        for group, names in self.GROUPS.items():
            present = [name in arrays for name in names]
            if any(present) and not all(present):
                raise DatasetError(
                    f"{self.KIND} dataset holds only some of the {group} arrays "
                    f"{sorted(names)}; they are stored all together or not at all."
                )
        n = len(arrays[self.ROWS])
        for name, arr in arrays.items():
            if arr.dtype != np.dtype(known[name]):
                raise DatasetError(f"array {name!r} has dtype {arr.dtype}, expected {known[name]}.")
            if len(arr) != n:
                raise DatasetError(f"array {name!r} has {len(arr)} rows, expected {n}.")

    def __post_init__(self) -> None:
        self.validate()

    def __len__(self) -> int:
        return len(self.arrays[self.ROWS])

    def __getitem__(self, name: str) -> np.ndarray:
        return self.arrays[name]

    @property
    def rows_label(self) -> str:
        """What the rows are, in words and plural (e.g. ``"pushes"``)."""
        return "rows"

    def objects_of(self, i: int) -> list[str]:
        """Catalogue names of the objects of row `i`, in slot order (empty slots left out)."""
        return [self.object_names[j] for j in self.arrays["object_ids"][i] if j >= 0]

    def check_plan(self, plan: dict[str, Any]) -> str | None:
        """What contradicts the generation plan of its manifest, or ``None``.

        Args:
            plan: The manifest's ``plan``.
        """
        return None

    @classmethod
    def check_joinable(cls, parts: Sequence[ArrayDataset]) -> None:
        """Raise `DatasetError` unless `parts` can be joined row-wise.

        The base checks the vocabularies; a subclass may check more.
        """
        if not parts:
            raise DatasetError("cannot concatenate zero datasets.")
        names = parts[0].object_names
        if any(p.object_names != names for p in parts):
            raise DatasetError("datasets with different object vocabularies cannot be joined.")

    @classmethod
    def concatenate(cls: type[_D], parts: Sequence[_D]) -> _D:
        """Join datasets of the same scene row-wise (metadata from the first).

        Raises:
            DatasetError: For no parts, or parts that cannot be joined (`check_joinable`).
        """
        cls.check_joinable(parts)
        keys = parts[0].arrays.keys()
        return cls(
            {k: np.concatenate([p.arrays[k] for p in parts]) for k in keys},
            list(parts[0].object_names),
            dict(parts[0].meta),
        )
