"""What each feature set reads from a dataset, and the one check that names what is missing.

Features are computed from dataset arrays, never from a simulator, so any dataset that holds
what a feature set reads will do: a simulated one, or a robot's own observations
(`probaff.data.observation_dataset`). `FEATURE_REQUIREMENTS` lists, per feature set, the arrays
and the ``meta`` entries it reads; each feature function checks its entry first and raises an
`InputError` naming the missing array (or entry) and the feature set, instead of failing deep
inside with a ``KeyError``.

====================  =========================================  ==============================
feature set           arrays                                     meta
====================  =========================================  ==============================
``ch3.cells``         none: `cell_features` reads a merged       none
                      cloud and an occupancy grid
``ch4``               clouds, push (origin, yaw, distance),      push_height
                      walls
``ch5``               clouds, push (origin, yaw, distance)       gripper_opening, push_height
``ch6.push.hand``     object ids, poses before and after, push,  finger_radius, gripper_opening,
                      ``traj_hand``                              push_height
``ch6.push.objects``  object ids, poses before and after         none
``ch6.scenes``        object ids, poses before and after, push   finger_radius, gripper_opening,
                                                                 push_height
``ch6.pick``          ids, sizes, poses, target, ``target_xz``,  lift
                      ``lifted``, tcp trajectories
``ch6.place``         ids, sizes, poses, target, support,        none
                      ``placed``, tcp trajectories
====================  =========================================  ==============================

No feature set reads what only a simulator knows (masses, frictions, contact flags, IK
waypoints), except the pick and place rows' outcome flags (``lifted``, ``placed``), which a
robot judges too. Fitting a model needs the targets besides (``effect`` for pushes).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from probaff.errors import InputError

__all__ = ["FEATURE_REQUIREMENTS", "Requirements", "requirements"]

_TRAJECTORY_PREFIXES = ("traj_", "ee_", "opening_")
_PUSH = ("push_origin", "push_yaw", "push_distance")
_CLOUDS = ("cloud_points", "cloud_normals")
_POSES = ("object_ids", "state_before", "state_after")
_HAND = ("finger_radius", "gripper_opening", "push_height")
_TCP = ("traj_length", "ee_commanded", "ee_actual")


@dataclass(frozen=True)
class Requirements:
    """The arrays and ``meta`` entries one feature set reads.

    Attributes:
        name: The feature set, as `FEATURE_REQUIREMENTS` names it (e.g. ``"ch4"``).
        function: The function that computes it, for messages (e.g. ``"chapter4_features"``).
        arrays: The dataset arrays it reads.
        meta: The ``meta`` entries it reads.

    Raises:
        InputError: For an empty name or function, or names that are not strings.
    """

    name: str
    function: str
    arrays: tuple[str, ...] = ()
    meta: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        for field in ("name", "function"):
            if not isinstance(getattr(self, field), str) or not getattr(self, field):
                raise InputError(f"Requirements.{field} must be a non-empty string.")
        for field in ("arrays", "meta"):
            values = getattr(self, field)
            if not isinstance(values, tuple) or not all(isinstance(v, str) for v in values):
                raise InputError(f"Requirements.{field} must be a tuple of names.")

    def missing(self, ds: Any) -> tuple[list[str], list[str]]:
        """The arrays and the ``meta`` entries of this feature set that `ds` lacks.

        Args:
            ds: A dataset or anything with ``arrays`` and ``meta`` mappings (`PushQueries`).
        """
        arrays = getattr(ds, "arrays", {})
        meta = getattr(ds, "meta", {})
        return [a for a in self.arrays if a not in arrays], [m for m in self.meta if m not in meta]

    def check(self, ds: Any) -> None:
        """Raise `InputError` naming the arrays or ``meta`` entries `ds` lacks, if any.

        Args:
            ds: A dataset or anything with ``arrays`` and ``meta`` mappings (`PushQueries`).
        """
        arrays, meta = self.missing(ds)
        what = f"{self.function} (feature set {self.name!r})"
        if arrays:
            kind = getattr(ds, "KIND", type(ds).__name__)
            trajectories = [a for a in arrays if a.startswith(_TRAJECTORY_PREFIXES)]
            hint = (
                f" {trajectories} are trajectory arrays: generate the dataset with trajectories "
                "(the default) or log them."
                if trajectories
                else ""
            )
            raise InputError(
                f"{what} needs array{'s' if len(arrays) > 1 else ''} {arrays}, which this {kind} "
                f"dataset lacks (it holds {sorted(getattr(ds, 'arrays', {}))}); build the dataset "
                f"with {'them' if len(arrays) > 1 else 'it'} (probaff.data.observation_dataset)."
                + hint
            )
        if meta:
            raise InputError(
                f"{what} needs dataset metadata {meta}, which the dataset's meta lacks; record "
                "the world's geometry in meta (probaff.data.queries.world_meta gives the "
                "simulated world's) or regenerate the dataset with this version of probaff."
            )


FEATURE_REQUIREMENTS: dict[str, Requirements] = {
    r.name: r
    for r in (
        Requirements("ch3.cells", "cell_features"),
        Requirements("ch4", "chapter4_features", (*_CLOUDS, *_PUSH, "walls"), ("push_height",)),
        Requirements(
            "ch5", "chapter5_features", (*_CLOUDS, *_PUSH), ("gripper_opening", "push_height")
        ),
        Requirements("ch6.push.hand", "push_interactions", (*_POSES, *_PUSH, "traj_hand"), _HAND),
        Requirements("ch6.push.objects", "push_interactions", _POSES),
        Requirements("ch6.scenes", "push_scenes", (*_POSES, *_PUSH), _HAND),
        Requirements(
            "ch6.pick",
            "pick_interactions",
            (*_POSES, "size", "target", "target_xz", "lifted", *_TCP),
            ("lift",),
        ),
        Requirements(
            "ch6.place",
            "place_interactions",
            (*_POSES, "size", "target", "support", "placed", *_TCP),
        ),
    )
}
"""Every feature set's `Requirements`, by name (see the module docstring's table)."""


def requirements(name: str) -> Requirements:
    """The `Requirements` of feature set `name`.

    Raises:
        InputError: For an unknown name, listing the known ones.
    """
    if not isinstance(name, str) or name not in FEATURE_REQUIREMENTS:
        raise InputError(
            f"unknown feature set {name!r}; the feature sets are {sorted(FEATURE_REQUIREMENTS)}."
        )
    return FEATURE_REQUIREMENTS[name]
