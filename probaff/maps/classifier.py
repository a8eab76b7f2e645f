"""Deprecated: the affordance classifier moved to `probaff.planning.classifier`.

Importing this module raises a `DeprecationWarning`.
"""

from probaff.maps._deprecated import warn_moved_module

warn_moved_module("probaff.maps.classifier", "probaff.planning.classifier")

from probaff.planning.classifier import (  # noqa: E402
    AffordanceClassifier,
    AffordanceEvaluation,
    VoxelDataset,
    collect_voxels,
    evaluate,
)

__all__ = [
    "AffordanceClassifier",
    "AffordanceEvaluation",
    "VoxelDataset",
    "collect_voxels",
    "evaluate",
]
