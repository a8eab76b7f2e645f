"""Chapter 5's two-step tool push: region, candidates, batched planning, trials, bad input.

Covers probaff.planning.tool_push.config, probaff.planning.tool_push.region,
probaff.planning.tool_push.state, probaff.planning.tool_push.candidates,
probaff.planning.tool_push.planners, probaff.planning.tool_push.trials and the argument checks
they share, probaff/planning/_checks.py.
"""

import dataclasses
import json

import numpy as np
import pytest
import torch
from torch.distributions import Independent, Normal

from probaff._threads import limit_threads
from probaff.data.generation import GenerateConfig, generate
from probaff.errors import InputError
from probaff.models import MIXTURE_GP, EMOptions
from probaff.planning.catalogue import fit_tool_push_model
from probaff.planning.learned import FeaturePushModel
from probaff.planning.tool_push import (
    TOOL_PUSH_PLANNERS,
    SampleSizes,
    ToolPushConfig,
    ToolPushState,
    ToolPushTrial,
    draw_tool_push_episode,
    plan_random_push,
    plan_single_push,
    plan_tool_push,
    reachable_region,
    run_tool_push_trial,
    sample_tool_pushes,
    tool_push_scores,
)
from probaff.planning.transitions import (
    LearnedTransition,
    QuasiStaticTransition,
    SimulatorTransition,
    TransitionPrediction,
)
from probaff.sim.arm import load_arm
from probaff.sim.sampling import sample_scene
from probaff.sim.specs import load_catalogue
from probaff.sim.tabletop_config import load_scene, load_tabletop

# Small sizes for the learned planners (the simulator's keep their defaults, 24/4/12): the
# tests check the pipeline, not the thesis's sample counts.
SMALL = ToolPushConfig(sizes=SampleSizes(12, 3, 6))


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    cfg = GenerateConfig(
        scene="tool_push", n=40, seed=0, shard_size=40, cloud_points=64, trajectories=False
    )
    return generate(cfg, tmp_path_factory.mktemp("tool_push") / "data", workers=0, progress=False)


@pytest.fixture(scope="module")
def model(dataset):
    gp = dataclasses.replace(MIXTURE_GP, max_iter=10)
    return fit_tool_push_model(
        dataset, n_experts=2, em=EMOptions(max_iter=2, n_restarts=1), gp=gp, seed=0
    )


class CountingModel:
    """Delegates to a FeaturePushModel and records the batch size of every call."""

    def __init__(self, inner: FeaturePushModel) -> None:
        self.inner = inner
        self.cloud_points = inner.cloud_points
        self.cloud_noise = inner.cloud_noise
        self.batches: list[int] = []

    def predict(self, queries):
        self.batches.append(len(queries))
        return self.inner.predict(queries)


def _state(seed):
    ep = draw_tool_push_episode(seed)
    return ToolPushState(ep.objects, ep.poses)


# ----------------------------------------------------------------------------- the region


def test_region_comes_from_the_receiving_arms_ik():
    region = reachable_region()
    world = load_tabletop()
    goal = dataclasses.replace(world.arm, base_xyz=(-1.0, 0.0, world.arm.base_xyz[2]))
    mask, xs, ys = load_arm(goal).reachable_mask((-0.5, 0.5), (-0.4, 0.4), 0.02, 2, "any")
    np.testing.assert_array_equal(region.mask, mask)
    assert reachable_region() is region  # computed once per process
    # near the receiving arm inside, far from it outside; the sign follows the mask
    assert region.depth(np.array([-0.4, 0.0])) > 0.05
    assert region.depth(np.array([0.3, 0.0])) < -0.2
    gx, gy = np.meshgrid(xs, ys)
    depth = region.depth(np.stack([gx, gy], -1))
    assert ((depth > 0) == mask).mean() > 0.99
    assert 0.1 < mask.mean() < 0.6  # part of the table, not all of it
    # beyond the table edge the depth keeps falling
    assert region.depth(np.array([-0.7, 0.0])) < region.depth(np.array([-0.45, 0.0]))


