"""Command-line options built from a study config's dataclass fields.

Each field of a study config becomes one flag (``ch5_pushes`` -> ``--ch5-pushes``) with the
field's default, type and docstring, so a script never restates a default or a help text:

    parser = argparse.ArgumentParser()
    add_config_arguments(parser, PushModelStudyConfig)
    config = config_from_args(PushModelStudyConfig, parser.parse_args())
"""

from __future__ import annotations

import argparse
import dataclasses
import re
import types
import typing
from collections.abc import Sequence
from typing import Any

__all__ = ["add_config_arguments", "config_from_args", "study_config", "study_parser"]


def _field_help(cls: type) -> dict[str, str]:
    """Field name -> first sentence of its entry in the class docstring's ``Attributes``."""
    doc = cls.__doc__ or ""
    if "Attributes:" not in doc:
        return {}
    out: dict[str, str] = {}
    current = None
    for line in doc.split("Attributes:", 1)[1].splitlines():
        m = re.match(r"^\s{8}(\w+): (.*)$", line)
        if m:
            current = m.group(1)
            out[current] = m.group(2).strip()
        elif current and line.startswith(" " * 12):
            out[current] += " " + line.strip()
        elif line.strip():
            current = None
    return {k: v.replace("%", "%%") for k, v in out.items()}


def _parser_for(hint: Any, name: str) -> tuple[Any, str]:
    """A string -> value converter for a field's type hint, and a metavar."""
    origin = typing.get_origin(hint)
    args = typing.get_args(hint)
    if origin in (typing.Union, types.UnionType) and type(None) in args:
        (inner,) = [a for a in args if a is not type(None)]
        convert, metavar = _parser_for(inner, name)

        def optional(text: str) -> Any:
            return None if text.lower() in ("none", "") else convert(text)

        return optional, metavar
    if origin is tuple:
        item = args[0]

        def items(text: str) -> tuple[Any, ...]:
            try:
                return tuple(item(t.strip()) for t in text.split(",") if t.strip())
            except ValueError as err:
                raise argparse.ArgumentTypeError(
                    f"--{name.replace('_', '-')} takes comma-separated {item.__name__} "
                    f"values, got {text!r}"
                ) from err

        return items, f"{item.__name__.upper()},..."
    if hint in (int, float, str):
        return hint, hint.__name__.upper()
    raise TypeError(f"field {name!r} has a type ({hint!r}) with no command-line form.")


def add_config_arguments(
    parser: argparse.ArgumentParser, config_cls: type, *, skip: tuple[str, ...] = ()
) -> None:
    """Add one flag per field of the dataclass `config_cls` (except `skip`).

    Booleans get ``--flag`` / ``--no-flag``; tuples take comma-separated values; optional
    fields accept ``none``. A field that is itself a dataclass (an options object such as
    `probaff.maps.MRFParams`) contributes one flag per field of its own, under the inner
    field's name. Defaults and help texts come from the dataclasses.

    Args:
        parser: The parser to extend.
        config_cls: A dataclass whose fields are ints, floats, strings, booleans, tuples of
            those, optional ones, or dataclasses of those.
        skip: Field names that get no flag (the script sets them itself).

    Raises:
        TypeError: For a field type with no command-line form, or two fields (outer and
            inner) of the same name.
    """
    seen: set[str] = set()
    for cls, f, default in _flat_fields(config_cls):
        if f.name in skip:
            continue
        if f.name in seen:
            raise TypeError(f"two fields named {f.name!r} in {config_cls.__name__}.")
        seen.add(f.name)
        hint = typing.get_type_hints(cls)[f.name]
        flag = "--" + f.name.replace("_", "-")
        text = _field_help(cls).get(f.name, "")
        shown = ",".join(map(str, default)) if isinstance(default, tuple) else default
        help_text = f"{text} (default: {shown})" if text else f"(default: {shown})"
        if hint is bool:
            parser.add_argument(
                flag,
                dest=f.name,
                action=argparse.BooleanOptionalAction,
                default=default,
                help=help_text,
            )
            continue
        convert, metavar = _parser_for(hint, f.name)
        parser.add_argument(
            flag, dest=f.name, type=convert, default=default, metavar=metavar, help=help_text
        )


def _default(f: dataclasses.Field[Any]) -> Any:
    if f.default_factory is not dataclasses.MISSING:
        return f.default_factory()
    return f.default


def _flat_fields(config_cls: type) -> list[tuple[type, dataclasses.Field[Any], Any]]:
    """(owning class, field, default) of every leaf field; nested dataclasses are opened."""
    hints = typing.get_type_hints(config_cls)
    out: list[tuple[type, dataclasses.Field[Any], Any]] = []
    for f in dataclasses.fields(config_cls):
        inner = hints[f.name]
        if dataclasses.is_dataclass(inner) and isinstance(inner, type):
            nested = _default(f)
            out += [(inner, g, getattr(nested, g.name)) for g in dataclasses.fields(inner)]
        else:
            out.append((config_cls, f, _default(f)))
    return out


