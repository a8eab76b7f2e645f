"""The registry of dataset kinds: how each kind of scene becomes shards, a manifest and a dataset.

A dataset kind belongs to one world kind (`probaff.sim.registry`), whose scene templates name
it. `probaff.data.generate` looks a scene's kind up here and needs nothing else of it: the
kind makes a shard's arrays from the shard's seeds, records its plan and manifest entries,
names its dataset class (a `probaff.data.dataset.ArrayDataset`) and summarises a dataset. The
built-in kinds:

=========  ============  ============================  ========================  =============
kind       world kind    dataset                       schema versions           progress unit
=========  ============  ============================  ========================  =============
``push``   ``tabletop``  `probaff.data.PushDataset`    1 (no pose noise), 2;     push
                                                       4 (observation-only)
``skill``  ``sideview``  `probaff.data.SkillDataset`   3; 5 (observation-only)   skill
=========  ============  ============================  ========================  =============

Each kind registers itself in the module that generates it, at import: the ``push`` kind at
the end of `probaff.data.push_generation`, the ``skill`` kind at the end of
`probaff.data.skill_generation`. This module imports neither: every lookup first imports the
modules of `probaff.data` not imported yet (`probaff._registry.import_submodules`), so a
module added to the package registers its kind without being named anywhere. A world kind
whose scenes declare their `probaff.sim.registry.SceneRows` needs no dataset kind of its own
here: its kind is made from its rows.

A kind's ``schema_versions`` are those of its simulated datasets; a dataset class may declare
an observation-only version besides (`ArrayDataset.OBSERVATION_VERSION`, listed by
`observation_versions`), for datasets that lack what only a simulator knows.

A manifest without a ``kind`` entry is a push dataset (`DEFAULT_KIND`), so push datasets are
written exactly as before other kinds existed.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import partial
from typing import Any

import numpy as np

from probaff._registry import Registry, import_submodules
from probaff.data.config import GenerateConfig, base_plan
from probaff.data.dataset import ArrayDataset
from probaff.errors import InputError
from probaff.sim.registry import SceneRows, WorldKind, world_kind, world_kinds

__all__ = [
    "DEFAULT_KIND",
    "DatasetKind",
    "dataset_kind",
    "dataset_kinds",
    "kind_of_dataset",
    "observation_versions",
    "readable_versions",
    "register_dataset_kind",
    "unregister_dataset_kind",
]

DEFAULT_KIND = "push"
"""The kind of a manifest without a ``kind`` entry; manifests of this kind omit it."""

ShardMaker = Callable[[GenerateConfig, int, np.random.SeedSequence], dict[str, np.ndarray]]
"""``make_shard(config, rows, seeds)``: the arrays of a shard of `rows` rows."""


def _summarize_rows(ds: ArrayDataset) -> dict[str, Any]:
    """The summary of a kind without its own: scene, seed and row count."""
    return {"scene": ds.meta.get("scene"), "seed": ds.meta.get("seed"), "n_rows": len(ds)}


@dataclass(frozen=True)
class DatasetKind:
    """One kind of dataset.

    Attributes:
        name: Registry key and manifest ``kind``, e.g. ``"push"``.
        world_kind: The world kind whose scenes make it (`probaff.sim.registry`).
        dataset_type: Its dataset class.
        schema_versions: The schema versions this probaff reads; a new dataset's is the
            ``schema_version`` entry of `manifest`.
        make_shard: ``make_shard(config, rows, seeds)``: simulate a shard of `rows` rows from
            the shard's ``numpy.random.SeedSequence`` alone (so a serial run, a local Dask
            cluster and a remote scheduler all give the same bytes).
        manifest: ``manifest(config)``: the ``schema_version``, ``object_names`` and ``meta``
            of a new dataset; it loads (and so validates) the scene before any work starts.
        plan: ``plan(config)``: the manifest's record of the config, which a resumed run must
            match; by default `base_plan`.
        summarize: A JSON-ready summary of a dataset (what ``probaff describe`` prints).
        unit: One row in words, for progress bars (``"push"``).
        loader: The `probaff.data` function that loads it, named in errors.
        resume_problem: ``resume_problem(started, plan)``: why a dataset started with plan
            `started` cannot be resumed with `plan`, in words, or ``None``; the plans are
            compared in full afterwards.
        order: Its place in `dataset_kinds`: lower first, kinds of equal order in
            registration order. The built-in kinds are 0 (push) and 1 (skill); the default
            puts a new kind after them.

    Raises:
        InputError: For an empty name, a dataset type that is not an `ArrayDataset`, no
            schema version, a hook that is not callable, or an order that is not an integer.
    """

    name: str
    world_kind: str
    dataset_type: type[ArrayDataset]
    schema_versions: tuple[int, ...]
    make_shard: ShardMaker
    manifest: Callable[[GenerateConfig], dict[str, Any]]
    plan: Callable[[GenerateConfig], dict[str, Any]] = base_plan
    summarize: Callable[[Any], dict[str, Any]] = _summarize_rows
    unit: str = "row"
    loader: str = "load_any_dataset"
    resume_problem: Callable[[dict[str, Any], dict[str, Any]], str | None] | None = None
    order: int = 100

    def __post_init__(self) -> None:
        for name in ("name", "world_kind", "unit", "loader"):
            value = getattr(self, name)
            if not isinstance(value, str) or not value:
                raise InputError(f"DatasetKind.{name} must be a non-empty string, got {value!r}.")
        if not (
            isinstance(self.dataset_type, type) and issubclass(self.dataset_type, ArrayDataset)
        ):
            raise InputError(
                f"DatasetKind.dataset_type of {self.name!r} must be a subclass of "
                f"probaff.data.dataset.ArrayDataset, got {self.dataset_type!r}."
            )
        if not self.schema_versions or not all(
            isinstance(v, int) and not isinstance(v, bool) for v in self.schema_versions
        ):
            raise InputError(
                f"DatasetKind.schema_versions of {self.name!r} must be a non-empty tuple of "
                f"integers, got {self.schema_versions!r}."
            )
        for name in ("make_shard", "manifest", "plan", "summarize"):
            if not callable(getattr(self, name)):
                raise InputError(f"DatasetKind.{name} of {self.name!r} must be callable.")
        if isinstance(self.order, bool) or not isinstance(self.order, int):
            raise InputError(
                f"DatasetKind.order of {self.name!r} must be an integer, got {self.order!r}."
            )


_KINDS: Registry[DatasetKind] = Registry("dataset kind", DatasetKind, "unregister_dataset_kind")
_PACKAGE = __name__.rpartition(".")[0]


def _rows_shard(
    rows: SceneRows, config: GenerateConfig, n: int, seeds: np.random.SeedSequence
) -> dict[str, np.ndarray]:
    return rows.make(config.scene, n, seeds)


def _rows_manifest(rows: SceneRows, config: GenerateConfig) -> dict[str, Any]:
    return {
        "schema_version": rows.schema_version,
        "object_names": list(rows.object_names(config.scene)),
        "meta": {"scene": config.scene},
    }


_DERIVED: dict[str, tuple[WorldKind, DatasetKind]] = {}


def _from_rows(world: WorldKind, rows: SceneRows, name: str) -> DatasetKind:
    """The dataset kind of a world kind's `SceneRows` (made once per `WorldKind` object)."""
    cached = _DERIVED.get(world.name)
    if cached is not None and cached[0] is world:
        return cached[1]
    dataset_type = type(
        f"{world.name.title().replace('_', '')}Dataset",
        (ArrayDataset,),
        {
            "__doc__": f"Rows of {world.label} scenes, as its `SceneRows` declare them.",
            "__module__": __name__,
            "KIND": name,
            "REQUIRED": dict(rows.arrays),
        },
    )
    kind = DatasetKind(
        name=name,
        world_kind=world.name,
        dataset_type=dataset_type,
        schema_versions=(rows.schema_version,),
        make_shard=partial(_rows_shard, rows),
        manifest=partial(_rows_manifest, rows),
        unit=rows.unit,
    )
    _DERIVED[world.name] = (world, kind)
    return kind