def test_scene_targets_start_out_of_reach_and_the_tool_is_pushable():
    scene, world = load_scene("tool_push"), load_tabletop()
    region, arm = reachable_region(), load_arm(world.arm)
    rng = np.random.default_rng(0)
    draws = [s for s in (sample_scene(scene, load_catalogue(), world, rng) for _ in range(60)) if s]
    outside = np.mean([region.depth(s.poses[1, :2]) < 0 for s in draws])
    assert outside > 0.5  # most of the template's targets start out of the receiving arm's reach
    for seed in (0, 1, 2):
        ep = draw_tool_push_episode(seed)
        assert -0.25 <= region.depth(ep.poses[1, :2]) <= -0.03
        assert [o.name for o in ep.objects][1] == "phone_box"
        cand = sample_tool_pushes(ep.objects, ep.poses, 8, np.random.default_rng(seed))
        assert len(cand) == 8 and (cand.state == 0).all()
        ok = arm.solve_pushes(torch.as_tensor(cand.origin), torch.as_tensor(cand.yaw), 0.25).ok
        assert bool(ok.all())
        # the hand starts behind the tool and points at it (within the lateral offset)
        to_tool = ep.poses[0, :2] - cand.origin
        d = np.stack([np.cos(cand.yaw), np.sin(cand.yaw)], -1)
        along = (to_tool * d).sum(-1)
        lateral = np.abs(to_tool[:, 0] * d[:, 1] - to_tool[:, 1] * d[:, 0])
        assert (along > 0.04).all() and (lateral <= 0.05 + 1e-9).all()
    a, b = draw_tool_push_episode(4), draw_tool_push_episode(4)
    np.testing.assert_array_equal(a.poses, b.poses)
    np.testing.assert_array_equal(a.ground_friction, b.ground_friction)


# --------------------------------------------------------------------------- planning


def test_planner_calls_the_model_once_per_step_with_every_candidate(model):
    counting = CountingModel(model)
    transition = LearnedTransition(counting, load_tabletop())
    config = ToolPushConfig()  # the thesis's 100, then 10 x 100
    with limit_threads(1):
        plan = plan_tool_push(transition, _state(0), np.random.default_rng(0), config)
    assert counting.batches == [100, 1000]
    assert plan.transition_calls == 2 and plan.n_candidates == (100, 1000)
    assert plan.push_origin.shape == (2, 2) and plan.predicted.shape == (2, 2, 3)
    assert np.isfinite(plan.predicted).all() and np.isfinite(plan.predicted_depth)
    counting.batches.clear()
    with limit_threads(1):
        single = plan_single_push(transition, _state(0), np.random.default_rng(0), config)
    assert counting.batches == [100] and single.push_yaw.shape == (1,)


def test_simulator_two_step_moves_the_target_further_than_random_pushes():
    gains = {"two_step_sim": [], "random": []}
    for seed in (0, 1):
        for planner in gains:
            t = run_tool_push_trial(planner, None, seed, SMALL)
            gains[planner].append(t.final_depth - t.initial_depth)
            assert t.pushes.shape[1] == 3 and len(t.executed) == len(t.pushes)
    assert np.mean(gains["two_step_sim"]) > np.mean(gains["random"]) + 0.03
    assert min(gains["two_step_sim"]) > 0  # every planned sequence moves the target closer


def test_a_fitted_mixture_runs_a_trial_end_to_end(model):
    trial = run_tool_push_trial("two_step", model, 3, SMALL)
    assert trial.planner == "two_step" and trial.seed == 3
    assert trial.transition_calls == 2 and trial.pushes.shape == (2, 3)
    assert trial.predicted.shape == trial.executed.shape == (2, 2, 3)
    assert np.isfinite(trial.predicted).all() and np.isfinite(trial.final_depth)
    assert trial.initial_depth < 0
    assert trial.reached == (trial.final_depth > 0)
    record = json.loads(json.dumps(trial.to_dict()))
    assert record["objects"][1] == "phone_box" and len(record["executed"]) == 2
    again = run_tool_push_trial("two_step", model, 3, SMALL)
    np.testing.assert_array_equal(trial.pushes, again.pushes)
    np.testing.assert_array_equal(trial.executed, again.executed)


