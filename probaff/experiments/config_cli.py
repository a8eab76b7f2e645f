"""Command-line options built from a study config's dataclass fields.

Each field of a study config becomes one flag (``ch5_pushes`` -> ``--ch5-pushes``) with the
field's default, type and docstring, so a script never restates a default or a help text:

    parser = argparse.ArgumentParser()
    add_config_arguments(parser, PushModelStudyConfig)
    config = config_from_args(PushModelStudyConfig, parser.parse_args())

A field that is itself a dataclass is opened: its fields become flags of their own, under
their own names (`probaff.maps.MRFParams`' ``alpha`` -> ``--alpha``), or, for a field whose
metadata is `option_flags` (fit options such as `probaff.models.EMOptions`), under the
field's name as a prefix (``em.max_iter`` -> ``--em-max-iter``), so a value keeps its name
from the flag to the fit, and stored results are keyed by those names (`settings_view`).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import re
import sys
import types
import typing
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from probaff._cli_errors import run_cli
from probaff.errors import InputError

__all__ = [
    "GIVEN",
    "TYPED",
    "Flag",
    "add_config_arguments",
    "config_flags",
    "config_from_args",
    "field_settings",
    "flag_values",
    "option_flags",
    "parse_study_args",
    "rebuild",
    "run_study_script",
    "settings_view",
    "study_config",
    "study_parser",
    "with_smoke",
]

GIVEN = "_given_on_command_line"
"""Name of the parsed namespace's attribute holding the destinations the command line set."""

TYPED = "_typed_on_command_line"
"""Name of the parsed namespace's attribute: destination -> the flag name the user typed."""

_OPTIONS = "probaff.option_flags"  # field metadata key of `option_flags`


@dataclass(frozen=True)
class Flag:
    """One command-line flag of a config: where its value goes, and how it reads.

    Attributes:
        dest: The flag's name with underscores (``"em_max_iter"`` for ``--em-max-iter``).
        path: Attribute path of the value in the config (``("em", "max_iter")``).
        owner: The dataclass that declares the value's field.
        default: The value in the default config.
    """

    dest: str
    path: tuple[str, ...]
    owner: type
    default: Any

    @property
    def hint(self) -> Any:
        """The value field's type hint."""
        return typing.get_type_hints(self.owner)[self.path[-1]]

    def option_string(self) -> str:
        """``--dest`` with dashes."""
        return "--" + self.dest.replace("_", "-")


def option_flags(flags: Sequence[str]) -> dict[str, Any]:
    """Field metadata of a config field holding fit options: which of them are flags.

    Used as ``em: EMOptions = field(default=EMOptions(), metadata=option_flags(...))``.

    Args:
        flags: Names of the options' fields that get a flag ``--<field>-<name>``; the others
            keep the default's values.

    Returns:
        The metadata mapping.
    """
    return {_OPTIONS: {"flags": tuple(flags)}}


def _field_help(cls: type) -> dict[str, str]:
    """Field name -> first sentence of its ``Attributes`` entry, subclasses' texts first."""
    out: dict[str, str] = {}
    for klass in reversed(cls.__mro__):
        doc = klass.__doc__ or ""
        if "Attributes:" not in doc:
            continue
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


def _parser_for(hint: Any, name: str) -> tuple[Callable[[str], Any], str]:
    """A string -> value converter for a field's type hint, and a metavar."""
    origin = typing.get_origin(hint)
    args = typing.get_args(hint)
    if origin in (typing.Union, types.UnionType) and type(None) in args:
        inner = [a for a in args if a is not type(None)]
        rest = inner[0] if len(inner) == 1 else typing.Union[tuple(inner)]  # noqa: UP007
        convert, metavar = _parser_for(rest, name)

        def optional(text: str) -> Any:
            return None if text.lower() in ("none", "") else convert(text)

        return optional, metavar
    numbers = [a for a in args if a in (int, float)]
    if origin in (typing.Union, types.UnionType) and bool in args and numbers:  # bool | float

        def switch_or_number(text: str) -> Any:
            words = {"true": True, "yes": True, "on": True, "false": False, "no": False}
            words["off"] = False
            if text.lower() in words:
                return words[text.lower()]
            try:
                return numbers[0](text)
            except ValueError:
                raise argparse.ArgumentTypeError(
                    f"--{name.replace('_', '-')} takes true, false or a number, got {text!r}"
                ) from None

        return switch_or_number, f"true|false|{numbers[0].__name__.upper()}"
    if origin in (typing.Union, types.UnionType):  # e.g. str | Tensor: the first with a form
        for arg in args:
            try:
                return _parser_for(arg, name)
            except TypeError:
                continue
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


