"""Simulated robot: the URDF arm (pytorch-kinematics), pymunk worlds, skills and sensors."""

from probaff.sim.arm import Arm, IKResult, PushPathIK, load_arm, topdown_pose
from probaff.sim.config import (
    ObjectSpec,
    SceneSpec,
    TabletopSpec,
    list_scenes,
    load_catalogue,
    load_scene,
    load_tabletop,
    worlds_dir,
)
from probaff.sim.geometry import push_frame_effect, to_push_frame
from probaff.sim.runner import PushSample, PushSimulator, straight_path, trapezoid_progress
from probaff.sim.sampling import sample_scene
from probaff.sim.sensing import Scan, object_cloud, scan_scene, table_cloud
from probaff.sim.tabletop import PushOutcome, SceneInstance, simulate_push

__all__ = [
    "Arm",
    "IKResult",
    "ObjectSpec",
    "PushOutcome",
    "PushPathIK",
    "PushSample",
    "PushSimulator",
    "Scan",
    "SceneInstance",
    "SceneSpec",
    "TabletopSpec",
    "list_scenes",
    "load_arm",
    "load_catalogue",
    "load_scene",
    "load_tabletop",
    "object_cloud",
    "push_frame_effect",
    "sample_scene",
    "scan_scene",
    "simulate_push",
    "straight_path",
    "table_cloud",
    "to_push_frame",
    "topdown_pose",
    "trapezoid_progress",
    "worlds_dir",
]
