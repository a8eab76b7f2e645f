"""The planner catalogue: planners and models by name, and a new model kind in one file.

`test_a_new_model_kind_plans_an_astar_step` is the whole cost of a new kind of push model for
the A* planner: the model and its registration, one catalogue entry, and this test.
"""

import dataclasses

import numpy as np
import pytest
import torch
from torch.distributions import Independent, Normal

from probaff.data.schema import PushDataset
from probaff.errors import InputError
from probaff.models import EMOptions, ModelKind, register_model_kind, unregister_model_kind
from probaff.planning.catalogue import (
    EDGE_MODELS,
    EDGE_PLANNERS,
    EdgeModelSpec,
    EdgePlannerSpec,
    edge_transition,
    fit_edge_model,
)
from probaff.planning.push_to_edge.episode import EDGE_SEARCHES, run_edge_episode
from probaff.planning.push_to_edge.planners import PushReachability
from probaff.planning.transitions import (
    LearnedTransition,
    QuasiStaticTransition,
    SimulatorTransition,
)

# ------------------------------------------------------------------ a new kind, in one file


class MeanPushModel:
    """A push model that predicts the mean training effect, whatever the push."""

    def __init__(self, groups):
        self.groups = dict(groups or {})
        self.n_features = self.n_outputs = None

    def predict(self, X):
        loc = self.mean.expand(len(X), -1)
        return Independent(Normal(loc, self.std.expand(len(X), -1), validate_args=False), 1)


def fit_mean(model, X, Y, options=None):
    model.n_features, model.n_outputs = X.shape[1], Y.shape[1]
    model.mean = torch.as_tensor(np.mean(Y, 0))
    model.std = torch.as_tensor(np.std(Y, 0) + 1e-3)
    return model


MEAN = ModelKind("mean", MeanPushModel, fit_mean, builder=lambda s: MeanPushModel(s.groups))


@pytest.fixture
def mean_kind(monkeypatch):
    register_model_kind(MEAN)
    monkeypatch.setitem(EDGE_MODELS, "mean", EdgeModelSpec("mean", 1, (), ("f_o", "f_c")))
    monkeypatch.setitem(EDGE_PLANNERS, "astar-mean", EdgePlannerSpec("astar", "mean"))
    yield EDGE_PLANNERS["astar-mean"]
    unregister_model_kind("mean")


def test_a_new_model_kind_plans_an_astar_step(mean_kind, edge_data, task):
    fitted = fit_edge_model("mean", edge_data)
    assert isinstance(fitted.model, MeanPushModel) and fitted.groups == ("f_o", "f_c")
    transition = edge_transition(mean_kind, task, {"mean": fitted}, seed=1)
    assert isinstance(transition, LearnedTransition) and transition.name == "mean"
    one_push = dataclasses.replace(task, budget=1)
    episode = run_edge_episode(
        one_push, transition, 2, search=mean_kind.search, reach=PushReachability(task)
    )
    assert episode.pushes == 1 and len(episode.plans) == 1 and transition.calls >= 1
    # the mean push moves the book forward along the push, as the training pushes did
    step = episode.steps[0]
    assert np.hypot(*np.subtract(step.predicted, step.before)[:2]) > 0.01


# --------------------------------------------------------------------------- the catalogue


def test_every_planner_names_a_search_and_a_model():
    for name, spec in EDGE_PLANNERS.items():
        assert spec.search in EDGE_SEARCHES, name
        assert spec.model in {*EDGE_MODELS, "simulator", "quasistatic"}, name
    assert {m.kind for m in EDGE_MODELS.values()} == {"em", "clustered"}
    assert EDGE_MODELS["moe"].groups == ("f_o", "f_c", "f_x")


def test_each_planner_gets_its_transition(task):
    models = {"moe": object()}
    sim = edge_transition(EDGE_PLANNERS["astar-sim"], task, models)
    qs = edge_transition(EDGE_PLANNERS["astar-quasistatic"], task, models)
    assert isinstance(sim, SimulatorTransition) and isinstance(qs, QuasiStaticTransition)
    with pytest.raises(InputError, match=r"model 'gp' is not among the fitted models \['moe'\]"):
        edge_transition(EDGE_PLANNERS["astar-gp"], task, models)
    with pytest.raises(InputError, match="spec must be an EdgePlannerSpec"):
        edge_transition(EdgePlannerSpec("dfs", "gp"), task, models)


def test_the_models_fit_through_the_registry(edge_data):
    clustered = fit_edge_model("clustered", edge_data, seed=1)
    assert type(clustered.model).__name__ == "ClusteredGPModel"
    gp = fit_edge_model("gp", edge_data, em=EMOptions(max_iter=1), cloud_points=64, cloud_noise=0.0)
    assert gp.model.n_experts == 1 and (gp.cloud_points, gp.cloud_noise) == (64, 0.0)


def test_an_unknown_kind_or_model_is_refused(edge_data, monkeypatch):
    monkeypatch.setitem(EDGE_MODELS, "lstm", EdgeModelSpec("lstm", 1, (), ("f_o",)))
    with pytest.raises(InputError, match="unknown model kind 'lstm'"):
        fit_edge_model("lstm", edge_data)
    with pytest.raises(InputError, match="unknown planner model 'rnn'"):
        fit_edge_model("rnn", edge_data)
    few = PushDataset(
        {k: v[:5] for k, v in edge_data.arrays.items()}, edge_data.object_names, edge_data.meta
    )
    with pytest.raises(InputError, match="at least 10"):
        fit_edge_model("gp", few)
