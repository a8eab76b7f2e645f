"""One box pushed straight along +x by the tabletop hand, shared by the hand's tests."""

import numpy as np

from probaff.sim import SceneInstance, load_catalogue, load_tabletop, simulate_push
from probaff.sim.runner import straight_path

CATALOGUE = load_catalogue()


def push_box(mode, obj, distance, mass_scale=1.0, wall_gap=None):
    """Push `obj` `distance` m along +x from just behind it; a wall `wall_gap` m ahead of its
    front; the box's mass scaled by `mass_scale`. The hand is `mode` ("stiff", "compliant")."""
    world = load_tabletop().with_hand(mode)
    o = CATALOGUE[obj]
    half = 0.5 * o.size[0]
    start = np.array([-0.2 - half - world.gripper.finger_radius - 0.005, 0.0])
    walls = None
    if wall_gap is not None:
        x = -0.2 + half + wall_gap
        walls = np.array([[x, -0.3, x, 0.3]])
    scene = SceneInstance.nominal(
        [o], [[-0.2, 0.0, 0.0]], start, 0.0, distance, world.physics.friction_grid, walls
    )
    scene.mass[:] *= mass_scale
    return simulate_push(world, scene, straight_path(world, start, 0.0, distance))
