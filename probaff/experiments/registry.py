"""The studies, found folder by folder, and the command that runs any of them.

A study is a subpackage (a folder with an ``__init__.py``) whose package names ``Config`` (a
`probaff.experiments.base.StudyConfig` subclass), ``SMOKE`` (its smoke sizes) and
``run(config) -> dict`` (whose ``"files"`` lists what it wrote). `discover_studies` lists
the folders without importing them; a study is imported when first looked up. Adding a study
is adding its folder: `STUDIES` and ``probaff study NAME`` find it.
"""

from __future__ import annotations

import importlib
import json
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path
from types import ModuleType

from probaff._cli_errors import check_output_flags, report_error
from probaff.errors import InputError, ProbaffError
from probaff.experiments.config_cli import parse_study_args

__all__ = ["STUDIES", "StudyRegistry", "discover_studies", "study_main"]

_FACE = ("Config", "SMOKE", "run")


class StudyRegistry(Mapping[str, ModuleType]):
    """Study name -> its package, for every study folder under one folder.

    Args:
        folder: The folder whose subfolders are studies.
        package: The dotted name under which `folder` is importable.
    """

    def __init__(self, folder: str | Path, package: str) -> None:
        self.folder = Path(folder)
        self.package = package
        self._loaded: dict[str, ModuleType] = {}

    def _names(self) -> list[str]:
        return sorted(
            p.parent.name
            for p in self.folder.glob("*/__init__.py")
            if not p.parent.name.startswith(("_", "."))
        )

    def __iter__(self) -> Iterator[str]:
        return iter(self._names())

    def __len__(self) -> int:
        return len(self._names())

    def __getitem__(self, name: str) -> ModuleType:
        """The study's package, imported and checked on first use.

        Raises:
            KeyError: For a name that is not a study folder.
            InputError: For a study package that lacks ``Config``, ``SMOKE`` or ``run``.
        """
        if name not in self._loaded:
            if name not in self._names():
                raise KeyError(name)
            importlib.invalidate_caches()  # a folder added since the last import is found
            module = importlib.import_module(f"{self.package}.{name}")
            missing = [a for a in _FACE if not hasattr(module, a)]
            if missing:
                raise InputError(
                    f"study {name!r} ({module.__name__}) does not name {missing}; a study's "
                    f"package names {list(_FACE)}."
                )
            self._loaded[name] = module
        return self._loaded[name]


def discover_studies(folder: str | Path, package: str) -> StudyRegistry:
    """The studies of `folder` (importable as `package`): one per subfolder.

    Args:
        folder: A folder of study folders.
        package: Its dotted import name (``"probaff.experiments"``).

    Returns:
        Study name -> its package, imported when first looked up.
    """
    return StudyRegistry(folder, package)


STUDIES = discover_studies(Path(__file__).resolve().parent, "probaff.experiments")
"""The studies of probaff: ``affordance_map``, ``modular``, ``planning``,
``point_cloud_labels``, ``push_models`` and ``pusht``."""


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
