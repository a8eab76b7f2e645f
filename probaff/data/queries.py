"""Pushes that have not happened yet: the inputs features need, without an outcome.

A planner asks a push model what candidate pushes *would* do. The feature functions of
`probaff.features` read only a push's inputs (the object clouds before it, the push pose and
length, the walls, and the world's geometry in ``meta``), so a `PushQueries` holds exactly those
arrays, named and shaped as in `probaff.data.schema`, and the feature functions take either.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from probaff._checks import check_count, check_finite, check_positive, check_shape
from probaff.data.schema import PushDataset
from probaff.errors import InputError
from probaff.sim.sensing import object_cloud
from probaff.sim.specs import ObjectSpec
from probaff.sim.tabletop_config import TabletopSpec

__all__ = ["QUERY_ARRAYS", "PushInputs", "PushQueries", "world_meta"]

QUERY_ARRAYS = {
    "cloud_points": "float32",
    "cloud_normals": "float32",
    "push_origin": "float64",
    "push_yaw": "float64",
    "push_distance": "float64",
    "walls": "float64",
}
"""The arrays of a query, with the dtypes of `probaff.data.schema`."""


def world_meta(world: TabletopSpec) -> dict[str, Any]:
    """The world geometry a dataset records in ``meta`` and the feature functions read.

    Args:
        world: The tabletop world.

    Returns:
        ``table_size``, ``push_height``, ``gripper_opening``, ``finger_radius``,
        ``control_rate``, ``record_rate``, ``arm_base_xyz``, ``arm_base_yaw`` and ``hand``
        (how the hand follows its command, `probaff.sim.pusher.HandSpec.to_dict`).
    """
    return {
        "table_size": list(world.table_size),
        "push_height": world.arm.push_height,
        "gripper_opening": world.gripper.push_opening,
        "finger_radius": world.gripper.finger_radius,
        "control_rate": world.physics.control_rate,
        "record_rate": world.record_rate,
        "arm_base_xyz": list(world.arm.base_xyz),
        "arm_base_yaw": world.arm.base_yaw,
        "hand": world.hand.to_dict(),
    }


@dataclass
class PushQueries:
    """C candidate pushes of one or more scenes, without outcomes.

    Attributes:
        arrays: ``cloud_points`` (C, K, P, 3) and ``cloud_normals`` (C, K, P, 3) world-frame
            clouds before each push (float32); ``push_origin`` (C, 2) world hand starts;
            ``push_yaw`` (C,) world yaws of z_p; ``push_distance`` (C,) d_p (m); ``walls``
            (C, Wn, 4) wall segments.
        meta: World geometry (see `world_meta`).
    """

    arrays: dict[str, np.ndarray]
    meta: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.validate()

    def validate(self) -> None:
        """Check names, shapes, dtypes and finiteness.

        Raises:
            InputError: Naming the offending array.
        """
        missing = set(QUERY_ARRAYS) - set(self.arrays)
        if missing:
            raise InputError(f"push queries lack arrays {sorted(missing)}; see QUERY_ARRAYS.")
        unknown = set(self.arrays) - set(QUERY_ARRAYS)
        if unknown:
            raise InputError(f"push queries have unknown arrays {sorted(unknown)}.")
        c = len(self.arrays["push_yaw"])
        if c == 0:
            raise InputError("push queries hold no pushes; give at least one candidate.")
        shapes = {
            "cloud_points": (c, None, None, 3),
            "cloud_normals": self.arrays["cloud_points"].shape,
            "push_origin": (c, 2),
            "push_yaw": (c,),
            "push_distance": (c,),
            "walls": (c, None, 4),
        }
        for name, dtype in QUERY_ARRAYS.items():
            arr = self.arrays[name]
            check_shape(f"queries[{name!r}]", arr, shapes[name])
            check_finite(f"queries[{name!r}]", arr)
            if arr.dtype != np.dtype(dtype):
                raise InputError(f"queries[{name!r}] has dtype {arr.dtype}, expected {dtype}.")
        if (self.arrays["push_distance"] <= 0).any():
            raise InputError("queries['push_distance'] must be > 0 (metres along z_p).")

    def __len__(self) -> int:
        return len(self.arrays["push_yaw"])

    def __getitem__(self, name: str) -> np.ndarray:
        return self.arrays[name]

    @property
    def n_objects(self) -> int:
        """Objects per scene, K."""
        return int(self.arrays["cloud_points"].shape[1])

    @classmethod
    def from_states(
        cls,
        objects: tuple[ObjectSpec, ...] | list[ObjectSpec],
        poses: np.ndarray,
        push_origin: np.ndarray,
        push_yaw: np.ndarray,
        push_distance: float,
        world: TabletopSpec,
        rng: np.random.Generator,
        *,
        walls: np.ndarray | None = None,
        cloud_points: int = 256,
        cloud_noise: float = 0.002,
    ) -> PushQueries:
        """Candidate pushes of C scene states, one push per state.

        Each object's cloud is sensed once, in its own frame, and moved rigidly to its pose
        in every state, so candidates differ only by where the objects are and how the push
        goes (the sensor's noise pattern does not change between candidates).

        Args:
            objects: The K catalogue objects; the first is the one pushed (o1).
            poses: (C, K, 3) world ``(x, y, theta)`` of the objects before each push, or
                (K, 3) for one state shared by every push.
            push_origin: (C, 2) world hand starts.
            push_yaw: (C,) world yaws of z_p (rad).
            push_distance: d_p (m), > 0.
            world: The tabletop world (its geometry goes to ``meta``).
            rng: Randomness of the cloud sensor.
            walls: (Wn, 4) wall segments shared by every push, or ``None``.
            cloud_points: Points per object cloud; use the training dataset's.
            cloud_noise: Cloud noise (m); use the training dataset's.

        Returns:
            C queries.

        Raises:
            InputError: For a wrong shape, a NaN, an empty candidate set or a bad count.
        """
        objects = tuple(objects)
        if not objects or not all(isinstance(o, ObjectSpec) for o in objects):
            raise InputError("objects must be a non-empty list of ObjectSpec (load_catalogue()).")
        K = len(objects)
        origin = np.asarray(push_origin, dtype=float)
        check_shape("push_origin", origin, (None, 2))
        c = origin.shape[0]
        yaw = np.asarray(push_yaw, dtype=float)
        check_shape("push_yaw", yaw, (c,))
        poses = np.asarray(poses, dtype=float)
        if poses.ndim == 2:
            check_shape("poses", poses, (K, 3))
            poses = np.broadcast_to(poses, (c, K, 3))
        check_shape("poses", poses, (c, K, 3))
        check_finite("poses", poses)
        check_positive("push_distance", push_distance)
        cloud_points = check_count("cloud_points", cloud_points)
        check_positive("cloud_noise", cloud_noise, allow_zero=True)
        local = [object_cloud(o, np.zeros(3), cloud_points, cloud_noise, rng) for o in objects]
        pts0 = np.stack([p for p, _ in local])  # (K, P, 3) object frames
        nrm0 = np.stack([n for _, n in local])
        cos, sin = np.cos(poses[..., 2])[..., None], np.sin(poses[..., 2])[..., None]
        pts = np.empty((c, K, cloud_points, 3))
        nrm = np.empty_like(pts)
        for out, src, shift in ((pts, pts0, True), (nrm, nrm0, False)):
            out[..., 0] = cos * src[None, ..., 0] - sin * src[None, ..., 1]
            out[..., 1] = sin * src[None, ..., 0] + cos * src[None, ..., 1]
            out[..., 2] = src[None, ..., 2]
            if shift:
                out[..., :2] += poses[..., None, :2]
        w = np.zeros((0, 4)) if walls is None else np.asarray(walls, dtype=float).reshape(-1, 4)
        return cls(
            {
                "cloud_points": pts.astype(np.float32),
                "cloud_normals": nrm.astype(np.float32),
                "push_origin": origin,
                "push_yaw": yaw,
                "push_distance": np.full(c, float(push_distance)),
                "walls": np.broadcast_to(w, (c, *w.shape)).copy(),
            },
            world_meta(world),
        )


PushInputs = PushDataset | PushQueries
"""What the feature functions read: a dataset's pushes, or candidate pushes."""
