"""The studies, found folder by folder and held in the shared registry, and their command.

A study is a subpackage (a folder with an ``__init__.py``) whose package names ``Config`` (a
`probaff.experiments.base.StudyConfig` subclass), ``SMOKE`` (its smoke sizes) and
``run(config) -> dict`` (whose ``"files"`` lists what it wrote). A `StudyRegistry` registers
every such folder of its package (on each folder of the package's ``__path__``) as a `Study`
under the folder's name, without importing it; a study is imported when first looked up. Its
names follow the rules of every probaff registry: a name taken twice is refused (an
`InputError` for a study registered by hand under a folder's name, a `ConfigError` for two
folders of one name on the path), and an unknown name is an `UnknownStudyError` that lists the
studies. Adding a study is adding its folder: `STUDIES`,
``probaff study NAME`` and the tests that iterate `STUDIES` find it.
"""

from __future__ import annotations

import importlib
import json
import pkgutil
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType

from probaff._cli_errors import check_output_flags, report_error
from probaff._registry import Registry
from probaff.errors import ConfigError, InputError, ProbaffError
from probaff.experiments.config_cli import parse_study_args

__all__ = [
    "STUDIES",
    "Study",
    "StudyRegistry",
    "UnknownStudyError",
    "discover_studies",
    "study_main",
]

_FACE = ("Config", "SMOKE", "run")


class UnknownStudyError(InputError, KeyError):
    """An unknown study name; also a `KeyError`, as a missing key of a mapping is."""

    def __str__(self) -> str:
        return str(self.args[0]) if self.args else ""


@dataclass(frozen=True)
class Study:
    """One study: its name and the dotted name of its package.

    Attributes:
        name: The registry key, the study folder's name (``"push_models"``).
        package: The package to import (``"probaff.experiments.push_models"``).

    Raises:
        InputError: For a name that is not an identifier, or an empty package name.
    """

    name: str
    package: str

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name.isidentifier():
            raise InputError(
                f"a study's name must be an identifier (its folder's name), got {self.name!r}."
            )
        if not isinstance(self.package, str) or not self.package:
            raise InputError(
                f"study {self.name!r} needs the dotted name of its package, got {self.package!r}."
            )


class StudyRegistry(Mapping[str, ModuleType]):
    """Study name -> its package, for every study folder of one package.

    The studies are the entries of a `probaff._registry.Registry` of `Study`: each lookup
    first registers the study folders not registered yet (sorted by name), so a folder added
    while running is found.

    Args:
        package: The dotted name of the importable package whose subpackages are studies.
    """

    def __init__(self, package: str) -> None:
        self.package = package
        self.studies: Registry[Study] = Registry("study", Study, "StudyRegistry.unregister")
        self._loaded: dict[str, ModuleType] = {}

    @property
    def folders(self) -> list[Path]:
        """The folders of the package (its ``__path__``), whose subfolders are studies."""
        return [Path(p) for p in importlib.import_module(self.package).__path__]

    def _discover(self) -> None:
        """Register the study folders not registered yet, sorted by name.

        Raises:
            ConfigError: If two folders of the package hold a study of one name.
            InputError: If a study registered by hand has a study folder's name.
        """
        found: dict[str, Path] = {}
        for folder in self.folders:
            for info in pkgutil.iter_modules([str(folder)]):
                name = info.name
                if not info.ispkg or name.startswith(("_", ".")):
                    continue
                if name in found:
                    raise ConfigError(
                        f"study {name!r} is a folder in both {found[name]} and {folder}; "
                        "rename one of the two."
                    )
                found[name] = folder
        for name in sorted(found):
            known = self.studies.entries.get(name)
            if known is None or known.package != f"{self.package}.{name}":
                self.studies.add(Study(name, f"{self.package}.{name}"))

    def register(self, study: Study) -> Study:
        """Register a study whose package lives elsewhere, and return it.

        Raises:
            InputError: If its name is taken (by a folder or an earlier registration).
        """
        self._discover()
        return self.studies.add(study)

    def unregister(self, name: str) -> Study:
        """Remove the study `name` registered by hand and return it.

        Raises:
            InputError: If no study has that name.
        """
        self._loaded.pop(name, None)
        return self.studies.remove(name)

    def study(self, name: str) -> Study:
        """The registered study `name`.

        Raises:
            UnknownStudyError: For a name that is no study (the message lists the studies).
        """
        self._discover()
        if not isinstance(name, str) or name not in self.studies:
            raise UnknownStudyError(
                f"unknown study {name!r}; studies: {self.studies.names()}. A study is a folder "
                f"with an __init__.py in {', '.join(map(str, self.folders))}."
            )
        return self.studies.get(name)

    def __iter__(self) -> Iterator[str]:
        self._discover()
        return iter(self.studies)

    def __repr__(self) -> str:
        """``StudyRegistry('PACKAGE', [NAME, ...])``: the package and its studies by name."""
        return f"{type(self).__name__}({self.package!r}, {list(self)!r})"

    def __len__(self) -> int:
        self._discover()
        return len(self.studies)

    def __contains__(self, name: object) -> bool:
        self._discover()
        return name in self.studies

    def __getitem__(self, name: str) -> ModuleType:
        """The study's package, imported and checked on first use.

        Raises:
            UnknownStudyError: For a name that is no study (also a `KeyError`).
            InputError: For a study package that lacks ``Config``, ``SMOKE`` or ``run``.
        """
        if name not in self._loaded:
            study = self.study(name)
            importlib.invalidate_caches()  # a folder added since the last import is found
            module = importlib.import_module(study.package)
            missing = [a for a in _FACE if not hasattr(module, a)]
            if missing:
                raise InputError(
                    f"study {name!r} ({module.__name__}) does not name {missing}; a study's "
                    f"package names {list(_FACE)}."
                )
            self._loaded[name] = module
        return self._loaded[name]


