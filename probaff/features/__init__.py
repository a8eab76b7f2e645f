"""Push features computed from datasets: chapter 4 (n = 631) and chapter 5 (n = 101)."""

from probaff.features.ch4 import CONTEXT_CLASSES, TableGeometry, chapter4_features
from probaff.features.ch5 import chapter5_features
from probaff.features.featureset import FeatureSet
from probaff.features.frames import directions_to_push_frame, points_to_push_frame

__all__ = [
    "CONTEXT_CLASSES",
    "FeatureSet",
    "TableGeometry",
    "chapter4_features",
    "chapter5_features",
    "directions_to_push_frame",
    "points_to_push_frame",
]
