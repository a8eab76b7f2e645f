"""The registry of model kinds: per kind, its class, fitter, options, save format and builder.

A `ModelKind` is everything probaff knows about one kind of model: the class it fits
(`model_class`), its fitting procedure (``fit(model, X, Y, options=None, **overrides)``), the
options that procedure takes (`options_type`, e.g. `EMOptions`), how `save` writes it and
`load` reads it back (its `Codec`: format tag, dump, restore), and how it is built from
simple settings (`builder`, from a `ModelSettings`). Every kind is registered once, in the
module of its fitter, with `register_model_kind`; `model_kind` finds a kind by name or by a
model's class, `fit` fits any registered model, and `probaff.models.save` / `load` handle
every kind with a codec. Adding a kind is its model's module, one registration and a test.

The built-in kinds:

* ``"em"``: `MixtureOfGPExperts` by `fit_em` (`EMOptions`);
* ``"svi"``: `VariationalMixtureOfGPExperts` by `fit_svi` (`SVIOptions`);
* ``"clustered"``: `ClusteredGPModel` (chapter 4's baseline; no fitting options);
* ``"transition"``: `SkillTransitionModel` by `fit_transition` (`EMOptions` for mixture
  components);
* ``"monolithic"``: `MonolithicTransitionModel` by `fit_transition` (no fitting options).

A kind's fitting procedure by name is ``model_kind(name).fit``.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any, TypeVar

from probaff._checks import check_count
from probaff._registry import Registry, import_submodules
from probaff.errors import InputError
from probaff.models.options import GPOptions

__all__ = [
    "Codec",
    "Fitter",
    "ModelKind",
    "ModelSettings",
    "discover_model_kinds",
    "fit",
    "model_kind",
    "model_kinds",
    "register_model_kind",
    "unregister_model_kind",
]

Fitter = Callable[..., Any]
"""``fitter(model, X, Y, options=None, **overrides)``: fits `model` in place on features
`(N, D)` and effects `(N, E)`, and returns what the procedure records (a history, or the
model)."""

F = TypeVar("F", bound=Fitter)


def _names(groups: Any, name: str) -> tuple[str, ...] | None:
    if groups is None:
        return None
    if isinstance(groups, str) or not all(isinstance(g, str) for g in groups):
        raise InputError(f"{name} must be a sequence of feature group names, got {groups!r}.")
    return tuple(groups)


@dataclass(frozen=True)
class ModelSettings:
    """Simple settings from which a registered kind builds a model (`ModelKind.build`).

    Attributes:
        n_experts: Experts (or clusters) `M`, a positive integer.
        groups: Named column groups of the feature matrix (name -> slice or indices), or
            None when `gate` and `experts` are None.
        gate: Feature groups the gate reads; None for every column. Kinds without a
            feature-selecting gate refuse a non-empty `gate`.
        experts: Feature groups the experts read; None for every column.
        seed: Seed of the model (where its constructor takes one) and of its fit (where its
            options have a ``seed``), an integer >= 0.
        gp: The GP experts' settings, whole (`GPOptions`: L-BFGS iterations, length-scale
            prior, noise floor, initial variances), handed to the model's constructor as
            they are; None for the kind's default (``"em"``:
            `probaff.models.options.MIXTURE_GP`, the prior on and a noise floor of 1 % of
            each effect's standard deviation; ``"clustered"``: `GPOptions()`). Kinds without
            GP experts of these settings (``"svi"``) refuse a `GPOptions`.
        fit: The kind's fitting options, whole (an instance of its `options_type`, e.g. a
            study's `EMOptions`), or overrides of its defaults (e.g. ``{"max_iter": 10}``
            for EM); applied by `ModelKind.fit_new`.

    Raises:
        InputError: On construction, for a field out of range.
    """

    n_experts: int = 1
    groups: Mapping[str, Any] | None = None
    gate: tuple[str, ...] | None = None
    experts: tuple[str, ...] | None = None
    seed: int = 0
    gp: GPOptions | None = None
    fit: Any = field(default_factory=dict)

    def __post_init__(self) -> None:
        """Validate every field and store groups and fit overrides as copies."""
        set_ = object.__setattr__
        set_(self, "n_experts", check_count("n_experts", self.n_experts))
        set_(self, "seed", check_count("seed", self.seed, minimum=0))
        set_(self, "gate", _names(self.gate, "gate"))
        set_(self, "experts", _names(self.experts, "experts"))
        if self.gp is not None and type(self.gp) is not GPOptions:
            raise InputError(
                f"gp must be GPOptions (e.g. GPOptions(max_iter=20, lengthscale_prior=True)) "
                f"or None for the kind's default, got {type(self.gp).__name__}."
            )
        if self.groups is not None and not isinstance(self.groups, Mapping):
            raise InputError(f"groups must map group names to columns, got {self.groups!r}.")
        if dataclasses.is_dataclass(self.fit) and not isinstance(self.fit, type):
            pass  # a kind's options, whole (checked against the kind by `fit_new`)
        elif not isinstance(self.fit, Mapping) or not all(isinstance(k, str) for k in self.fit):
            raise InputError(
                f"fit must be a kind's fitting options (e.g. EMOptions) or map option names "
                f"to values, got {self.fit!r}."
            )
        else:
            set_(self, "fit", dict(self.fit))
        if self.groups is not None:
            set_(self, "groups", dict(self.groups))

    def columns(self) -> dict[str, Any]:
        """The column selection as a gated mixture's constructor arguments.

        Returns:
            ``groups``, ``gate_features`` and ``expert_features`` (lists of group names, or
            None for every column).
        """
        return {
            "groups": self.groups,
            "gate_features": None if self.gate is None else list(self.gate),
            "expert_features": None if self.experts is None else list(self.experts),
        }


@dataclass(frozen=True)
class Codec:
    """How `probaff.models.save` writes a kind of model and `load` reads it back.

    Attributes:
        format: Identifier and version stored in the file (e.g.
            ``"probaff.models.MixtureOfGPExperts/1"``).
        dump: ``dump(model) -> payload``: a dict of builtins and tensors that restores the
            fitted model.
        restore: ``restore(payload) -> model``: the inverse of `dump`.
        required: Entries `load` requires in a payload before it calls `restore`.
    """

    format: str
    dump: Callable[[Any], dict[str, Any]]
    restore: Callable[[dict[str, Any]], Any]
    required: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        """Check the tag and store `required` as a tuple."""
        if not isinstance(self.format, str) or not self.format:
            raise InputError(f"a codec's format must be a non-empty string, got {self.format!r}.")
        object.__setattr__(self, "required", tuple(self.required))


@dataclass(frozen=True)
class ModelKind:
    """One kind of model: its class, fitter, fitting options, save format and builder.

    Attributes:
        name: The kind's name (``"em"``, ``"svi"``, ...), unique in the registry.
        model_class: The class of its models; `fit` and `save` dispatch on it. None for a
            fitting procedure without a class of its own (found by name only).
        fit: ``fit(model, X, Y, options=None, **overrides)``; fits `model` in place.
        options_type: The frozen dataclass of its fitting options (e.g. `EMOptions`), or
            None when the fit takes none.
        codec: How `save` writes its models and `load` reads them (`Codec`), or None for
            a kind that cannot be saved.
        builder: ``builder(settings: ModelSettings) -> model``: a new, unfitted model; None
            for a kind that cannot be built from `ModelSettings`.
    """

    name: str
    model_class: type | None
    fit: Fitter
    options_type: type | None = None
    codec: Codec | None = None
    builder: Callable[[ModelSettings], Any] | None = None

    def __post_init__(self) -> None:
        """Check the name, the fitter and the codec."""
        if not isinstance(self.name, str) or not self.name:
            raise InputError(f"a model kind's name must be a non-empty string, got {self.name!r}.")
        if not callable(self.fit):
            raise InputError(f"the fitter of model kind {self.name!r} is not callable.")
        if self.codec is not None and not isinstance(self.codec, Codec):
            raise InputError(f"the codec of model kind {self.name!r} must be a Codec.")

    @property
    def option_names(self) -> frozenset[str]:
        """Names of the fitting options (fields of `options_type`); empty without options."""
        if self.options_type is None:
            return frozenset()
        return frozenset(f.name for f in dataclasses.fields(self.options_type))

    def build(self, settings: ModelSettings | None = None, **fields: Any) -> Any:
        """A new, unfitted model of this kind.

        Args:
            settings: The settings; None for ``ModelSettings(**fields)``.
            **fields: Fields of `ModelSettings` that replace those of `settings`.

        Returns:
            An unfitted instance of `model_class`.

        Raises:
            InputError: If the kind has no builder, or for settings it cannot honour.
        """
        if self.builder is None:
            raise InputError(
                f"model kind {self.name!r} cannot be built from ModelSettings; construct a "
                f"{getattr(self.model_class, '__name__', 'model')} directly."
            )
        base = ModelSettings() if settings is None else settings
        return self.builder(dataclasses.replace(base, **fields) if fields else base)

    def fit_new(self, X: Any, Y: Any, settings: ModelSettings | None = None, **fields: Any) -> Any:
        """Build a model of this kind (`build`) and fit it on `X` `(N, D)` and `Y` `(N, E)`.

        The fit gets the settings' `fit` (options whole, or overrides), and their `seed` when
        the kind's options have one (models whose constructor takes the seed get it from
        `build`).

        Args:
            X: Features, `(N, D)`.
            Y: Effects, `(N, E)`.
            settings: The settings; None for ``ModelSettings(**fields)``.
            **fields: Fields of `ModelSettings` that replace those of `settings`.

        Returns:
            The fitted model.

        Raises:
            InputError: As `build` and as the kind's fitter.
        """
        base = ModelSettings() if settings is None else settings
        resolved = dataclasses.replace(base, **fields) if fields else base
        options = None if isinstance(resolved.fit, Mapping) else resolved.fit
        if options is not None and (
            self.options_type is None or not isinstance(options, self.options_type)
        ):
            want = "no options" if self.options_type is None else self.options_type.__name__
            raise InputError(
                f"fit holds {type(options).__name__}, but model kind {self.name!r} takes "
                f"{want}; give its options or a mapping of overrides."
            )
        model = self.build(resolved)
        overrides = {} if options is not None else dict(resolved.fit)
        if "seed" in self.option_names:
            overrides.setdefault("seed", resolved.seed)
        if options is not None:
            overrides["options"] = options
        self.fit(model, X, Y, **overrides)
        return model


_KINDS: Registry[ModelKind] = Registry("model kind", ModelKind, "unregister_model_kind")


def register_model_kind(kind: ModelKind) -> ModelKind:
    """Register `kind` under its name.

    Args:
        kind: The kind to register.

    Returns:
        `kind`.

    Raises:
        InputError: If `kind` is not a `ModelKind`, its name is taken (remove the old kind
            with `unregister_model_kind` first), or its class or format is already another
            registered kind's.
    """
    if not isinstance(kind, ModelKind):
        raise InputError(f"register_model_kind takes a ModelKind, got {type(kind).__name__}.")
    tag = None if kind.codec is None else kind.codec.format
    for other in _KINDS.values():
        if other.name == kind.name:
            continue  # the registry refuses the taken name
        if kind.model_class is not None and other.model_class is kind.model_class:
            raise InputError(
                f"{kind.model_class.__name__} is already the class of model kind {other.name!r}."
            )
        if tag is not None and other.codec is not None and other.codec.format == tag:
            raise InputError(f"format {tag!r} is already model kind {other.name!r}'s.")
    return _KINDS.add(kind)


def unregister_model_kind(name: str) -> ModelKind:
    """Remove the kind registered under `name` and return it.

    Raises:
        InputError: For an unknown name.
    """
    return _KINDS.remove(name)


def discover_model_kinds() -> list[str]:
    """Import every module of `probaff.models` (subpackages included) not imported yet.

    Each kind registers itself in its own module (``register_model_kind(ModelKind(...))``
    beside its fitter), so a kind's module added anywhere under ``probaff/models`` is found by
    the next lookup (`model_kind`, `model_kinds`) without being named anywhere else.

    Returns:
        The modules it imported (none once every module is imported).
    """
    return import_submodules(__name__.rpartition(".")[0], subpackages=True)


def model_kinds() -> dict[str, ModelKind]:
    """Every registered kind, by name (a copy)."""
    discover_model_kinds()
    return {kind.name: kind for kind in _KINDS.values()}


def model_kind(name_or_model: Any) -> ModelKind:
    """The kind registered under a name, or the kind of a model (by its class).

    A model's kind is that of the nearest class in its method resolution order that a kind
    registers, so a subclass of a registered class is fitted and saved as its parent.

    Args:
        name_or_model: A kind's name, or a model.

    Returns:
        The registered kind.

    Raises:
        InputError: For an unknown name, or a model of no registered class.
    """
    discover_model_kinds()
    if isinstance(name_or_model, str):
        return _KINDS.get(name_or_model)
    by_class = {k.model_class: k for k in _KINDS.values() if k.model_class is not None}
    for cls in type(name_or_model).__mro__:
        if cls in by_class:
            return by_class[cls]
    classes = ", ".join(sorted(c.__name__ for c in by_class))
    raise InputError(
        f"{type(name_or_model).__name__} is not a registered kind of model; registered "
        f"classes: {classes}."
    )


def fit(model: Any, X: Any, Y: Any, options: Any = None, **overrides: Any) -> Any:
    """Fit any registered model in place with its kind's fitter.

    Args:
        model: A model of a registered class.
        X: Features, `(N, D)`.
        Y: Effects, `(N, E)`.
        options: The kind's options (e.g. an `EMOptions` for a `MixtureOfGPExperts`);
            None for its defaults.
        **overrides: Fields of the options that replace those of `options`, and other
            arguments of the fitter (e.g. a transition model's reactions ``R``).

    Returns:
        What the kind's fitter returns (e.g. an `EMHistory`).

    Raises:
        InputError: For a model of no registered class, and as the kind's fitter.
    """
    kind = model_kind(model)
    if options is not None:
        overrides = {"options": options, **overrides}
    return kind.fit(model, X, Y, **overrides)
