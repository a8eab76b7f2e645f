"""Chapter 6 interactions of side-view pick datasets: the open fingers lifting at the grasp.

A pick (`probaff.sim.skills`) lowers the open gripper around an object, closes it and lifts
by ``meta["lift"]``. Its interaction row, for a per-skill pick model
(`probaff.models.SkillTransitionModel("pick")`):

* target: the picked object, a box of ``size`` at its pose before the skill, lifted to 3-D
  with `sideview_transform` (the view's plane is world y = 0);
* actor: the two fingers, open to the span, at the grasp pose (the tcp at ``target_xz``):
  boxes of the finger thickness along x, the finger length along z (their tips
  ``tip_below_tcp`` below the tcp) and the object's depth along y, on either side of the
  span. Where an object is wider than the span they overlap it, which the shape voxels show;
* action: the commanded lift, from the grasp pose straight up by the lift height;
* effect: the object's displacement from before to after the skill in the action frame
  (about the lift along y when it was lifted, about 0 when it could not be grasped);
* reaction: the tcp's deviation from its commanded end point, in the action frame's (y, z),
  which for this vertical action are world up and world x.

The action is vertical, so the action frame's z is world x (`probaff.features.action_frame`):
an object moves in the view's plane along y (up) and z (world x) and turns about x (the
viewing axis), `SIDEVIEW_EFFECT_COLUMNS`. The finger geometry comes from the side-view world
(`probaff.sim.sideview_config.load_sideview`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from probaff.data.skill_schema import SkillDataset
from probaff.errors import InputError
from probaff.features.action_frame import effect_in_action_frame, sideview_transform
from probaff.features.ch6_push import _check_finite_rows
from probaff.features.chain_geometry import Ch6Geometry, InteractionRows, resolve_geometry
from probaff.features.requirements import FEATURE_REQUIREMENTS
from probaff.sim.sideview_config import SideViewSpec, load_sideview

__all__ = [
    "REQUIRES",
    "SIDEVIEW_EFFECT_COLUMNS",
    "PickInteractions",
    "check_skill",
    "check_skill_arrays",
    "pick_interactions",
    "tcp_reaction",
]

REQUIRES = FEATURE_REQUIREMENTS["ch6.pick"]
"""What `pick_interactions` reads: ids, sizes, poses, the grasp point, the ``lifted`` flag,
the tcp trajectories and ``meta["lift"]``."""

SIDEVIEW_EFFECT_COLUMNS = (1, 2, 3)
"""Effect columns that move in the side view under a vertical action: up, world x, the turn."""


@dataclass(frozen=True)
class PickInteractions(InteractionRows):
    """Interaction rows of a pick dataset, one per pick.

    Attributes:
        features: (N, D) the geometry's features.
        touches: (N,) whether the fingers touch the object during the lift.
        T_world_action: (N, 4, 4) the action frames A_t.
        effect: (N, 6) the object's displacement in A_t.
        reaction: (N, 2) the tcp's end-point deviation in A_t's (y, z) (m).
        lifted: (N,) the simulator's verdict that the object was lifted.
        T_world_before: (N, 4, 4) the object's pose before the skill, which `effect` starts
            from.
    """

    lifted: np.ndarray
    T_world_before: np.ndarray


def _fingers(
    geometry: Ch6Geometry, world: SideViewSpec, grasp: np.ndarray, depth: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Points and normals of both open fingers `(N, Q, 3)`, and the hand poses `(N, 4, 4)`."""
    g = world.gripper
    thickness, length = g.finger_size
    n = grasp.shape[0]
    T_hand = sideview_transform(np.column_stack([grasp, np.zeros(n)]))
    size = np.column_stack([np.full(n, thickness), depth, np.full(n, length)])
    points, normals = [], []
    for side in (-1.0, 1.0):
        T_finger = T_hand.copy()
        T_finger[:, 0, 3] += side * 0.5 * (g.span + thickness)
        T_finger[:, 2, 3] += 0.5 * length - g.tip_below_tcp
        p, q = geometry.surface(size, T_finger)
        points.append(p)
        normals.append(q)
    return np.concatenate(points, axis=1), np.concatenate(normals, axis=1), T_hand


