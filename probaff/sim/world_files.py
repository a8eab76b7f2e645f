"""Reading world files: locating ``worlds/``, parsing YAML and validating its fields.

Every world loader (`probaff.sim.tabletop_config`, `probaff.sim.sideview_config`,
`probaff.sim.warehouse_config`, `probaff.sim.office_config`, `probaff.sim.camera`) and any other
reader of ``worlds/`` files (e.g. a planning task) builds its frozen specs with these helpers,
so that a missing, unknown or malformed entry is refused with a `ConfigError` that names the
file and the field.

Names of places: ``where`` is the file name (``"tabletop.yaml"``) for the top level of a file
and ``"FILE:section.subsection"`` below it; the helpers that take a ``(where, table, key)``
triple name the entry ``FILE:key`` at the top level and ``FILE:section.key`` below it.
"""

from __future__ import annotations

import importlib.resources
import math
import os
from dataclasses import fields
from pathlib import Path
from typing import Any, ClassVar, TypedDict, TypeVar

import yaml

from probaff._checks import check_count, check_positive
from probaff.errors import ConfigError, InputError

__all__ = [
    "CheckedSpec",
    "Range",
    "SceneHeader",
    "check_spec",
    "child",
    "count",
    "count_field",
    "count_range",
    "load_root",
    "mapping",
    "no_extra",
    "number",
    "number_field",
    "optional_section",
    "pair_field",
    "positive_pair",
    "probability",
    "range_field",
    "read_yaml",
    "scene_header",
    "scene_names",
    "section",
    "take",
    "value_range",
    "worlds_dir",
]

Range = tuple[float, float]
"""A ``(low, high)`` pair of numbers, low <= high."""

_S = TypeVar("_S", bound="CheckedSpec")


def worlds_dir() -> Path:
    """Return the folder that holds the world descriptions.

    ``$PROBAFF_WORLDS`` wins; otherwise the package data ``probaff/worlds`` that an installed
    wheel carries (read through `importlib.resources`); otherwise, for an editable install or
    a source checkout, the repository's ``worlds/`` folder beside the ``probaff`` package (the
    one source of both).

    Raises:
        ConfigError: If ``$PROBAFF_WORLDS`` is set to a folder without ``tabletop.yaml``, or
            it is unset and neither the package data nor the repository holds one.
    """
    env = os.environ.get("PROBAFF_WORLDS")
    if env:
        if not (Path(env) / "tabletop.yaml").is_file():
            raise ConfigError(
                f"PROBAFF_WORLDS is {env}, which holds no world descriptions (no "
                "tabletop.yaml); set it to the folder holding tabletop.yaml, or unset it to "
                "use the world descriptions installed with probaff."
            )
        return Path(env)
    packaged = importlib.resources.files("probaff") / "worlds"
    if isinstance(packaged, Path) and (packaged / "tabletop.yaml").is_file():
        return packaged
    path = Path(__file__).resolve().parents[2] / "worlds"
    if not (path / "tabletop.yaml").is_file():
        raise ConfigError(
            f"no world descriptions found in {packaged} or {path}; install probaff with its "
            "package data (`pip install .`, a built wheel, or `pip install -e .` from its "
            "repository) or set PROBAFF_WORLDS to the folder holding tabletop.yaml."
        )
    return path


def scene_names(folder: str | Path) -> list[str]:
    """Sorted names of the scene templates ``NAME.yaml`` in a folder.

    Args:
        folder: A folder; a relative one is taken under `worlds_dir()`.
    """
    path = Path(folder)
    if not path.is_absolute():
        path = worlds_dir() / path
    return sorted(p.stem for p in path.glob("*.yaml"))


class SceneHeader(TypedDict):
    """The ``name`` and ``description`` of a scene template."""

    name: str
    description: str


def scene_header(raw: dict[str, Any], name: str) -> SceneHeader:
    """The ``name`` and ``description`` of a scene template (by default its file's stem and ``""``).

    Args:
        raw: The template's top level.
        name: The name it was loaded by.
    """
    return {"name": str(raw.get("name", name)), "description": str(raw.get("description", ""))}


