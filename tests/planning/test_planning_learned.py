"""A fitted push model with its features, for planners; effects back to world poses."""

import numpy as np
import pytest

from probaff.data.generation import GenerateConfig, make_shard
from probaff.data.queries import world_meta
from probaff.data.schema import PushDataset
from probaff.errors import InputError
from probaff.planning.edge_episode import run_edge_episode
from probaff.planning.edge_models import fit_edge_model
from probaff.planning.edge_task import load_edge_task
from probaff.planning.edge_transitions import LearnedTransition, PushReachability
from probaff.planning.learned import FeaturePushModel, apply_effects
from probaff.sim.config import load_catalogue, load_tabletop
from probaff.sim.geometry import push_frame_effect


def test_apply_effects_inverts_the_pushing_frame_effect():
    rng = np.random.default_rng(0)
    for _ in range(5):
        before, after = rng.normal(size=(3, 3)), rng.normal(size=(3, 3))
        yaw = float(rng.uniform(-3, 3))
        eff = push_frame_effect(before, after, yaw)
        assert np.allclose(apply_effects(before, eff, np.array(yaw)), after)


@pytest.fixture(scope="module")
def edge_data():
    arrays = make_shard(GenerateConfig("push_to_edge", 48, shard_size=48, trajectories=False), 0)
    meta = {**world_meta(load_tabletop()), "cloud_points": 256, "cloud_noise": 0.002}
    return PushDataset(arrays, sorted(load_catalogue()), meta)


@pytest.fixture(scope="module")
def gp(edge_data):
    return fit_edge_model("gp", edge_data, em_iterations=1)


def test_a_model_fitted_on_other_features_is_refused(gp, edge_data):
    wrong = FeaturePushModel(gp.model, "ch4", ("f_o",))
    with pytest.raises(
        InputError, match="fitted on 55 feature columns, but the planner computes 13"
    ):
        wrong.predict(edge_data)
    with pytest.raises(InputError, match="unknown feature set 'ch9'"):
        FeaturePushModel(gp.model, "ch9", ("f_o",))
    with pytest.raises(InputError, match="must be a fitted probaff push model"):
        FeaturePushModel(object(), "ch4", ("f_o",))  # type: ignore[arg-type]
    with pytest.raises(InputError, match="unknown planner model"):
        fit_edge_model("lstm", edge_data)


def test_learned_planner_runs_closed_loop_with_batched_predictions(gp, edge_data):
    pred = gp.predict(edge_data)
    assert pred.mean.shape == (len(edge_data), 3)
    task = load_edge_task()
    model = LearnedTransition(gp, task, seed=0)
    episode = run_edge_episode(task, model, 3, reach=PushReachability(task), trajectories=False)
    assert episode.pushes >= 1 and model.calls >= 1
    assert episode.outcome in ("success", "fell", "budget", "stuck")
    assert np.isfinite(episode.mean_error) and episode.mean_error < 0.15
    # the predictive draws of the risk-aware planner are seeded
    book = np.array([[0.0, 0.0, 0.0], [0.05, 0.1, 1.0]])
    origins, yaws = task.candidate_pushes(book)
    a = LearnedTransition(gp, task, seed=4).predict(book, origins[:, 0], yaws[:2], np.ones(3), 8)
    b = LearnedTransition(gp, task, seed=4).predict(book, origins[:, 0], yaws[:2], np.ones(3), 8)
    assert a.samples is not None and a.samples.shape == (8, 2, 3)
    assert np.array_equal(a.samples, b.samples)
