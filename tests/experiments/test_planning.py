"""The planning study runs end to end on a shrunken configuration, resumes, its summary counts
what the episodes did, and its figures draw what the records hold.

Covers probaff.experiments.planning.config, probaff.experiments.planning.demo,
probaff.experiments.planning.figures, probaff.experiments.planning.report,
probaff.experiments.planning.run.
"""

import copy
import json

import numpy as np
import pytest
import torch
from matplotlib.patches import Polygon
from study_helpers import (
    assert_resumes,
    assert_wrote,
    is_png,
    record_saved_figures,
    rerun_smoke,
    run_smoke,
)

import probaff.experiments.planning.figures as pf
from probaff.errors import InputError
from probaff.experiments.planning import PlanningStudyConfig, run
from probaff.experiments.planning.config import trial_seed
from probaff.experiments.planning.report import attribute_failures, summarise
from probaff.experiments.planning.run import edge_trial
from probaff.planning import (
    PushReachability,
    QuasiStaticTransition,
    load_edge_task,
    run_edge_episode,
)


@pytest.mark.slow
def test_script_smoke_and_resume(tmp_path):
    out = tmp_path / "plan"
    files = run_smoke("planning", out)
    assert_wrote(
        files, out, ("edge_summary.csv", "summary.md", "edge_success.png", "edge_pushes.png")
    )
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
    models = sorted((out / "models").glob("*.pt"))
    assert_resumes(lambda: rerun_smoke("planning", out), tasks + models)  # resumes: no reruns


@pytest.mark.slow
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


@pytest.mark.slow
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


@pytest.mark.slow
def test_trial_seeds_are_shared_and_distinct():
    assert trial_seed(0, 3) == trial_seed(0, 3)
    assert len({trial_seed(0, t) for t in range(50)}) == 50


@pytest.mark.slow
def test_bad_config():
    with pytest.raises(InputError, match="unknown or no planners"):
        run(PlanningStudyConfig(planners=("astar-lstm",)))
    with pytest.raises(InputError, match="trials must be a positive integer, got 0"):
        run(PlanningStudyConfig(trials=0))
    with pytest.raises(InputError, match="train_pushes must be at least 10"):
        run(PlanningStudyConfig(train_pushes=5))
    for bad in (0.0, -0.02, float("nan"), "2 cm", True):
        with pytest.raises(InputError, match="replan_distance must be a finite number > 0"):
            run(PlanningStudyConfig(replan_distance=bad))


@pytest.mark.slow
def test_an_episode_replans_by_the_study_s_distance():
    """The study's `replan_distance` replaces the task file's in every episode it runs."""
    seed = trial_seed(0, 1)

    def steps(distance):
        record = edge_trial("astar-quasistatic", 1, seed, False, models={}, **distance)
        return [(s["error"], s["replanned"], s["fell"]) for s in record["steps"]]

    default = steps({})
    eager, lazy = steps({"replan_distance": 1e-6}), steps({"replan_distance": 9.0})
    task = load_edge_task()
    assert default and all(r == (e > task.replan_distance and not f) for e, r, f in default)
    assert eager and all(r == (not f) for _, r, f in eager)
    assert lazy and not any(r for _, r, _ in lazy)


# --- figures


@pytest.fixture(scope="module")
def task():
    return load_edge_task()


@pytest.fixture(scope="module")
def episodes(task):
    """Two short real episodes: seed 2 gets stuck, seed 1 succeeds (quasi-static A*)."""
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        reach = PushReachability(task)
        eps = [
            run_edge_episode(task, QuasiStaticTransition(task), seed, reach=reach).to_dict()
            for seed in (2, 1)
        ]
    finally:
        torch.set_num_threads(threads)
    assert {e["success"] for e in eps} == {True, False}
    assert all(e["steps"] and e["steps"][0]["book_path"] for e in eps)
    return eps


@pytest.fixture
def saved(monkeypatch):
    """The figures the module saves, in order (the files are still written)."""
    return record_saved_figures(monkeypatch, pf)


def _rates():
    return [
        {
            "planner": "astar:moe",
            "success_rate": 0.8,
            "success_low": 0.55,
            "success_high": 0.93,
            "trials": 15,
        },
        {
            "planner": "greedy:moe",
            "success_rate": 0.4,
            "success_low": 0.2,
            "success_high": 0.64,
            "trials": 15,
        },
    ]


def test_edge_episodes_panels(tmp_path, task, episodes, saved):
    out = pf.plot_edge_episodes(episodes, task, tmp_path / "eps.png", title="two episodes")
    assert out == str(tmp_path / "eps.png")
    assert is_png(out)
    (fig,) = saved
    axes = [ax for ax in fig.axes if ax.axison]
    assert len(axes) == 2
    for ax, ep in zip(axes, episodes, strict=True):
        title = ax.get_title()
        assert f"seed {ep['seed']}" in title and ep["outcome"] in title
        assert ep["planner"] in title and f"{ep['pushes']} pushes" in title
        assert f"{ep['replans']} replans" in title
        assert ax.get_aspect() == 1.0
        lo, hi = ax.get_xlim()
        assert lo <= -0.5 and hi >= task.edge_x + task.grasp_depth
        # one hand-start arrow per executed push
        assert len(ax.texts) == len(ep["steps"])
    # the end footprint is green for the success and red for the failure
    ends = {}
    for ax, ep in zip(axes, episodes, strict=True):
        final = pf.box_corners(np.asarray(ep["final"]), task.book.size)
        (patch,) = [
            p
            for p in ax.patches
            if isinstance(p, Polygon) and np.allclose(p.get_xy()[:4], final, atol=1e-9)
        ]
        ends[ep["success"]] = patch.get_edgecolor()[:3]
    assert ends[True] != ends[False]
    assert fig.get_suptitle() == "two episodes"


