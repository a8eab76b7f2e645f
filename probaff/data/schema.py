"""The push dataset: a versioned schema of named arrays, one row per push.

Every array's first axis is the push index N. K is the number of objects in the scene (object 0
is the pushed one, o1), P the points per object cloud, W the IK waypoints per push, T the
trajectory samples and D the arm's degrees of freedom.

============================  ===============  ========  ====================================
array                         shape            dtype     meaning
============================  ===============  ========  ====================================
``object_ids``                (N, K)           int16     index into ``object_names``
``state_before``              (N, K, 3)        float64   observed world (x, y, theta) before
                                                         the push
``state_after``               (N, K, 3)        float64   observed world (x, y, theta) after
                                                         (unwrapped)
``effect``                    (N, K, 3)        float64   observed (dy_p, dz_p, dtheta_p) from
                                                         ``state_before`` to ``state_after``,
                                                         pushing frame
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
``object_size`` (version 4)   (N, K, 3)        float64   box (length, width, height) (m) the
                                                         clouds were sampled from
``traj_time`` (optional)      (N, T)           float64   trajectory sample times (s)
``traj_hand`` (optional)      (N, T, 3)        float32   world (x, y, yaw) of the hand
``traj_objects`` (optional)   (N, T, K, 3)     float32   world (x, y, theta) of the objects
``traj_commanded`` (opt., 6)  (N, T, 3)        float32   commanded world (x, y, yaw) of the
                                                         hand at ``traj_time``
``hand_reaction`` (opt., 6)   (N, R, 3)        float64   the hand's deviation from its
                                                         commanded pose (actual - commanded)
                                                         in the pushing frame (dy_p, dz_p,
                                                         dtheta) at R times evenly spaced
                                                         over the push and its settling
``true_state_before`` (opt.)  (N, K, 3)        float64   exact world (x, y, theta) before
``true_state_after`` (opt.)   (N, K, 3)        float64   exact world (x, y, theta) after
``true_effect`` (optional)    (N, K, 3)        float64   exact (dy_p, dz_p, dtheta_p)
============================  ===============  ========  ====================================

Observations and the simulator. The arrays a robot observes, `OBSERVATION_ARRAYS` (the object
ids, the poses before and after, their effect, the push, the walls and the object clouds), are
required in every version. Schema versions 1 and 2 (what `probaff generate` writes) also
require `SIMULATOR_ARRAYS`, which only a simulator knows (masses, frictions, support weights,
contact flags, IK waypoints, hand lag, penetration). Version 4 (`OBSERVATION_SCHEMA_VERSION`)
makes each of those optional, for a robot's own logs
(`probaff.data.observations.observation_dataset` builds one from arrays); it alone may hold
``object_size``, the boxes a dataset's clouds were sampled from when it was given box
footprints instead of clouds. Poses are world ``(x, y, theta)`` (m, m, rad), with the table top
at z = 0 and theta unwrapped; the clouds are world points (m) with unit normals; the units of
every array are `ARRAY_UNITS`.

The reaction (version 6). Chapter 6's backward component models the hand's deviation from its
commanded pose, the reaction. Version 6 datasets record it along the path: ``hand_reaction``
at ``R`` (``meta["hand"]["reaction_samples"]``) evenly spaced times from the start of the push
to the end of its settling, and, with the trajectories, the commanded hand pose
``traj_commanded`` beside the actual ``traj_hand``; ``meta["hand"]`` records how the hand
followed its command (`probaff.sim.pusher.HandSpec`: stiff or compliant, its stiffness,
damping and force limit). Versions 1 and 2 lack both arrays and are read as before; what needs
the reaction along the path asks for a regenerated dataset. A robot's own logs (version 4)
may hold both, from its commanded and measured flange poses.

Observed and exact poses. Without pose noise (the default) the recorded poses are the
simulator's exact ones and the three ``true_*`` arrays are absent. A dataset generated with a
`probaff.data.noise.PoseNoise` model stores, in ``state_before``, ``state_after`` and
``effect``, what a camera would measure (the exact poses plus independent Gaussian noise before
and after the push, and the pushing-frame difference of those measurements), and keeps the
simulator's exact values in the ``true_*`` arrays, so models are fitted to observations and
studies can score against either (`PushDataset.true_effect` gives the exact effect in both
cases). Everything else is exact whether or not there is pose noise: the contact and
``fell_off`` flags come from the simulator, ``traj_objects`` holds the exact trajectories, and
the clouds are sensed around the exact start poses with their own noise.
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np

from probaff.data.dataset import ArrayDataset, Shape, split_arrays
from probaff.errors import DatasetError

__all__ = [
    "ARRAY_UNITS",
    "GROUND_TRUTH_ARRAYS",
    "OBSERVATION_ARRAYS",
    "OBSERVATION_SCHEMA_VERSION",
    "OPTIONAL_ARRAYS",
    "PUSH_SHAPES",
    "REACTION_ARRAYS",
    "READABLE_SCHEMA_VERSIONS",
    "REQUIRED_ARRAYS",
    "SCHEMA_VERSION",
    "SIMULATOR_ARRAYS",
    "PushDataset",
    "schema_version_for",
]

SCHEMA_VERSION = 6
"""Newest simulated push schema version: 2 added the ``true_*`` arrays and pose noise, 6 the
hand's reaction along the path (``hand_reaction``, ``traj_commanded``, ``meta["hand"]``)."""
READABLE_SCHEMA_VERSIONS = (1, 2, 6)
"""Versions of simulated push datasets this probaff reads: a version 1 dataset is a version 2
one without pose noise, a version 2 one a version 6 one without the reaction."""
REACTION_ARRAYS = ("hand_reaction", "traj_commanded")
"""The arrays version 6 added: the reaction along the path and the commanded hand path."""
OBSERVATION_SCHEMA_VERSION = 4
"""Version of observation-only push datasets: `SIMULATOR_ARRAYS` optional, ``object_size``
allowed (version 3 is the skill datasets')."""

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
"""The arrays schema versions 1 and 2 require, and their dtypes."""
OBSERVATION_ARRAYS, SIMULATOR_ARRAYS = split_arrays(
    REQUIRED_ARRAYS,
    (
        "object_ids",
        "state_before",
        "state_after",
        "effect",
        "push_origin",
        "push_yaw",
        "push_distance",
        "walls",
        "cloud_points",
        "cloud_normals",
    ),
)
"""`OBSERVATION_ARRAYS`: what a robot observes, the arrays every version requires.
`SIMULATOR_ARRAYS`: what only a simulator knows, required by versions 1 and 2, optional in
version 4. Both map names to dtypes."""
OPTIONAL_ARRAYS: dict[str, str] = {
    "traj_time": "float64",
    "traj_hand": "float32",
    "traj_objects": "float32",
    "traj_commanded": "float32",
    "hand_reaction": "float64",
    "true_state_before": "float64",
    "true_state_after": "float64",
    "true_effect": "float64",
}
"""The optional arrays of every version, and their dtypes."""
GROUND_TRUTH_ARRAYS = ("true_state_before", "true_state_after", "true_effect")
"""The exact poses and effect, stored (all three together) when the observed ones are noisy."""
_OBSERVED_ONLY = {"object_size": "float64"}

