"""Simulated robot: the URDF arm (pytorch-kinematics), pymunk worlds, skills and sensors."""

from probaff.sim.arm import (
    Arm,
    IKResult,
    PathIK,
    PushPathIK,
    load_arm,
    sideview_pose,
    topdown_pose,
)
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
from probaff.sim.sideview import SideViewRun, SideViewScene, simulate_rest, simulate_sideview
from probaff.sim.sideview_config import (
    SideViewSceneSpec,
    SideViewSpec,
    list_sideview_scenes,
    load_sideview,
    load_sideview_scene,
)
from probaff.sim.skills import (
    SkillOutcome,
    SkillPlan,
    pick,
    place,
    plan_skills,
    run_sampled,
    run_skills,
    sample_sideview_scenes,
    simulate_skill,
)
from probaff.sim.tabletop import PushOutcome, SceneInstance, simulate_push

__all__ = [
    "Arm",
    "IKResult",
    "ObjectSpec",
    "PathIK",
    "PushOutcome",
    "PushPathIK",
    "PushSample",
    "PushSimulator",
    "Scan",
    "SceneInstance",
    "SceneSpec",
    "SideViewRun",
    "SideViewScene",
    "SideViewSceneSpec",
    "SideViewSpec",
    "SkillOutcome",
    "SkillPlan",
    "TabletopSpec",
    "list_scenes",
    "list_sideview_scenes",
    "load_arm",
    "load_catalogue",
    "load_scene",
    "load_sideview",
    "load_sideview_scene",
    "load_tabletop",
    "object_cloud",
    "pick",
    "place",
    "plan_skills",
    "push_frame_effect",
    "run_sampled",
    "run_skills",
    "sample_scene",
    "sample_sideview_scenes",
    "scan_scene",
    "sideview_pose",
    "simulate_push",
    "simulate_rest",
    "simulate_sideview",
    "simulate_skill",
    "straight_path",
    "table_cloud",
    "to_push_frame",
    "topdown_pose",
    "trapezoid_progress",
    "worlds_dir",
]
