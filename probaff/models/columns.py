"""Selection of feature columns by index or by the name of a column group."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from probaff._checks import check_count, check_positive
from probaff.errors import InputError

__all__ = [
    "FeatureGroups",
    "FeatureSpec",
    "check_feature_spec",
    "check_mixture_args",
    "resolve_features",
    "resolve_groups",
]

FeatureGroups = Mapping[str, slice | Sequence[int]]
"""Named column groups of a feature matrix, e.g. ``{"f_x": slice(0, 3), "f_o": [3, 4]}``."""

FeatureSpec = str | Sequence[str] | Sequence[int] | None
"""Columns to use: ``None`` (all), a group name, group names, or column indices."""


def _names(spec: FeatureSpec) -> list[str] | None:
    if isinstance(spec, str):
        return [spec]
    if spec is None or len(spec) == 0:
        return None
    kinds = {isinstance(s, str) for s in spec}
    if kinds == {True}:
        return [str(s) for s in spec]
    if kinds == {False}:
        return None
    raise InputError(f"a feature selection mixes group names and column indices: {spec!r}.")


def check_feature_spec(what: str, spec: FeatureSpec, groups: FeatureGroups | None) -> None:
    """Raise `InputError` if `spec` names a group that `groups` does not define.

    Args:
        what: Which selection this is (e.g. ``"gate_features"``).
        spec: The selection.
        groups: The known column groups.
    """
    names = _names(spec)
    if names is None:
        return
    known = dict(groups or {})
    unknown = [n for n in names if n not in known]
    if unknown:
        listing = ", ".join(sorted(known)) if known else "none (pass groups=...)"
        raise InputError(
            f"{what} names unknown feature group(s) {unknown}; known groups: {listing}."
        )


def check_mixture_args(
    n_experts: int,
    groups: FeatureGroups | None,
    gate_features: FeatureSpec,
    expert_features: FeatureSpec,
    gate_l2: float | str,
) -> int:
    """Validate the arguments every mixture of experts takes; return `n_experts` as an int.

    Raises:
        InputError: For a non-positive or non-integer `n_experts`, an unknown feature group,
            or a `gate_l2` that is neither ``"cv"`` nor a number >= 0.
    """
    n_experts = check_count("n_experts", n_experts)
    check_feature_spec("gate_features", gate_features, groups)
    check_feature_spec("expert_features", expert_features, groups)
    if not isinstance(gate_l2, str):
        check_positive("gate_l2", gate_l2, allow_zero=True)
    elif gate_l2 != "cv":
        raise InputError(f"gate_l2 must be a number >= 0 or 'cv', got {gate_l2!r}.")
    return n_experts


def _group_columns(name: str, cols: slice | Sequence[int], n_features: int) -> list[int]:
    out = list(range(*cols.indices(n_features))) if isinstance(cols, slice) else list(cols)
    if not out:
        raise InputError(f"feature group {name!r} selects no column of {n_features}.")
    return [int(c) for c in out]


def resolve_groups(groups: FeatureGroups | None, n_features: int) -> dict[str, list[int]]:
    """Turn every group's slice or index list into explicit column indices.

    Args:
        groups: The column groups.
        n_features: Number of columns `D` of the feature matrix.

    Returns:
        Group name to sorted-as-given column indices.
    """
    return {name: _group_columns(name, cols, n_features) for name, cols in (groups or {}).items()}


def resolve_features(
    what: str, spec: FeatureSpec, groups: FeatureGroups | None, n_features: int
) -> list[int]:
    """Column indices selected by `spec` in a matrix with `n_features` columns.

    Args:
        what: Which selection this is, for error messages.
        spec: ``None`` for all columns, group name(s), or column indices.
        groups: The column groups the names refer to.
        n_features: Number of columns `D`.

    Returns:
        Column indices, in the order selected.

    Raises:
        InputError: For an unknown group, an index out of range, or a column selected twice.
    """
    check_feature_spec(what, spec, groups)
    names = _names(spec)
    if spec is None:
        cols = list(range(n_features))
    elif names is not None:
        resolved = resolve_groups(groups, n_features)
        cols = [c for n in names for c in resolved[n]]
    else:
        cols = [int(c) for c in spec]
    if not cols:
        raise InputError(f"{what} selects no column; pass None to use every column.")
    bad = [c for c in cols if not -n_features <= c < n_features]
    if bad:
        raise InputError(f"{what} selects column(s) {bad} of a matrix with {n_features} columns.")
    cols = [c % n_features for c in cols]
    if len(set(cols)) != len(cols):
        dup = sorted({c for c in cols if cols.count(c) > 1})
        raise InputError(f"{what} selects column(s) {dup} more than once.")
    return cols
