"""The skill dataset: a versioned schema of named arrays, one row per side-view pick or place.

Every array's first axis is the sample index N. K is the number of object slots of the scene
template (fixed per template: its placements, plus the held object of a place), W the most IK
waypoints of one of its skills, D the arm's degrees of freedom and T the trajectory samples,
fixed per dataset by its record rate and the template's longest skill. Poses are world
``(x, z, phi)`` in the side-view plane: x horizontal (m), z up from the table top (m), phi the
counter-clockwise rotation seen from -y (rad, unwrapped).

Object slots hold a scene's objects in its order (an object stacked on another comes after
it): for a pick the picked object is the last present one, for a place the held one. When a
template draws fewer objects than K (an optional placement left out), the slots after the
present objects are padding: their ``object_ids`` are `NO_OBJECT` (-1) and every other
per-object value (size, mass, friction, poses, trajectory poses) is 0.

Trajectories are resampled from the simulator's recording (linear interpolation) at
``meta["record_rate"]`` Hz: sample j is at ``j / record_rate`` seconds after the hand starts
moving, and the skill's last instant is appended when it falls between two of those. The
first ``traj_length[i]`` samples of row i are the skill; the samples after it repeat the last
one (its time included), so every row has T samples.

===========================  ============  ========  ============================================
array                        shape         dtype     meaning
===========================  ============  ========  ============================================
``object_ids``               (N, K)        int16     index into ``object_names``, -1 = no object
``size``                     (N, K, 3)     float64   (length along x, depth along the viewing
                                                     axis, height along z) (m)
``mass``                     (N, K)        float64   kg
``friction``                 (N, K)        float64   surface coefficient (a contact pair uses the
                                                     geometric mean of its two surfaces')
``state_before``             (N, K, 3)     float64   world (x, z, phi) when the hand starts
                                                     moving (after the objects settled)
``state_after``              (N, K, 3)     float64   world (x, z, phi) at the end of the skill
``target``                   (N,)          int16     slot of the object the skill acts on: the
                                                     picked one, or the held one of a place
``support``                  (N,)          int16     place: slot of the object the held one is
                                                     placed on, -1 for the table; pick: -1
``target_xz``                (N, 2)        float64   world (x, z) the skill aims at: pick: the
                                                     tcp's grasp point; place: the point of the
                                                     target top (table or support) below the
                                                     held object's centre
``release_height``           (N,)          float64   place: height of the held object's bottom
                                                     above the target top when the fingers open
                                                     (m); pick: 0
``grasped``                  (N,)          bool      pick: squeezed between both pads, off its
                                                     support, at the end; place: held until the
                                                     release
``lifted``                   (N,)          bool      pick: grasped and raised by at least half
                                                     the lift; place: False
``slipped``                  (N,)          bool      the held object moved relative to the hand
                                                     while it should have been held
``placed``                   (N,)          bool      place: rests released and flat on its
                                                     target; pick: False
``q_waypoints``              (N, W, D)     float64   arm joint waypoints (rad), the last one
                                                     repeated after ``n_waypoints``
``n_waypoints``              (N,)          int32     waypoints of each skill (<= W)
``traj_time`` (opt.)         (N, T)        float64   sample times (s), 0 when the hand starts
``traj_length`` (opt.)       (N,)          int32     samples of each skill (<= T)
``ee_commanded`` (opt.)      (N, T, 3)     float32   commanded world (x, z, phi) of the tcp
``ee_actual`` (opt.)         (N, T, 3)     float32   actual world (x, z, phi) of the tcp (the
                                                     difference is the reaction)
``opening_commanded`` (opt)  (N, T)        float32   commanded gap between the finger pads (m)
``opening_actual`` (opt.)    (N, T)        float32   actual gap between the finger pads (m)
``traj_objects`` (opt.)      (N, T, K, 3)  float32   world (x, z, phi) of the objects
===========================  ============  ========  ============================================

The optional trajectory arrays are stored all together or not at all, and so are
``q_waypoints`` and ``n_waypoints``.

Observations and the simulator. Every version requires what a robot observes,
`SKILL_OBSERVATION_ARRAYS`: the object ids and box sizes, the poses before and after, and the
skill itself (``target``, ``support`` and ``target_xz``; the trajectories, when stored, are
observations too). Version 3 (what `probaff generate` writes) also requires
`SKILL_SIMULATOR_ARRAYS`, which only a simulator knows or judges (masses, frictions, the
release height, the outcome flags, the IK waypoints); version 5
(`SKILL_OBSERVATION_SCHEMA_VERSION`) makes each of them optional, for a robot's own logs
(`probaff.data.observations.observation_dataset`). The units of every array are
`SKILL_ARRAY_UNITS`.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, ClassVar

import numpy as np

from probaff.data.dataset import ArrayDataset, Shape, split_arrays
from probaff.errors import DatasetError

__all__ = [
    "NO_OBJECT",
    "SKILL_ARRAYS",
    "SKILL_ARRAY_UNITS",
    "SKILL_OBSERVATION_ARRAYS",
    "SKILL_OBSERVATION_SCHEMA_VERSION",
    "SKILL_SCHEMA_VERSION",
    "SKILL_SHAPES",
    "SKILL_SIMULATOR_ARRAYS",
    "SKILL_TRAJECTORY_ARRAYS",
    "SkillDataset",
]

SKILL_SCHEMA_VERSION = 3
"""Schema version of simulated skill datasets (manifest kind ``"skill"``); push datasets use 1,
2 and 4."""
SKILL_OBSERVATION_SCHEMA_VERSION = 5
"""Schema version of observation-only skill datasets: `SKILL_SIMULATOR_ARRAYS` optional."""
NO_OBJECT = -1
"""``object_ids`` value of an empty object slot."""

SKILL_ARRAYS: dict[str, str] = {
    "object_ids": "int16",
    "size": "float64",
    "mass": "float64",
    "friction": "float64",
    "state_before": "float64",
    "state_after": "float64",
    "target": "int16",
    "support": "int16",
    "target_xz": "float64",
    "release_height": "float64",
    "grasped": "bool",
    "lifted": "bool",
    "slipped": "bool",
    "placed": "bool",
    "q_waypoints": "float64",
    "n_waypoints": "int32",
}
"""The arrays version 3 requires, and their dtypes."""
SKILL_OBSERVATION_ARRAYS, SKILL_SIMULATOR_ARRAYS = split_arrays(
    SKILL_ARRAYS,
    ("object_ids", "size", "state_before", "state_after", "target", "support", "target_xz"),
)
"""`SKILL_OBSERVATION_ARRAYS`: what a robot observes, the arrays every version requires.
`SKILL_SIMULATOR_ARRAYS`: what only a simulator knows or judges, required by version 3,
optional in version 5. Both map names to dtypes."""
SKILL_TRAJECTORY_ARRAYS: dict[str, str] = {
    "traj_time": "float64",
    "traj_length": "int32",
    "ee_commanded": "float32",
    "ee_actual": "float32",
    "opening_commanded": "float32",
    "opening_actual": "float32",
    "traj_objects": "float32",
}
"""The optional trajectory arrays (all or none) and their dtypes."""

SKILL_SHAPES: dict[str, Shape] = {
    "object_ids": ("N", "K"),
    "size": ("N", "K", 3),
    "mass": ("N", "K"),
    "friction": ("N", "K"),
    "state_before": ("N", "K", 3),
    "state_after": ("N", "K", 3),
    "target": ("N",),
    "support": ("N",),
    "target_xz": ("N", 2),
    "release_height": ("N",),
    "grasped": ("N",),
    "lifted": ("N",),
    "slipped": ("N",),
    "placed": ("N",),
    "q_waypoints": ("N", "W", "D"),
    "n_waypoints": ("N",),
    "traj_time": ("N", "T"),
    "traj_length": ("N",),
    "ee_commanded": ("N", "T", 3),
    "ee_actual": ("N", "T", 3),
    "opening_commanded": ("N", "T"),
    "opening_actual": ("N", "T"),
    "traj_objects": ("N", "T", "K", 3),
}
"""The symbolic shape of every skill array (`probaff.data.dataset.Shape`)."""
_POSE = "m, m, rad"
SKILL_ARRAY_UNITS: dict[str, str] = {
    "object_ids": "index",
    "size": "m",
    "mass": "kg",
    "friction": "1",
    "state_before": _POSE,
    "state_after": _POSE,
    "target": "index",
    "support": "index",
    "target_xz": "m",
    "release_height": "m",
    "grasped": "bool",
    "lifted": "bool",
    "slipped": "bool",
    "placed": "bool",
    "q_waypoints": "rad",
    "n_waypoints": "1",
    "traj_time": "s",
    "traj_length": "1",
    "ee_commanded": _POSE,
    "ee_actual": _POSE,
    "opening_commanded": "m",
    "opening_actual": "m",
    "traj_objects": _POSE,
}
"""The units of every skill array: one unit, or one per component of the last axis."""


class SkillDataset(ArrayDataset):
    """Picks or places of one side-view scene template, in memory.

    Attributes:
        arrays: Named arrays (see the module docstring for the schema).
        object_names: Vocabulary of ``arrays["object_ids"]`` (the sorted names of the
            side-view catalogue, ``worlds/cuboids.yaml``).
        meta: Scene name, skill, seed, world settings and generation options.
    """

    KIND = "skill"
    REQUIRED = SKILL_OBSERVATION_ARRAYS
    OPTIONAL: ClassVar[dict[str, str]] = {**SKILL_SIMULATOR_ARRAYS, **SKILL_TRAJECTORY_ARRAYS}
    GROUPS: ClassVar[dict[str, tuple[str, ...]]] = {
        "trajectory": tuple(SKILL_TRAJECTORY_ARRAYS),
        "waypoint": ("q_waypoints", "n_waypoints"),
    }
    ROWS = "object_ids"
    SHAPES = SKILL_SHAPES
    UNITS = SKILL_ARRAY_UNITS
    SIMULATED = tuple(SKILL_SIMULATOR_ARRAYS)
    SIMULATOR_ONLY = tuple(SKILL_SIMULATOR_ARRAYS)
    OBSERVATION_VERSION = SKILL_OBSERVATION_SCHEMA_VERSION

    def validate(self) -> None:
        """Check names, dtypes, row counts, shapes and indices.

        Raises:
            DatasetError: Naming the offending array.
        """
        ids = self.arrays.get("object_ids")
        if ids is not None and ids.ndim != 2:
            raise DatasetError(f"array 'object_ids' has shape {ids.shape}, expected (N, K).")
        super().validate()
        arrays = self.arrays
        ids = arrays["object_ids"]
        n, k = ids.shape
        if ids.size and (ids.min() < NO_OBJECT or ids.max() >= len(self.object_names)):
            raise DatasetError("object_ids index outside object_names (or below -1, no object).")
        rows = np.arange(n)
        target, support = arrays["target"].astype(int), arrays["support"].astype(int)
        if n and (target.min() < 0 or target.max() >= k or np.any(ids[rows, target] < 0)):
            raise DatasetError("target must be the slot of a present object (0..K-1).")
        if n and (support.min() < -1 or support.max() >= k):
            raise DatasetError("support must be -1 (the table) or an object slot (0..K-1).")
        if "q_waypoints" in arrays:
            self._check_lengths("n_waypoints", arrays["q_waypoints"].shape[1])
        if self.has_trajectories:
            self._check_lengths("traj_length", arrays["traj_time"].shape[1])

    def _check_lengths(self, name: str, most: int) -> None:
        lengths = self.arrays[name]
        if lengths.size and (lengths.min() < 1 or lengths.max() > most):
            raise DatasetError(f"array {name!r} must lie in 1..{most}.")

    @property
    def simulated_version(self) -> int:
        """`SKILL_SCHEMA_VERSION`."""
        return SKILL_SCHEMA_VERSION

    @property
    def rows_label(self) -> str:
        """The skill's name, plural: ``"picks"`` or ``"places"``."""
        return f"{self.skill or 'skill'}s"

    @property
    def n_objects(self) -> int:
        """Object slots per scene, K."""
        return int(self.arrays["object_ids"].shape[1])

    @property
    def n_samples(self) -> int:
        """Trajectory samples per row, T (0 without trajectories)."""
        return int(self.arrays["traj_time"].shape[1]) if self.has_trajectories else 0

    @property
    def has_trajectories(self) -> bool:
        """Whether the optional trajectories are stored."""
        return "traj_time" in self.arrays

    @property
    def present(self) -> np.ndarray:
        """(N, K) bool: which object slots hold an object (the rest are padding)."""
        return np.asarray(self.arrays["object_ids"] != NO_OBJECT)

    @property
    def skill(self) -> str:
        """``"pick"`` or ``"place"``, from ``meta`` (empty if it is not recorded)."""
        return str(self.meta.get("skill", ""))

    def plan_entries(self) -> dict[str, Any]:
        """``trajectories``, and ``record_rate`` (Hz) when ``meta`` records it."""
        entries: dict[str, Any] = {"trajectories": self.has_trajectories}
        if "record_rate" in self.meta:
            entries["record_rate"] = self.meta["record_rate"]
        return entries

    def check_plan(self, plan: dict[str, Any]) -> str | None:
        """What contradicts the plan's ``trajectories``: the trajectory arrays come with it."""
        wanted = bool(plan.get("trajectories"))
        if self.has_trajectories == wanted:
            return None
        return (
            f"{'hold' if self.has_trajectories else 'lack'} the trajectory arrays but its "
            f"manifest says trajectories are {'on' if wanted else 'off'}"
        )

    @classmethod
    def check_joinable(cls, parts: Sequence[ArrayDataset]) -> None:
        """Raise `DatasetError` unless the parts share vocabularies, arrays and K, W and T."""
        super().check_joinable(parts)
        keys = parts[0].arrays.keys()
        differ = sorted(set().union(*(p.arrays.keys() ^ keys for p in parts)))
        if any(name in SKILL_TRAJECTORY_ARRAYS for name in differ):
            raise DatasetError(
                "skill datasets with and without trajectories cannot be joined; generate them "
                "with the same options."
            )
        if differ:
            raise DatasetError(
                f"skill datasets with and without arrays {differ} cannot be joined; give every "
                "part the same arrays."
            )
        for name in keys:
            tails = {p.arrays[name].shape[1:] for p in parts}
            if len(tails) > 1:
                raise DatasetError(
                    f"array {name!r} has per-row shapes {sorted(tails)} in the parts; only "
                    "datasets of one scene template and record rate can be joined."
                )
