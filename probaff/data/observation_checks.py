"""The checks of `probaff.data.observations.observation_dataset` that look past one array.

`check_meta` types a dataset's ``meta`` per kind; `check_scale` and `check_yaw_steps` check
a push dataset's scale against its table and its yaws along each push (units a per-array
bound cannot tell apart: millimetres below 100, degrees below 8 pi); `unwrap_yaws` unwraps
yaws logged within (-pi, pi]. `bad_rows` and `row_message` name the rows at fault in every
message of both modules.

Covered by tests/data/test_observations.py.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

import numpy as np

from probaff._checks import check_count, check_number
from probaff.errors import InputError

__all__ = [
    "DEFAULT_TABLE",
    "bad_rows",
    "check_meta",
    "check_scale",
    "check_yaw_steps",
    "row_message",
    "unwrap_yaws",
]

DEFAULT_TABLE = (1.0, 0.8)
"""Table (length, width) in m that chapter 4's features assume without ``meta["table_size"]``."""

_WORLD_NUMBERS: dict[str, tuple[str, str]] = {
    "control_rate": ("> 0", "Hz"),
    "record_rate": ("> 0", "Hz"),
    "arm_base_yaw": ("", "rad"),
}
"""The numeric ``meta`` entries every dataset kind records of its world, checked last."""
_META_NUMBERS: dict[str, dict[str, tuple[str, str]]] = {
    "push": {
        "push_height": ("> 0", "m"),
        "gripper_opening": ("> 0", "m"),
        "finger_radius": ("> 0", "m"),
        "cloud_noise": (">= 0", "m"),
        **_WORLD_NUMBERS,
    },
    "skill": {
        "lift": ("> 0", "m"),
        "table_length": ("> 0", "m"),
        "gripper_span": ("> 0", "m"),
        "grasp_fraction": ("> 0", "1"),
        "plane_y": ("", "m"),
        **_WORLD_NUMBERS,
    },
}
"""The numeric ``meta`` entries of each dataset kind: (bound, unit) of each."""
_META_VECTORS: dict[str, dict[str, tuple[str, str, str]]] = {
    "push": {"table_size": ("(length, width)", "> 0", "m"), "arm_base_xyz": ("(x, y, z)", "", "m")},
    "skill": {"arm_base_xyz": ("(x, y, z)", "", "m")},
}
"""The ``meta`` entries of each kind that are fixed-length lists: (components, bound, unit)."""
_META_FIX = (
    "record the world's geometry as numbers in metres, radians and Hz, as "
    "probaff.data.queries.world_meta does"
)


def check_meta(kind: str, meta: Mapping[str, Any]) -> None:
    """Refuse a ``meta`` entry of the wrong type or out of range, naming the key.

    Numbers must be real numbers (not strings or bools), finite and within their bound; lists
    of numbers must have their length; entries not listed in `_META_NUMBERS` and
    `_META_VECTORS` (nor ``cloud_points``, ``hand``, ``scene``) are not checked beyond being
    JSON-serialisable.
    """
    try:
        for key, (bound, unit) in _META_NUMBERS[kind].items():
            if key in meta:
                check_number(f"meta[{key!r}]", meta[key], bound=bound, unit=unit)
        for key, (parts, bound, unit) in _META_VECTORS[kind].items():
            if key not in meta:
                continue
            value, n = meta[key], parts.count(",") + 1
            if not isinstance(value, (list, tuple)) or len(value) != n:
                raise InputError(
                    f"meta[{key!r}] must be {n} numbers {parts}{' ' + bound if bound else ''} "
                    f"({unit}), got {value!r}."
                )
            for i, v in enumerate(value):
                check_number(f"meta[{key!r}][{i}]", v, bound=bound, unit=unit)
        if "cloud_points" in meta:
            check_count("meta['cloud_points']", meta["cloud_points"])
    except InputError as exc:
        raise InputError(f"{str(exc).rstrip('.')}; {_META_FIX}.") from None
    if "hand" in meta and not isinstance(meta["hand"], Mapping):
        raise InputError(
            f"meta['hand'] must be a mapping of the hand's settings "
            f"(probaff.sim.pusher.HandSpec.to_dict()), got {meta['hand']!r}."
        )
    scene = meta.get("scene")
    if scene is not None and not isinstance(scene, str):
        raise InputError(f"meta['scene'] must be a scene's name (a string) or None, got {scene!r}.")


def row_message(rows: np.ndarray) -> str:
    """``"row 3"`` or ``"row 3 (and 2 more rows)"`` for the flagged rows."""
    first, others = int(rows[0]), rows.size - 1
    return f"row {first}" + (
        f" (and {others} more row{'s' if others > 1 else ''})" if others else ""
    )


def bad_rows(mask: np.ndarray) -> np.ndarray:
    """Rows (first axis) where the boolean `mask` holds anywhere."""
    return np.flatnonzero(mask.reshape(len(mask), -1).any(axis=1)) if mask.size else np.zeros(0)


