"""Features computed from data.

Push features of chapters 4 (n = 631) and 5 (n = 101), interaction features of chapter 6
(n = 169) with their action-frame geometry and the push, pick and place rows built from them,
and per-voxel warehouse features of chapter 3. Each feature set states the dataset arrays and
``meta`` entries it reads (`FEATURE_REQUIREMENTS`) and refuses a dataset that lacks one, naming
it.
"""

from probaff.features.action_frame import (
    action_frame,
    apply_effect,
    box_surface,
    effect_in_action_frame,
    planar_pose_from_sideview,
    planar_pose_from_tabletop,
    sideview_transform,
    tabletop_transform,
)
from probaff.features.cells import HMP_SCALES, VoxelFeatures, cell_features
from probaff.features.ch4 import CONTEXT_CLASSES, TableGeometry, chapter4_features
from probaff.features.ch5 import chapter5_features
from probaff.features.ch6 import (
    INTERACTION_FEATURE_COUNT,
    INTERACTION_GROUPS,
    InteractionFeatureConfig,
    InteractionFeatures,
    interaction_features,
)
from probaff.features.ch6_pick import SIDEVIEW_EFFECT_COLUMNS, PickInteractions, pick_interactions
from probaff.features.ch6_place import TABLE_SLAB_THICKNESS, PlaceInteractions, place_interactions
from probaff.features.ch6_push import (
    PAIR_KINDS,
    PLANAR_EFFECT_COLUMNS,
    PushInteractions,
    push_interactions,
)
from probaff.features.ch6_scenes import (
    SCENE_EFFECT_NAMES,
    PushScenes,
    push_scenes,
    scene_effects,
    scene_feature_names,
    scene_features,
)
from probaff.features.chain_geometry import MOTION_COLUMNS, Ch6Geometry
from probaff.features.featureset import FeatureSet
from probaff.features.frames import directions_to_push_frame, points_to_push_frame
from probaff.features.requirements import FEATURE_REQUIREMENTS, Requirements, requirements

__all__ = [
    "CONTEXT_CLASSES",
    "FEATURE_REQUIREMENTS",
    "HMP_SCALES",
    "INTERACTION_FEATURE_COUNT",
    "INTERACTION_GROUPS",
    "MOTION_COLUMNS",
    "PAIR_KINDS",
    "PLANAR_EFFECT_COLUMNS",
    "SCENE_EFFECT_NAMES",
    "SIDEVIEW_EFFECT_COLUMNS",
    "TABLE_SLAB_THICKNESS",
    "Ch6Geometry",
    "FeatureSet",
    "InteractionFeatureConfig",
    "InteractionFeatures",
    "PickInteractions",
    "PlaceInteractions",
    "PushInteractions",
    "PushScenes",
    "Requirements",
    "TableGeometry",
    "VoxelFeatures",
    "action_frame",
    "apply_effect",
    "box_surface",
    "cell_features",
    "chapter4_features",
    "chapter5_features",
    "directions_to_push_frame",
    "effect_in_action_frame",
    "interaction_features",
    "pick_interactions",
    "place_interactions",
    "planar_pose_from_sideview",
    "planar_pose_from_tabletop",
    "points_to_push_frame",
    "push_interactions",
    "push_scenes",
    "requirements",
    "scene_effects",
    "scene_feature_names",
    "scene_features",
    "sideview_transform",
    "tabletop_transform",
]
