"""The registry of world kinds: each kind's loaders, its simulation and the dataset it makes.

A world kind (gym's and robosuite's registered environments) is what a scene template belongs
to: its world file loader, its scene templates (``worlds/<folder>/NAME.yaml``) and their
loader, its simulation entry point and the kind of dataset its scenes generate
(`probaff.data.generate` looks it up). The built-in kinds, in this order:

==============  ==========================  =============================  ============
kind            world file, loader          scene templates                dataset kind
==============  ==========================  =============================  ============
``tabletop``    ``tabletop.yaml``           ``scenes/``                    ``push``
``sideview``    ``sideview.yaml``           ``sideview_scenes/``           ``skill``
``warehouse``   ``warehouse.yaml``          none (maps are generated)      none
``office``      ``office.yaml``             none (scenes are sampled)      none
==============  ==========================  =============================  ============

Each kind registers itself in its own module, at import: ``register_world(WorldKind(...))``
at the end of `probaff.sim.tabletop`, `probaff.sim.sideview`, `probaff.sim.warehouse` and
`probaff.sim.office`. This module imports none of them: every lookup (`world_kind`,
`world_kinds`, `kind_of_scene`) first imports the modules of `probaff.sim` not imported yet
(`discover_worlds`), so a module added to the package registers its kind without being named
anywhere, and a name registered twice is an `InputError`. Listings keep the order of
`WorldKind.order` (the built-in kinds first, in the table's order). A new world kind is
therefore its YAML (world file and scene templates under ``worlds/``), its module in
`probaff.sim` (spec, loader, simulate function and its `register_world` call) and its test.
A kind whose scenes become dataset rows declares `SceneRows` and gets its dataset kind from
`probaff.data.kinds` with nothing registered there.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from probaff._checks import check_count
from probaff._registry import Registry, import_submodules
from probaff.errors import ConfigError, InputError
from probaff.sim.world_files import scene_names, worlds_dir

__all__ = [
    "SceneRows",
    "UnknownSceneError",
    "WorldKind",
    "discover_worlds",
    "kind_of_scene",
    "register_world",
    "unregister_world",
    "world_kind",
    "world_kinds",
]


class UnknownSceneError(InputError):
    """An unknown scene name: a bad ``scene`` argument naming no world file."""


@dataclass(frozen=True)
class SceneRows:
    """How a world kind's scenes become dataset rows, for a kind with no options of its own.

    `probaff.data.kinds` turns it into a dataset kind (a dataset class of these arrays, its
    shards and manifest) unless a `probaff.data.kinds.DatasetKind` is registered for it.

    Attributes:
        arrays: Name and dtype of each array; the first axis of each is the row.
            ``object_ids`` (``int16``, an index into the object names, -1 for an empty slot)
            is added when missing.
        make: ``make(scene, rows, seeds)``: the arrays of `rows` rows of scene template
            `scene`, drawn from the shard's ``numpy.random.SeedSequence`` alone.
        object_names: ``object_names(scene)``: the vocabulary of ``object_ids``.
        unit: One row in words, for progress bars.
        schema_version: The version of this array schema, recorded in the manifest.

    Raises:
        InputError: For no arrays, a `make` or `object_names` that is not callable, or a
            schema version that is not a positive integer.
    """

    arrays: dict[str, str]
    make: Callable[[str, int, np.random.SeedSequence], dict[str, np.ndarray]]
    object_names: Callable[[str], list[str]]
    unit: str = "row"
    schema_version: int = 1

    def __post_init__(self) -> None:
        if not isinstance(self.arrays, dict) or not self.arrays:
            raise InputError(f"SceneRows.arrays must name at least one array, got {self.arrays!r}.")
        object.__setattr__(self, "arrays", {"object_ids": "int16", **self.arrays})
        for name in ("make", "object_names"):
            if not callable(getattr(self, name)):
                raise InputError(f"SceneRows.{name} must be callable.")
        check_count("SceneRows.schema_version", self.schema_version)


@dataclass(frozen=True)
class WorldKind:
    """One kind of world.

    Attributes:
        name: Registry key, e.g. ``"tabletop"``.
        label: The kind in words, as in "a side-view scene", e.g. ``"side-view"``.
        load_world: Loads the world file: ``load_world()`` for the standard one,
            ``load_world(path)`` for another (e.g. `probaff.sim.load_tabletop`).
        simulate: The world's simulation entry point (e.g. `probaff.sim.simulate_push`); its
            arguments are the kind's own.
        scenes: Folder of the scene templates ``NAME.yaml`` (relative: under
            `probaff.sim.world_files.worlds_dir`), or ``None`` for a kind without templates.
        load_scene: Loads a scene template by name; required with `scenes`.
        dataset_kind: Name of the dataset kind its scenes generate (`probaff.data.kinds`), or
            ``None``.
        actions: What its scenes' datasets hold, in words (``"push"``, ``"pick/place"``).
        describe_scene: A one-line description of a scene for listings; by default the
            loaded template's ``description``.
        rows: How its scenes become dataset rows, for a `dataset_kind` that is not registered
            in `probaff.data.kinds` (one with no options of its own).
        order: Its place in `world_kinds` and in listings such as ``probaff scenes``: lower
            first, kinds of equal order in registration order. The built-in kinds are 0
            (tabletop) to 3 (office); the default puts a new kind after them.

    Raises:
        InputError: For an empty name or label, a non-callable loader or simulation, scene
            templates without a `load_scene`, `rows` without scene templates and a
            `dataset_kind`, or an order that is not an integer.
    """

    name: str
    label: str
    load_world: Callable[..., Any]
    simulate: Callable[..., Any]
    scenes: str | Path | None = None
    load_scene: Callable[[str], Any] | None = None
    dataset_kind: str | None = None
    actions: str = ""
    describe_scene: Callable[[str], str] | None = None
    rows: SceneRows | None = None
    order: int = 100

    def __post_init__(self) -> None:
        for name in ("name", "label"):
            value = getattr(self, name)
            if not isinstance(value, str) or not value:
                raise InputError(f"WorldKind.{name} must be a non-empty string, got {value!r}.")
        for name in ("load_world", "simulate"):
            if not callable(getattr(self, name)):
                raise InputError(f"WorldKind.{name} of {self.name!r} must be callable.")
        if self.scenes is not None and not callable(self.load_scene):
            raise InputError(
                f"WorldKind {self.name!r} has scene templates ({self.scenes}) but no "
                "load_scene; give the function that loads a template by name."
            )
        if self.dataset_kind is not None and not isinstance(self.dataset_kind, str):
            raise InputError(
                f"WorldKind.dataset_kind of {self.name!r} must be a name or None, got "
                f"{self.dataset_kind!r}."
            )
        if self.rows is not None and (self.scenes is None or self.dataset_kind is None):
            raise InputError(
                f"WorldKind {self.name!r} has rows but no scene templates or dataset_kind; "
                "rows are made from a scene template for the dataset kind."
            )
        if isinstance(self.order, bool) or not isinstance(self.order, int):
            raise InputError(
                f"WorldKind.order of {self.name!r} must be an integer, got {self.order!r}."
            )

    def scene_names(self) -> list[str]:
        """Sorted names of its scene templates (none without a `scenes` folder)."""
        return [] if self.scenes is None else scene_names(self.scenes)

    def scene_path(self, name: str) -> Path:
        """The file of scene template `name` (which need not exist).

        Raises:
            InputError: If the kind has no scene templates.
        """
        if self.scenes is None:
            raise InputError(f"world kind {self.name!r} has no scene templates.")
        folder = Path(self.scenes)
        return (folder if folder.is_absolute() else worlds_dir() / folder) / f"{name}.yaml"

    def describe(self, scene: str) -> str:
        """One line on scene template `scene`, for listings such as ``probaff scenes``."""
        if self.describe_scene is not None:
            return self.describe_scene(scene)
        assert self.load_scene is not None  # checked with scenes
        return str(getattr(self.load_scene(scene), "description", ""))


_WORLDS: Registry[WorldKind] = Registry("world kind", WorldKind, "unregister_world")
_PACKAGE = __name__.rpartition(".")[0]


def discover_worlds() -> list[str]:
    """Import every module of `probaff.sim` not imported yet, so that each registers its kind.

    Run by every lookup (`probaff._registry.import_submodules`), so a world module added to
    the package (or to a folder on its ``__path__``) is found without being named anywhere.

    Returns:
        The modules it imported (none once every module is imported).

    Raises:
        InputError: If a module registers a world kind under a name that is taken.
    """
    return import_submodules(_PACKAGE)


register_world = _WORLDS.add
"""Register a world kind under its name and return it (see `probaff._registry.Registry.add`).