def test_scores_summarise_trials_per_planner():
    def trial(planner, depth):
        nan = np.full((1, 2, 3), np.nan)
        return ToolPushTrial(
            planner=planner,
            seed=0,
            objects=("cracker_box", "phone_box"),
            initial=np.zeros((2, 3)),
            initial_depth=-0.1,
            pushes=np.zeros((1, 3)),
            predicted=nan,
            executed=np.zeros((1, 2, 3)),
            final_depth=depth,
            reached=depth > 0,
            fell_off=False,
            refused=False,
            planning_time_s=0.5,
        )

    scores = tool_push_scores([trial("a", 0.1), trial("a", -0.1), trial("b", 0.3)])
    assert scores["a"]["success"] == 0.5 and scores["a"]["mean_depth"] == pytest.approx(0.0)
    assert scores["b"] == pytest.approx(
        {"trials": 1, "success": 1, "mean_depth": 0.3, "std_depth": 0, "mean_planning_time_s": 0.5}
    )
    assert json.loads(json.dumps(trial("a", 0.1).to_dict()))["predicted"][0][0][0] is None
    assert set(TOOL_PUSH_PLANNERS) == {"random", "single_step", "two_step", "two_step_sim"}


# -------------------------------------------------------------------------- bad input


@pytest.mark.parametrize(
    "kwargs",
    [
        {"sizes": (100, 10, 100)},
        {"sim_sizes": None},
        {"region_yaws": 1.5},
        {"min_outside": 0.3, "max_outside": 0.2},
        {"goal_base_xy": (1.0,)},
    ],
)
def test_config_rejects_bad_budgets(kwargs):
    with pytest.raises(InputError, match="ToolPushConfig"):
        ToolPushConfig(**kwargs)


@pytest.mark.parametrize(
    ("sizes", "match"),
    [
        ((0, 0, 1), r"SampleSizes.first must be a positive integer, got 0"),
        ((3, 1, -3), r"SampleSizes.second must be a positive integer, got -3"),
        ((3, 0, 1), r"SampleSizes.keep must be a positive integer, got 0"),
        ((5, 6, 1), r"keep=6 exceeds first=5"),
        ((5, 2, 1.5), r"SampleSizes.second must be a positive integer, got 1.5"),
    ],
)
def test_sample_sizes_are_checked(sizes, match):
    with pytest.raises(InputError, match=match):
        SampleSizes(*sizes)


def test_bad_states_planners_and_models_are_refused(dataset, model):
    cat = load_catalogue()
    tool, target = cat["cracker_box"], cat["phone_box"]
    with pytest.raises(InputError, match="overlap"):
        ToolPushState((tool, target), np.array([[0.2, 0.0, 0.0], [0.25, 0.0, 0.3]]))
    with pytest.raises(InputError, match=r"\(tool, target\) pair"):
        ToolPushState((tool,), np.zeros((1, 3)))
    with pytest.raises(InputError, match="off the"):
        ToolPushState((tool, target), np.array([[0.2, 0.0, 0.0], [0.9, 0.0, 0.0]]))
    far = ToolPushState((tool, target), np.array([[0.1, 0.0, 0.0], [0.42, 0.0, 0.0]]))
    with pytest.raises(InputError, match="cannot be brought"):
        plan_tool_push(SimulatorTransition(load_tabletop()), far, np.random.default_rng(0))
    with pytest.raises(InputError, match=r"sizes must be a SampleSizes\(first, keep, second\)"):
        plan_tool_push(
            SimulatorTransition(load_tabletop()),
            _state(0),
            np.random.default_rng(0),
            sizes=(4, 2, 1),  # type: ignore[arg-type]
        )
    with pytest.raises(InputError, match="unknown planner"):
        run_tool_push_trial("three_step", model, 0)
    with pytest.raises(InputError, match="needs a fitted chapter-5 model"):
        run_tool_push_trial("two_step", None, 0)
    with pytest.raises(InputError, match="transition must be a push transition model"):
        plan_tool_push(model, _state(0), np.random.default_rng(0))
    # a model fitted on f_o alone, presented as if it read f_o and f_c
    only_o = fit_tool_push_model(
        dataset,
        n_experts=1,
        groups=("f_o",),
        em=EMOptions(max_iter=1, n_restarts=1),
        gp=dataclasses.replace(MIXTURE_GP, max_iter=5),
    )
    assert list(only_o.model.groups) == ["f_o"]
    with pytest.raises(
        InputError,
        match=r"fitted on feature groups \['f_o'\], but the planner would give it "
        r"\['f_o', 'f_c'\] \(ch5\)",
    ):
        dataclasses.replace(only_o, groups=("f_o", "f_c"))


