"""The push dataset: a versioned schema of named arrays, one row per push.

Every array's first axis is the push index N. K is the number of objects in the scene (object 0
is the pushed one, o1), P the points per object cloud, W the IK waypoints per push, T the
trajectory samples and D the arm's degrees of freedom.

============================  ===============  ========  ====================================
array                         shape            dtype     meaning
============================  ===============  ========  ====================================
``object_ids``                (N, K)           int16     index into ``object_names``
``state_before``              (N, K, 3)        float64   world (x, y, theta) before the push
``state_after``               (N, K, 3)        float64   world (x, y, theta) after (unwrapped)
``effect``                    (N, K, 3)        float64   (dy_p, dz_p, dtheta_p), pushing frame
``push_origin``               (N, 2)           float64   hand start = pushing-frame origin
``push_yaw``                  (N,)             float64   world yaw of z_p
``push_distance``             (N,)             float64   d_p (m)
``q_waypoints``               (N, W, D)        float64   arm joint waypoints of the push
``mass``                      (N, K)           float64   kg, after randomisation
``ground_friction``           (N, K)           float64   Coulomb coefficient to the table
``contact_friction``          (N, K)           float64   surface coefficient
``support_weights``           (N, K, G)        float64   relative loads of the G friction
                                                         support points (0 = no point)
``walls``                     (N, Wn, 4)       float64   wall segments (x0, y0, x1, y1)
``hand_contact``              (N, K)           bool      the hand touched the object
``object_contact``            (N, K, K)        bool      two objects touched
``wall_contact``              (N, K)           bool      the object touched a wall
``fell_off``                  (N, K)           bool      the object fell off the table
``hand_lag``                  (N,)             float64   largest hand tracking error (m)
``max_penetration``           (N,)             float64   deepest final overlap (m)
``cloud_points``              (N, K, P, 3)     float32   object clouds before the push
``cloud_normals``             (N, K, P, 3)     float32   their outward normals
``traj_time`` (optional)      (N, T)           float64   trajectory sample times (s)
``traj_hand`` (optional)      (N, T, 3)        float32   world (x, y, yaw) of the hand
``traj_objects`` (optional)   (N, T, K, 3)     float32   world (x, y, theta) of the objects
============================  ===============  ========  ====================================
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from probaff.errors import DatasetError

__all__ = ["OPTIONAL_ARRAYS", "REQUIRED_ARRAYS", "SCHEMA_VERSION", "PushDataset"]

SCHEMA_VERSION = 1

REQUIRED_ARRAYS: dict[str, str] = {
    "object_ids": "int16",
    "state_before": "float64",
    "state_after": "float64",
    "effect": "float64",
    "push_origin": "float64",
    "push_yaw": "float64",
    "push_distance": "float64",
    "q_waypoints": "float64",
    "mass": "float64",
    "ground_friction": "float64",
    "contact_friction": "float64",
    "support_weights": "float64",
    "walls": "float64",
    "hand_contact": "bool",
    "object_contact": "bool",
    "wall_contact": "bool",
    "fell_off": "bool",
    "hand_lag": "float64",
    "max_penetration": "float64",
    "cloud_points": "float32",
    "cloud_normals": "float32",
}
OPTIONAL_ARRAYS: dict[str, str] = {
    "traj_time": "float64",
    "traj_hand": "float32",
    "traj_objects": "float32",
}


@dataclass
class PushDataset:
    """Pushes of one scene template, in memory.

    Attributes:
        arrays: Named arrays (see the module docstring for the schema).
        object_names: Vocabulary of ``arrays["object_ids"]``.
        meta: Scene name, seed, world settings and generation options.
    """

    arrays: dict[str, np.ndarray]
    object_names: list[str]
    meta: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.validate()

    def validate(self) -> None:
        """Check names, dtypes and that every array has the same number of rows.

        Raises:
            DatasetError: Naming the offending array.
        """
        missing = set(REQUIRED_ARRAYS) - set(self.arrays)
        if missing:
            raise DatasetError(f"push dataset is missing arrays {sorted(missing)}.")
        unknown = set(self.arrays) - set(REQUIRED_ARRAYS) - set(OPTIONAL_ARRAYS)
        if unknown:
            raise DatasetError(f"push dataset has unknown arrays {sorted(unknown)}.")
        n = len(self.arrays["effect"])
        for name, arr in self.arrays.items():
            want = {**REQUIRED_ARRAYS, **OPTIONAL_ARRAYS}[name]
            if arr.dtype != np.dtype(want):
                raise DatasetError(f"array {name!r} has dtype {arr.dtype}, expected {want}.")
            if len(arr) != n:
                raise DatasetError(f"array {name!r} has {len(arr)} rows, expected {n}.")
        ids = self.arrays["object_ids"]
        if ids.size and (ids.min() < 0 or ids.max() >= len(self.object_names)):
            raise DatasetError("object_ids index outside object_names.")

    def __len__(self) -> int:
        return len(self.arrays["effect"])

    def __getitem__(self, name: str) -> np.ndarray:
        return self.arrays[name]

    @property
    def n_objects(self) -> int:
        """Objects per scene, K."""
        return int(self.arrays["effect"].shape[1])

    @property
    def has_trajectories(self) -> bool:
        """Whether the optional trajectories are stored."""
        return "traj_hand" in self.arrays

    def objects_of(self, i: int) -> list[str]:
        """Catalogue names of the objects of push `i`."""
        return [self.object_names[j] for j in self.arrays["object_ids"][i]]

    @staticmethod
    def concatenate(parts: list[PushDataset]) -> PushDataset:
        """Join datasets of the same scene row-wise (metadata from the first)."""
        if not parts:
            raise DatasetError("cannot concatenate zero datasets.")
        names = parts[0].object_names
        if any(p.object_names != names for p in parts):
            raise DatasetError("datasets with different object vocabularies cannot be joined.")
        keys = parts[0].arrays.keys()
        return PushDataset({k: np.concatenate([p.arrays[k] for p in parts]) for k in keys},
                           list(names), dict(parts[0].meta))