def _ordered_fields(cls: type) -> list[dataclasses.Field[Any]]:
    """`cls`'s fields, those named in its ``TRAILING_FLAGS`` last (how a study runs)."""
    trailing = tuple(getattr(cls, "TRAILING_FLAGS", ()))
    fields = dataclasses.fields(cls)
    return [f for f in fields if f.name not in trailing] + [
        f for name in trailing for f in fields if f.name == name
    ]


def _flags(cls: type, instance: Any, path: tuple[str, ...]) -> list[Flag]:
    hints = typing.get_type_hints(cls)
    out: list[Flag] = []
    for f in _ordered_fields(cls):
        value, inner = getattr(instance, f.name), hints[f.name]
        here = (*path, f.name)
        spec = f.metadata.get(_OPTIONS)
        if spec is not None:
            out += [
                Flag(f"{f.name}_{n}", (*here, n), type(value), getattr(value, n))
                for n in spec["flags"]
            ]
        elif dataclasses.is_dataclass(inner) and isinstance(inner, type):
            out += _flags(inner, value, here)
        else:
            out.append(Flag(f.name, here, cls, value))
    return out


def config_flags(config_cls: type) -> list[Flag]:
    """Every flag of the dataclass `config_cls`, in the order they are listed.

    Args:
        config_cls: A dataclass whose fields all have defaults.

    Raises:
        TypeError: If two flags share a name.
    """
    flags = _flags(config_cls, config_cls(), ())
    seen: set[str] = set()
    for flag in flags:
        if flag.dest in seen:
            raise TypeError(f"two fields named {flag.dest!r} in {config_cls.__name__}.")
        seen.add(flag.dest)
    return flags


def add_config_arguments(
    parser: argparse.ArgumentParser, config_cls: type, *, skip: tuple[str, ...] = ()
) -> None:
    """Add one flag per field of the dataclass `config_cls` (except `skip`).

    Booleans get ``--flag`` / ``--no-flag``; tuples take comma-separated values; optional
    fields accept ``none``. A field that is itself a dataclass (an options object such as
    `probaff.maps.MRFParams`) contributes one flag per field of its own, under the inner
    field's name, or, if its metadata is `option_flags`, under ``<field>_<name>``. Defaults and
    help texts come from the dataclasses.

    Args:
        parser: The parser to extend.
        config_cls: A dataclass whose fields are ints, floats, strings, booleans, tuples of
            those, optional ones, or dataclasses of those.
        skip: Flag names (underscores) that get no flag (the script sets them itself).

    Raises:
        TypeError: For a field type with no command-line form, or two flags of one name.
    """
    for flag in config_flags(config_cls):
        if flag.dest in skip:
            continue
        text = _field_help(flag.owner).get(flag.path[-1], "")
        default = flag.default
        shown = ",".join(map(str, default)) if isinstance(default, tuple) else default
        help_text = f"{text} (default: {shown})" if text else f"(default: {shown})"
        if flag.hint is bool:
            kwargs: dict[str, Any] = {"action": argparse.BooleanOptionalAction}
        else:
            convert, metavar = _parser_for(flag.hint, flag.dest)
            kwargs = {"type": convert, "metavar": metavar}
        parser.add_argument(
            flag.option_string(), dest=flag.dest, default=default, help=help_text, **kwargs
        )


def rebuild(instance: Any, **changes: Any) -> Any:
    """A copy of the dataclass `instance` with `changes`, built from its fields alone.

    Unlike `dataclasses.replace`, init-only keywords (``InitVar`` shorthands such as
    `AffordanceMapConfig`'s ``alpha``) are not passed again, so they cannot undo a change
    of the field they stand for.
    """
    values = {f.name: getattr(instance, f.name) for f in dataclasses.fields(instance) if f.init}
    return type(instance)(**{**values, **changes})


def _named(err: InputError, shown: Mapping[str, str], fields: Iterable[str]) -> InputError:
    """`err` of a nested dataclass, speaking of its fields by the flag names in `shown`."""
    text = str(err)
    for leaf, name in shown.items():
        if re.match(rf"{re.escape(leaf)}\b", text):
            return type(err)(name + text[len(leaf) :])
    if len(shown) == 1 and not any(re.match(rf"{re.escape(f)}\b", text) for f in fields):
        return type(err)(f"{next(iter(shown.values()))}: {text}")
    return err


