"""The Push-T study's parts that need no gym-pusht: geometry, primitives, the analytic model,
the search, the report, the config's checks, and the worker's failures (a missing
environment, another gym-pusht version, a worker that dies).

Covers probaff.experiments.pusht.geometry, probaff.experiments.pusht.primitives,
probaff.experiments.pusht.models, probaff.experiments.pusht.planner,
probaff.experiments.pusht.report, probaff.experiments.pusht.config,
probaff.experiments.pusht.env, probaff.experiments.pusht.figures and
probaff.experiments.pusht.data (its worker restart).
"""

import math
import stat
import sys
import textwrap

import numpy as np
import pytest
import torch

from probaff.errors import InputError, ProbaffError
from probaff.experiments.pusht import PushTStudyConfig
from probaff.experiments.pusht.data import with_worker, worker
from probaff.experiments.pusht.env import ENV_VAR, PushTEnvError, PushTWorker, pusht_python
from probaff.experiments.pusht.figures import plot_episodes, plot_models, plot_success_curve
from probaff.experiments.pusht.geometry import (
    AGENT_RADIUS,
    COG,
    INERTIA,
    PERIMETER,
    cog_pose,
    contact_points,
    distance_to_tee,
    keypoint_cost,
    origin_pose,
    to_block,
    to_world,
)
from probaff.experiments.pusht.models import FEATURES, LearnedModel, QuasiStaticTee
from probaff.experiments.pusht.planner import Node, SearchSettings, plan_push
from probaff.experiments.pusht.primitives import (
    PrimitiveSettings,
    primitive_actions,
    push_frames,
    sample_primitives,
)
from probaff.experiments.pusht.report import blame, curve_rows, planner_rows
from probaff.experiments.pusht.transitions import ModelTransition
from probaff.models import MixtureOfGPExperts, fit

PNG = b"\x89PNG\r\n\x1a\n"


def test_poses_frames_and_outline():
    origin = np.array([[100.0, 200.0, 0.7], [300.0, 50.0, -2.0]])
    pose = cog_pose(origin)
    assert np.allclose(origin_pose(pose), origin)
    # the centre of gravity is the body point (0, 45) turned with the block
    assert np.allclose(pose[0, :2], origin[0, :2] + 45 * np.array([-math.sin(0.7), math.cos(0.7)]))
    pts = np.array([[10.0, -3.0], [0.0, 70.0]])
    assert np.allclose(to_block(pose[0], to_world(pose[0], pts)), pts)
    s = np.linspace(0, PERIMETER, 97, endpoint=False)
    points, normals = contact_points(s)
    d, _ = distance_to_tee(points)
    assert np.allclose(d, 0) and np.allclose(np.linalg.norm(normals, axis=1), 1)
    d_out, _ = distance_to_tee(points + 5 * normals)  # outward normals point off the T
    assert np.all(d_out > 0) and np.mean(np.isclose(d_out, 5)) > 0.9  # < 5 by inner corners
    assert PERIMETER == 480 and COG[1] == 45
    assert keypoint_cost(pose[0], pose[0]) == 0
    shifted = pose[0] + [3.0, 4.0, 0.0]
    assert keypoint_cost(shifted, pose[0]) == pytest.approx(5.0)


def test_primitive_goes_around_the_tee_then_pushes():
    s = PrimitiveSettings()
    pose = np.array([256.0, 256.0, 0.3])
    agent = to_world(pose, np.array([[0.0, 150.0]]))[0]  # behind the stem's end
    prim = np.array([30.0, 0.0, 20.0])  # on the bar's underside edge, straight in
    plan = primitive_actions(pose, agent, prim, s)
    assert plan.feasible
    local = to_block(pose, plan.actions)
    d, _ = distance_to_tee(local[: plan.push_start])
    assert np.all(d >= AGENT_RADIUS + s.gap - 1e-6)  # never through the T on the way
    geo = push_frames(prim[None], s)
    assert np.allclose(local[plan.push_start - 1], geo["start"][0])
    assert np.allclose(local[-1], geo["start"][0] + geo["direction"][0] * (s.gap + 20.0))
    # a contact 5 px from the inner corner leaves no room for the disc: infeasible
    inner = np.array([PERIMETER - 30 - 45 + 5, 0.0, 10.0])
    assert not primitive_actions(pose, agent, inner, s).feasible
    prims = sample_primitives(np.random.default_rng(0), 200, s)
    assert prims[:, 2].min() >= s.min_length and prims[:, 2].max() <= s.max_length
    with pytest.raises(InputError, match="max_length"):
        PrimitiveSettings(min_length=10, max_length=5)