def read_yaml(path: Path) -> Any:
    """The parsed content of a world file.

    Raises:
        ConfigError: If `path` is missing, a folder, unreadable, not UTF-8 text or not YAML.
    """
    if path.is_dir():
        raise ConfigError(
            f"world file {path} is a folder, not a YAML file; give the path of a world file."
        )
    if not path.is_file():
        raise ConfigError(
            f"world file {path} does not exist; give the path of an existing world file."
        )
    try:
        return yaml.safe_load(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise ConfigError(
            f"cannot read world file {path} ({exc.strerror or exc}); check that you may read it."
        ) from exc
    except UnicodeDecodeError as exc:
        raise ConfigError(
            f"world file {path} is not UTF-8 text ({exc.reason} at byte {exc.start}); give the "
            "path of a YAML world file."
        ) from exc
    except yaml.YAMLError as exc:
        raise ConfigError(f"{path} is not valid YAML: {exc}; fix the file's syntax.") from exc


def load_root(path: Path | None, default: str) -> tuple[dict[str, Any], str, Path]:
    """Read a world file whose top level is a mapping.

    Args:
        path: The file; ``None`` for `default` in `worlds_dir()`.
        default: File name of the standard world file, e.g. ``"tabletop.yaml"``.

    Returns:
        ``(mapping, file name for messages, path)``.
    """
    p = path or worlds_dir() / default
    return mapping(str(p), read_yaml(p)), p.name, p


def child(where: str, key: str) -> str:
    """The name of entry `key` of `where`: ``FILE:key`` at the top level, else ``where.key``."""
    return f"{where}.{key}" if ":" in where else f"{where}:{key}"


def mapping(where: str, value: Any) -> dict[str, Any]:
    """`value`, which must be a mapping.

    Raises:
        ConfigError: Naming `where`, for any other value.
    """
    if not isinstance(value, dict):
        raise ConfigError(f"{where} must be a mapping, got {type(value).__name__}.")
    return value


def take(where: str, table: dict[str, Any], key: str) -> Any:
    """``table[key]``.

    Raises:
        ConfigError: Naming `where` and `key`, if the field is missing.
    """
    if key not in table:
        raise ConfigError(f"{where} is missing the field '{key}'.")
    return table[key]


def no_extra(where: str, table: dict[str, Any], allowed: set[str]) -> None:
    """Refuse fields of `table` outside `allowed`.

    Raises:
        ConfigError: Naming `where`, the unknown fields and the allowed ones.
    """
    extra = set(table) - allowed
    if extra:
        raise ConfigError(
            f"{where} has unknown field(s) {sorted(extra)}; allowed: {sorted(allowed)}."
        )


def section(
    where: str, table: dict[str, Any], key: str, allowed: set[str] | None = None
) -> dict[str, Any]:
    """The required mapping ``table[key]``, its fields checked against `allowed` if given.

    Raises:
        ConfigError: If it is missing, not a mapping or has a field outside `allowed`.
    """
    name = child(where, key)
    out = mapping(name, take(where, table, key))
    if allowed is not None:
        no_extra(name, out, allowed)
    return out


def optional_section(
    where: str, table: dict[str, Any], key: str, allowed: set[str]
) -> dict[str, Any]:
    """The optional mapping ``table[key]``: ``{}`` when it is missing or empty.

    Raises:
        ConfigError: If it is given but not a mapping, or has a field outside `allowed`.
    """
    name = child(where, key)
    out = mapping(name, table.get(key) or {})
    no_extra(name, out, allowed)
    return out


def number(where: str, value: Any, *, positive: bool = False, nonneg: bool = False) -> float:
    """`value` as a finite float (> 0 if `positive`, >= 0 if `nonneg`).

    Raises:
        ConfigError: Naming `where`, for a non-number (a bool included) or a value out of range.
    """
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ConfigError(f"{where} must be a number, got {value!r}.")
    v = float(value)
    if not math.isfinite(v):
        raise ConfigError(f"{where} must be finite, got {value!r}.")
    if positive and v <= 0:
        raise ConfigError(f"{where} must be > 0, got {value!r}.")
    if nonneg and v < 0:
        raise ConfigError(f"{where} must be >= 0, got {value!r}.")
    return v


def number_field(where: str, table: dict[str, Any], key: str, **kw: bool) -> float:
    """The number ``table[key]``, validated by `number` (keywords `positive`, `nonneg`)."""
    return number(child(where, key), take(where, table, key), **kw)


def count(where: str, value: Any, *, minimum: int = 1) -> int:
    """`check_count` for a world file's field: the same rule, reported as a `ConfigError`."""
    try:
        return check_count(where, value, minimum=minimum)
    except InputError as exc:
        raise ConfigError(str(exc)) from None


def count_field(where: str, table: dict[str, Any], key: str, *, minimum: int = 1) -> int:
    """The count ``table[key]``, validated by `count`."""
    return count(child(where, key), take(where, table, key), minimum=minimum)


def value_range(where: str, value: Any, *, nonneg: bool = False, positive: bool = False) -> Range:
    """`value` as a ``(low, high)`` pair of numbers, low <= high.

    Raises:
        ConfigError: For anything but a pair of such numbers, or low > high.
    """
    if not isinstance(value, (list, tuple)) or len(value) != 2:
        raise ConfigError(f"{where} must be a [low, high] pair, got {value!r}.")
    lo = number(f"{where}[0]", value[0], nonneg=nonneg, positive=positive)
    hi = number(f"{where}[1]", value[1], nonneg=nonneg, positive=positive)
    if lo > hi:
        raise ConfigError(f"{where} has low {lo} > high {hi}; swap them.")
    return (lo, hi)


def range_field(
    where: str,
    table: dict[str, Any],
    key: str,
    default: Range | None = None,
    *,
    nonneg: bool = False,
    positive: bool = False,
) -> Range:
    """The range ``table[key]`` (`value_range`); `default` when it is absent, if given."""
    raw = take(where, table, key) if default is None else table.get(key, list(default))
    return value_range(child(where, key), raw, nonneg=nonneg, positive=positive)


def positive_pair(where: str, value: Any) -> tuple[float, float]:
    """`value` as a pair of numbers > 0 (a size, not a range: any order).

    Raises:
        ConfigError: For anything else.
    """
    if not isinstance(value, (list, tuple)) or len(value) != 2:
        raise ConfigError(f"{where} must be a pair of positive numbers, got {value!r}.")
    return (
        number(f"{where}[0]", value[0], positive=True),
        number(f"{where}[1]", value[1], positive=True),
    )


def pair_field(where: str, table: dict[str, Any], key: str) -> tuple[float, float]:
    """The pair ``table[key]`` of numbers > 0 (`positive_pair`)."""
    return positive_pair(child(where, key), take(where, table, key))


def probability(where: str, value: Any) -> float:
    """`value` as a probability in [0, 1].

    Raises:
        ConfigError: For a non-number or a number outside [0, 1].
    """
    v = number(where, value, nonneg=True)
    if v > 1.0:
        raise ConfigError(f"{where} must be a probability in [0, 1], got {value!r}.")
    return v


def count_range(where: str, value: Any) -> tuple[int, int]:
    """`value` as a ``(low, high)`` pair of counts, 0 <= low <= high.

    Raises:
        ConfigError: For anything else.
    """
    if not isinstance(value, (list, tuple)) or len(value) != 2:
        raise ConfigError(f"{where} must be a [low, high] pair of counts, got {value!r}.")
    lo, hi = (count(f"{where}[{i}]", v, minimum=0) for i, v in enumerate(value))
    if lo > hi:
        raise ConfigError(f"{where} has low {lo} > high {hi}; swap them.")
    return (lo, hi)


def check_spec(
    spec: object,
    *,
    positive: tuple[str, ...] = (),
    nonneg: tuple[str, ...] = (),
    counts: tuple[str, ...] = (),
) -> None:
    """Check the physical fields of a spec built in code, before any reaches pymunk.

    The loaders check the world files field by field; this repeats the range checks for a spec
    made or changed directly (e.g. with `dataclasses.replace`), where a negative mass or
    friction would otherwise abort the process inside Chipmunk.

    Args:
        spec: The dataclass instance.
        positive: Fields that must be finite numbers > 0 (a pair or tuple: each entry).
        nonneg: Fields that must be finite numbers >= 0.
        counts: Fields that must be positive integers.

    Raises:
        ConfigError: Naming the first bad field, e.g. ``ObjectSpec.mass``.
    """
    kind = type(spec).__name__
    try:
        for names, allow_zero in ((positive, False), (nonneg, True)):
            for name in names:
                value = getattr(spec, name)
                items = enumerate(value) if isinstance(value, (tuple, list)) else [(None, value)]
                for i, v in items:
                    where = f"{kind}.{name}" if i is None else f"{kind}.{name}[{i}]"
                    if isinstance(v, (bool, str, bytes)):
                        raise ConfigError(f"{where} must be a number, got {v!r}.")
                    check_positive(where, v, allow_zero=allow_zero)
        for name in counts:
            check_count(f"{kind}.{name}", getattr(spec, name))
    except InputError as exc:
        raise ConfigError(str(exc)) from None


class CheckedSpec:
    """Base of the frozen spec dataclasses: fields checked on construction, read by name.

    A subclass (a ``@dataclass(frozen=True)``) names its physical fields in the class
    attributes below. Construction checks them with `check_spec` (a subclass with further
    rules extends ``__post_init__``), and `read` builds one from a world-file section whose
    keys are the field names, each read by its annotated type: ``float`` by `number` (> 0 for
    `POSITIVE`, >= 0 for `NONNEG`, `probability` for `PROBABILITIES`), ``int`` by `count`,
    ``Range`` by `value_range`, ``tuple[float, float]`` by `positive_pair`,
    ``tuple[int, int]`` by `count_range` and ``str`` as text.
    """

    POSITIVE: ClassVar[tuple[str, ...]] = ()
    """Fields that must be > 0 (every entry of a pair)."""
    NONNEG: ClassVar[tuple[str, ...]] = ()
    """Fields that must be >= 0."""
    COUNTS: ClassVar[tuple[str, ...]] = ()
    """Fields that must be positive integers."""
    PROBABILITIES: ClassVar[tuple[str, ...]] = ()
    """Fields that are probabilities: >= 0, and <= 1 in a world file."""
    PAIRS: ClassVar[dict[str, str]] = {}
    """Fields that must be pairs, with what their two entries are, e.g. ``"(length, width)"``."""

    def __post_init__(self) -> None:
        for name, what in self.PAIRS.items():
            value = getattr(self, name)
            if not isinstance(value, (tuple, list)) or len(value) != 2:
                raise ConfigError(
                    f"{type(self).__name__}.{name} must be a {what} pair, got {value!r}."
                )
        check_spec(
            self,
            positive=self.POSITIVE,
            nonneg=self.NONNEG + self.PROBABILITIES,
            counts=self.COUNTS,
        )

    @classmethod
    def read(cls: type[_S], where: str, table: dict[str, Any], **given: Any) -> _S:
        """Build one from the section `table` named `where`, field by field in order.

        Args:
            where: Name of the section, ``"FILE:section"``.
            table: The section; its keys are the field names.
            **given: Values of the fields not read from `table`.

        Raises:
            ConfigError: Naming the missing or malformed field.
        """
        names = [f.name for f in fields(cls) if f.name not in given]  # type: ignore[arg-type]
        return cls(**cls.read_fields(where, table, {name: name for name in names}), **given)

    @classmethod
    def read_fields(cls, where: str, table: dict[str, Any], keys: dict[str, str]) -> dict[str, Any]:
        """Read fields of this spec from a section whose keys may differ from the field names.

        Args:
            where: Name of the section, ``"FILE:section"``.
            table: The section.
            keys: Section key -> field name, in the order to read them; each value is read by
                its field's annotated type and class attributes.

        Returns:
            Field name -> value.

        Raises:
            ConfigError: Naming the missing or malformed entry.
        """
        types = {f.name: str(f.type) for f in fields(cls)}  # type: ignore[arg-type]
        return {
            name: cls._read_field(where, table, key, name, types[name])
            for key, name in keys.items()
        }

    @classmethod
    def _read_field(cls, where: str, table: dict[str, Any], key: str, name: str, kind: str) -> Any:
        positive, nonneg = name in cls.POSITIVE, name in cls.NONNEG
        if kind == "float" and name in cls.PROBABILITIES:
            return probability(child(where, key), take(where, table, key))
        if kind == "float":
            return number_field(where, table, key, positive=positive, nonneg=nonneg)
        if kind == "int":
            return count_field(where, table, key)
        if kind == "Range":
            return range_field(where, table, key, positive=positive, nonneg=nonneg)
        if kind == "tuple[float, float]":
            return pair_field(where, table, key)
        if kind == "tuple[int, int]":
            return count_range(child(where, key), take(where, table, key))
        if kind == "str":
            return str(take(where, table, key))
        raise TypeError(f"{cls.__name__}.{name} of type {kind} cannot be read; pass it.")