def discover_studies(package: str) -> StudyRegistry:
    """The studies of `package`: one per subfolder with an ``__init__.py``.

    Args:
        package: The dotted name of an importable package (``"probaff.experiments"``).

    Returns:
        Study name -> its package, imported when first looked up.
    """
    return StudyRegistry(package)


STUDIES = discover_studies(__name__.rpartition(".")[0])
"""The studies of probaff, one per folder of `probaff.experiments`, sorted by name."""


def _usage(studies: Mapping[str, ModuleType]) -> str:
    names = ", ".join(studies)
    return (
        "usage: probaff study NAME [--smoke] [--FIELD VALUE ...] (NAME --help lists a "
        f"study's flags); studies: {names}"
    )


def study_main(
    argv: Sequence[str] | None = None, studies: Mapping[str, ModuleType] | None = None
) -> int:
    """``probaff study NAME [--smoke] [--FIELD VALUE ...]``: run one study from its flags.

    The flags are the study's config fields, exactly as its script in ``inference/`` takes
    them; the written files are printed as JSON.

    Args:
        argv: The arguments after ``study`` (default: none, which prints the usage).
        studies: The registry to look NAME up in (default: `STUDIES`).

    Returns:
        0 on success (or for ``--help``), 2 for a bad name, flag or setting (one line on
        stderr, or argparse's usage message).
    """
    registry = STUDIES if studies is None else studies
    args = list(argv or [])
    if not args or args[0] in ("-h", "--help"):
        print(_usage(registry))
        return 0 if args else 2
    name, rest = args[0], args[1:]
    prog = f"probaff study {name}"
    try:
        if name not in registry:
            raise InputError(f"unknown study {name!r}; choose one of {', '.join(registry)}.")
        study = registry[name]
        check_output_flags(["--out"], rest)
        config = parse_study_args(study.Config, study.SMOKE, study.__doc__ or name, rest, prog)
        result = study.run(config)
    except ProbaffError as exc:
        return report_error(prog, exc)
    except SystemExit as exc:  # argparse: --help, or a malformed flag (its usage printed)
        return exc.code if isinstance(exc.code, int) else 2
    shown = {k: result[k] for k in ("files", "computed") if k in result}
    print(json.dumps(shown, indent=1))
    return 0