PUSH_SHAPES: dict[str, Shape] = {
    "object_ids": ("N", "K"),
    "state_before": ("N", "K", 3),
    "state_after": ("N", "K", 3),
    "effect": ("N", "K", 3),
    "push_origin": ("N", 2),
    "push_yaw": ("N",),
    "push_distance": ("N",),
    "walls": ("N", "Wn", 4),
    "cloud_points": ("N", "K", "P", 3),
    "cloud_normals": ("N", "K", "P", 3),
    "object_size": ("N", "K", 3),
    "q_waypoints": ("N", "W", "D"),
    "mass": ("N", "K"),
    "ground_friction": ("N", "K"),
    "contact_friction": ("N", "K"),
    "support_weights": ("N", "K", "G"),
    "hand_contact": ("N", "K"),
    "object_contact": ("N", "K", "K"),
    "wall_contact": ("N", "K"),
    "fell_off": ("N", "K"),
    "hand_lag": ("N",),
    "max_penetration": ("N",),
    "traj_time": ("N", "T"),
    "traj_hand": ("N", "T", 3),
    "traj_objects": ("N", "T", "K", 3),
    "traj_commanded": ("N", "T", 3),
    "hand_reaction": ("N", "R", 3),
}
"""The symbolic shape of every push array (`probaff.data.dataset.Shape`)."""
_POSE = "m, m, rad"
ARRAY_UNITS: dict[str, str] = {
    "object_ids": "index",
    "state_before": _POSE,
    "state_after": _POSE,
    "effect": _POSE,
    "push_origin": "m",
    "push_yaw": "rad",
    "push_distance": "m",
    "walls": "m",
    "cloud_points": "m",
    "cloud_normals": "1",
    "object_size": "m",
    "q_waypoints": "rad",
    "mass": "kg",
    "ground_friction": "1",
    "contact_friction": "1",
    "support_weights": "1",
    "hand_contact": "bool",
    "object_contact": "bool",
    "wall_contact": "bool",
    "fell_off": "bool",
    "hand_lag": "m",
    "max_penetration": "m",
    "traj_time": "s",
    "traj_hand": "m, m, rad",
    "traj_objects": _POSE,
    "traj_commanded": "m, m, rad",
    "hand_reaction": _POSE,
    "true_state_before": _POSE,
    "true_state_after": _POSE,
    "true_effect": _POSE,
}
"""The units of every push array: one unit, or one per component of the last axis."""


