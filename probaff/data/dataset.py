"""What every dataset kind shares: named arrays, one row per sample, checked on construction.

A dataset kind (`probaff.data.schema.PushDataset`, `probaff.data.skill_schema.SkillDataset`)
declares its arrays and their dtypes, the optional groups stored all together or not at all,
their symbolic shapes and units, and its own further checks; this base checks names, dtypes,
groups, row counts and shapes, and joins shards.

Observations and the simulator. A kind may split its arrays into what every dataset holds
(`ArrayDataset.REQUIRED`: what a robot observes) and what only its simulated datasets must hold
(`ArrayDataset.SIMULATED`: what only a simulator knows). A dataset that lacks one of the latter,
or holds an array only observation-only datasets hold (`ArrayDataset.OBSERVED_ONLY`), is
*observation-only* and is stored under the kind's observation-only schema version
(`ArrayDataset.OBSERVATION_VERSION`); the others are stored as before.

Covered by tests/data/test_data.py and tests/data/test_dataset.py.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, ClassVar, TypeVar

import numpy as np

from probaff.errors import DatasetError, InputError

__all__ = ["ArrayDataset", "Shape", "shape_problem", "split_arrays"]

Shape = tuple[int | str, ...]
"""A symbolic array shape: integers are fixed sizes, names (``"N"``, ``"K"``) sizes shared by
every array that names them (``"N"`` is the row count)."""


def split_arrays(
    dtypes: Mapping[str, str], observed: Sequence[str]
) -> tuple[dict[str, str], dict[str, str]]:
    """Split a schema's arrays into what a robot observes and what only a simulator knows.

    Args:
        dtypes: Array name -> dtype.
        observed: The names of the observed arrays, each a key of `dtypes`.

    Returns:
        ``(observed, simulator)``: the observed arrays in the order of `observed`, and the
        others in the order of `dtypes`.
    """
    seen = {name: dtypes[name] for name in observed}
    return seen, {name: dtype for name, dtype in dtypes.items() if name not in seen}


def shape_problem(arrays: Mapping[str, np.ndarray], shapes: Mapping[str, Shape]) -> str | None:
    """What is wrong with the shapes of `arrays`, in words, or ``None``.

    Arrays are checked in the order of `shapes`; the first array that names a size binds it
    and every later array must agree. Arrays that `shapes` does not name, and names of
    `shapes` absent from `arrays`, are not checked.

    Args:
        arrays: Named arrays.
        shapes: The symbolic shape of each array (see `Shape`).

    Returns:
        E.g. ``"array 'effect' has shape (4, 2), expected (N, K, 3) with N = 4, K = 2 (from
        'object_ids')"``, or ``None`` when every shape fits.
    """
    sizes: dict[str, tuple[int, str]] = {}
    for name, spec in shapes.items():
        if name not in arrays:
            continue
        actual = tuple(np.shape(arrays[name]))
        fits = len(actual) == len(spec) and all(
            a == (s if isinstance(s, int) else sizes.get(s, (a, ""))[0])
            for a, s in zip(actual, spec, strict=True)
        )
        if not fits:
            want = "(" + ", ".join(str(s) for s in spec) + ")"
            known = [
                f"{s} = {sizes[s][0]} (from {sizes[s][1]!r})"
                for s in dict.fromkeys(spec)
                if isinstance(s, str) and s in sizes
            ]
            return f"array {name!r} has shape {actual}, expected {want}" + (
                f" with {', '.join(known)}" if known else ""
            )
        for a, s in zip(actual, spec, strict=True):
            if isinstance(s, str):
                sizes.setdefault(s, (a, name))
    return None


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
    SHAPES: ClassVar[dict[str, Shape]] = {}
    """The symbolic shape of each array (`Shape`); arrays not named here are not checked."""
    UNITS: ClassVar[dict[str, str]] = {}
    """The units of each array (``"m"``, ``"rad"``, ``"m, m, rad"`` per last-axis component,
    ``"1"`` dimensionless, ``"index"``, ``"bool"``), as the HDF5 layout records them."""
    SIMULATED: ClassVar[tuple[str, ...]] = ()
    """Optional arrays that the kind's simulated schema versions require: what only a
    simulator knows. A dataset lacking one is observation-only."""
    SIMULATOR_ONLY: ClassVar[tuple[str, ...]] = ()
    """Every array only a simulator knows (`SIMULATED` and exact values such as ground truth):
    what `probaff.data.observations.observations_of` drops."""
    OBSERVED_ONLY: ClassVar[tuple[str, ...]] = ()
    """Optional arrays that only observation-only datasets hold."""
    OBSERVATION_VERSION: ClassVar[int | None] = None
    """The schema version of the kind's observation-only datasets, or ``None`` (every
    dataset of the kind is simulated)."""

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
        problem = shape_problem(arrays, self.SHAPES)
        if problem:
            raise DatasetError(f"{problem}.")

    def __post_init__(self) -> None:
        self.validate()

    def __len__(self) -> int:
        return len(self.arrays[self.ROWS])

    def __getitem__(self, name: str) -> np.ndarray:
        try:
            return self.arrays[name]
        except KeyError:
            raise InputError(self.lacks_message([name], f"array {name!r}")) from None

    def lacks_message(self, names: Sequence[str], what: str) -> str:
        """The message of an error for arrays `names` that this dataset lacks.

        Args:
            names: The missing arrays.
            what: What needs them, e.g. ``"chapter 4 features"``.
        """
        observed = " (an observation-only dataset)" if self.observation_only else ""
        return (
            f"{what} needs array{'s' if len(names) > 1 else ''} {sorted(names)}, which this "
            f"{self.KIND} dataset{observed} lacks; it holds {sorted(self.arrays)}. Add "
            f"{'them' if len(names) > 1 else 'it'} to the arrays the dataset is built from "
            "(probaff.data.observation_dataset) or use a dataset that has "
            f"{'them' if len(names) > 1 else 'it'}."
        )

    @property
    def missing_simulated(self) -> list[str]:
        """The arrays of `SIMULATED` this dataset lacks, sorted."""
        return sorted(set(self.SIMULATED) - set(self.arrays))

    @property
    def observation_only(self) -> bool:
        """Whether it lacks an array of `SIMULATED` or holds one of `OBSERVED_ONLY`."""
        return bool(self.missing_simulated) or any(n in self.arrays for n in self.OBSERVED_ONLY)

    @property
    def simulated_version(self) -> int | None:
        """The schema version a simulated dataset of this content is stored with.

        ``None`` (the base) leaves it to the kind's newest registered version.
        """
        return None

    @property
    def schema_version(self) -> int | None:
        """The schema version this dataset is stored with.

        `OBSERVATION_VERSION` when it is observation-only, else `simulated_version` (``None``:
        the kind's newest).
        """
        return self.OBSERVATION_VERSION if self.observation_only else self.simulated_version

    @property
    def rows_label(self) -> str:
        """What the rows are, in words and plural (e.g. ``"pushes"``)."""
        return "rows"

    def objects_of(self, i: int) -> list[str]:
        """Catalogue names of the objects of row `i`, in slot order (empty slots left out)."""
        return [self.object_names[j] for j in self.arrays["object_ids"][i] if j >= 0]

    def plan_entries(self) -> dict[str, Any]:
        """The plan entries a saved dataset of this content records (`check_plan` accepts them).

        The base records none; `probaff.data.store.save_dataset` adds ``scene``, ``n``,
        ``seed`` and ``shard_size``.
        """
        return {}

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
