"""Perception: the warehouse's occupancy and exploration (ch. 3), point-cloud labels (ch. 2).

Modules:
    occupancy: a free/occupied/unknown grid of the floor from the depth sensor's rays.
    exploration: the robot explores a map until no reachable frontier remains.
    normals: k-nearest-neighbour PCA normals and curvature of a point cloud.
    region_growing: PCL-style region-growing segmentation.
    segment_features: the 25 geometric features of each segment.
    segment_context: support, load, free space and contact-group descriptors of segments.
    labels: six per-label logistic regressions, cross-validated by scene.
    label_boosting: calibrated gradient-boosted trees per label.
    scan_labels: one office scene scanned from the robot's head to labelled segments.
    open3d_backend: Open3D's normals, neighbours, DBSCAN and ray casting, for comparison.
    refinement: Algorithm 1, iterative 2-means entropy minimisation of label vectors.
    merge: merging the segments of several views.
"""

from probaff.perception.exploration import Exploration, explore, grid_distances
from probaff.perception.label_boosting import BoostedLabelClassifier, BoostingOptions
from probaff.perception.labels import (
    THESIS_PR,
    LabelClassifier,
    LabelCVResult,
    Reliability,
    cross_validate_labels,
    reliability,
)
from probaff.perception.merge import PROXIMITIES, MergedSegments, MergeView, merge_views
from probaff.perception.normals import Normals, estimate_normals
from probaff.perception.occupancy import FREE_SPACE, OCCUPIED, UNKNOWN, OccupancyGrid
from probaff.perception.refinement import (
    SplitNode,
    SplitTree,
    label_entropy,
    purity_completeness,
    refine_segments,
)
from probaff.perception.region_growing import Segmentation, region_growing
from probaff.perception.scan_labels import PerceptionConfig, ScanSegments, head_pose, scan_segments
from probaff.perception.segment_features import FEATURE_NAMES, SegmentFeatures, segment_features

__all__ = [
    "FEATURE_NAMES",
    "FREE_SPACE",
    "OCCUPIED",
    "PROXIMITIES",
    "THESIS_PR",
    "UNKNOWN",
    "BoostedLabelClassifier",
    "BoostingOptions",
    "Exploration",
    "LabelCVResult",
    "LabelClassifier",
    "MergeView",
    "MergedSegments",
    "Normals",
    "OccupancyGrid",
    "PerceptionConfig",
    "Reliability",
    "ScanSegments",
    "SegmentFeatures",
    "Segmentation",
    "SplitNode",
    "SplitTree",
    "cross_validate_labels",
    "estimate_normals",
    "explore",
    "grid_distances",
    "head_pose",
    "label_entropy",
    "merge_views",
    "purity_completeness",
    "refine_segments",
    "region_growing",
    "reliability",
    "scan_segments",
    "segment_features",
]