def check_skill(ds: SkillDataset, skill: str, caller: str) -> None:
    """Refuse a skill dataset of another skill than `skill`.

    Args:
        ds: A side-view skill dataset.
        skill: The skill `caller` reads (``"pick"`` or ``"place"``).
        caller: The refusing function's name, for the message.

    Raises:
        InputError: Naming `caller`, the skill it needs and the dataset's.
    """
    if ds.skill != skill:
        raise InputError(
            f"{caller} needs a {skill} dataset, got a {ds.skill!r} one; generate it "
            f"with a {skill} scene (probaff scenes lists them)."
        )


def check_skill_arrays(ds: SkillDataset, names: tuple[str, ...]) -> None:
    """Refuse a skill dataset without trajectories, or with NaN or inf where rows read it.

    Args:
        ds: A pick or place dataset.
        names: Its per-row arrays the rows read; the tcp trajectories ``ee_commanded`` and
            ``ee_actual`` are checked too, within each row's ``traj_length``.

    Raises:
        InputError: Naming the missing trajectories, or the array and row holding NaN or inf.
    """
    if not ds.has_trajectories:
        raise InputError(
            f"the {ds.skill}'s reaction needs the tcp trajectories; regenerate the dataset with "
            "trajectories (the default)."
        )
    for name in names:
        _check_finite_rows(name, ds[name])
    length = ds["traj_length"].astype(int)
    for name in ("ee_commanded", "ee_actual"):
        _check_finite_rows(name, ds[name], length)


def tcp_reaction(ds: SkillDataset, T_world_action: np.ndarray) -> np.ndarray:
    """(N, 2) the tcp's deviation from its commanded end point, in A_t's (y, z) (m).

    Args:
        ds: A pick or place dataset with trajectories.
        T_world_action: (N, 4, 4) the rows' action frames A_t.
    """
    rows = np.arange(len(ds))
    end = ds["traj_length"].astype(int) - 1
    miss = (ds["ee_actual"][rows, end] - ds["ee_commanded"][rows, end]).astype(np.float64)
    deviation = np.column_stack([miss[:, 0], np.zeros(len(ds)), miss[:, 1]])  # world (x, y, z)
    in_a = np.einsum("nji,nj->ni", T_world_action[:, :3, :3], deviation)
    return in_a[:, 1:]


def pick_interactions(
    ds: SkillDataset,
    *,
    geometry: Ch6Geometry | None = None,
    world: SideViewSpec | None = None,
) -> PickInteractions:
    """Chapter 6 interaction rows of a side-view pick dataset.

    Args:
        ds: A pick dataset (``ds.skill == "pick"``) with trajectories.
        geometry: Surfaces and features (``Ch6Geometry()`` if ``None``).
        world: The side-view world the dataset was simulated in (``load_sideview()`` if
            ``None``); its gripper gives the finger geometry.

    Returns:
        One row per pick.

    Raises:
        InputError: For a dataset of another skill, one without trajectories or another
            array or ``meta`` entry of `REQUIRES` (naming it), a geometry of the wrong type,
            or NaN or inf in an array the rows read (naming the array and its first such row).
    """
    geometry = resolve_geometry(geometry)
    check_skill(ds, "pick", "pick_interactions")
    REQUIRES.check(ds)
    check_skill_arrays(ds, ("size", "state_before", "state_after", "target_xz"))
    world = load_sideview() if world is None else world
    rows = np.arange(len(ds))
    slot = ds["target"].astype(int)
    size = ds["size"][rows, slot]
    T_before = sideview_transform(ds["state_before"][rows, slot])
    T_after = sideview_transform(ds["state_after"][rows, slot])
    t_pts, t_nrm = geometry.surface(size, T_before)
    a_pts, a_nrm, T_s = _fingers(geometry, world, ds["target_xz"], size[:, 1])
    T_e = T_s.copy()
    T_e[:, 2, 3] += float(ds.meta["lift"])
    X, touches, T_a = geometry.features(t_pts, t_nrm, a_pts, a_nrm, T_s, T_e)
    return PickInteractions(
        X,
        touches,
        T_a,
        effect_in_action_frame(T_a, T_before, T_after),
        tcp_reaction(ds, T_a),
        ds["lifted"].copy(),
        T_before,
    )
