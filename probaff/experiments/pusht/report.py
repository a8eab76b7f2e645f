"""Tables and summary of the Push-T study: models against data, planners against the target.

`model_rows` orders the held-out scores, `planner_rows` gives one row per planner scored as
LeRobot scores (`probaff.experiments.pusht.scoring.score`: the observation it planned from,
success rate with its 95 % Wilson interval, mean maximum reward in the environment's own reward
and the raw mean maximum coverage beside it) with pushes, control steps and prediction error,
`timing_rows` the planning time per push of each planner (a measurement, which differs run to
run, kept apart from the results), `curve_rows` the learned-model planner's success and reward
at every training size, and `summary_lines` the Markdown summary: the goal (LeRobot's diffusion
policy, 63.8 % success and 0.959 mean maximum reward from ``pixels_agent_pos``) as a row of
the same table, where the learned-model planner stands in those units, and whether a shortfall
is its model's or its search's (the planner over the environment itself, on the same episodes).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from probaff.eval.tables import group_rows, markdown_table
from probaff.experiments.pusht.config import PushTStudyConfig
from probaff.experiments.pusht.scoring import DIFFUSION_POLICY, reference_row, score

__all__ = ["blame", "curve_rows", "model_rows", "planner_rows", "summary_lines", "timing_rows"]

_MODEL_COLUMNS = [
    "model",
    "train_pushes",
    "rmse_y",
    "rmse_z",
    "rmse_theta",
    "nlpd",
    "coverage90",
]
_SCORE_COLUMNS = [
    "episodes",
    "successes",
    "success_rate",
    "success_low",
    "success_high",
    "max_reward",
    "max_coverage",
]
_PLANNER_COLUMNS = [
    "planner",
    "observation",
    *_SCORE_COLUMNS,
    "pushes",
    "steps",
    "error_px",
]
_CURVE_COLUMNS = ["train_pushes", "observation", *_SCORE_COLUMNS]


def model_rows(scored: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """The held-out scores, by model then training size."""
    order = {"moe": 0, "gp": 1, "analytic": 2}
    return sorted(scored, key=lambda r: (order.get(r["model"], 9), r["train_pushes"]))


def planner_rows(records: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """One row per planner, in the order planners first appear.

    Args:
        records: Episode records (`probaff.experiments.pusht.planner.run_episode` with
            ``planner``).

    Returns:
        Rows with `_PLANNER_COLUMNS`: the observation planned from (gym-pusht's ``obs_type``),
        success with its 95 % Wilson interval, the mean maximum reward (the environment's own,
        LeRobot's ``avg_max_reward``) and coverage, and the means of pushes, control steps and
        the distance (px) between predicted and executed vertices. The means are over the
        episodes in the order of `records`, so the same records give the same rows to the
        last bit.
    """
    rows = []
    for planner, rs in group_rows(records, "planner").items():
        errors = [r["error_px"] for r in rs if np.isfinite(r["error_px"])]
        rows.append(
            {
                "planner": planner,
                **score(rs),
                "pushes": float(np.mean([r["pushes"] for r in rs])),
                "steps": float(np.mean([r["steps"] for r in rs])),
                "error_px": float(np.mean(errors)) if errors else float("nan"),
            }
        )
    return rows


def timing_rows(records: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """Planning time of each planner: a measurement of this machine, unlike the results.

    Args:
        records: Episode records with ``planner`` and ``plan_seconds`` (NaN where unknown).

    Returns:
        Rows ``planner``, ``episodes``, ``plan_seconds`` (mean over the episodes of their
        mean wall-clock seconds per push) and ``plan_seconds_max`` (the slowest episode's).
    """
    rows = []
    for planner, rs in group_rows(records, "planner").items():
        seconds = np.array([float(r["plan_seconds"]) for r in rs])
        known = seconds[np.isfinite(seconds)]
        rows.append(
            {
                "planner": planner,
                "episodes": len(rs),
                "plan_seconds": float(known.mean()) if known.size else math.nan,
                "plan_seconds_max": float(known.max()) if known.size else math.nan,
            }
        )
    return rows


def curve_rows(records: Sequence[dict[str, Any]]) -> list[dict[str, Any]]:
    """The learned-model planner's success (95 % Wilson intervals) and reward at each size."""
    by: dict[int, list[dict[str, Any]]] = {}
    for r in records:
        by.setdefault(int(r["train_pushes"]), []).append(r)
    return [{"train_pushes": n, **score(rs)} for n, rs in sorted(by.items())]


def blame(records: Sequence[dict[str, Any]], planner: str = "beam-moe") -> dict[str, int]:
    """Failures of `planner` on episodes the environment-as-model planner also ran.

    Returns:
        ``shared`` (episodes both ran), ``failures`` of `planner` among them, ``model`` (those
        the environment-as-model planner solved: the model's fault) and ``search`` (those it
        failed too: the search's, or the budget's).
    """
    env = {r["episode"]: bool(r["success"]) for r in records if r["planner"] == "beam-env"}
    mine = [r for r in records if r["planner"] == planner and r["episode"] in env]
    failed = [r for r in mine if not r["success"]]
    model = sum(env[r["episode"]] for r in failed)
    return {
        "shared": len(mine),
        "failures": len(failed),
        "model": model,
        "search": len(failed) - model,
    }


def _verdict(rows: Sequence[dict[str, Any]]) -> list[str]:
    mine = next((r for r in rows if r["planner"] == "beam-moe"), None)
    if mine is None:
        return []
    ref = DIFFUSION_POLICY
    above = mine["success_low"] > ref.success_rate
    reward = mine["max_reward"] > ref.avg_max_reward
    return [
        f"The learned-model planner (beam-moe, from {mine['observation']}) succeeds in "
        f"{mine['successes']}/{mine['episodes']} episodes ({100 * mine['success_rate']:.1f} %, "
        f"95 % interval {100 * mine['success_low']:.1f}-{100 * mine['success_high']:.1f} %), "
        f"mean maximum reward {mine['max_reward']:.3f} (raw coverage "
        f"{mine['max_coverage']:.3f}). Goal, in the same units: interval above "
        f"{100 * ref.success_rate:.1f} % ({'met' if above else 'not met'}), mean maximum reward "
        f"above {ref.avg_max_reward} ({'met' if reward else 'not met'}).",
    ]


def summary_lines(
    config: PushTStudyConfig,
    models: Sequence[dict[str, Any]],
    planners: Sequence[dict[str, Any]],
    curve: Sequence[dict[str, Any]],
    records: Sequence[dict[str, Any]],
    moved: np.ndarray,
    perception: dict[str, int] | None = None,
) -> list[str]:
    """The study's Markdown summary.

    `perception`: for pushes recorded from pixels, the counts of resets lost, pushes dropped
    and frames flagged while recording them (`probaff.experiments.pusht.data.push_dataset`'s
    ``meta["perception"]``).
    """
    b = blame(records)
    table = [*planners, dict.fromkeys(_PLANNER_COLUMNS, math.nan) | reference_row()]
    lines = [
        "# Push-T: learned push models and a planner in gym-pusht 0.1.8",
        "",
        f"Goal ({DIFFUSION_POLICY.name}, {DIFFUSION_POLICY.episodes} episodes from "
        f"{DIFFUSION_POLICY.observation}): success {100 * DIFFUSION_POLICY.success_rate:.1f} %, "
        f"mean maximum reward {DIFFUSION_POLICY.avg_max_reward}. Scored in the same units: the "
        "environment's own reward, min(coverage / 0.95, 1), its maximum in each episode "
        f"averaged (`max_reward`), the raw coverage beside it. Episodes reset with seeds "
        f"{config.seed}.. (the same for every planner); the environment's own rule (coverage "
        "> 95 %) and limit (300 control steps).",
        "",
        *_verdict(planners),
        "",
        "## Planners",
        "",
        markdown_table(table, _PLANNER_COLUMNS, digits=3),
        "`observation`: what each planner observed, in gym-pusht's `obs_type` names (`state`: "
        "the block's exact pose; `pixels_agent_pos`: the 96 x 96 image and the agent's "
        "position). The last row is the published goal (its interval: Wilson's for its rate; "
        "its coverage is not published). `max_reward`: mean maximum reward (LeRobot's "
        "`avg_max_reward`); `max_coverage`: mean maximum raw coverage. "
        "`error_px`: mean distance (px) of the T's executed from its predicted vertices. "
        "Planning time per push, a measurement of this machine that differs from run to run, "
        "is in timings.csv.",
        f"On the {b['shared']} episodes beam-env also ran, beam-moe failed {b['failures']}: "
        f"{b['model']} that the environment-as-model planner solved (the model's fault), "
        f"{b['search']} that it failed too (the search's or the budget's).",
        "",
        "## Models (held-out pushes)",
        "",
        markdown_table(models, _MODEL_COLUMNS, digits=3),
        "RMSE in px (dy_p across, dz_p along the push) and rad; NLPD in nats summed over the "
        "three effects; coverage of the central 90 % intervals, averaged over them.",
        "",
    ]
    if curve:
        lines += ["## Success against training pushes (beam-moe)", ""]
        lines += [markdown_table(curve, _CURVE_COLUMNS, digits=3)]
    if moved.size:
        lines.append(
            f"The block moved more than 1 px while the pusher went around it in "
            f"{100 * float((moved > 1).mean()):.1f} % of {moved.size} recorded pushes."
        )
    if config.observation == "pixels":
        counts = ", ".join(f"{k.replace('_', ' ')} {v}" for k, v in (perception or {}).items())
        lines.append(
            "The training and held-out pushes were recorded from pixels: every pose perceived "
            "from the 96 x 96 image, the state logged beside it for scoring only"
            + (f" ({counts})." if counts else ".")
        )
    return lines
