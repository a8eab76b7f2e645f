"""Acting on what was learned: affordance maps (chapter 3) and push planners (chapters 4, 5).

The chapter 3 agent refines affordance maps by pushing; the planners of chapters 4 and 5 use
the learned push models.

`probaff.maps` is the factor-graph library (the MRF, its inference and entropies) and
`probaff.models` the push models; this package is the robot built on them, with perception,
learning and simulation:

Modules:
    classifier: per-cell affordance classifier from voxel features, and its evaluation.
    info_gain: candidate pushes scored by expected entropy reduction against travel; it takes
        travel distances as an array and needs no perception.
    manipulation_loop: the manipulation loop (information gain or exhaustive) on one map,
        change detection of pushes (`VerifiedPush`) and travel distances on the belief grid.
    learned: a fitted push model with the features it reads (`FeaturePushModel`), and
        pushing-frame effects back to world poses (`apply_effects`).
    edge_task: chapter 4's push-to-edge task: goal, fall and collision geometry, candidate
        pushes, episode starts.
    edge_transitions: the planner's models of a push (learned, simulator, quasi-static) and
        the arm's push reachability.
    edge_planner: A* over push transitions and the greedy one-step planner.
    edge_episode: one closed-loop episode in the simulator, with replanning.
    edge_models: the learned models the push-to-edge planners compare.
    tool_push: chapter 5's two-step tool push: the receiving arm's reachable region,
        candidate pushes of the tool, the two-step, single-push and random planners, trials.

The planning study is `probaff.studies.planning` (`run`, `PlanningStudyConfig`), also reachable
here as `probaff.planning.run`.
"""

from typing import Any

from probaff.maps.options import DEFAULT_ALPHA, MRFParams, check_alpha
from probaff.planning.classifier import (
    AffordanceClassifier,
    AffordanceEvaluation,
    VoxelDataset,
    collect_voxels,
    evaluate,
)
from probaff.planning.edge_episode import EDGE_SEARCHES, EdgeEpisode, EdgeStep, run_edge_episode
from probaff.planning.edge_models import EDGE_MODELS, EdgeModelSpec, fit_edge_model
from probaff.planning.edge_planner import EdgePlan, plan_astar, plan_greedy
from probaff.planning.edge_task import (
    EdgeTask,
    RiskBounds,
    SearchOptions,
    load_edge_task,
    sample_episode,
)
from probaff.planning.edge_transitions import (
    EdgeTransition,
    LearnedTransition,
    PushReachability,
    QuasiStaticTransition,
    SimulatorTransition,
    TransitionPrediction,
)
from probaff.planning.info_gain import (
    PushCandidate,
    PushCandidates,
    PushPlan,
    candidate_pushes,
    expected_entropies,
    plan_pushes,
)
from probaff.planning.learned import FEATURE_FUNCTIONS, FeaturePushModel, apply_effects
from probaff.planning.manipulation_loop import (
    POLICIES,
    UNKNOWN_PRIOR,
    LoopResult,
    LoopSnapshot,
    LoopStep,
    ManipulationLoop,
    VerifiedPush,
    cloud_distance,
    detect_push,
    plan_pushes_on_grid,
    predict_unary,
    travel_distances,
)
from probaff.planning.tool_push import (
    TOOL_PUSH_PLANNERS,
    ModelTransition,
    ReachableRegion,
    SimTransition,
    ToolPushCandidates,
    ToolPushConfig,
    ToolPushPlan,
    ToolPushState,
    ToolPushTrial,
    TransitionModel,
    draw_tool_push_episode,
    fit_tool_push_model,
    plan_random_push,
    plan_single_push,
    plan_tool_push,
    reachable_region,
    run_tool_push_trial,
    sample_tool_pushes,
    tool_push_scores,
)

__all__ = [
    "DEFAULT_ALPHA",
    "EDGE_MODELS",
    "EDGE_SEARCHES",
    "FEATURE_FUNCTIONS",
    "POLICIES",
    "TOOL_PUSH_PLANNERS",
    "UNKNOWN_PRIOR",
    "AffordanceClassifier",
    "AffordanceEvaluation",
    "EdgeEpisode",
    "EdgeModelSpec",
    "EdgePlan",
    "EdgeStep",
    "EdgeTask",
    "EdgeTransition",
    "FeaturePushModel",
    "LearnedTransition",
    "LoopResult",
    "LoopSnapshot",
    "LoopStep",
    "MRFParams",
    "ManipulationLoop",
    "ModelTransition",
    "PlanningStudyConfig",
    "PushCandidate",
    "PushCandidates",
    "PushPlan",
    "PushReachability",
    "QuasiStaticTransition",
    "ReachableRegion",
    "RiskBounds",
    "SearchOptions",
    "SimTransition",
    "SimulatorTransition",
    "ToolPushCandidates",
    "ToolPushConfig",
    "ToolPushPlan",
    "ToolPushState",
    "ToolPushTrial",
    "TransitionModel",
    "TransitionPrediction",
    "VerifiedPush",
    "VoxelDataset",
    "apply_effects",
    "candidate_pushes",
    "check_alpha",
    "cloud_distance",
    "collect_voxels",
    "detect_push",
    "draw_tool_push_episode",
    "evaluate",
    "expected_entropies",
    "fit_edge_model",
    "fit_tool_push_model",
    "load_edge_task",
    "plan_astar",
    "plan_greedy",
    "plan_pushes",
    "plan_pushes_on_grid",
    "plan_random_push",
    "plan_single_push",
    "plan_tool_push",
    "predict_unary",
    "reachable_region",
    "run",
    "run_edge_episode",
    "run_tool_push_trial",
    "sample_episode",
    "sample_tool_pushes",
    "tool_push_scores",
    "travel_distances",
]


def __getattr__(name: str) -> Any:
    """The planning study's `run` and `PlanningStudyConfig`, imported when first used."""
    if name in ("run", "PlanningStudyConfig"):
        from probaff.studies import planning as study

        return getattr(study, name)
    raise AttributeError(f"module 'probaff.planning' has no attribute {name!r}")
