"""One registry for every kind of named thing probaff looks up: models, worlds, datasets, studies.

Each registry is a `Registry` of entries of one class, each with a ``name``. A kind registers
itself in its own module (``register_world(WorldKind(...))`` in the world's module of
`probaff.sim`, ``register_model_kind(ModelKind(...))`` beside the model's fitter, a study by its
folder in `probaff.experiments`, ...). The rules are the same everywhere: a name taken
already is refused (remove the old entry first), an unknown name is refused with the
registered names listed, and entries keep their registration order. A registry of kinds that
register themselves finds their modules with `import_submodules` (discovery, not lists): the
world kinds in `probaff.sim`, the dataset kinds in `probaff.data`.

Example:
    >>> from dataclasses import dataclass
    >>> @dataclass(frozen=True)
    ... class Colour:
    ...     name: str
    >>> colours = Registry("colour", Colour, "unregister_colour")
    >>> colours.add(Colour("red")).name
    'red'
    >>> colours.add(Colour("red"))  # doctest: +ELLIPSIS
    Traceback (most recent call last):
    ...
    probaff.errors.InputError: colour 'red' is registered already; unregister_colour it ...
    >>> colours.names()
    ['red']
"""

from __future__ import annotations

import importlib
import pkgutil
import sys
from collections.abc import Iterator
from typing import Generic, Protocol, TypeVar

from probaff.errors import InputError

__all__ = ["Registry", "import_submodules"]


class _Named(Protocol):
    @property
    def name(self) -> str: ...


_N = TypeVar("_N", bound=_Named)


class Registry(Generic[_N]):
    """Named entries in registration order: the store behind a registry's functions.

    Args:
        what: What an entry is, in messages (``"world kind"``).
        cls: The class of every entry.
        unregister: The public function that removes one, named in messages.
    """

    def __init__(self, what: str, cls: type[_N], unregister: str) -> None:
        self.what, self.cls, self.unregister = what, cls, unregister
        self.entries: dict[str, _N] = {}

    def add(self, entry: _N) -> _N:
        """Register `entry` under its name and return it.

        Raises:
            InputError: If `entry` is of another class, or its name is taken.
        """
        if not isinstance(entry, self.cls):
            raise InputError(
                f"a {self.what} must be a {self.cls.__name__}, got {type(entry).__name__}."
            )
        if entry.name in self.entries:
            raise InputError(
                f"{self.what} {entry.name!r} is registered already; {self.unregister} it first "
                "or choose another name."
            )
        self.entries[entry.name] = entry
        return entry

    def remove(self, name: str) -> _N:
        """Remove the entry `name` and return it.

        Raises:
            InputError: If no entry has that name.
        """
        if not isinstance(name, str) or name not in self.entries:
            raise InputError(f"{self.what} {name!r} is not registered; registered: {self.names()}.")
        return self.entries.pop(name)

    def get(self, name: str) -> _N:
        """The entry `name`.

        Raises:
            InputError: If no entry has that name (the message lists the registered ones).
        """
        if not isinstance(name, str) or name not in self.entries:
            raise InputError(f"unknown {self.what} {name!r}; registered: {self.names()}.")
        return self.entries[name]

    def values(self) -> list[_N]:
        """Every entry, in registration order."""
        return list(self.entries.values())

    def names(self) -> list[str]:
        """Every entry's name, in registration order."""
        return list(self.entries)

    def __contains__(self, name: object) -> bool:
        return name in self.entries

    def __iter__(self) -> Iterator[str]:
        return iter(list(self.entries))

    def __len__(self) -> int:
        return len(self.entries)


def import_submodules(package: str, *, subpackages: bool = False) -> list[str]:
    """Import every module of `package` not imported yet, so that each registers its entries.

    A registry whose kinds register themselves in their own modules calls this before a
    lookup: a module added to the package (or to a folder on its ``__path__``) is then found
    without being named anywhere. Modules whose names start with ``_`` are skipped, and so are
    subpackages unless `subpackages` (a registry's kinds are then modules of the package and
    of its subpackages, at any depth, as the model kinds in `probaff.models`).

    Args:
        package: The dotted name of a package (``"probaff.sim"``); a package still being
            imported is searched as far as its ``__path__`` goes.
        subpackages: Also import the modules of its subpackages, recursively.

    Returns:
        The modules imported (none once every module is imported).

    Raises:
        InputError: If a module registers an entry under a name that is taken.
    """
    infos = [
        info
        for info in pkgutil.iter_modules(importlib.import_module(package).__path__, f"{package}.")
        if not info.name.rpartition(".")[2].startswith("_")
    ]
    found = [i.name for i in infos if not i.ispkg and i.name not in sys.modules]
    if found:
        importlib.invalidate_caches()  # a module written since the last import is found
    for name in found:
        importlib.import_module(name)
    if subpackages:
        for info in infos:
            if info.ispkg:
                found += import_submodules(info.name, subpackages=True)
    return found
