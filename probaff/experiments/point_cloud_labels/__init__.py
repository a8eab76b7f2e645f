"""The chapter 2 study: affordance labels of office segments, Algorithm 1 and multi-view merge.

Modules:
    config: `PointCloudStudyConfig`, the thesis's data set, the smoke sizes.
    scans: one scene scan and one merge scan (the study's tasks), and their arrays.
    oracle: the oracle object segments of a view and the segments' under/over-segmentation.
    comparison: the thesis's logistic regressions against the new model, by CV.
    causes: the baseline's labelling errors attributed to causes.
    intervals: precision and recall with 95 % scene-bootstrap intervals.
    model_report: the model table and the error breakdown.
    truth_figure: one scene's labels against the ground truth.
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
