"""Chapter 6 interactions of side-view place datasets: the held cube released onto its support.

A place (`probaff.sim.skills`) holds a cube ``hold_height`` above its target (the table or the
top of a support object), lowers it to the release height above that top and opens the
fingers. The cube then lands on the support, or falls off it or tips over its edge when it was
released too far out. Its interaction row, for a per-skill place model
(`probaff.models.SkillTransitionModel("place")`):

* actor: the held cube (``ds["target"]``), a box of its ``size`` lifted to 3-D with
  `sideview_transform` (the view's plane is world y = 0). It starts at its pose before the
  skill and moves by the commanded lowering: the tcp's commanded displacement from the first
  to the last sample of ``ee_commanded``, a straight move down (vertical up to the arm's IK
  tolerance; the cube is held rigidly until the fingers open, and the tcp holds still after
  the release). Its end pose is the
  release pose, where the cube is when the fingers open;
* target: what the cube is placed on. That is the support object's box (``ds["support"]``)
  at its pose before the skill or, for ``support == -1``, the table top, drawn as a slab of
  the table's length (along world x, centred at x = 0) by the cube's depth (along the viewing
  axis) by `TABLE_SLAB_THICKNESS` (along z), its top face at world z = 0. The contact
  features thus see whether, and where on its top, the cube comes down on its support;
* action: the commanded lowering, vertical and down;
* effect: the held cube's displacement from its release pose to its final pose
  (``state_after``) in the action frame. A placed cube drops by the release height, along
  the action, so its effect is about ``+release_height`` along y; a cube that falls off
  drops further, moves sideways (along z, world x) and turns (about x);
* reaction: the tcp's deviation from its commanded end point, in the action frame's (y, z),
  which for this vertical action are world down and world x (as for a pick);
* placed: the simulator's verdict that the cube rests, released and flat, on its target.

The action is vertical, so the action frame's z is world x (`probaff.features.action_frame`):
the cube moves in the view's plane along y (down) and z (world x) and turns about x (the
viewing axis), `SIDEVIEW_EFFECT_COLUMNS`. The table comes from the side-view world
(`probaff.sim.sideview_config.load_sideview`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from probaff.data.skill_schema import SkillDataset
from probaff.errors import InputError
from probaff.features.action_frame import effect_in_action_frame, sideview_transform
from probaff.features.ch6_pick import check_skill, check_skill_arrays, tcp_reaction
from probaff.features.chain_geometry import Ch6Geometry, InteractionRows, resolve_geometry
from probaff.features.requirements import FEATURE_REQUIREMENTS
from probaff.sim.sideview_config import SideViewSpec, load_sideview

__all__ = ["REQUIRES", "TABLE_SLAB_THICKNESS", "PlaceInteractions", "place_interactions"]

REQUIRES = FEATURE_REQUIREMENTS["ch6.place"]
"""What `place_interactions` reads: ids, sizes, poses, the support, the ``placed`` flag and
the tcp trajectories."""

TABLE_SLAB_THICKNESS = 0.02
"""Thickness (m) of the slab that stands for the table top when the cube goes on the table."""


@dataclass(frozen=True)
class PlaceInteractions(InteractionRows):
    """Interaction rows of a place dataset, one per place.

    Attributes:
        features: (N, D) the geometry's features.
        touches: (N,) whether the held cube touches its support during the lowering.
        T_world_action: (N, 4, 4) the action frames A_t.
        effect: (N, 6) the held cube's displacement from its release pose to its final pose
            in A_t.
        reaction: (N, 2) the tcp's end-point deviation in A_t's (y, z) (m).
        placed: (N,) the simulator's verdict that the cube was placed.
        T_world_before: (N, 4, 4) the held cube's release pose, which `effect` starts from.
    """

    placed: np.ndarray
    T_world_before: np.ndarray


def _support_boxes(
    ds: SkillDataset, world: SideViewSpec, depth: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Sizes `(N, 3)` and side-view poses `(N, 3)` of each place's support, or the table slab.

    Args:
        ds: A place dataset.
        world: Its side-view world (the table's length).
        depth: (N,) the held cube's depth along the viewing axis (m).
    """
    rows = np.arange(len(ds))
    support = ds["support"].astype(int)
    on_table = support < 0
    slot = np.where(on_table, 0, support)
    size = ds["size"][rows, slot].astype(np.float64)
    pose = ds["state_before"][rows, slot].astype(np.float64)
    slab = np.column_stack(
        [np.full(len(ds), world.table_length), depth, np.full(len(ds), TABLE_SLAB_THICKNESS)]
    )
    size[on_table] = slab[on_table]
    pose[on_table] = (0.0, -0.5 * TABLE_SLAB_THICKNESS, 0.0)
    return size, pose


def place_interactions(
    ds: SkillDataset,
    *,
    geometry: Ch6Geometry | None = None,
    world: SideViewSpec | None = None,
) -> PlaceInteractions:
    """Chapter 6 interaction rows of a side-view place dataset.

    Args:
        ds: A place dataset (``ds.skill == "place"``) with trajectories.
        geometry: Surfaces and features (``Ch6Geometry()`` if ``None``).
        world: The side-view world the dataset was simulated in (``load_sideview()`` if
            ``None``); its table gives the slab of places onto the table.

    Returns:
        One row per place.

    Raises:
        InputError: For a dataset of another skill, one without rows, trajectories or
            another array of `REQUIRES` (naming it), a geometry of the wrong type, NaN or inf
            in an array the rows read (naming the array and its first such row), or a place
            whose commanded lowering is not down.
    """
    geometry = resolve_geometry(geometry)
    check_skill(ds, "place", "place_interactions")
    if len(ds) == 0:
        raise InputError("the dataset has no places; generate at least one.")
    REQUIRES.check(ds)
    check_skill_arrays(ds, ("size", "state_before", "state_after"))
    world = load_sideview() if world is None else world
    rows = np.arange(len(ds))
    held = ds["target"].astype(int)
    cube = ds["size"][rows, held].astype(np.float64)
    T_start = sideview_transform(ds["state_before"][rows, held])
    end = ds["traj_length"].astype(int) - 1
    lowering = (ds["ee_commanded"][rows, end, :2] - ds["ee_commanded"][:, 0, :2]).astype(
        np.float64
    )  # (N, 2) world (x, z)
    up = np.flatnonzero(lowering[:, 1] >= 0.0)
    if up.size:
        raise InputError(
            f"ee_commanded in row {int(up[0])} does not go down (a place lowers the held cube); "
            "pass a place dataset generated by probaff."
        )
    T_release = T_start.copy()
    T_release[:, 0, 3] += lowering[:, 0]
    T_release[:, 2, 3] += lowering[:, 1]
    T_after = sideview_transform(ds["state_after"][rows, held])
    s_size, s_pose = _support_boxes(ds, world, cube[:, 1])
    t_pts, t_nrm = geometry.surface(s_size, sideview_transform(s_pose))
    a_pts, a_nrm = geometry.surface(cube, T_start)
    X, touches, T_a = geometry.features(t_pts, t_nrm, a_pts, a_nrm, T_start, T_release)
    return PlaceInteractions(
        X,
        touches,
        T_a,
        effect_in_action_frame(T_a, T_release, T_after),
        tcp_reaction(ds, T_a),
        ds["placed"].copy(),
        T_release,
    )