def _all_kinds() -> dict[str, DatasetKind]:
    """The registered dataset kinds (by order), then those of world kinds that declare rows.

    The modules of `probaff.data` not imported yet are imported first, so that each kind
    defined in one is registered.
    """
    import_submodules(_PACKAGE)
    out = {kind.name: kind for kind in sorted(_KINDS.values(), key=lambda kind: kind.order)}
    for world in world_kinds():
        name = world.dataset_kind
        if world.rows is not None and name is not None and name not in out:
            out[name] = _from_rows(world, world.rows, name)
    return out


def register_dataset_kind(kind: DatasetKind) -> DatasetKind:
    """Register a dataset kind under its name.

    Returns:
        `kind`.

    Raises:
        InputError: If `kind` is not a `DatasetKind`, its name is taken, its world kind is not
            registered, or that world kind's scenes make another dataset kind.
    """
    world = world_kind(kind.world_kind) if isinstance(kind, DatasetKind) else None
    if world is not None and world.dataset_kind != kind.name:
        raise InputError(
            f"world kind {world.name!r} makes {world.dataset_kind!r} datasets, not "
            f"{kind.name!r}; give its WorldKind dataset_kind={kind.name!r}."
        )
    return _KINDS.add(kind)


unregister_dataset_kind = _KINDS.remove
"""Remove a registered dataset kind by name and return it (see `probaff._registry.Registry`)."""


def dataset_kind(name: str) -> DatasetKind:
    """The registered dataset kind `name`.

    Raises:
        InputError: If no kind has that name (the message lists the registered ones).
    """
    kinds = _all_kinds()
    if not isinstance(name, str) or name not in kinds:
        raise InputError(f"unknown dataset kind {name!r}; registered kinds: {list(kinds)}.")
    return kinds[name]


def dataset_kinds() -> list[DatasetKind]:
    """Every dataset kind: the registered ones, then those of world kinds with `SceneRows`.

    The registered ones come by `DatasetKind.order` (push, then skill, then the others in
    registration order).
    """
    return list(_all_kinds().values())


def readable_versions() -> dict[str, tuple[int, ...]]:
    """Each dataset kind (`dataset_kinds`) and the schema versions of it this probaff reads.

    These are the versions of simulated datasets; a kind's observation-only version is in
    `observation_versions`.
    """
    return {k.name: k.schema_versions for k in _all_kinds().values()}


def observation_versions() -> dict[str, int]:
    """Each dataset kind with an observation-only schema version, and that version."""
    out = {}
    for kind in _all_kinds().values():
        version = kind.dataset_type.OBSERVATION_VERSION
        if version is not None:
            out[kind.name] = version
    return out


def kind_of_dataset(ds: ArrayDataset) -> DatasetKind:
    """The dataset kind whose dataset class `ds` is an instance of (the most derived).

    Raises:
        InputError: If `ds` is of no registered kind's class.
    """
    for kind in _all_kinds().values():
        if type(ds) is kind.dataset_type:
            return kind
    for kind in _all_kinds().values():
        if isinstance(ds, kind.dataset_type):
            return kind
    raise InputError(
        f"{type(ds).__name__} is the dataset class of no registered dataset kind; give a "
        "PushDataset, a SkillDataset or a dataset of a registered kind."
    )
