"""Features computed from data.

Push features of chapters 4 (n = 631) and 5 (n = 101), and per-voxel warehouse features of
chapter 3.
"""

from probaff.features.cells import HMP_SCALES, VoxelFeatures, cell_features
from probaff.features.ch4 import CONTEXT_CLASSES, TableGeometry, chapter4_features
from probaff.features.ch5 import chapter5_features
from probaff.features.featureset import FeatureSet
from probaff.features.frames import directions_to_push_frame, points_to_push_frame

__all__ = [
    "CONTEXT_CLASSES",
    "HMP_SCALES",
    "FeatureSet",
    "TableGeometry",
    "VoxelFeatures",
    "cell_features",
    "chapter4_features",
    "chapter5_features",
    "directions_to_push_frame",
    "points_to_push_frame",
]