class _NaNTransition:
    """A transition model whose predicted poses are all NaN."""

    name = "nan"

    def predict(self, pushes, *, n_samples=0, rng=None):
        return TransitionPrediction(np.full(pushes.poses.shape, np.nan))


class _NaNQueryModel:
    """A learned model whose predicted effects are all NaN."""

    cloud_points = 64
    cloud_noise = 0.002

    def predict(self, queries):
        loc = torch.full((len(queries), 6), float("nan"), dtype=torch.float64)
        return Independent(Normal(loc, torch.ones_like(loc), validate_args=False), 1)


def test_non_finite_predictions_name_the_model():
    state, rng = _state(0), np.random.default_rng(0)
    match = r"transition model _NaNTransition 'nan' predicted \d+ NaN .* not finite; refit the"
    with pytest.raises(InputError, match=match):
        plan_single_push(_NaNTransition(), state, rng, SMALL)
    with pytest.raises(InputError, match=match):
        plan_tool_push(_NaNTransition(), state, rng, SMALL)
    learned = LearnedTransition(_NaNQueryModel(), load_tabletop())
    with pytest.raises(InputError, match=r"push model _NaNQueryModel predicted NaN .* not finite"):
        plan_single_push(learned, state, rng, SMALL)


def test_tool_push_refuses_non_models_and_bad_arguments():
    state, rng, world = _state(0), np.random.default_rng(0), load_tabletop()
    sim = SimulatorTransition(world)
    with pytest.raises(InputError, match=r"model must be a fitted push model with its features"):
        LearnedTransition("gp", world)  # type: ignore[arg-type]
    with pytest.raises(InputError, match=r"SimulatorTransition needs the tabletop world"):
        SimulatorTransition("tabletop")
    with pytest.raises(InputError, match="transition must be a push transition model"):
        plan_single_push("sim", state, rng, SMALL)  # type: ignore[arg-type]
    with pytest.raises(InputError, match=r"config must be a ToolPushConfig .*got dict"):
        plan_tool_push(sim, state, rng, {"sizes": (4, 2, 2)})  # type: ignore[arg-type]
    with pytest.raises(InputError, match=r"rng must be a numpy.random.Generator .*got int"):
        plan_tool_push(sim, state, 0, SMALL)  # type: ignore[arg-type]
    with pytest.raises(InputError, match=r"sizes must be a SampleSizes.*got tuple"):
        plan_tool_push(sim, state, rng, sizes=(4, 2))  # type: ignore[arg-type]
    with pytest.raises(InputError, match="state must be a ToolPushState"):
        plan_random_push(state.poses, rng)  # type: ignore[arg-type]
    with pytest.raises(InputError, match=r"objects must be the \(tool, target\) ObjectSpec"):
        sample_tool_pushes("cracker_box", state.poses, 4, rng)  # type: ignore[arg-type]
    with pytest.raises(InputError, match="config must be a ToolPushConfig"):
        run_tool_push_trial("random", None, 0, "fast")  # type: ignore[arg-type]
    with pytest.raises(InputError, match="unknown planner"):
        run_tool_push_trial(["random"], None, 0)  # type: ignore[arg-type]


_MEAN_KIND = """
import numpy as np
import torch
from torch.distributions import Independent, Normal

from probaff.models import ModelKind, register_model_kind


class ToolMeanModel:
    def __init__(self, groups):
        self.groups = dict(groups or {})
        self.n_features = self.n_outputs = None

    def predict(self, X):
        loc = self.mean.expand(len(X), -1)
        return Independent(Normal(loc, self.std.expand(len(X), -1)), 1)


def fit_mean(model, X, Y, options=None):
    model.n_features, model.n_outputs = X.shape[1], Y.shape[1]
    model.mean, model.std = torch.as_tensor(Y.mean(0)), torch.as_tensor(Y.std(0) + 1e-3)
    return model


register_model_kind(
    ModelKind("toolmean", ToolMeanModel, fit_mean, builder=lambda s: ToolMeanModel(s.groups))
)
"""


@pytest.fixture
def kind_module(tmp_path, monkeypatch):
    """A model kind in a module of its own under probaff.models's path, named nowhere else."""
    import sys

    import probaff.models
    from probaff.models import unregister_model_kind

    (tmp_path / "toolmean_kind.py").write_text(_MEAN_KIND)
    monkeypatch.setattr(probaff.models, "__path__", [*probaff.models.__path__, str(tmp_path)])
    yield "toolmean"
    unregister_model_kind("toolmean")
    sys.modules.pop("probaff.models.toolmean_kind", None)


