"""Datasets from a robot's own arrays: the observation-only constructor and its checks.

`observation_dataset` builds a `probaff.data.PushDataset` or `probaff.data.SkillDataset` from
plain arrays, such as a robot's logs, and checks them the way a user's input deserves: each
array's dtype, shape, units, frames and finiteness, naming the array and the row at fault.
Only what a robot observes is needed (`probaff.data.schema.OBSERVATION_ARRAYS`,
`probaff.data.skill_schema.SKILL_OBSERVATION_ARRAYS`); what only a simulator knows is optional
and checked alike when given. `observations_of` reduces a dataset to what a robot would have
logged.

What is checked, for every array given:

* dtype: numbers where the schema has floats (integers are converted, a float32 cloud is
  kept), integers where it has indices (in range of the schema's integer type), booleans for
  flags; strings, objects and ragged lists are refused;
* shape: the schema's symbolic shapes (`probaff.data.schema.PUSH_SHAPES`,
  `probaff.data.skill_schema.SKILL_SHAPES`), with N, K, P, ... bound by the first array that
  names them;
* finiteness: the first row holding NaN or inf is named;
* units: `units`, when given, must name each array's units as the schema does
  (`probaff.data.schema.ARRAY_UNITS`); whatever is given, lengths beyond `MAX_METRES` and
  angles beyond `MAX_RADIANS` are refused as another unit (millimetres, degrees);
* scene scale (pushes): a ``push_distance`` or an ``object_size`` longer than the table's
  diagonal (``meta["table_size"]``, else 1 x 0.8 m) is refused as millimetres, and two
  consecutive yaws of one push (an object's ``state_before``, ``traj_objects`` samples and
  ``state_after``; the hand's ``traj_hand`` and ``traj_commanded`` samples) more than pi
  apart are refused as wrapped or in degrees;
* angles (pushes): with ``angles="wrapped"`` (yaws logged within (-pi, pi]) each push's yaws
  are first unwrapped along its time axis by ``numpy.unwrap``: every yaw after the pose before
  the push gets the multiple of 2 pi that brings it within pi of the one before it (the pose
  before keeps its value); the schema's default ``angles="unwrapped"`` takes them as given;
* meta: a mapping whose world entries (pushes: ``push_height``, ``gripper_opening``,
  ``finger_radius``, ``table_size``, ...; skills: ``lift``, ``record_rate``, ...) must be
  finite numbers (not strings or bools) within their bounds, checked when the dataset is
  built rather than when features run;
* frames (pushes): cloud normals must be unit vectors, each object's position before the push
  must lie within its cloud's footprint grown by `frame_tolerance` (clouds are world points,
  not object- or camera-frame ones), and a given ``effect`` must be the pushing-frame
  difference of the poses (`probaff.sim.geometry.push_frame_effect`); indices must name
  objects of ``object_names`` (skills: present slots).

What is filled in (pushes): ``effect`` from the poses and ``push_yaw`` when it is not given
(row by row with `probaff.sim.geometry.push_frame_effect`, as the simulator computes it, so the
values are the simulator's to the bit); ``walls`` as none (``(N, 0, 4)``) when not given; and,
when ``cloud_points`` and ``cloud_normals`` are not given but ``object_size`` (the boxes'
``(length, width, height)``) is, clouds sampled on the boxes' visible surfaces at their poses
before the push (`CloudSampling`; `probaff.sim.sensing.object_cloud`).
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Literal, overload

import numpy as np

from probaff._checks import check_count, check_positive
from probaff.data.dataset import ArrayDataset, shape_problem
from probaff.data.observation_checks import (
    bad_rows,
    check_meta,
    check_scale,
    check_yaw_steps,
    row_message,
    unwrap_yaws,
)
from probaff.data.schema import PushDataset
from probaff.data.skill_schema import NO_OBJECT, SkillDataset
from probaff.errors import DatasetError, InputError
from probaff.sim.geometry import push_frame_effect
from probaff.sim.sensing import object_cloud
from probaff.sim.specs import ObjectSpec

__all__ = [
    "MAX_METRES",
    "MAX_RADIANS",
    "CloudSampling",
    "observation_dataset",
    "observations_of",
]

MAX_METRES = 100.0
"""Largest length (m) a dataset holds: larger values are taken for millimetres."""
MAX_RADIANS = 8 * math.pi
"""Largest angle (rad, unwrapped: four turns) a dataset holds: larger ones are taken for
degrees."""
_EFFECT_TOLERANCE = 1e-4  # m and rad: a given effect versus the poses' pushing-frame difference
_NORMAL_TOLERANCE = 0.05  # how far a unit normal's length may stray from 1
_KINDS: dict[str, type[ArrayDataset]] = {"push": PushDataset, "skill": SkillDataset}
_ANGLES = ("unwrapped", "wrapped")


@dataclass(frozen=True)
class CloudSampling:
    """How clouds are sampled on box footprints when a push dataset is given no clouds.

    Attributes:
        points: Points per object cloud P, a positive integer.
        noise: Standard deviation of the Gaussian position noise (m), >= 0.
        seed: Seed of the sampler (the same seed gives the same clouds), an integer >= 0.

    Raises:
        InputError: For a count, noise or seed out of range.
    """

    points: int = 256
    noise: float = 0.0
    seed: int = 0

    def __post_init__(self) -> None:
        check_count("CloudSampling.points", self.points)
        check_positive("CloudSampling.noise", self.noise, allow_zero=True)
        check_count("CloudSampling.seed", self.seed, minimum=0)


def observations_of(ds: ArrayDataset) -> dict[str, np.ndarray]:
    """The arrays of `ds` a robot could have logged: all but what only a simulator knows.

    Args:
        ds: A dataset of any kind.

    Returns:
        Its arrays without those of ``ds.SIMULATOR_ONLY`` (for pushes the simulator's arrays
        and the exact ``true_*`` poses; for skills the simulator's arrays), shared, not
        copied.

    Raises:
        InputError: If `ds` is not a dataset (a folder's path, say: load it first).
    """
    if not isinstance(ds, ArrayDataset):
        if isinstance(ds, (str, os.PathLike)):
            raise InputError(
                f"observations_of needs a dataset, got the path {os.fspath(ds)!r}; load it "
                "first: observations_of(probaff.data.load_any_dataset(path))."
            )
        raise InputError(
            f"observations_of needs a dataset (a PushDataset or SkillDataset), got "
            f"{type(ds).__name__}; load one with probaff.data.load_any_dataset(path)."
        )
    return {k: v for k, v in ds.arrays.items() if k not in ds.SIMULATOR_ONLY}


def _convert(name: str, value: Any, dtype: str) -> np.ndarray:
    """`value` as an array of the schema's `dtype`, or `InputError` naming `name`."""
    try:
        arr = np.asarray(value)
    except (TypeError, ValueError):
        raise InputError(
            f"array {name!r} is not an array of one shape (a ragged list?); give a numpy array."
        ) from None
    target = np.dtype(dtype)
    if arr.dtype == target:
        return arr
    kind = arr.dtype.kind
    if target.kind == "b" and kind != "b":
        raise InputError(f"array {name!r} has dtype {arr.dtype}, expected bool (flags).")
    if target.kind in "iu":
        if kind not in "iu":
            raise InputError(
                f"array {name!r} has dtype {arr.dtype}, expected integers ({dtype}): it holds "
                "indices."
            )
        info = np.iinfo(target)
        if arr.size and (arr.min() < info.min or arr.max() > info.max):
            raise InputError(
                f"array {name!r} holds values outside {dtype}'s range [{info.min}, {info.max}]."
            )
    if target.kind == "f" and kind not in "iuf":
        raise InputError(
            f"array {name!r} has dtype {arr.dtype}, expected numbers ({dtype}); convert it to "
            "floats first."
        )
    return arr.astype(target)


def _check_finite(name: str, arr: np.ndarray) -> None:
    if arr.dtype.kind != "f":
        return
    rows = bad_rows(~np.isfinite(arr))
    if rows.size:
        raise InputError(
            f"array {name!r} holds NaN or inf in {row_message(rows)}; drop or repair those "
            "rows before building the dataset."
        )


def _check_units(name: str, arr: np.ndarray, units: str) -> None:
    """Refuse lengths beyond `MAX_METRES` and angles beyond `MAX_RADIANS` (another unit)."""
    parts = [u.strip() for u in units.split(",")]
    columns = [arr] if len(parts) == 1 else [arr[..., j] for j in range(len(parts))]
    for unit, values in zip(parts, columns, strict=True):
        limit = {"m": MAX_METRES, "rad": MAX_RADIANS}.get(unit)
        if limit is None or values.size == 0:
            continue
        rows = bad_rows(np.abs(values) > limit)
        if rows.size:
            worst = float(np.abs(values[int(rows[0])]).max())
            other = "millimetres" if unit == "m" else "degrees"
            raise InputError(
                f"array {name!r} ({units}) holds {worst:.6g} in {row_message(rows)}, beyond "
                f"{limit:.4g} {unit}: it looks like {other}; give lengths in metres and angles "
                "in radians."
            )


def _normal_units(units: str) -> str:
    return ", ".join(u.strip() for u in units.split(","))


def _check_given_units(cls: type[ArrayDataset], units: Mapping[str, str]) -> None:
    for name, given in units.items():
        expected = cls.UNITS.get(name)
        if expected is None:
            raise InputError(f"units names {name!r}, which is not a {cls.KIND} array.")
        if not isinstance(given, str) or _normal_units(given) != expected:
            raise InputError(
                f"array {name!r} is given in {given!r}, but probaff expects {expected!r}; "
                "convert it (millimetres / 1000 = metres, degrees * pi / 180 = radians)."
            )


def _convert_all(
    cls: type[ArrayDataset], arrays: Mapping[str, Any], units: Mapping[str, str]
) -> dict[str, np.ndarray]:
    """Names, dtypes, units, shapes and finiteness of every given array."""
    if not isinstance(arrays, Mapping):
        raise InputError(f"arrays must be a mapping of names to arrays, got {type(arrays)}.")
    known = {**cls.REQUIRED, **cls.OPTIONAL}
    unknown = sorted(set(arrays) - set(known))
    if unknown:
        raise InputError(
            f"{cls.KIND} arrays {unknown} are not in the schema; its arrays are {sorted(known)}."
        )
    _check_given_units(cls, units)
    out = {name: _convert(name, value, known[name]) for name, value in arrays.items()}
    rows = cls.ROWS if cls.ROWS in out else "object_ids"
    n = len(out[rows]) if rows in out and out[rows].ndim else None
    for name, arr in out.items():
        if arr.ndim == 0 or (n is not None and len(arr) != n):
            raise InputError(
                f"array {name!r} has shape {arr.shape}, expected {n} rows (one per row of "
                f"{rows!r})."
            )
    problem = shape_problem(out, cls.SHAPES)
    if problem:
        raise InputError(f"{problem}.")
    for name, arr in out.items():
        _check_finite(name, arr)
        _check_units(name, arr, cls.UNITS.get(name, "1"))
    return out


def _check_ids(ids: np.ndarray, names: list[str], lowest: int) -> None:
    rows = bad_rows((ids < lowest) | (ids >= len(names)))
    if rows.size:
        bad = ids[int(rows[0])]
        raise InputError(
            f"array 'object_ids' holds {bad.tolist()} in {row_message(rows)}, outside "
            f"object_names ({len(names)} names, ids 0..{len(names) - 1}"
            f"{', or -1 for an empty slot' if lowest < 0 else ''})."
        )


def _box(size: np.ndarray) -> ObjectSpec:
    """A catalogue object for sampling a box's cloud (only its shape and size are read)."""
    return ObjectSpec(
        name="box",
        shape="box",
        size=(float(size[0]), float(size[1])),
        radius=0.0,
        height=float(size[2]),
        mass=1.0,
        ground_friction=0.0,
        contact_friction=0.0,
    )


def _sample_clouds(
    size: np.ndarray, poses: np.ndarray, sampling: CloudSampling
) -> tuple[np.ndarray, np.ndarray]:
    """(N, K, P, 3) clouds and normals on boxes `size (N, K, 3)` at `poses (N, K, 3)`."""
    rows = bad_rows(size <= 0)
    if rows.size:
        raise InputError(
            f"array 'object_size' holds a length, width or height <= 0 in {row_message(rows)}; "
            "give each box's (length, width, height) in metres."
        )
    n, k = size.shape[:2]
    rng = np.random.default_rng(sampling.seed)
    pts = np.empty((n, k, sampling.points, 3), dtype=np.float32)
    nrm = np.empty_like(pts)
    for i in range(n):
        for j in range(k):
            p, q = object_cloud(_box(size[i, j]), poses[i, j], sampling.points, sampling.noise, rng)
            pts[i, j], nrm[i, j] = p, q
    return pts, nrm


def _effects(before: np.ndarray, after: np.ndarray, yaw: np.ndarray) -> np.ndarray:
    """(N, K, 3) pushing-frame effects, row by row as the simulator computes them."""
    out = np.empty(before.shape)
    for i in range(len(before)):
        out[i] = push_frame_effect(before[i], after[i], float(yaw[i]))
    return out


def _check_effect(arrays: dict[str, np.ndarray], prefix: str) -> None:
    """A given ``{prefix}effect`` must be the pushing-frame difference of the poses."""
    name = f"{prefix}effect"
    before, after = arrays.get(f"{prefix}state_before"), arrays.get(f"{prefix}state_after")
    if name not in arrays or before is None or after is None:
        return
    diff = np.abs(arrays[name] - _effects(before, after, arrays["push_yaw"]))
    rows = bad_rows(diff > _EFFECT_TOLERANCE)
    if rows.size:
        raise InputError(
            f"array {name!r} differs from the pushing-frame difference of "
            f"'{prefix}state_before' and '{prefix}state_after' by up to "
            f"{float(diff[int(rows[0])].max()):.3g} in {row_message(rows)}; it must be "
            "(dy_p, dz_p, dtheta_p) in the frame of push_yaw (leave it out to have it computed)."
        )


def _check_clouds(arrays: dict[str, np.ndarray], tolerance: float) -> None:
    """Unit normals, and each object's position within its cloud's grown footprint."""
    pts, nrm, pose = arrays["cloud_points"], arrays["cloud_normals"], arrays["state_before"]
    length = np.linalg.norm(nrm.astype(np.float64), axis=-1)
    rows = bad_rows(np.abs(length - 1.0) > _NORMAL_TOLERANCE)
    if rows.size:
        i = int(rows[0])
        raise InputError(
            f"array 'cloud_normals' holds normals of length {length[i].min():.3g} to "
            f"{length[i].max():.3g} in {row_message(rows)}; give unit outward normals in the "
            "world frame."
        )
    if pts.shape[2] == 0:
        return
    lo, hi = pts[..., :2].min(axis=2), pts[..., :2].max(axis=2)  # (N, K, 2)
    xy = pose[..., :2]
    outside = (xy < lo - tolerance) | (xy > hi + tolerance)
    rows = bad_rows(outside)
    if rows.size:
        i = int(rows[0])
        j = int(np.flatnonzero(outside[i].any(axis=-1))[0])
        raise InputError(
            f"array 'cloud_points' in {row_message(rows)}, object {j}: the cloud spans x in "
            f"[{lo[i, j, 0]:.3f}, {hi[i, j, 0]:.3f}] and y in [{lo[i, j, 1]:.3f}, "
            f"{hi[i, j, 1]:.3f}] m, but 'state_before' puts the object at "
            f"({xy[i, j, 0]:.3f}, {xy[i, j, 1]:.3f}); clouds are world-frame points of the "
            "objects before the push (not in an object's or the camera's frame)."
        )


def _complete_push(
    arrays: dict[str, np.ndarray], sampling: CloudSampling | None, tolerance: float
) -> dict[str, np.ndarray]:
    """The push arrays with effect, walls and clouds filled in, and the frames checked."""
    for name in ("object_ids", "state_before", "state_after", "push_origin", "push_yaw"):
        if name not in arrays:
            raise InputError(f"push observations need array {name!r}; see OBSERVATION_ARRAYS.")
    if "push_distance" not in arrays:
        raise InputError("push observations need array 'push_distance' (m, > 0).")
    rows = bad_rows(arrays["push_distance"] <= 0)
    if rows.size:
        raise InputError(f"array 'push_distance' must be > 0 (m); see {row_message(rows)}.")
    out = dict(arrays)
    n = len(out["object_ids"])
    has_clouds = [name in out for name in ("cloud_points", "cloud_normals")]
    if any(has_clouds) and not all(has_clouds):
        raise InputError("give both 'cloud_points' and 'cloud_normals', or neither.")
    if not any(has_clouds):
        if "object_size" not in out:
            raise InputError(
                "push observations need object clouds ('cloud_points' and 'cloud_normals') or "
                "box footprints to sample them from ('object_size', (N, K, 3) length, width, "
                "height in m)."
            )
        pts, nrm = _sample_clouds(
            out["object_size"], out["state_before"], sampling or CloudSampling()
        )
        out["cloud_points"], out["cloud_normals"] = pts, nrm
    out.setdefault("walls", np.zeros((n, 0, 4)))
    _check_effect(out, "")
    _check_effect(out, "true_")
    if "effect" not in out:
        out["effect"] = _effects(out["state_before"], out["state_after"], out["push_yaw"])
    _check_clouds(out, tolerance)
    return out


def _complete_skill(arrays: dict[str, np.ndarray], meta: Mapping[str, Any]) -> None:
    """Skill checks with rows: present targets and supports, positive sizes, the skill."""
    for name in ("object_ids", "target", "support", "size"):
        if name not in arrays:
            raise InputError(
                f"skill observations need array {name!r}; see SKILL_OBSERVATION_ARRAYS."
            )
    ids = arrays["object_ids"]
    k = ids.shape[1]
    rows = np.arange(len(ids))
    target, support = arrays["target"].astype(int), arrays["support"].astype(int)
    bad = (target < 0) | (target >= k)
    bad[~bad] = ids[rows[~bad], target[~bad]] == NO_OBJECT
    if bad.any():
        raise InputError(
            f"array 'target' must be the slot of a present object (0..{k - 1}, object_ids not "
            f"-1); see {row_message(np.flatnonzero(bad))}."
        )
    bad = (support < -1) | (support >= k)
    if bad.any():
        raise InputError(
            f"array 'support' must be -1 (the table) or an object slot (0..{k - 1}); see "
            f"{row_message(np.flatnonzero(bad))}."
        )
    small = bad_rows((arrays["size"] <= 0).any(axis=-1) & (ids != NO_OBJECT))
    if small.size:
        raise InputError(
            f"array 'size' holds a length, depth or height <= 0 for a present object in "
            f"{row_message(small)}; give each box's size in metres."
        )
    skill = meta.get("skill")
    if skill is not None and skill not in ("pick", "place"):
        raise InputError(f"meta['skill'] must be 'pick' or 'place', got {skill!r}.")


def _checked_options(
    kind: str, object_names: Any, meta: Any, units: Any, angles: Any
) -> tuple[list[str], dict[str, Any]]:
    """The names and a copy of `meta`, after checking the options of `observation_dataset`.

    `meta` is typed per `kind` by `check_meta`.
    """
    if angles not in _ANGLES:
        raise InputError(
            f"angles must be 'unwrapped' (yaws logged as they turn, the schema's) or 'wrapped' "
            f"(yaws logged within (-pi, pi], unwrapped here), got {angles!r}."
        )
    if isinstance(object_names, (str, bytes)):
        raise InputError(
            f"object_names must be a list of names, not one string, got {object_names!r}; "
            f"give [{object_names!r}] for a single object."
        )
    names = list(object_names) if isinstance(object_names, Sequence) else []
    if (
        not names
        or not all(isinstance(n, str) and n for n in names)
        or len(set(names)) < len(names)
    ):
        raise InputError(
            f"object_names must be a non-empty list of distinct names, got {object_names!r}."
        )
    for what, value, example in (
        ("meta", meta, "probaff.data.queries.world_meta(world)"),
        ("units", units, "{'state_before': 'm, m, rad'}"),
    ):
        if value is not None and not isinstance(value, Mapping):
            raise InputError(
                f"{what} must be a mapping of names to values (e.g. {example}), or None, got "
                f"{type(value).__name__} {value!r:.60}."
            )
    meta = dict(meta or {})
    try:
        json.dumps(meta)
    except (TypeError, ValueError) as exc:
        raise InputError(
            f"meta must be JSON-serialisable (numbers, strings, lists, mappings): {exc}."
        ) from None
    check_meta(kind, meta)
    return names, meta


@overload
def observation_dataset(
    arrays: Mapping[str, Any],
    object_names: Sequence[str],
    meta: Mapping[str, Any] | None = ...,
    *,
    kind: Literal["push"] = ...,
    units: Mapping[str, str] | None = ...,
    sampling: CloudSampling | None = ...,
    frame_tolerance: float = ...,
    angles: str = ...,
) -> PushDataset: ...


@overload
def observation_dataset(
    arrays: Mapping[str, Any],
    object_names: Sequence[str],
    meta: Mapping[str, Any] | None = ...,
    *,
    kind: Literal["skill"],
    units: Mapping[str, str] | None = ...,
    sampling: CloudSampling | None = ...,
    frame_tolerance: float = ...,
    angles: str = ...,
) -> SkillDataset: ...


def observation_dataset(
    arrays: Mapping[str, Any],
    object_names: Sequence[str],
    meta: Mapping[str, Any] | None = None,
    *,
    kind: str = "push",
    units: Mapping[str, str] | None = None,
    sampling: CloudSampling | None = None,
    frame_tolerance: float = 0.1,
    angles: str = "unwrapped",
) -> ArrayDataset:
    """Build a push or skill dataset from a robot's arrays, checking each one.

    Pushes need `probaff.data.schema.OBSERVATION_ARRAYS` (``effect``, ``walls`` and the
    clouds may be left out: see the module docstring); skills
    `probaff.data.skill_schema.SKILL_OBSERVATION_ARRAYS`. Every other array of the schema is
    optional. Arrays already of the schema's dtype are kept as they are (not copied), so a
    dataset reduced by `observations_of` and rebuilt here holds the very same values.

    Args:
        arrays: Named arrays, first axis the row (push or skill), in the schema's units and
            frames (world ``(x, y, theta)`` poses for pushes, side-view ``(x, z, phi)`` for
            skills; metres and radians).
        object_names: The vocabulary ``object_ids`` index (feature sets that look objects up
            in the catalogue, such as chapter 6's, need catalogue names).
        meta: What the features read about the world (pushes: ``push_height``,
            ``gripper_opening``, ``finger_radius``, ``table_size``; skills: ``skill``,
            ``lift``, ...; see `probaff.data.queries.world_meta`), and ``scene``; it must be
            JSON-serialisable.
        kind: ``"push"`` or ``"skill"``.
        units: The units each array is in, as the HDF5 layout records them (e.g.
            ``{"state_before": "m, m, rad"}``); each must be the schema's
            (`probaff.data.schema.ARRAY_UNITS`, `probaff.data.skill_schema.SKILL_ARRAY_UNITS`).
        sampling: How clouds are sampled on ``object_size`` boxes when no clouds are given
            (``CloudSampling()`` if ``None``).
        frame_tolerance: How far (m) an object's position before the push may lie outside
            its cloud's xy extent, > 0.
        angles: Pushes' yaws: ``"unwrapped"`` (default, the schema's: given as the objects
            turn, consecutive yaws of a push within pi of each other) or ``"wrapped"``
            (logged within (-pi, pi]): each push's yaws are unwrapped along its time axis
            with ``numpy.unwrap`` (see the module docstring). Skills' angles are taken as
            given.

    Returns:
        The dataset: a `PushDataset` or a `SkillDataset`, observation-only when it lacks an
        array only a simulator knows.

    Raises:
        InputError: For arrays of no rows (a dataset holds at least one push or skill);
            naming the array (and the first row) that is missing, of the wrong
            dtype, shape or units, not finite, in another frame, of another scale (a push or
            box longer than the table's diagonal, a yaw step above pi), or indexing outside
            `object_names`; or for a bad `kind`, `object_names`, `units`, `angles` or
            `meta` (naming the entry).

    Example:
        >>> import numpy as np  # six 4 cm pushes of a block along +y, a book behind it
        >>> from probaff.data import observation_dataset
        >>> before = np.zeros((6, 2, 3)) + [[0, 0.1, 0], [0, 0.3, 0]]  # world (x, y, theta)
        >>> arrays = {"object_ids": np.tile([0, 1], (6, 1)), "state_before": before,
        ...     "state_after": before + [[0, 0.04, 0], [0, 0, 0]], "push_distance": np.full(6, 0.1),
        ...     "push_origin": np.zeros((6, 2)), "push_yaw": np.full(6, np.pi / 2),
        ...     "object_size": np.full((6, 2, 3), 0.06)}  # clouds are sampled on the boxes
        >>> ds = observation_dataset(arrays, ["wood_block", "book"])
        >>> len(ds), ds.observation_only, round(float(ds["effect"][0, 0, 1]), 3)
        (6, True, 0.04)
    """
    cls = _KINDS.get(kind) if isinstance(kind, str) else None
    if cls is None:
        raise InputError(f"kind must be one of {sorted(_KINDS)}, got {kind!r}.")
    check_positive("frame_tolerance", frame_tolerance)
    if sampling is not None and not isinstance(sampling, CloudSampling):
        raise InputError(f"sampling must be a CloudSampling or None, got {sampling!r}.")
    names, meta = _checked_options(kind, object_names, meta, units, angles)
    out = _convert_all(cls, arrays, dict(units or {}))
    missing = [n for n in cls.REQUIRED if n not in out and n not in _FILLED[kind]]
    if missing:
        raise InputError(
            f"{kind} observations need arrays {missing}; give them (see "
            f"{'OBSERVATION_ARRAYS' if kind == 'push' else 'SKILL_OBSERVATION_ARRAYS'})."
        )
    if len(out["object_ids"]) == 0:  # a dataset of no rows has no shards and cannot load
        raise InputError(
            f"{kind} observations hold no rows: 'object_ids' has 0 rows; a dataset needs at "
            f"least one {kind} (arrays are one row per {kind}, first axis the row)."
        )
    _check_ids(out["object_ids"], names, NO_OBJECT if kind == "skill" else 0)
    if kind == "push":
        if angles == "wrapped":
            out = unwrap_yaws(out)
        check_yaw_steps(out)
        check_scale(out, meta)
        out = _complete_push(out, sampling, float(frame_tolerance))
    else:
        _complete_skill(out, meta)
    try:
        return cls(out, names, meta)
    except DatasetError as exc:
        raise InputError(str(exc)) from None


_FILLED = {"push": ("effect", "walls", "cloud_points", "cloud_normals"), "skill": ()}
"""Required arrays `observation_dataset` fills in when they are not given."""
