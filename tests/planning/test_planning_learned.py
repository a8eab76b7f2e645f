"""A fitted push model with its features, for planners; effects back to world poses."""

import numpy as np
import pytest
import torch
from torch.distributions import Independent, Normal

from probaff.errors import InputError
from probaff.models import EMOptions
from probaff.planning.catalogue import fit_edge_model
from probaff.planning.learned import FeaturePushModel, apply_effects
from probaff.planning.push_to_edge.episode import run_edge_episode
from probaff.planning.push_to_edge.planners import PushReachability, predict_books
from probaff.planning.push_to_edge.task import load_edge_task
from probaff.planning.transitions import LearnedTransition
from probaff.sim.geometry import push_frame_effect

FAR = np.array([-0.4, 0.35, 0.0])  # a battery pose out of the way


def test_apply_effects_inverts_the_pushing_frame_effect():
    rng = np.random.default_rng(0)
    for _ in range(5):
        before, after = rng.normal(size=(3, 3)), rng.normal(size=(3, 3))
        yaw = float(rng.uniform(-3, 3))
        eff = push_frame_effect(before, after, yaw)
        assert np.allclose(apply_effects(before, eff, np.array(yaw)), after)


@pytest.mark.parametrize(
    ("poses", "effects", "yaw", "name"),
    [
        (np.zeros((2, 2)), np.zeros((2, 3)), 0.0, "poses"),
        ("abc", np.zeros((2, 3)), 0.0, "poses"),
        (np.zeros((2, 3)), [[0.0, 0.0, 0.0], [0.0]], 0.0, "effects"),
        (np.zeros((2, 3)), np.full((2, 3), np.nan), 0.0, "effects"),
        (np.zeros((2, 3)), np.zeros((2, 3)), None, "push_yaw"),
        (np.zeros((2, 3)), np.zeros((2, 3)), np.inf, "push_yaw"),
    ],
)
def test_apply_effects_names_bad_input(poses, effects, yaw, name):
    with pytest.raises(InputError, match=name):
        apply_effects(poses, effects, yaw)


@pytest.fixture(scope="module")
def gp(edge_data):
    return fit_edge_model("gp", edge_data, em=EMOptions(max_iter=1))


class _FakeModel:
    """A push model that records its features as told and predicts `value` everywhere."""

    n_outputs = 3

    def __init__(self, n_features, groups=None, value=0.0):
        self.n_features, self.value = n_features, value
        if groups is not None:
            self.groups = groups

    def predict(self, X):
        loc = torch.full((len(X), 3), self.value, dtype=torch.float64)
        return Independent(Normal(loc, torch.ones_like(loc), validate_args=False), 1)


def test_a_model_fitted_on_other_features_is_refused(gp, edge_data):
    assert list(gp.model.groups) == ["f_o", "f_c"]
    with pytest.raises(
        InputError,
        match=r"fitted on feature groups \['f_o', 'f_c'\], but the planner would give it "
        r"\['f_o'\] \(ch4\)",
    ):
        FeaturePushModel(gp.model, "ch4", ("f_o",))
    # a model that records no groups is checked by its width
    wrong = FeaturePushModel(_FakeModel(55), "ch4", ("f_o",))  # type: ignore[arg-type]
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
    a = predict_books(task, LearnedTransition(gp, task, 4), book, origins[:, 0], yaws[:2], FAR, 8)
    b = predict_books(task, LearnedTransition(gp, task, 4), book, origins[:, 0], yaws[:2], FAR, 8)
    assert a.samples is not None and a.samples.shape == (8, 2, 3)
    assert np.array_equal(a.samples, b.samples)


def test_a_model_fitted_on_the_same_width_of_other_groups_is_refused(gp, edge_data):
    # f_c then f_o is 55 columns, as the model's f_o then f_c
    with pytest.raises(
        InputError,
        match=r"fitted on feature groups \['f_o', 'f_c'\], but the planner would give it "
        r"\['f_c', 'f_o'\]",
    ):
        FeaturePushModel(gp.model, "ch4", ("f_c", "f_o"))
    # the same group names, of another feature set's widths (ch5's f_o and f_c)
    ch5_like = _FakeModel(21, {"f_o": slice(0, 8), "f_c": slice(8, 21)})
    wrong = FeaturePushModel(ch5_like, "ch4", ("f_o", "f_c"))  # type: ignore[arg-type]
    with pytest.raises(
        InputError,
        match=r"fitted on feature groups of widths \{'f_o': 8, 'f_c': 13\}, but the planner "
        r"computes \{'f_o': 13, 'f_c': 42\}",
    ):
        wrong.predict(edge_data)
    with pytest.raises(InputError, match=r"groups \['f_z'\] must name distinct feature groups"):
        FeaturePushModel(gp.model, "ch4", ("f_z",))
    with pytest.raises(InputError, match="must name distinct feature groups"):
        FeaturePushModel(gp.model, "ch4", ("f_o", "f_o"))


def test_a_model_predicting_nan_names_itself(edge_data):
    broken = _FakeModel(55, value=float("nan"))
    nan = FeaturePushModel(broken, "ch4", ("f_o", "f_c"))  # type: ignore[arg-type]
    with pytest.raises(
        InputError, match=r"push model _FakeModel predicted .* NaN .* predictions are not finite"
    ):
        nan.predict(edge_data)
    task = load_edge_task()
    book = np.zeros((1, 3))
    origins, yaws = task.candidate_pushes(book)
    with pytest.raises(InputError, match="push model _FakeModel predicted"):
        predict_books(task, LearnedTransition(nan, task), book, origins[:, 0], yaws[:1], FAR)


def test_learned_transition_and_fit_refuse_bad_arguments(gp, edge_data):
    task = load_edge_task()
    with pytest.raises(InputError, match="model must be a fitted push model with its features"):
        LearnedTransition(gp.model, task)  # type: ignore[arg-type]
    with pytest.raises(InputError, match="seed must be an integer >= 0, got -1"):
        LearnedTransition(gp, task, seed=-1)
    with pytest.raises(InputError, match="LearnedTransition needs the tabletop world"):
        LearnedTransition(gp, "push_to_edge")
    with pytest.raises(InputError, match="em must be EMOptions"):
        fit_edge_model("gp", edge_data, em=0)
    with pytest.raises(InputError, match="ds must be a PushDataset"):
        fit_edge_model("gp", edge_data.arrays)  # type: ignore[arg-type]


def test_the_recorded_groups_of_each_feature_set_are_its_own(edge_data):
    from probaff.planning.learned import _FEATURE_GROUPS, FEATURE_FUNCTIONS

    for name, features in FEATURE_FUNCTIONS.items():
        assert tuple(features(edge_data).groups) == _FEATURE_GROUPS[name]