def test_edge_episodes_without_trajectories_or_steps(tmp_path, task, episodes):
    eps = copy.deepcopy(episodes)
    for step in eps[0]["steps"]:
        step["book_path"] = []
    eps[1]["steps"], eps[1]["pushes"] = [], 0
    assert is_png(pf.plot_edge_episodes(eps, task, tmp_path / "chain.png"))


def test_edge_episodes_caps_panels(tmp_path, task, episodes, saved):
    pf.plot_edge_episodes(episodes * 4, task, tmp_path / "many.png", max_panels=6)
    (fig,) = saved
    assert sum(ax.axison for ax in fig.axes) == 6
    assert "first 6 of 8" in fig.get_suptitle()


def test_edge_episodes_bad_input(tmp_path, task, episodes):
    with pytest.raises(InputError, match="episodes is empty"):
        pf.plot_edge_episodes([], task, tmp_path / "x.png")
    no_steps = {k: v for k, v in episodes[0].items() if k != "steps"}
    with pytest.raises(InputError, match=r"episodes\[1\] lacks key\(s\) \['steps'\]"):
        pf.plot_edge_episodes([episodes[0], no_steps], task, tmp_path / "x.png")
    bad_step = copy.deepcopy(episodes[0])
    del bad_step["steps"][0]["origin"]
    with pytest.raises(InputError, match=r"\['steps'\]\[0\] lacks key\(s\) \['origin'\]"):
        pf.plot_edge_episodes([bad_step], task, tmp_path / "x.png")
    bad_start = dict(episodes[0], start=[[0.0, 0.0, 0.0]])
    with pytest.raises(InputError, match="start"):
        pf.plot_edge_episodes([bad_start], task, tmp_path / "x.png")
    with pytest.raises(InputError, match="EdgeTask"):
        pf.plot_edge_episodes(episodes, "push_to_edge", tmp_path / "x.png")
    with pytest.raises(InputError, match="sequence"):
        pf.plot_edge_episodes(episodes[0], task, tmp_path / "x.png")
    assert not (tmp_path / "x.png").exists()


def test_success_rates(tmp_path, saved):
    out = pf.plot_success_rates(
        _rates(), tmp_path / "rates.png", title="push to edge", reference=("thesis", 14 / 15)
    )
    assert is_png(out)
    (fig,) = saved
    (ax,) = fig.axes
    assert [t.get_text() for t in ax.get_yticklabels()] == ["astar:moe", "greedy:moe"]
    assert [t.get_text() for t in ax.texts] == ["12/15", "6/15"]
    ref = [line for line in ax.get_lines() if line.get_linestyle() == "--"]
    assert len(ref) == 1 and np.allclose(ref[0].get_xdata(), 100 * 14 / 15)
    assert ax.get_title() == "push to edge"


def test_success_rates_bad_input(tmp_path):
    with pytest.raises(InputError, match="rows is empty"):
        pf.plot_success_rates([], tmp_path / "x.png")
    rows = _rates()
    del rows[1]["trials"]
    with pytest.raises(InputError, match=r"rows\[1\] lacks key\(s\) \['trials'\]"):
        pf.plot_success_rates(rows, tmp_path / "x.png")
    percent = [dict(_rates()[0], success_rate=80.0, success_high=93.0)]
    with pytest.raises(InputError, match="fractions, not percent"):
        pf.plot_success_rates(percent, tmp_path / "x.png")
    with pytest.raises(InputError, match="reference rate"):
        pf.plot_success_rates(_rates(), tmp_path / "x.png", reference=("thesis", 93.3))
    assert not (tmp_path / "x.png").exists()


def test_pushes_per_trial(tmp_path, episodes, saved):
    failed = [dict(e, success=False) for e in episodes]
    out = pf.plot_pushes_per_trial(
        {"astar:quasi-static": episodes, "all failed": failed}, tmp_path / "pushes.png", title="t"
    )
    assert is_png(out)
    (fig,) = saved
    pushes, replans = fig.axes
    assert pushes.get_ylabel() == "pushes per trial" and replans.get_ylabel() == "replans per trial"
    labels = [t.get_text() for t in pushes.get_xticklabels()]
    assert labels == ["astar:quasi-static\n1/2 succeeded", "all failed\n0/2 succeeded"]
    # every trial is one point, in the panel of its own quantity
    points = np.concatenate(
        [line.get_ydata() for line in pushes.get_lines() if line.get_marker() in ("o", "x")]
    )
    assert sorted(points) == sorted(2 * [float(e["pushes"]) for e in episodes])


def test_pushes_per_trial_bad_input(tmp_path, episodes):
    with pytest.raises(InputError, match="episodes_by_planner is empty"):
        pf.plot_pushes_per_trial({}, tmp_path / "x.png")
    with pytest.raises(InputError, match=r"episodes_by_planner\['a'\] is empty"):
        pf.plot_pushes_per_trial({"a": []}, tmp_path / "x.png")
    no_replans = [{k: v for k, v in e.items() if k != "replans"} for e in episodes]
    with pytest.raises(InputError, match=r"lacks key\(s\) \['replans'\]"):
        pf.plot_pushes_per_trial({"a": no_replans}, tmp_path / "x.png")
    with pytest.raises(InputError, match="map planner labels"):
        pf.plot_pushes_per_trial(episodes, tmp_path / "x.png")
    assert not (tmp_path / "x.png").exists()
