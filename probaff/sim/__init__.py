"""Simulated robot: registered world kinds, the URDF arm, pymunk worlds, skills and sensors.

Each world kind (tabletop, side view, warehouse, office) registers itself in its own module
with `probaff.sim.registry` (its loaders, its simulation and the dataset kind its scenes make),
which finds the world modules of this package by itself; its world file is read by its own
``<world>_config`` module over the shared YAML helpers of `probaff.sim.world_files`. The
depth camera (`probaff.sim.camera`) images any of them through
`probaff.sim.primitives.PrimitiveScene`. Everything not named here stays importable from its
module.
"""

from probaff.sim.arm import Arm, load_arm
from probaff.sim.camera import CameraSpec, DepthCamera, head_views, load_camera, scan_views
from probaff.sim.office import OfficeScene, sample_office_scenes
from probaff.sim.office_config import OfficeSpec, load_office
from probaff.sim.registry import (
    WorldKind,
    kind_of_scene,
    register_world,
    world_kind,
    world_kinds,
)
from probaff.sim.runner import PushSimulator
from probaff.sim.sideview import SideViewScene, simulate_sideview
from probaff.sim.sideview_config import SideViewSpec, load_sideview, load_sideview_scene
from probaff.sim.skills import run_skills
from probaff.sim.specs import ObjectSpec, load_catalogue
from probaff.sim.tabletop import SceneInstance, simulate_push
from probaff.sim.tabletop_config import TabletopSpec, load_scene, load_tabletop
from probaff.sim.warehouse import WarehouseMap, generate_map, push_box
from probaff.sim.warehouse_config import WarehouseSpec, load_warehouse

__all__ = [
    "Arm",
    "CameraSpec",
    "DepthCamera",
    "ObjectSpec",
    "OfficeScene",
    "OfficeSpec",
    "PushSimulator",
    "SceneInstance",
    "SideViewScene",
    "SideViewSpec",
    "TabletopSpec",
    "WarehouseMap",
    "WarehouseSpec",
    "WorldKind",
    "generate_map",
    "head_views",
    "kind_of_scene",
    "load_arm",
    "load_camera",
    "load_catalogue",
    "load_office",
    "load_scene",
    "load_sideview",
    "load_sideview_scene",
    "load_tabletop",
    "load_warehouse",
    "push_box",
    "register_world",
    "run_skills",
    "sample_office_scenes",
    "scan_views",
    "simulate_push",
    "simulate_sideview",
    "world_kind",
    "world_kinds",
]
