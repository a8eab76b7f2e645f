"""The tool push's reachable region: the receiving arm's reach on the table, as a distance field.

A single arm cannot do this task: a push that starts within its reach moves objects away from
it, so a target beyond its reach is never pushed back in. As on the thesis's PR2, which pushed
with one arm into the workspace of the other, the region is the reach of a *receiving* arm: a
second mount of the world's URDF arm at ``ToolPushConfig.goal_base_xy`` (default world
(-1.0, 0.0), beside the table's -x end). A table point is reachable where IK can point that
arm's tool straight down at it at push height with any of ``ToolPushConfig.region_yaws`` yaws
(`Arm.reachable_mask`), i.e. where the arm can grasp an object from above. The mask is computed
once per process on a grid over the table (cells beyond the table edge count as unreachable),
and its signed distance field (metres, positive inside) scores how deep the target's centre
lies in the region.

Covered by tests/planning/tool_push/test_tool_push.py.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from scipy import ndimage

from probaff._checks import check_finite, check_shape
from probaff.planning.tool_push.config import ToolPushConfig, check_config
from probaff.sim.arm import load_arm
from probaff.sim.specs import ArmSpec
from probaff.sim.tabletop_config import TabletopSpec, load_tabletop

__all__ = ["ReachableRegion", "reachable_region"]


@dataclass(frozen=True, eq=False)
class ReachableRegion:
    """The receiving arm's reachable region of the table and its signed distance field.

    Attributes:
        mask: (H, W) bool, indexed ``[iy, ix]``: the tool can point down at the grid point.
        xs: (W,) world x of the grid columns (m).
        ys: (H,) world y of the grid rows (m).
        sdf: (H, W) signed distance to the region's boundary (m): positive inside, negative
            outside. The table edge bounds the region.
        resolution: Grid spacing (m).
        base_xy: World ``(x, y)`` of the receiving arm's base.
    """

    mask: np.ndarray
    xs: np.ndarray
    ys: np.ndarray
    sdf: np.ndarray
    resolution: float
    base_xy: tuple[float, float]

    def depth(self, xy: np.ndarray) -> np.ndarray:
        """Signed distance of world points into the region (bilinear in the grid).

        Args:
            xy: (..., 2) world positions (m).

        Returns:
            (...,) metres; positive inside the region, negative outside. Beyond the grid,
            the value at the nearest grid point minus the distance to it.

        Raises:
            InputError: For a last axis that is not 2 or a NaN.
        """
        pts = np.asarray(xy, dtype=float)
        check_shape("xy", pts, (*(None,) * (pts.ndim - 1), 2))
        check_finite("xy", pts)
        fx = (pts[..., 0] - self.xs[0]) / self.resolution
        fy = (pts[..., 1] - self.ys[0]) / self.resolution
        cx = np.clip(fx, 0.0, len(self.xs) - 1.0)
        cy = np.clip(fy, 0.0, len(self.ys) - 1.0)
        inside = ndimage.map_coordinates(
            self.sdf, [cy.ravel(), cx.ravel()], order=1, mode="nearest"
        ).reshape(cx.shape)
        return np.asarray(inside - self.resolution * np.hypot(fx - cx, fy - cy))

    def contains(self, xy: np.ndarray) -> np.ndarray:
        """Whether world points lie inside the region.

        Args:
            xy: (..., 2) world positions (m).

        Returns:
            (...,) bool.
        """
        return self.depth(xy) > 0.0


def _goal_arm_spec(world: TabletopSpec, base_xy: tuple[float, float]) -> ArmSpec:
    return dataclasses.replace(world.arm, base_xyz=(base_xy[0], base_xy[1], world.arm.base_xyz[2]))


@lru_cache(maxsize=8)
def _region(
    world: TabletopSpec, base_xy: tuple[float, float], resolution: float, n_yaws: int
) -> ReachableRegion:
    arm = load_arm(_goal_arm_spec(world, base_xy))
    hx, hy = 0.5 * world.table_size[0], 0.5 * world.table_size[1]
    mask, xs, ys = arm.reachable_mask((-hx, hx), (-hy, hy), resolution, n_yaws, "any")
    padded = np.pad(mask, 1, constant_values=False)  # off the table is out of reach
    inside = ndimage.distance_transform_edt(padded)[1:-1, 1:-1] * resolution
    outside = ndimage.distance_transform_edt(~padded)[1:-1, 1:-1] * resolution
    sdf = np.where(mask, inside - 0.5 * resolution, -(outside - 0.5 * resolution))
    for arr in (mask, xs, ys, sdf):
        arr.setflags(write=False)
    return ReachableRegion(mask=mask, xs=xs, ys=ys, sdf=sdf, resolution=resolution, base_xy=base_xy)


def reachable_region(config: ToolPushConfig | None = None) -> ReachableRegion:
    """The reachable region of the task: the receiving arm's reach on the table.

    Computed from the arm's IK once per process and configuration (the mask is cached by
    `Arm.reachable_mask` and the distance field here).

    Args:
        config: Task settings (`goal_base_xy`, `region_resolution`, `region_yaws`).

    Returns:
        The region and its signed distance field.
    """
    config = check_config(config)
    return _region(
        load_tabletop(), config.goal_base_xy, float(config.region_resolution), config.region_yaws
    )
