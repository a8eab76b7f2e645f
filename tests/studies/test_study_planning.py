"""The planning study runs end to end on a shrunken configuration, resumes, and its summary
counts what the episodes did."""

import json
import subprocess
import sys
from pathlib import Path

import pytest

from probaff.errors import InputError
from probaff.studies.planning import (
    PlanningStudyConfig,
    attribute_failures,
    run,
    summarise,
    trial_seed,
)

pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[2]


def test_script_smoke_and_resume(tmp_path):
    out = tmp_path / "plan"
    cmd = [sys.executable, str(ROOT / "inference/planning.py"), "--smoke", "--out", str(out)]
    proc = subprocess.run(cmd, capture_output=True, text=True, check=True)
    files = json.loads(proc.stdout)["files"]
    for name in ("edge_summary.csv", "summary.md", "edge_success.png", "edge_pushes.png"):
        assert str(out / name) in files and (out / name).stat().st_size > 0
    assert (out / "edge_episodes.png").stat().st_size > 0
    text = (out / "summary.md").read_text()
    assert "| astar-moe | 2 |" in text and "thesis" in text
    tasks = sorted((out / "tasks").glob("*.json"))
    assert len(tasks) == 2 * 4 + 1 * 2  # push-to-edge episodes, then tool-push trials
    records = [json.loads(p.read_text()) for p in tasks if p.name.startswith("edge.")]
    assert "## Two-step tool push" in text and "| two_step | 1 |" in text
    assert (out / "tool_summary.csv").stat().st_size > 0
    tool = [json.loads(p.read_text()) for p in tasks if p.name.startswith("tool.")]
    assert {r["planner"] for r in tool} == {"random", "two_step"}
    assert len({json.dumps(r["initial"]) for r in tool}) == 1  # the same start for both
    assert {r["planner"] for r in records} == {
        "astar-moe",
        "astar-risk-moe",
        "astar-quasistatic",
        "greedy-moe",
    }
    # every planner gets the same two starts
    starts = {(r["trial"], json.dumps(r["start"])) for r in records}
    assert len(starts) == 2
    stamp = [p.stat().st_mtime_ns for p in tasks]
    models = sorted((out / "models").glob("*.pt"))
    model_stamp = [p.stat().st_mtime_ns for p in models]
    subprocess.run(cmd, capture_output=True, text=True, check=True)  # resumes: no reruns
    assert [p.stat().st_mtime_ns for p in tasks] == stamp
    assert [p.stat().st_mtime_ns for p in models] == model_stamp


def test_summary_counts_and_intervals():
    def rec(planner, success, pushes, errors):
        steps = [{"error": e} for e in errors]
        return {
            "planner": planner,
            "success": success,
            "outcome": "success" if success else "fell",
            "pushes": pushes,
            "replans": 1,
            "steps": steps,
            "planning_seconds": [0.5, 1.5],
        }

    rows = summarise(
        [rec("a", True, 3, [0.01, 0.03]), rec("a", False, 2, [0.05]), rec("b", True, 4, [])]
    )
    a, b = rows
    assert (a["trials"], a["successes"], a["n_fell"]) == (2, 1, 1)
    assert a["success_low"] < 0.5 < a["success_high"]
    assert a["error_cm"] == pytest.approx(3.0) and a["pushes_success"] == 3
    assert a["plan_seconds"] == pytest.approx(1.0) and a["plan_seconds_max"] == 1.5
    assert b["success_rate"] == 1.0 and b["success_high"] == 1.0


def test_failures_are_blamed_on_the_model_only_where_the_simulator_succeeded():
    def rec(planner, trial, success, outcome="success", error=0.01):
        return {
            "planner": planner,
            "trial": trial,
            "success": success,
            "outcome": outcome,
            "steps": [{"error": error}],
        }

    records = [
        rec("astar-sim", 0, True),
        rec("astar-sim", 1, False, "budget"),
        rec("astar-sim", 2, True),
        rec("astar-gp", 0, False, "fell", 0.08),
        rec("astar-gp", 1, False, "budget", 0.02),
        rec("astar-gp", 2, True, error=0.02),
    ]
    (row,) = attribute_failures(records)
    assert (row["failures"], row["model_failures"], row["search_failures"]) == (2, 1, 1)
    assert row["model_fell"] == 1 and row["model_budget"] == 0
    assert row["error_cm_failed"] == pytest.approx(5.0)
    assert row["error_cm_succeeded"] == pytest.approx(2.0)
    assert attribute_failures([rec("astar-gp", 0, True)]) == []


def test_trial_seeds_are_shared_and_distinct():
    assert trial_seed(0, 3) == trial_seed(0, 3)
    assert len({trial_seed(0, t) for t in range(50)}) == 50


def test_bad_config():
    with pytest.raises(InputError, match="unknown or no planners"):
        run(PlanningStudyConfig(planners=("astar-lstm",)))
    with pytest.raises(InputError, match="trials must be a positive integer, got 0"):
        run(PlanningStudyConfig(trials=0))
    with pytest.raises(InputError, match="train_pushes must be at least 10"):
        run(PlanningStudyConfig(train_pushes=5))