def test_a_new_model_kind_module_is_found_and_plans_the_tool_push(dataset, kind_module):
    fitted = fit_tool_push_model(dataset, n_experts=1, kind=kind_module)
    assert type(fitted.model).__name__ == "ToolMeanModel" and fitted.model.n_outputs == 6
    transition = LearnedTransition(fitted, load_tabletop())
    with limit_threads(1):
        plan = plan_tool_push(transition, _state(0), np.random.default_rng(0), SMALL)
    assert plan.push_origin.shape == (2, 2) and np.isfinite(plan.predicted).all()
    with pytest.raises(InputError, match="unknown model kind 'lstm'"):
        fit_tool_push_model(dataset, kind="lstm")
    with pytest.raises(InputError, match="kind must be the name of a registered model kind"):
        fit_tool_push_model(dataset, kind=3)  # type: ignore[arg-type]


def test_fit_tool_push_model_refuses_bad_settings(dataset):
    with pytest.raises(
        InputError, match=r"groups \['f_q'\] must name distinct chapter-5 feature groups"
    ):
        fit_tool_push_model(dataset, groups=("f_q",))
    with pytest.raises(InputError, match=r"em must be EMOptions .* got dict"):
        fit_tool_push_model(dataset, em={"n_restarts": 0})
    with pytest.raises(InputError, match="seed must be an integer >= 0, got -2"):
        fit_tool_push_model(dataset, seed=-2)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"region_resolution": 0}, "region_resolution must be a finite number > 0, got 0"),
        ({"region_resolution": -0.02}, "region_resolution must be a finite number > 0"),
        ({"region_resolution": float("nan")}, "region_resolution must be a finite number > 0"),
        ({"region_yaws": 0}, "region_yaws must be a positive integer, got 0"),
    ],
)
def test_region_grid_must_be_positive(kwargs, match):
    with pytest.raises(InputError, match=match):
        ToolPushConfig(**kwargs)
    with pytest.raises(InputError, match="config must be a ToolPushConfig"):
        reachable_region(kwargs)  # type: ignore[arg-type]


def test_the_analytic_transition_plans_tool_pushes_too():
    # the quasi-static model slides the tool and leaves the target where it stands
    state, world = _state(1), load_tabletop()
    qs = QuasiStaticTransition(world, start_gap=0.02)
    plan = plan_single_push(qs, state, np.random.default_rng(0), SMALL)
    assert plan.transition_calls == 1 and plan.n_candidates == (12,)
    np.testing.assert_array_equal(plan.predicted[0, 1], state.poses[1])
    assert not np.array_equal(plan.predicted[0, 0], state.poses[0])


def test_a_model_of_the_tool_alone_is_refused_naming_model_and_task(dataset, model):
    """A push-to-edge-like model predicts 3 effects (one object): the target would never move."""
    from probaff.features import chapter5_features
    from probaff.models import MixtureOfGPExperts, fit_em

    fs = chapter5_features(dataset)
    tool_only = MixtureOfGPExperts(1, gp=dataclasses.replace(MIXTURE_GP, max_iter=5))
    with limit_threads(1):
        fit_em(
            tool_only,
            fs.select("f_o", "f_c"),
            dataset["effect"][:, 0],
            init="effects",
            max_iter=1,
            n_restarts=1,
            split_merge=0,
        )
    pushed = FeaturePushModel.for_dataset(tool_only, "ch5", ("f_o", "f_c"), dataset)
    transition = LearnedTransition(pushed, load_tabletop(), name="edge")
    assert transition.n_moved == 1
    assert LearnedTransition(model, load_tabletop()).n_moved == 2
    state, rng = _state(0), np.random.default_rng(0)
    match = (
        r"transition model LearnedTransition 'edge' predicts the effects of 1 object\(s\) "
        r"\(3 outputs\), but the tool push task \(the tool and the target\) moves 2 objects"
        r".*fit_tool_push_model"
    )
    for planner in (plan_tool_push, plan_single_push):
        with pytest.raises(InputError, match=match):
            planner(transition, state, rng, SMALL)