Raises:
    InputError: If the name is taken (`unregister_world` it first, or choose another name).
"""
unregister_world = _WORLDS.remove
"""Remove a registered world kind by name and return it (`probaff._registry.Registry.remove`)."""


def world_kind(name: str) -> WorldKind:
    """The registered world kind of a name (after `discover_worlds`).

    Raises:
        InputError: If no kind has that name (the message lists the registered ones).
    """
    discover_worlds()
    return _WORLDS.get(name)


def world_kinds() -> list[WorldKind]:
    """Every registered world kind (after `discover_worlds`), by `WorldKind.order`.

    The built-in kinds come first, in the order tabletop, side view, warehouse, office; kinds
    of equal order keep their registration order.
    """
    discover_worlds()
    return sorted(_WORLDS.values(), key=lambda kind: kind.order)


def kind_of_scene(scene: str) -> WorldKind:
    """The world kind whose scene templates hold `scene`.

    Args:
        scene: A scene template name, e.g. ``"two_objects"`` or ``"pick"``.

    Raises:
        InputError: If `scene` is not a string.
        UnknownSceneError: If no kind has a template of that name (the message lists every
            kind's templates); it is also a `ConfigError`.
        ConfigError: If two kinds have a template of that name.
    """
    if not isinstance(scene, str):
        raise InputError(f"scene must be a scene name (a string), got {scene!r}.")
    owners = [k for k in world_kinds() if scene in k.scene_names()]
    if len(owners) > 1:
        paths = " and in ".join(str(k.scene_path(scene)) for k in owners)
        raise ConfigError(
            f"scene {scene!r} is defined twice, in {paths}; rename one of the two files."
        )
    if not owners:
        listing = ", ".join(
            f"{k.label} ({k.actions or k.dataset_kind}) {k.scene_names()}"
            for k in world_kinds()
            if k.scenes is not None
        )
        raise UnknownSceneError(f"unknown scene {scene!r}; available scenes: {listing}.")
    return owners[0]
