"""Chapter 3's manipulation loop: push boxes to confirm affordances and refine the map.

Modules:
    classifier: per-cell affordance classifier from voxel features, and its evaluation.
    info_gain: candidate pushes scored by expected entropy reduction against travel; it takes
        travel distances as an array and needs no perception.
    change_detection: whether a pushed box moved, from the observed cloud against two
        predicted scans (`VerifiedPush`).
    loop: the manipulation loop (information gain or exhaustive) on one map, and travel
        distances on the belief grid.
"""

from probaff.planning.manipulation.change_detection import (
    VerifiedPush,
    cloud_distance,
    detect_push,
)
from probaff.planning.manipulation.classifier import (
    AffordanceClassifier,
    AffordanceEvaluation,
    VoxelDataset,
    collect_voxels,
    evaluate,
)
from probaff.planning.manipulation.info_gain import (
    PushCandidate,
    PushCandidates,
    PushPlan,
    candidate_pushes,
    expected_entropies,
    plan_pushes,
)
from probaff.planning.manipulation.loop import (
    POLICIES,
    UNKNOWN_PRIOR,
    LoopResult,
    LoopSnapshot,
    LoopStep,
    ManipulationLoop,
    plan_pushes_on_grid,
    predict_unary,
    travel_distances,
)

__all__ = [
    "POLICIES",
    "UNKNOWN_PRIOR",
    "AffordanceClassifier",
    "AffordanceEvaluation",
    "LoopResult",
    "LoopSnapshot",
    "LoopStep",
    "ManipulationLoop",
    "PushCandidate",
    "PushCandidates",
    "PushPlan",
    "VerifiedPush",
    "VoxelDataset",
    "candidate_pushes",
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
