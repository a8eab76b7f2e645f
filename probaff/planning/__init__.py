"""The chapter 3 agent: it pushes boxes to confirm affordances and refine an affordance map.

`probaff.maps` is the factor-graph library (the MRF, its inference and entropies); this
package is the robot built on it, with perception, learning and simulation:

Modules:
    classifier: per-cell affordance classifier from voxel features, and its evaluation.
    info_gain: candidate pushes scored by expected entropy reduction against travel; it takes
        travel distances as an array and needs no perception.
    manipulation_loop: the manipulation loop (information gain or exhaustive) on one map,
        change detection of pushes (`VerifiedPush`) and travel distances on the belief grid.
"""

from probaff.maps.options import DEFAULT_ALPHA, MRFParams, check_alpha
from probaff.planning.classifier import (
    AffordanceClassifier,
    AffordanceEvaluation,
    VoxelDataset,
    collect_voxels,
    evaluate,
)
from probaff.planning.info_gain import (
    PushCandidate,
    PushCandidates,
    PushPlan,
    candidate_pushes,
    expected_entropies,
    plan_pushes,
)
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

__all__ = [
    "DEFAULT_ALPHA",
    "POLICIES",
    "UNKNOWN_PRIOR",
    "AffordanceClassifier",
    "AffordanceEvaluation",
    "LoopResult",
    "LoopSnapshot",
    "LoopStep",
    "MRFParams",
    "ManipulationLoop",
    "PushCandidate",
    "PushCandidates",
    "PushPlan",
    "VerifiedPush",
    "VoxelDataset",
    "candidate_pushes",
    "check_alpha",
    "cloud_distance",
    "collect_voxels",
    "detect_push",
    "evaluate",
    "expected_entropies",
    "plan_pushes",
    "plan_pushes_on_grid",
    "predict_unary",
    "travel_distances",
]
