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

The optional trajectory arrays are stored all together or not at all.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, ClassVar

import numpy as np

from probaff.data.dataset import ArrayDataset
from probaff.errors import DatasetError

__all__ = [
    "NO_OBJECT",
    "SKILL_ARRAYS",
    "SKILL_SCHEMA_VERSION",
    "SKILL_TRAJECTORY_ARRAYS",
    "SkillDataset",
]

SKILL_SCHEMA_VERSION = 3
"""Schema version of skill datasets (manifest kind ``"skill"``); push datasets use 1 and 2."""
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
"""The required arrays and their dtypes."""
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

_PER_OBJECT = {"size": (3,), "mass": (), "friction": (), "state_before": (3,), "state_after": (3,)}
_PER_SAMPLE = {"target_xz": (2,)}
_PER_STEP = {
    "traj_time": (),
    "ee_commanded": (3,),
    "ee_actual": (3,),
    "opening_commanded": (),
    "opening_actual": (),
}


class SkillDataset(ArrayDataset):
    """Picks or places of one side-view scene template, in memory.

    Attributes:
        arrays: Named arrays (see the module docstring for the schema).
        object_names: Vocabulary of ``arrays["object_ids"]`` (the sorted names of the
            side-view catalogue, ``worlds/cuboids.yaml``).
        meta: Scene name, skill, seed, world settings and generation options.
    """

    KIND = "skill"
    REQUIRED = SKILL_ARRAYS
    OPTIONAL = SKILL_TRAJECTORY_ARRAYS
    GROUPS: ClassVar[dict[str, tuple[str, ...]]] = {"trajectory": tuple(SKILL_TRAJECTORY_ARRAYS)}
    ROWS = "object_ids"

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
        self._check_shapes(n, k)
        q = arrays["q_waypoints"]
        if q.ndim != 3:
            raise DatasetError(f"array 'q_waypoints' has shape {q.shape}, expected (N, W, D).")
        if ids.size and (ids.min() < NO_OBJECT or ids.max() >= len(self.object_names)):
            raise DatasetError("object_ids index outside object_names (or below -1, no object).")
        rows = np.arange(n)
        target, support = arrays["target"].astype(int), arrays["support"].astype(int)
        if n and (target.min() < 0 or target.max() >= k or np.any(ids[rows, target] < 0)):
            raise DatasetError("target must be the slot of a present object (0..K-1).")
        if n and (support.min() < -1 or support.max() >= k):
            raise DatasetError("support must be -1 (the table) or an object slot (0..K-1).")
        self._check_lengths("n_waypoints", q.shape[1])
        if self.has_trajectories:
            self._check_lengths("traj_length", arrays["traj_time"].shape[1])

    def _check_shapes(self, n: int, k: int) -> None:
        """Raise `DatasetError` for an array whose shape does not fit N rows and K slots."""
        arrays = self.arrays
        shapes: dict[str, tuple[int, ...]] = {
            **{name: (n, k, *tail) for name, tail in _PER_OBJECT.items()},
            **{name: (n, *tail) for name, tail in _PER_SAMPLE.items()},
        }
        for name in ("target", "support", "release_height", "n_waypoints", "traj_length"):
            shapes[name] = (n,)
        for flag in ("grasped", "lifted", "slipped", "placed"):
            shapes[flag] = (n,)
        if self.has_trajectories:
            t = arrays["traj_time"].shape[1] if arrays["traj_time"].ndim == 2 else -1
            shapes.update({name: (n, t, *tail) for name, tail in _PER_STEP.items()})
            shapes["traj_objects"] = (n, t, k, 3)
        for name, shape in shapes.items():
            if name in arrays and arrays[name].shape != shape:
                raise DatasetError(
                    f"array {name!r} has shape {arrays[name].shape}, expected {shape}."
                )

    def _check_lengths(self, name: str, most: int) -> None:
        lengths = self.arrays[name]
        if lengths.size and (lengths.min() < 1 or lengths.max() > most):
            raise DatasetError(f"array {name!r} must lie in 1..{most}.")

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
        if any(p.arrays.keys() != keys for p in parts):
            raise DatasetError(
                "skill datasets with and without trajectories cannot be joined; generate them "
                "with the same options."
            )
        for name in keys:
            tails = {p.arrays[name].shape[1:] for p in parts}
            if len(tails) > 1:
                raise DatasetError(
                    f"array {name!r} has per-row shapes {sorted(tails)} in the parts; only "
                    "datasets of one scene template and record rate can be joined."
                )
