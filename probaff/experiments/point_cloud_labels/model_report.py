"""The chapter 2 study's model table and error breakdown, from `compare_models` results.

`model_rows` gives the rows of ``models.csv``: per segment set (all segments, and those of at
least ``min_points`` points), per model (the thesis's logistic regressions, the trees on the
same features, the new model, and the baseline on the oracle object segments) and per label,
the pooled precision and recall of the decisions (``p >= 0.5`` for the logistic regressions,
``p >=`` each fold model's own threshold for the trees, `BoostingOptions.threshold`) with
their 95 % scene-bootstrap intervals, beside the thesis's Table 2.2. `cause_rows` gives those
of ``causes.csv`` and `model_section` the summary's Markdown.
"""

from __future__ import annotations

from typing import Any

from probaff.eval.tables import markdown_table
from probaff.experiments.point_cloud_labels.causes import CAUSES
from probaff.experiments.point_cloud_labels.comparison import ModelComparison
from probaff.experiments.point_cloud_labels.intervals import interval_text
from probaff.perception.labels import THESIS_PR

__all__ = ["cause_rows", "model_rows", "model_section"]

_DESCRIPTIONS = {
    "thesis": "logistic regressions on the 25 features (the thesis's, reproduced)",
    "capacity": "calibrated gradient-boosted trees on the 25 features",
    "new": "calibrated gradient-boosted trees on the 25 features + 23 context descriptors",
    "whole_object": "logistic regressions on the 25 features of the oracle object segments",
}

_MODEL_COLUMNS = [
    "min_points",
    "model",
    "label",
    "precision_pct",
    "precision_lo",
    "precision_hi",
    "recall_pct",
    "recall_lo",
    "recall_hi",
    "thesis_precision_pct",
    "thesis_recall_pct",
]

_CAUSE_COLUMNS = [
    "min_points",
    "label",
    "segments",
    "tp",
    "fp",
    "fn",
    "tn",
    "errors",
    *(f"{c}_pct" for c in CAUSES),
]


def model_rows(comparisons: list[ModelComparison]) -> list[dict[str, Any]]:
    """Rows of ``models.csv``: per comparison, model and label (and ``"average"``)."""
    return [
        {
            "min_points": c.min_points,
            "model": model,
            **row,
            "thesis_precision_pct": THESIS_PR[row["label"]][0],
            "thesis_recall_pct": THESIS_PR[row["label"]][1],
        }
        for c in comparisons
        for model, rows in c.scores.items()
        for row in rows
    ]


def cause_rows(comparisons: list[ModelComparison]) -> list[dict[str, Any]]:
    """Rows of ``causes.csv``: the baseline's confusion and error causes per comparison."""
    return [{"min_points": c.min_points, **row} for c in comparisons for row in c.breakdown]


def model_section(comparisons: list[ModelComparison], n_scenes: int) -> str:
    """The summary's Markdown for the models and the breakdown.

    Args:
        comparisons: `compare_models` results (all segments first).
        n_scenes: The scenes they cover.

    Returns:
        Markdown: a compact P / R table per segment set (cells ``P [lo, hi] / R [lo, hi]``,
        percent), the models' descriptions and the cause breakdown.
    """
    md = [
        "## Models past the thesis (out-of-fold decisions)",
        "",
        f"{n_scenes} scenes, CV by scene; cells: precision [95 % interval] / recall [95 % "
        "interval], percent, pooled over segments, intervals from 2000 scene bootstrap draws. "
        "Decisions: p >= 0.5 for the logistic regressions; the trees' thresholds are chosen "
        "per label and fold on the training scenes only (inner CV by scene, "
        "`BoostingOptions.threshold`). Models:",
        "",
        *(f"- `{name}`: {text}" for name, text in _DESCRIPTIONS.items()),
        "",
        "`whole_object` runs on other segments (one per object and view) and is the oracle "
        "of the breakdown, not a rival model.",
        "",
    ]
    for c in comparisons:
        models = list(c.scores)
        labels = [r["label"] for r in c.scores[models[0]]]
        rows = []
        for k, label in enumerate(labels):
            row: dict[str, Any] = {"label": label}
            for model in models:
                row[model] = interval_text(c.scores[model][k])
            row["thesis_table_2_2"] = f"{THESIS_PR[label][0]} / {THESIS_PR[label][1]}"
            rows.append(row)
        subset = "all segments" if not c.min_points else f"segments of >= {c.min_points} points"
        md += [
            f"### {subset} ({len(c.labels)} segments)",
            "",
            markdown_table(rows, ["label", *models, "thesis_table_2_2"]),
            "",
        ]
    md += [
        "## Where the baseline's errors come from",
        "",
        "Each wrong (segment, label) decision of the thesis's logistic regressions goes to the "
        "first cause that explains it: `under_segmentation` (the segment mixes objects that "
        "disagree on the label), `over_segmentation` (a fragment of its object whose whole "
        "object the same features and classifier label right), `classifier_capacity` (the "
        "trees on the same features get it right), `features` (the trees get it right with "
        "the context descriptors), `label_rules` (the residual: what the segment's "
        "description does not show). `tp` .. `tn`: the baseline's confusion; cause columns: "
        "percent of its errors.",
        "",
        markdown_table(cause_rows(comparisons), _CAUSE_COLUMNS, digits=1),
        "",
    ]
    return "\n".join(md)