def _assign(
    instance: Any,
    values: Mapping[tuple[str, ...], Any],
    names: Mapping[tuple[str, ...], str] | None = None,
    path: tuple[str, ...] = (),
) -> Any:
    """`instance` with the value at every attribute path of `values` replaced.

    A nested dataclass that refuses a value (`InputError` from its ``__post_init__``) is
    reported with the value's flag name from `names` (attribute path -> name).
    """
    heads: dict[str, dict[tuple[str, ...], Any]] = {}
    changes: dict[str, Any] = {}
    for where, value in values.items():
        if len(where) == 1:
            changes[where[0]] = value
        else:
            heads.setdefault(where[0], {})[where[1:]] = value
    for name, inner in heads.items():
        current = changes.get(name, getattr(instance, name))
        changes[name] = _assign(current, inner, names, (*path, name))
    if not changes:
        return instance
    try:
        return rebuild(instance, **changes)
    except InputError as err:
        if not path or not names:
            raise
        shown = {n: names[(*path, n)] for n in changes if (*path, n) in names}
        fields = [f.name for f in dataclasses.fields(instance)]
        raise _named(err, shown, fields) from None


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
    typed: Mapping[str, str] = getattr(args, TYPED, {})
    given = getattr(args, GIVEN, None)
    flags = [f for f in config_flags(config_cls) if f.dest in parsed]
    values = {f.path: parsed[f.dest] for f in flags}
    values.update({(name,): value for name, value in overrides.items()})
    names = {f.path: typed.get(f.dest, f.dest) for f in flags if given is None or f.dest in given}
    return _assign(config_cls(), values, names)


def flag_values(config: Any) -> dict[str, Any]:
    """Flag name (underscores) -> value of every flag of `config`, in the flags' order."""
    out: dict[str, Any] = {}
    for flag in config_flags(type(config)):
        value = config
        for name in flag.path:
            value = getattr(value, name)
        out[flag.dest] = value
    return out


def field_settings(instance: Any, f: dataclasses.Field[Any]) -> dict[str, Any]:
    """The settings one field of a config stands for, by the names its flags first had.

    A plain field is itself; a nested dataclass is its own settings (a mapping); fit options
    (`option_flags`) are one setting per flag, named as the flag, and one per other field
    whose value is not the options' default.
    """
    value = getattr(instance, f.name)
    spec = f.metadata.get(_OPTIONS)
    if spec is not None:
        default = type(value)()
        out = {f"{f.name}_{n}": getattr(value, n) for n in spec["flags"]}
        for g in dataclasses.fields(value):
            if g.name not in spec["flags"] and getattr(value, g.name) != getattr(default, g.name):
                out[f"{f.name}_{g.name}"] = getattr(value, g.name)
        return out
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: settings_view(value)}
    return {f.name: value}


def settings_view(instance: Any) -> dict[str, Any]:
    """Every setting of the dataclass `instance` by name (`field_settings` of each field).

    In the order of the flags; the names are those a stored result's fingerprint uses.
    """
    out: dict[str, Any] = {}
    for f in _ordered_fields(type(instance)):
        out.update(field_settings(instance, f))
    return out


def _smoke_leaves(
    instance: Any, smoke: Mapping[str, Any], path: tuple[str, ...]
) -> dict[tuple[str, ...], Any]:
    """Attribute path -> value of every leaf a smoke mapping sets (nested ones opened)."""
    out: dict[tuple[str, ...], Any] = {}
    for name, value in smoke.items():
        current = getattr(instance, name)
        if dataclasses.is_dataclass(current) and isinstance(value, Mapping):
            out.update(_smoke_leaves(current, value, (*path, name)))
        elif dataclasses.is_dataclass(current) and dataclasses.is_dataclass(value):
            fields = {f.name: getattr(value, f.name) for f in dataclasses.fields(value)}
            out.update(_smoke_leaves(current, fields, (*path, name)))
        else:
            out[(*path, name)] = value
    return out