def test_analytic_model_pushes_through_the_centre_and_turns_off_it():
    qs = QuasiStaticTee(sigma=np.ones(3))
    # a pusher under the bar's middle pushing up through the centre of gravity: no turn
    start = np.array([0.0, -45.0 - AGENT_RADIUS - 3.0])
    X = np.array([[*start, 0.0, 1.0, 23.0], [start[0] + 40.0, start[1], 0.0, 1.0, 23.0]])
    eff = qs.effects(X)
    assert eff[0, 1] == pytest.approx(20.0, abs=0.2) and abs(eff[0, 2]) < 1e-6
    # off-centre: less translation, and the block turns (counter-clockwise for a push
    # up on the right)
    assert eff[1, 1] < eff[0, 1] and eff[1, 2] > 0.05
    # the lever: lambda = delta / (1 + c^2 / rho^2) at the start of the push
    assert INERTIA == 3000.0
    dist = qs.predict(X)
    assert dist.mean.shape == (2, 3)
    with pytest.raises(InputError, match="calibrate"):
        QuasiStaticTee().predict(X)


def test_search_moves_towards_the_goal_with_the_analytic_model():
    qs = QuasiStaticTee(sigma=np.full(3, 0.1))
    goal = np.array([256.0, 256.0, 0.0])
    node = Node(np.array([230.0, 256.0, 0.0]), np.array([100.0, 100.0]), np.zeros(2))
    rng = np.random.default_rng(1)
    _, predicted, score = plan_push(
        node,
        goal,
        ModelTransition(qs),
        rng,
        SearchSettings(candidates=64, children=16),
        PrimitiveSettings(),
    )
    assert keypoint_cost(predicted, goal) < keypoint_cost(node.pose, goal) - 5
    assert score < keypoint_cost(node.pose, goal)
    with pytest.raises(InputError):
        SearchSettings(depth=3)


def test_a_model_fitted_on_other_features_is_refused():
    model = LearnedModel("moe", object(), features=("a", "b"))
    with pytest.raises(InputError, match="fitted on features"):
        model.predict(np.zeros((1, len(FEATURES))))
    other = MixtureOfGPExperts(1)
    fit(other, torch.randn(12, 7, dtype=torch.float64), torch.randn(12, 3, dtype=torch.float64))
    with pytest.raises(InputError, match="7 columns"):
        LearnedModel("gp", other).predict(np.zeros((1, len(FEATURES))))


def _records():
    out = []
    for planner, wins in (("beam-moe", [1, 0, 1, 0]), ("beam-env", [1, 1, 0, 0])):
        for i, w in enumerate(wins):
            out.append(
                {
                    "planner": planner,
                    "episode": i,
                    "success": bool(w),
                    "max_coverage": 0.96 if w else 0.5,
                    "pushes": 5,
                    "steps": 100,
                    "plan_seconds": 0.1,
                    "error_px": 1.0,
                    "poses": [[256.0, 256.0, 0.0], [250.0, 260.0, 0.2]],
                }
            )
    return out


def test_report_rates_blame_and_figures(tmp_path):
    rows = {r["planner"]: r for r in planner_rows(_records())}
    assert rows["beam-moe"]["successes"] == 2 and rows["beam-moe"]["episodes"] == 4
    assert rows["beam-moe"]["success_low"] < 0.5 < rows["beam-moe"]["success_high"]
    assert rows["beam-moe"]["max_coverage"] == pytest.approx(0.73)
    b = blame(_records())
    # beam-moe failed episodes 1 and 3; beam-env solved 1 (model's fault) and failed 3
    assert b == {"shared": 4, "failures": 2, "model": 1, "search": 1}
    curve = curve_rows([{**r, "train_pushes": 250} for r in _records()[:4]])
    curve += curve_rows([{**r, "train_pushes": 500, "success": True} for r in _records()[:3]])
    assert curve[0]["train_pushes"] == 250 and curve[0]["success_rate"] == 0.5
    for path in (
        plot_episodes(_records(), tmp_path / "e.png"),
        plot_success_curve(curve, tmp_path / "c.png"),
        plot_models(
            [{"model": "moe", "train_pushes": n, "rmse_z": 1.0, "nlpd": 2.0} for n in (10, 100)],
            tmp_path / "m.png",
        ),
    ):
        with open(path, "rb") as f:
            assert f.read(8) == PNG