def _yaw_series(
    arrays: Mapping[str, np.ndarray], prefix: str
) -> tuple[np.ndarray, list[str]] | None:
    """The (N, S, K) yaws of each push's objects in time order, and the array of each step.

    The series is ``{prefix}state_before``, then ``traj_objects``' samples (observed series
    only, when given), then ``{prefix}state_after``; ``None`` without the two states.
    """
    before, after = arrays.get(f"{prefix}state_before"), arrays.get(f"{prefix}state_after")
    if before is None or after is None:
        return None
    parts, names = [before[:, None, :, 2]], [f"{prefix}state_before"]
    traj = arrays.get("traj_objects") if not prefix else None
    if traj is not None:
        parts.append(traj[..., 2].astype(np.float64))
        names += ["traj_objects"] * traj.shape[1]
    parts.append(after[:, None, :, 2])
    names.append(f"{prefix}state_after")
    return np.concatenate(parts, axis=1), names


def unwrap_yaws(arrays: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """The arrays with every push's yaws unwrapped along its time axis (``angles="wrapped"``).

    Each object's yaw series (`_yaw_series`: the pose before, the trajectory's samples, the
    pose after) goes through ``numpy.unwrap``: every yaw after the first gets the multiple of
    2 pi that brings it within pi of the one before, so the pose before keeps its value. The
    exact ``true_*`` poses alike, and the hand's yaw along ``traj_hand`` and
    ``traj_commanded``. New arrays are made; the given ones are not changed.
    """
    out = dict(arrays)
    for prefix in ("", "true_"):
        found = _yaw_series(out, prefix)
        if found is None:
            continue
        series = np.unwrap(found[0], axis=1)
        for name, values in (
            (f"{prefix}state_before", series[:, 0]),
            (f"{prefix}state_after", series[:, -1]),
        ):
            out[name] = out[name].copy()
            out[name][..., 2] = values
        if not prefix and "traj_objects" in out:
            out["traj_objects"] = out["traj_objects"].copy()
            out["traj_objects"][..., 2] = series[:, 1:-1]
    for name in ("traj_hand", "traj_commanded"):
        if name in out:
            out[name] = out[name].copy()
            out[name][..., 2] = np.unwrap(out[name][..., 2].astype(np.float64), axis=1)
    return out


def check_yaw_steps(arrays: Mapping[str, np.ndarray]) -> None:
    """Refuse consecutive yaws of one push (object or hand) that differ by more than pi."""
    found: list[tuple[np.ndarray, list[str], str]] = []
    for prefix in ("", "true_"):
        series = _yaw_series(arrays, prefix)
        if series is not None:
            found.append((*series, "object"))
    for name in ("traj_hand", "traj_commanded"):
        if name in arrays:
            yaw = arrays[name][..., 2].astype(np.float64)[..., None]  # (N, T, 1)
            found.append((yaw, [name] * yaw.shape[1], "the hand"))
    for yaws, names, what in found:
        if yaws.shape[1] < 2:
            continue
        step = np.diff(yaws, axis=1)  # (N, S - 1, K)
        bad = np.abs(step) > math.pi
        rows = bad_rows(bad)
        if not rows.size:
            continue
        i = int(rows[0])
        j, k = (int(a[0]) for a in np.nonzero(bad[i]))
        who = f"object {k}" if what == "object" else what
        raise InputError(
            f"array {names[j + 1]!r} turns {who} by {step[i, j, k]:.4g} rad from "
            f"{names[j]!r} in {row_message(rows)}: consecutive yaws of one push differ by "
            "more than pi, so they look wrapped into (-pi, pi] or given in degrees; give "
            "unwrapped yaws in radians, or pass angles='wrapped' to have each push's yaws "
            "unwrapped along its time axis."
        )


def check_scale(arrays: Mapping[str, np.ndarray], meta: Mapping[str, Any]) -> None:
    """Refuse pushes longer than the table's diagonal and boxes larger than it (millimetres)."""
    length, width = (float(v) for v in meta.get("table_size", DEFAULT_TABLE))
    diagonal = math.hypot(length, width)
    table = (
        f"the table's diagonal, {diagonal:.4g} m for a {length:g} x {width:g} m table "
        f"({'meta[' + repr('table_size') + ']' if 'table_size' in meta else 'the default'})"
    )
    for name, what in (("push_distance", "push"), ("object_size", "box")):
        values = arrays.get(name)
        if values is None:
            continue
        rows = bad_rows(values > diagonal)
        if rows.size:
            worst = float(np.max(values[int(rows[0])]))
            raise InputError(
                f"array {name!r} (m) holds {worst:.6g} in {row_message(rows)}: a {what} "
                f"longer than {table}; it looks like millimetres: give lengths in metres "
                "(millimetres / 1000), or record the table's (length, width) in "
                "meta['table_size']."
            )