def with_smoke(config: Any, smoke: Mapping[str, Any], given: Iterable[str] = ()) -> Any:
    """`config` with the `smoke` sizes, except for the flags in `given`.

    Args:
        config: A config dataclass instance.
        smoke: Field name -> smoke value; a nested dataclass field takes a mapping of its own
            fields (or a dataclass instance, every field of which counts) so that only those
            are replaced.
        given: Flag names (underscores) the user set, whose values the smoke sizes keep.

    Returns:
        A new config.
    """
    mine = set(given)
    kept = {f.path for f in config_flags(type(config)) if f.dest in mine}
    leaves = _smoke_leaves(config, smoke, ())
    return _assign(config, {p: v for p, v in leaves.items() if p not in kept})


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
        words = list(sys.argv[1:] if args is None else args)
        typed = {
            a.dest: s.lstrip("-").replace("-", "_")
            for a in self._actions
            for s in a.option_strings
            if any(w == s or w.startswith(s + "=") for w in words)
        }
        setattr(parsed, TYPED, typed)
        return parsed, extra


def study_parser(config_cls: type, doc: str, prog: str | None = None) -> argparse.ArgumentParser:
    """A study script's parser: one flag per config field, its shorthands, and ``--smoke``.

    Args:
        config_cls: The study's config dataclass. Its ``SHORTHANDS`` (flag -> (field,
            value, help)), if any, become flags that set that field to that value.
        doc: The script's docstring; its first line is the description.
        prog: The program's name in messages (default: the script's file name).

    Returns:
        The parser; add the script's own flags to it before parsing.
    """
    parser = _StudyParser(prog=prog, description=doc.splitlines()[0])
    add_config_arguments(parser, config_cls)
    for flag, (dest, value, text) in getattr(config_cls, "SHORTHANDS", {}).items():
        parser.add_argument(
            flag, dest=dest, action="store_const", const=value, default=argparse.SUPPRESS, help=text
        )
    parser.add_argument(
        "--smoke",
        action="store_true",
        help="a tiny run that checks the pipeline (the study's smoke sizes for every field "
        "not given on the command line)",
    )
    return parser


def study_config(
    config_cls: type, args: argparse.Namespace, smoke: Mapping[str, Any], **overrides: Any
) -> Any:
    """The config from parsed flags, with the `smoke` sizes on top when ``--smoke`` was given.

    The flags the user gave are validated first (the config is built from them before any
    smoke size is applied), and a smoke size never replaces a value given on the command
    line: ``--smoke --trials 0`` is refused, ``--smoke --trials 5`` runs 5 trials.

    Args:
        config_cls: The study's config dataclass.
        args: What a `study_parser` returned from ``parse_args()``; a namespace from another
            parser counts every field as not given.
        smoke: The study's smoke-sized field values (see `with_smoke`).
        **overrides: Field values from the script's own flags (applied last).

    Returns:
        A `config_cls` instance.
    """
    cfg = config_from_args(config_cls, args)
    if getattr(args, "smoke", False):
        cfg = with_smoke(cfg, smoke, getattr(args, GIVEN, frozenset()))
    return rebuild(cfg, **overrides) if overrides else cfg


def parse_study_args(
    config_cls: type,
    smoke: Mapping[str, Any],
    doc: str,
    argv: Sequence[str] | None = None,
    prog: str | None = None,
) -> Any:
    """A study script's whole command line: its flags, ``--smoke``, parsed into a config.

    Args:
        config_cls: The study's config dataclass.
        smoke: Its smoke sizes.
        doc: The script's docstring (the description of ``--help``).
        argv: The arguments (default: ``sys.argv[1:]``).
        prog: The program's name in messages.

    Returns:
        A `config_cls` instance (not validated yet: the study's run validates it).
    """
    args = study_parser(config_cls, doc, prog).parse_args(argv)
    return study_config(config_cls, args, smoke)


def run_study_script(
    config_cls: type,
    smoke: Mapping[str, Any],
    run: Callable[[Any], Mapping[str, Any]],
    doc: str,
    shown: Sequence[str] = ("files",),
) -> int:
    """A study script's whole body: parse its command line, run the study, print a summary.

    Use as ``sys.exit(run_study_script(Config, SMOKE, run, __doc__))`` under
    ``if __name__ == "__main__":``; a bad flag is one line on stderr and exit status 2
    (`probaff._cli_errors.run_cli`).

    Args:
        config_cls: The study's config dataclass.
        smoke: Its smoke sizes.
        run: The study's ``run(config)``; it returns a summary with the keys in `shown`.
        doc: The script's docstring (the description of ``--help``).
        shown: The keys of the summary printed as JSON on stdout.

    Returns:
        The exit status: 0 on success, 2 for a probaff error.
    """

    def main() -> None:
        summary = run(parse_study_args(config_cls, smoke, doc))
        print(json.dumps({key: summary[key] for key in shown}, indent=1))

    return run_cli(main)
