"""The chapter 2 study: affordance labels of office segments, Algorithm 1 and multi-view merge.

Modules:
    config: `PointCloudStudyConfig`, the thesis's data set, the smoke sizes.
    scans: one scene scan and one merge scan (the study's tasks), and their arrays.
    run: the scans as resumable tasks, the cross-validations, and `run`.
    report: the label, refinement and merge tables, and the summary.
    figures: clouds by segment and by label, the entropy tree, reliability, the merge.
    demo: a held-out scene, segmented, labelled and drawn (``probaff demo``).
"""

from probaff.experiments.point_cloud_labels.config import SMOKE, PointCloudStudyConfig
from probaff.experiments.point_cloud_labels.run import run

Config = PointCloudStudyConfig
"""The study's config class (the registry's name for it)."""

__all__ = ["SMOKE", "Config", "PointCloudStudyConfig", "run"]
