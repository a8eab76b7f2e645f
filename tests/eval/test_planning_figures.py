import copy
from pathlib import Path

import numpy as np
import pytest
import torch
from matplotlib.patches import Polygon

import probaff.eval.planning_figures as pf
from probaff.errors import InputError
from probaff.planning.edge_episode import run_edge_episode
from probaff.planning.edge_task import load_edge_task
from probaff.planning.edge_transitions import PushReachability, QuasiStaticTransition

PNG = b"\x89PNG\r\n\x1a\n"


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
    figures = []
    real = pf.atomic_save_figure

    def save(fig, path, **kw):
        figures.append(fig)
        real(fig, path, **kw)

    monkeypatch.setattr(pf, "atomic_save_figure", save)
    return figures


def _is_png(path):
    data = Path(path).read_bytes()
    return len(data) > 1000 and data.startswith(PNG)


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
    assert _is_png(out)
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
    assert _is_png(pf.plot_edge_episodes(eps, task, tmp_path / "chain.png"))


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
    assert _is_png(out)
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
    assert _is_png(out)
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