def config_from_args(config_cls: type, args: argparse.Namespace, **overrides: Any) -> Any:
    """The config of `config_cls` from parsed flags, with `overrides` on top.

    Args:
        config_cls: The dataclass the flags were built from.
        args: What `parser.parse_args()` returned.
        **overrides: Field values that replace the parsed ones (outer fields only).

    Returns:
        A `config_cls` instance.
    """
    parsed = vars(args)
    hints = typing.get_type_hints(config_cls)
    values: dict[str, Any] = {}
    for f in dataclasses.fields(config_cls):
        inner = hints[f.name]
        if dataclasses.is_dataclass(inner) and isinstance(inner, type):
            base = _default(f)
            values[f.name] = dataclasses.replace(
                base,
                **{g.name: parsed[g.name] for g in dataclasses.fields(inner) if g.name in parsed},
            )
        elif f.name in parsed:
            values[f.name] = parsed[f.name]
    return config_cls(**{**values, **overrides})


class _StudyParser(argparse.ArgumentParser):
    """A parser that also records which options the command line gave.

    `study_config` needs to know them: ``--smoke`` sizes apply only to the fields the user
    left at their defaults, so a value typed on the command line is never replaced (and is
    validated) even in a smoke run.
    """

    def parse_known_args(  # type: ignore[override]
        self, args: Sequence[str] | None = None, namespace: argparse.Namespace | None = None
    ) -> tuple[argparse.Namespace, list[str]]:
        parsed, extra = super().parse_known_args(args, namespace)
        saved = [(a, a.default) for a in self._actions]
        try:
            for action, _ in saved:
                action.default = argparse.SUPPRESS
            given, _ = super().parse_known_args(args, None)
        finally:
            for action, default in saved:
                action.default = default
        setattr(parsed, GIVEN, frozenset(vars(given)))
        return parsed, extra


GIVEN = "_given_on_command_line"
"""Name of the parsed namespace's attribute holding the destinations the command line set."""


def study_parser(config_cls: type, doc: str) -> argparse.ArgumentParser:
    """A study script's parser: one flag per config field, and ``--smoke``.

    Args:
        config_cls: The study's config dataclass.
        doc: The script's docstring; its first line is the description.

    Returns:
        The parser; add the script's own flags to it before parsing.
    """
    parser = _StudyParser(description=doc.splitlines()[0])
    add_config_arguments(parser, config_cls)
    parser.add_argument(
        "--smoke",
        action="store_true",
        help="a tiny run that checks the pipeline (the study's smoke sizes for every field "
        "not given on the command line)",
    )
    return parser


def _smoke_values(
    config_cls: type, cfg: Any, smoke: dict[str, Any], given: frozenset[str]
) -> dict[str, Any]:
    """The `smoke` field values, less every (outer or nested) field the user gave."""
    hints = typing.get_type_hints(config_cls)
    out: dict[str, Any] = {}
    for name, value in smoke.items():
        inner = hints.get(name)
        if dataclasses.is_dataclass(inner) and isinstance(inner, type):
            mine = getattr(cfg, name)
            keep = {g.name: getattr(mine, g.name) for g in dataclasses.fields(inner)}
            out[name] = dataclasses.replace(value, **{k: v for k, v in keep.items() if k in given})
        elif name not in given:
            out[name] = value
    return out


def study_config(
    config_cls: type, args: argparse.Namespace, smoke: dict[str, Any], **overrides: Any
) -> Any:
    """The config from parsed flags, with the `smoke` sizes on top when ``--smoke`` was given.

    The flags the user gave are validated first (the config is built from them before any
    smoke size is applied), and a smoke size never replaces a value given on the command
    line: ``--smoke --trials 0`` is refused, ``--smoke --trials 5`` runs 5 trials.

    Args:
        config_cls: The study's config dataclass.
        args: What a `study_parser` returned from ``parse_args()``; a namespace from another
            parser counts every field as not given.
        smoke: The study's smoke-sized field values (a nested options dataclass counts field
            by field).
        **overrides: Field values from the script's own flags (applied last).

    Returns:
        A `config_cls` instance.
    """
    cfg = config_from_args(config_cls, args)
    if getattr(args, "smoke", False):
        given: frozenset[str] = getattr(args, GIVEN, frozenset())
        cfg = dataclasses.replace(cfg, **_smoke_values(config_cls, cfg, smoke, given))
    return dataclasses.replace(cfg, **overrides) if overrides else cfg