def test_config_checks():
    with pytest.raises(InputError, match="planners"):
        PushTStudyConfig(planners=("nope",)).validate()
    with pytest.raises(InputError, match="episodes"):
        PushTStudyConfig(episodes=0).validate()
    with pytest.raises(InputError, match="baseline_episodes"):
        PushTStudyConfig(baseline_episodes=1.5).validate()
    ok = PushTStudyConfig(train_pushes=(20,), plan_pushes=20).validate()
    assert ok.train_pushes == (20,)


_FAKE = textwrap.dedent(
    """
    import json, sys
    VERSION, DIE_ON = {version!r}, {die_on!r}
    for line in sys.stdin:
        msg = json.loads(line)
        if msg["cmd"] == "hello":
            out = {{"ok": True, "versions": {{"gym-pusht": VERSION}}}}
        elif msg["cmd"] == DIE_ON:
            sys.exit(3)
        elif msg["cmd"] == "close":
            break
        else:
            out = {{"ok": True, "steps": 0}}
        print(json.dumps(out), flush=True)
    """
)


def _fake_python(tmp_path, version="0.1.8", die_on="never"):
    """An executable that plays the worker (it ignores the worker script's path)."""
    script = tmp_path / f"fake_{version}_{die_on}.py"
    script.write_text(_FAKE.format(version=version, die_on=die_on))
    exe = tmp_path / f"python_{version}_{die_on}"
    exe.write_text(f"#!/bin/sh\nexec {sys.executable} {script}\n")
    exe.chmod(exe.stat().st_mode | stat.S_IEXEC)
    return str(exe)


def test_missing_environment_and_other_version(tmp_path, monkeypatch):
    monkeypatch.delenv(ENV_VAR, raising=False)
    monkeypatch.chdir(tmp_path)
    with pytest.raises(PushTEnvError, match=r"probaff\.experiments\.pusht\.env"):
        pusht_python()
    monkeypatch.setenv(ENV_VAR, str(tmp_path / "none" / "python"))
    with pytest.raises(PushTEnvError, match="PROBAFF_PUSHT_PYTHON"):
        PushTWorker()
    monkeypatch.delenv(ENV_VAR)
    with pytest.raises(PushTEnvError, match=r"gym-pusht 0\.1\.7.*0\.1\.8"):
        PushTWorker(_fake_python(tmp_path, version="0.1.7"))
    assert issubclass(PushTEnvError, ProbaffError)


def test_a_dead_worker_is_reported_and_restarted(tmp_path, monkeypatch):
    monkeypatch.delenv(ENV_VAR, raising=False)
    dying = PushTWorker(_fake_python(tmp_path, die_on="reset"))
    with pytest.raises(PushTEnvError, match="died"):
        dying.ask("reset", seed=0)
    assert not dying.alive
    python = _fake_python(tmp_path)
    calls = []

    def task(w):
        calls.append(w._proc.pid)
        if len(calls) == 1:
            w._proc.kill()
            w._proc.wait()
        return w.ask("state")["steps"]

    assert with_worker(python, task) == 0
    assert len(calls) == 2 and calls[0] != calls[1]  # run again, on a fresh process
    worker(python).close()


def test_every_planner_runs_its_own_count_of_the_same_episodes():
    from probaff.experiments.pusht.run import _planner_jobs

    c = PushTStudyConfig(episodes=5, baseline_episodes=2, env_episodes=3).validate()
    head, tail = _planner_jobs(c)
    jobs = head + tail
    assert len(jobs) == len(set(jobs))  # no episode twice
    count = {p: sum(q == p for q, _ in jobs) for p in c.planners}
    assert count["beam-moe"] == 5 and count["beam-env"] == 3 and count["random"] == 2
    assert [i for _, i in head[: len(c.planners)]] == [0] * len(c.planners)  # episode-major