def schema_version_for(pose_noise: bool, reaction: bool = False) -> int:
    """The schema version a dataset is written with.

    A dataset with the reaction along the path is version 6, which earlier releases refuse by
    its version number. Without it, a dataset without pose noise uses nothing that version 2
    added, so it is written as version 1, byte-identical to what earlier releases wrote; one
    with pose noise is version 2.

    Args:
        pose_noise: Whether the dataset records noisy observed poses.
        reaction: Whether it records the hand's reaction (`REACTION_ARRAYS`).
    """
    if reaction:
        return SCHEMA_VERSION
    return 2 if pose_noise else 1


class PushDataset(ArrayDataset):
    """Pushes of one scene template, in memory.

    Attributes:
        arrays: Named arrays (see the module docstring for the schema).
        object_names: Vocabulary of ``arrays["object_ids"]``.
        meta: Scene name, seed, world settings and generation options.

    Example:
        Eight simulated pushes of the ``two_objects`` scene (`probaff.data.generate` writes
        the folder and loads it back), then the arrays a push model reads:

        >>> import tempfile
        >>> from probaff.data import GenerateConfig, generate
        >>> config = GenerateConfig("two_objects", n=8, trajectories=False, cloud_points=64)
        >>> ds = generate(config, f"{tempfile.mkdtemp()}/pushes", progress=False)
        >>> len(ds), ds.n_objects, ds.objects_of(0)  # N pushes, K objects, row 0's objects
        (8, 2, ['cracker_box', 'nut_container'])
        >>> ds["state_before"].shape  # (N, K, 3): world (x, y, theta) before each push
        (8, 2, 3)
        >>> ds["effect"].shape  # (N, K, 3): (dy_p, dz_p, dtheta_p) in the pushing frame
        (8, 2, 3)
        >>> ds["cloud_points"].shape  # (N, K, P, 3): each object's cloud before the push
        (8, 2, 64, 3)
        >>> ds.meta["scene"], ds.observation_only  # simulated, so nothing is missing
        ('two_objects', False)
    """

    KIND = "push"
    REQUIRED = OBSERVATION_ARRAYS
    OPTIONAL: ClassVar[dict[str, str]] = {**SIMULATOR_ARRAYS, **OPTIONAL_ARRAYS, **_OBSERVED_ONLY}
    GROUPS: ClassVar[dict[str, tuple[str, ...]]] = {"ground-truth": GROUND_TRUTH_ARRAYS}
    ROWS = "effect"
    SHAPES = PUSH_SHAPES
    UNITS = ARRAY_UNITS
    SIMULATED = tuple(SIMULATOR_ARRAYS)
    SIMULATOR_ONLY = (*SIMULATOR_ARRAYS, *GROUND_TRUTH_ARRAYS)
    OBSERVED_ONLY = tuple(_OBSERVED_ONLY)
    OBSERVATION_VERSION = OBSERVATION_SCHEMA_VERSION

    def validate(self) -> None:
        """Check names, dtypes, row counts, shapes (the ground truth's first) and object ids.

        Raises:
            DatasetError: Naming the offending array.
        """
        for name in GROUND_TRUTH_ARRAYS:
            observed = self.arrays.get(name.removeprefix("true_"))
            if (
                name in self.arrays
                and observed is not None
                and (self.arrays[name].shape != observed.shape)
            ):
                raise DatasetError(
                    f"array {name!r} has shape {self.arrays[name].shape}, "
                    f"expected that of {name.removeprefix('true_')!r}, "
                    f"{observed.shape}."
                )
        super().validate()
        ids = self.arrays["object_ids"]
        if ids.size and (ids.min() < 0 or ids.max() >= len(self.object_names)):
            raise DatasetError("object_ids index outside object_names.")

    @property
    def rows_label(self) -> str:
        """``"pushes"``."""
        return "pushes"

    @property
    def n_objects(self) -> int:
        """Objects per scene, K."""
        return int(self.arrays["effect"].shape[1])

    @property
    def has_trajectories(self) -> bool:
        """Whether the optional trajectories are stored."""
        return "traj_hand" in self.arrays

    @property
    def simulated_version(self) -> int:
        """6 with the reaction, else 1 without pose noise and 2 with it (`schema_version_for`)."""
        return schema_version_for(self.has_pose_noise, self.has_reaction)

    @property
    def has_reaction(self) -> bool:
        """Whether the hand's reaction along the path (``hand_reaction``) is stored."""
        return "hand_reaction" in self.arrays

    @property
    def has_pose_noise(self) -> bool:
        """Whether the observed poses and effects are noisy (the ``true_*`` arrays are stored)."""
        return "true_effect" in self.arrays

    @property
    def true_effect(self) -> np.ndarray:
        """(N, K, 3) exact ``(dy_p, dz_p, dtheta_p)`` in the pushing frame (m, m, rad).

        ``arrays["true_effect"]`` when the dataset has pose noise, else ``arrays["effect"]``,
        which is then exact.
        """
        return self.arrays["true_effect"] if self.has_pose_noise else self.arrays["effect"]

    def plan_entries(self) -> dict[str, Any]:
        """``trajectories``, and ``pose_noise`` when the dataset holds the ground truth.

        The noise's parameters come from ``meta["pose_noise"]``; when it does not record
        them (a robot's own ground truth), they are ``None``.
        """
        entries: dict[str, Any] = {"trajectories": self.has_trajectories}
        if self.has_pose_noise:
            noise = self.meta.get("pose_noise")
            entries["pose_noise"] = (
                noise if isinstance(noise, dict) else {"position_std": None, "yaw_std": None}
            )
        return entries

    def check_plan(self, plan: dict[str, Any]) -> str | None:
        """What contradicts the plan's pose noise: the ground-truth arrays come with it."""
        noisy = plan.get("pose_noise") is not None
        if self.has_pose_noise == noisy:
            return None
        return (
            f"{'lack' if noisy else 'hold'} the ground-truth arrays but its manifest says pose "
            f"noise is {'on' if noisy else 'off'}"
        )
