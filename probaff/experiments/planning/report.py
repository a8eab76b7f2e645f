"""Tables and summary of the planning study: success rates with their intervals, blame, means.

`summarise` gives one row per push-to-edge planner (success rate with its 95 % Wilson
interval, pushes and replans per trial, the mean one-step prediction error, planning time per
plan, outcomes), `attribute_failures` whether a planner's failures are its model's, and
`summarise_tool` one row per tool-push planner. `edge_section` and `tool_section` are the
summary's Markdown.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from probaff.eval.metrics import wilson_interval
from probaff.eval.tables import group_rows, markdown_table
from probaff.experiments.planning.config import THESIS_EDGE, PlanningStudyConfig

__all__ = [
    "attribute_failures",
    "edge_section",
    "summarise",
    "summarise_tool",
    "tool_section",
]

_RATE_COLUMNS = ["planner", "trials", "successes", "success_rate", "success_low", "success_high"]
_EDGE_COLUMNS = [
    *_RATE_COLUMNS,
    "pushes",
    "replans",
    "vetoes",
    "error_cm",
    "plan_seconds",
    "n_fell",
    "n_budget",
    "n_stuck",
]
_BLAME_COLUMNS = [
    "planner",
    "trials",
    "failures",
    "model_failures",
    "search_failures",
    "model_fell",
    "model_budget",
    "model_stuck",
    "error_cm_failed",
    "error_cm_succeeded",
]
_TOOL_COLUMNS = [*_RATE_COLUMNS, "depth_cm", "depth_sd_cm", "gain_cm", "plan_seconds"]


def _rate(planner: str, rs: list[dict[str, Any]], key: str) -> dict[str, Any]:
    """A planner's trials, successes (records whose `key` is true), rate and its interval.

    The interval is the 95 % Wilson interval of the success rate.
    """
    k = sum(bool(r[key]) for r in rs)
    lo, hi = wilson_interval(k, len(rs))
    return {
        "planner": planner,
        "trials": len(rs),
        "successes": k,
        "success_rate": k / len(rs),
        "success_low": lo,
        "success_high": hi,
    }


def summarise_tool(records: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """One row per tool-push planner: success with its interval, depth, planning time.

    Success is the target ending inside the reachable region (95 % Wilson interval); depth
    is its final signed distance into the region (cm).

    Args:
        records: Trial records (``planner``, ``reached``, ``final_depth``, ``initial_depth``,
            ``planning_time_s``).

    Returns:
        Rows with ``planner``, ``trials``, ``successes``, ``success_rate``, ``success_low``,
        ``success_high``, ``depth_cm`` and its standard deviation ``depth_sd_cm``,
        ``gain_cm`` (mean final minus initial depth) and ``plan_seconds``.
    """
    rows = []
    for planner, rs in group_rows(records, "planner").items():
        depth = 100 * np.array([r["final_depth"] for r in rs])
        start = 100 * np.array([r["initial_depth"] for r in rs])
        rows.append(
            {
                **_rate(planner, rs, "reached"),
                "depth_cm": float(depth.mean()),
                "depth_sd_cm": float(depth.std(ddof=1)) if len(rs) > 1 else 0.0,
                "gain_cm": float((depth - start).mean()),
                "plan_seconds": float(np.mean([r["planning_time_s"] for r in rs])),
            }
        )
    return rows


def summarise(records: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """One row per planner: success rate with its 95 % Wilson interval and the means.

    Args:
        records: Episode records (``planner`` keys).

    Returns:
        Rows with ``planner``, ``trials``, ``successes``, ``success_rate``, ``success_low``,
        ``success_high``, ``pushes`` (mean over trials), ``pushes_success`` (mean over
        successful trials), ``replans``, ``vetoes`` (pushes of kept plans refused from the
        book's pose then; 0 in records without them), ``error_cm`` (mean one-step prediction
        error), ``plan_seconds`` (mean per planning call), ``plan_seconds_max``, and the
        counts of each outcome.
    """
    rows = []
    for planner, rs in group_rows(records, "planner").items():
        errors = [s["error"] for r in rs for s in r["steps"]]
        plan_s = [t for r in rs for t in r["planning_seconds"]]
        ok = [r["pushes"] for r in rs if r["success"]]
        row: dict[str, Any] = {
            **_rate(planner, rs, "success"),
            "pushes": float(np.mean([r["pushes"] for r in rs])),
            "pushes_success": float(np.mean(ok)) if ok else math.nan,
            "replans": float(np.mean([r["replans"] for r in rs])),
            "vetoes": float(np.mean([r.get("vetoes", 0) for r in rs])),
            "error_cm": 100 * float(np.mean(errors)) if errors else math.nan,
            "plan_seconds": float(np.mean(plan_s)) if plan_s else math.nan,
            "plan_seconds_max": float(np.max(plan_s)) if plan_s else math.nan,
        }
        for outcome in ("success", "fell", "budget", "stuck"):
            row[f"n_{outcome}"] = sum(r["outcome"] == outcome for r in rs)
        rows.append(row)
    return rows


def attribute_failures(
    records: list[dict[str, Any]], reference: str = "astar-sim"
) -> list[dict[str, Any]]:
    """Whether a planner's failures are its model's: compare each trial with the reference.

    The reference planner (A* with the true simulator) plans with the same search on the same
    start; where it succeeds and a planner with a learned or analytic model fails, the model
    is to blame, not the search. Where both fail, the start is hard for the search itself.

    Args:
        records: Episode records of several planners (``planner``, ``trial``, ``success``,
            ``outcome``, ``steps``).
        reference: The planner whose results stand for the search with a perfect model.

    Returns:
        One row per other planner: ``failures``, ``model_failures`` (the reference succeeded
        on that start), ``search_failures`` (it failed too), the outcomes of the model
        failures, and ``error_cm_failed`` / ``error_cm_succeeded``, the mean one-step
        prediction errors over the failed and the successful trials. Empty if the reference
        did not run.
    """
    ref = {r["trial"]: r for r in records if r["planner"] == reference}
    if not ref:
        return []
    rows = []
    for planner in dict.fromkeys(r["planner"] for r in records):
        if planner == reference:
            continue
        rs = [r for r in records if r["planner"] == planner and r["trial"] in ref]
        failed = [r for r in rs if not r["success"]]
        model = [r for r in failed if ref[r["trial"]]["success"]]

        def err(group: list[dict[str, Any]]) -> float:
            e = [s["error"] for r in group for s in r["steps"]]
            return 100 * float(np.mean(e)) if e else math.nan

        row: dict[str, Any] = {
            "planner": planner,
            "trials": len(rs),
            "failures": len(failed),
            "model_failures": len(model),
            "search_failures": len(failed) - len(model),
            "error_cm_failed": err(failed),
            "error_cm_succeeded": err([r for r in rs if r["success"]]),
        }
        for outcome in ("fell", "budget", "stuck"):
            row[f"model_{outcome}"] = sum(r["outcome"] == outcome for r in model)
        rows.append(row)
    return rows


def _thesis_row() -> dict[str, Any]:
    t = THESIS_EDGE
    lo, hi = wilson_interval(int(t["successes"]), int(t["trials"]))
    return {
        "planner": "thesis (A*, hierarchical m=2)",
        "trials": t["trials"],
        "successes": t["successes"],
        "success_rate": t["successes"] / t["trials"],
        "success_low": lo,
        "success_high": hi,
        "pushes": t["pushes"],
        "replans": t["replans"],
        "error_cm": t["error_cm"],
        **dict.fromkeys(("vetoes", "plan_seconds", "n_fell", "n_budget", "n_stuck"), ""),
    }


def edge_section(
    config: PlanningStudyConfig,
    rows: list[dict[str, Any]],
    blame: list[dict[str, Any]],
    *,
    replan_distance: float,
) -> list[str]:
    """The summary's push-to-edge section: the planners' table beside the thesis's, blame.

    Args:
        config: The study's settings.
        rows: `summarise` rows.
        blame: `attribute_failures` rows (may be empty).
        replan_distance: The episodes' replanning distance (m).

    Returns:
        Markdown lines.
    """
    md = [
        "# Planning study",
        "",
        "## Push to the edge, then grasp (chapter 4)",
        "",
        f"{config.trials} seeded episodes per planner, the same starts for every planner; "
        f"models fitted on {config.train_pushes} pushes of the `push_to_edge` scene; an "
        f"episode replans when a push lands more than {100 * replan_distance:.1f} cm from "
        "its prediction (the thesis: 5 cm).",
        "",
        markdown_table([*rows, _thesis_row()], _EDGE_COLUMNS, digits=3),
        "",
        "`success_low`/`success_high`: 95 % Wilson interval. `pushes`, `replans`, `vetoes` "
        "(pushes of a kept plan refused from the book's pose then, each replanned): means per "
        "trial; `error_cm`: mean distance between the predicted and the executed book "
        "position after a push; `plan_seconds`: mean wall time per planning call.",
        "",
    ]
    if blame:
        md += [
            "Failures the model is to blame for: `model_failures` counts the starts on which "
            "A* with the true simulator succeeded (same search, same start) and this planner "
            "failed; `search_failures` those on which both failed.",
            "",
            markdown_table(blame, _BLAME_COLUMNS, digits=3),
            "",
        ]
    return md


def tool_section(config: PlanningStudyConfig, rows: list[dict[str, Any]]) -> list[str]:
    """The summary's tool-push section."""
    return [
        "## Two-step tool push (chapter 5)",
        "",
        f"{config.tool_trials} seeded trials per planner, the same starts for every planner; "
        f"chapter 5's mixture (M = 3, f_o & f_c) fitted on {config.tool_train_pushes} pushes "
        "of the `tool_push` scene.",
        "",
        markdown_table(rows, _TOOL_COLUMNS, digits=3),
        "",
        "`depth_cm`: the target's final signed distance into the reachable region "
        "(positive inside); `gain_cm`: final minus initial depth.",
        "",
    ]
