"""Chapter 6's transition models and `fit_transition`.

Covers probaff.models.transitions.transition, probaff.models.transitions.transition_base,
probaff.models.transitions.skill_transition and probaff.models.transitions.monolithic.
"""

import math
from dataclasses import replace

import pytest
import torch

from probaff._threads import limit_threads
from probaff.errors import InputError, NotFittedError
from probaff.models import (
    TRANSITION_GP,
    GPExpert,
    GPOptions,
    MonolithicTransitionModel,
    PushModel,
    SkillTransitionModel,
    TransitionHistory,
    fit_transition,
    model_kind,
)
from probaff.models.persistence import FORMATS, load, save

N_TRAIN, N_TEST = 60, 40


pytestmark = pytest.mark.usefixtures("single_thread")


def _reaction_data(n: int, seed: int) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Features X (n, 4), effects Y (n, 2) and reactions R (n, 1) with a known structure.

    A hidden contact depth u = x0 + x1 + x2 drives the effect Y = [sin(2 u), 0.5 u] + noise;
    the reaction R = 0.8 u + 0.4 Y1 + noise is a function of [X, Y] plus noise and equals u
    up to noise, so Y is a simple 1-D function of R but an oblique ridge in X, which an ARD
    GP on X alone learns poorly from 60 samples.
    """
    g = torch.Generator().manual_seed(seed)
    x = torch.rand(n, 4, generator=g, dtype=torch.float64) * 2 - 1
    u = x[:, :3].sum(1)
    y = torch.stack([torch.sin(2 * u), 0.5 * u], dim=1)
    y = y + 0.02 * torch.randn(n, 2, generator=g, dtype=torch.float64)
    r = 0.8 * u + 0.4 * y[:, 1]
    r = (r + 0.01 * torch.randn(n, generator=g, dtype=torch.float64))[:, None]
    return x, y, r


def _rmse(pred: torch.Tensor, truth: torch.Tensor) -> float:
    return float((pred - truth).square().mean().sqrt())


@pytest.fixture(scope="module")
def data():
    return _reaction_data(N_TRAIN, 0), _reaction_data(N_TEST, 1)


@pytest.fixture(scope="module")
def backward_model(data):
    (x, y, r), _ = data
    with limit_threads(1):
        model = SkillTransitionModel("push")
        history = fit_transition(model, x, y, r)
    return model, history


@pytest.fixture(scope="module")
def forward_model(data):
    (x, y, _), _ = data
    with limit_threads(1):
        model = SkillTransitionModel("push", backward=False)
        fit_transition(model, x, y)
    return model


def test_backward_component_beats_forward_only_and_the_mean(data, backward_model, forward_model):
    (_, y, _), (xt, yt, rt) = data
    model, history = backward_model
    assert isinstance(history, TransitionHistory)
    assert set(history.objective) == {"effect", "reaction", "corrected"}
    assert history.n_samples == N_TRAIN and history.em == {}
    assert all(math.isfinite(v) for v in history.objective.values())

    pred_b, pred_f = model.predict(xt), forward_model.predict(xt)
    assert pred_b.batch_shape == (N_TEST,) and pred_b.event_shape == (2,)
    assert pred_f.batch_shape == (N_TEST,) and pred_f.event_shape == (2,)
    rmse_b, rmse_f = _rmse(pred_b.mean, yt), _rmse(pred_f.mean, yt)
    rmse_mean = _rmse(y.mean(0).expand_as(yt), yt)
    assert rmse_b < 0.8 * rmse_f, (rmse_b, rmse_f)
    assert rmse_f < 0.5 * rmse_mean, (rmse_f, rmse_mean)
    # the reaction itself is predicted from [X, mean Y0]
    reaction = model.predict_reaction(xt)
    assert reaction.event_shape == (1,)
    assert _rmse(reaction.mean, rt) < 0.05 * float(rt.std())
    assert isinstance(model, PushModel) and model.n_outputs == 2 and model.n_reaction == 1


def test_gp_kind_starts_at_the_thesis_values_and_fits_away_from_them(data, backward_model):
    fresh = SkillTransitionModel("pick")
    fresh.build(4, 2, 1)
    assert set(fresh.components) == {"effect", "reaction", "corrected"}
    for name in ("effect", "reaction", "corrected"):
        expert = fresh.component(name)
        assert isinstance(expert, GPExpert)
        kernel = expert.gp.covar_module
        torch.testing.assert_close(kernel.outputscale, torch.full_like(kernel.outputscale, 0.1))
        noise = expert.likelihood.noise
        torch.testing.assert_close(noise, torch.full_like(noise, 0.1))
    assert fresh.component("reaction").n_features == 6  # [X, Y]
    assert fresh.component("corrected").n_features == 5  # [X, R]
    # GPExpert's own defaults are unchanged
    plain = GPExpert(3, 2)
    assert torch.allclose(plain.gp.covar_module.outputscale, torch.ones(2, dtype=torch.float64))
    custom = GPExpert(3, 2, outputscale=0.5, noise=0.2)
    assert torch.allclose(custom.gp.covar_module.outputscale, torch.full((2,), 0.5).double())
    assert torch.allclose(custom.likelihood.noise, torch.full((2, 1), 0.2).double())
    with pytest.raises(InputError, match="outputscale must lie strictly between"):
        GPExpert(3, 2, outputscale=1e5)
    with pytest.raises(InputError, match="noise must be a finite number"):
        GPExpert(3, 2, noise=float("nan"))
    fitted = backward_model[0].component("effect").gp.covar_module.outputscale
    assert not torch.allclose(fitted, torch.full_like(fitted, 0.1))


def test_one_expert_mixture_agrees_with_the_gp_kind(data, forward_model):
    (x, y, _), (xt, _, _) = data
    mixture = SkillTransitionModel("push", kind="mixture", n_experts=1, backward=False)
    history = fit_transition(mixture, x, y, seed=0)
    assert set(history.em) == {"effect"}
    a, b = mixture.predict(xt), forward_model.predict(xt)
    assert a.batch_shape == b.batch_shape and a.event_shape == b.event_shape
    # from the thesis's start values the GP reaches nearly the same fit
    rel = (a.mean - b.mean).abs() / y.std(0)
    assert float(rel.mean()) < 0.03 and float(rel.max()) < 0.15
    # from the mixture's own start values (GPExpert's defaults) it is the same fit
    same_start = SkillTransitionModel(
        "push", backward=False, gp=replace(TRANSITION_GP, outputscale=1.0)
    )
    fit_transition(same_start, x, y)
    c = same_start.predict(xt)
    torch.testing.assert_close(c.mean, a.mean, rtol=1e-6, atol=1e-8)
    torch.testing.assert_close(c.stddev, a.stddev, rtol=1e-6, atol=1e-8)


def test_sampled_prediction_propagates_the_reaction_uncertainty(data, backward_model):
    _, (xt, _, _) = data
    model, _ = backward_model
    analytic = model.predict(xt)
    sampled = model.predict(xt, n_samples=300, generator=torch.Generator().manual_seed(3))
    assert sampled.batch_shape == (N_TEST,) and sampled.event_shape == (2,)
    scale = analytic.stddev.mean(0)
    assert float(((sampled.mean - analytic.mean).abs() / scale).max()) < 0.3
    assert float(((sampled.mean - analytic.mean).abs() / scale).mean()) < 0.1
    assert bool((sampled.variance.mean(0) > analytic.variance.mean(0)).all())
    # seeded sampling is deterministic; the default generator is seeded too
    again = model.predict(xt, n_samples=300, generator=torch.Generator().manual_seed(3))
    assert torch.equal(again.mean, sampled.mean) and torch.equal(again.variance, sampled.variance)
    default_a = model.predict(xt, n_samples=20)
    default_b = model.predict(xt, n_samples=20)
    assert torch.equal(default_a.mean, default_b.mean)
    other = model.predict(xt, n_samples=300, generator=torch.Generator().manual_seed(4))
    assert not torch.equal(other.mean, sampled.mean)


def test_skill_checks_and_bad_input(data, backward_model, forward_model):
    (x, y, r), (xt, _, _) = data
    model, _ = backward_model
    with pytest.raises(InputError, match="a push model cannot predict pick; use the pick model"):
        model.predict(xt, skill="pick")
    with pytest.raises(InputError, match="cannot predict place"):
        model.predict_reaction(xt, skill="place")
    assert torch.equal(model.predict(xt, skill="push").mean, model.predict(xt).mean)
    with pytest.raises(InputError, match="known skills: 'pick', 'place', 'push'"):
        model.predict(xt, skill="throw")
    with pytest.raises(InputError, match="known skills"):
        SkillTransitionModel("throw")
    with pytest.raises(InputError, match="known kinds"):
        SkillTransitionModel("push", kind="forest")

    bad = xt.clone()
    bad[0, 1] = float("nan")
    with pytest.raises(InputError, match="NaN"):
        model.predict(bad)
    with pytest.raises(InputError, match="NaN"):
        fit_transition(SkillTransitionModel("push"), torch.cat([x[:-1], bad[:1]]), y, r)
    with pytest.raises(InputError, match="features X has shape"):
        model.predict(xt[:, :2])
    with pytest.raises(InputError, match="reactions R has 59 samples"):
        fit_transition(SkillTransitionModel("push"), x, y, r[:-1])
    with pytest.raises(InputError, match="effects Y has 59"):
        fit_transition(SkillTransitionModel("push"), x, y[:-1], r)
    with pytest.raises(InputError, match="reactions R are required"):
        fit_transition(SkillTransitionModel("push"), x, y)
    with pytest.raises(InputError, match="no backward component"):
        fit_transition(SkillTransitionModel("push", backward=False), x, y, r)
    with pytest.raises(InputError, match="at least 2 training samples"):
        fit_transition(SkillTransitionModel("push"), x[:1], y[:1], r[:1])
    with pytest.raises(InputError, match="zero samples"):
        fit_transition(SkillTransitionModel("push"), x[:0], y[:0], r[:0])
    with pytest.raises(InputError, match="2-D"):
        fit_transition(SkillTransitionModel("push", backward=False), x, y[:, 0])

    with pytest.raises(InputError, match="n_experts must be a positive integer"):
        SkillTransitionModel("push", kind="mixture", n_experts=1.5)
    with pytest.raises(InputError, match="n_experts=2 needs kind='mixture'"):
        SkillTransitionModel("push", n_experts=2)
    with pytest.raises(InputError, match="max_iter must be a positive integer"):
        SkillTransitionModel("push", gp=GPOptions(max_iter=True))
    with pytest.raises(InputError, match="n_samples"):
        model.predict(xt, n_samples=2.5)
    with pytest.raises(InputError, match="n_samples draws the reaction"):
        forward_model.predict(xt, n_samples=10)
    with pytest.raises(InputError, match="generator"):
        model.predict(xt, n_samples=10, generator=3)
    with pytest.raises(InputError, match="does not predict reactions"):
        forward_model.predict_reaction(xt)
    with pytest.raises(InputError, match="outputscale"):
        SkillTransitionModel("push", gp=GPOptions(outputscale=0.0))
    with pytest.raises(InputError, match="noise_floor"):
        SkillTransitionModel("push", gp=GPOptions(noise_floor="high"))
    with pytest.raises(InputError, match="one standard deviation"):
        SkillTransitionModel("push", gp=GPOptions(noise_floor=[0.1, 0.2]))
    with pytest.raises(InputError, match="gp must be GPOptions"):
        MonolithicTransitionModel(2, gp={"max_iter": 5})
    with pytest.raises(TypeError, match="unexpected keyword"):
        SkillTransitionModel("push", max_iter=5)

    with pytest.raises(InputError, match="exceeds the 3 training samples"):
        fit_transition(
            SkillTransitionModel("push", kind="mixture", n_experts=4, backward=False), x[:3], y[:3]
        )
    with pytest.raises(InputError, match="fit_em's, for kind='mixture'"):
        fit_transition(SkillTransitionModel("push", backward=False), x, y, seed=1)
    with pytest.raises(InputError, match="unknown fitting option"):
        fit_transition(SkillTransitionModel("push", kind="mixture", backward=False), x, y, foo=1)
    with pytest.raises(InputError, match="fits a SkillTransitionModel"):
        fit_transition(GPExpert(3, 2), x, y)

    unfitted = SkillTransitionModel("push")
    with pytest.raises(NotFittedError, match="fit_transition"):
        unfitted.predict(xt)
    with pytest.raises(NotFittedError):
        unfitted.predict_reaction(xt)
    with pytest.raises(NotFittedError):
        MonolithicTransitionModel().predict(xt)


def test_the_old_flat_gp_keywords_are_refused_naming_gp_options():
    """Each old keyword gets one `InputError` naming the `GPOptions` field to give instead."""
    flat = "takes its GP settings as one GPOptions: use gp=GPOptions"
    with pytest.raises(InputError, match=rf"SkillTransitionModel {flat}\(max_iter=\.\.\.\)"):
        SkillTransitionModel("push", gp_max_iter=5)
    with pytest.raises(
        InputError, match=r"lengthscale_prior=\.\.\., noise_floor=\.\.\.\) instead of"
    ):
        SkillTransitionModel("push", kind="mixture", lengthscale_prior=True, noise_floor=0.1)
    with pytest.raises(InputError, match=rf"MonolithicTransitionModel {flat}\(outputscale="):
        MonolithicTransitionModel(2, outputscale=0.5)
    with pytest.raises(InputError, match=r"GPOptions\(noise=\.\.\.\) instead of noise"):
        MonolithicTransitionModel(2, noise=0.5)
    # the default is the thesis's settings: no prior, the automatic floor, theta_0 = 0.1
    assert SkillTransitionModel("push").gp == GPOptions(noise_floor="auto", outputscale=0.1)
    assert SkillTransitionModel("push").config()["gp"] is TRANSITION_GP


def test_registered_fitter_fits_the_model(data):
    (x, y, r), (xt, _, _) = data
    assert model_kind("transition").fit is fit_transition
    a = SkillTransitionModel("place", gp=replace(TRANSITION_GP, max_iter=5))
    b = SkillTransitionModel("place", gp=replace(TRANSITION_GP, max_iter=5))
    model_kind("transition").fit(a, x, y, R=r)
    fit_transition(b, x, y, r)
    assert a.is_fitted and torch.equal(a.predict(xt).mean, b.predict(xt).mean)


def _assert_same(a, b, xt, yt):
    assert torch.equal(a.mean, b.mean)
    assert torch.equal(a.variance, b.variance)
    assert torch.equal(a.log_prob(yt), b.log_prob(yt))


def test_save_load_round_trip_predicts_identically(tmp_path, data, backward_model):
    (x, y, r), (xt, yt, rt) = data
    model, _ = backward_model
    path = tmp_path / "push.pt"
    save(model, path)
    assert torch.load(path, weights_only=True)["format"] == FORMATS[SkillTransitionModel]
    loaded = load(path)
    assert type(loaded) is SkillTransitionModel and loaded.config() == model.config()
    _assert_same(model.predict(xt), loaded.predict(xt), xt, yt)
    _assert_same(model.predict_reaction(xt), loaded.predict_reaction(xt), xt, rt)
    _assert_same(model.predict(xt, n_samples=50), loaded.predict(xt, n_samples=50), xt, yt)

    mixture = SkillTransitionModel(
        "pick", kind="mixture", n_experts=2, gp=replace(TRANSITION_GP, max_iter=10)
    )
    fit_transition(mixture, x, y, r, n_restarts=1, max_iter=2, split_merge=0)
    save(mixture, tmp_path / "pick.pt")
    loaded_mixture = load(tmp_path / "pick.pt")
    assert loaded_mixture.config() == mixture.config()
    _assert_same(mixture.predict(xt), loaded_mixture.predict(xt), xt, yt)
    sampled = mixture.predict(xt, n_samples=30)
    assert sampled.batch_shape == (N_TEST,) and bool(torch.isfinite(sampled.variance).all())
    _assert_same(sampled, loaded_mixture.predict(xt, n_samples=30), xt, yt)
    with pytest.raises(NotFittedError):
        save(SkillTransitionModel("push"), tmp_path / "unfitted.pt")


def _scenes(n: int, seed: int) -> tuple[torch.Tensor, torch.Tensor]:
    """Two-object scenes: features (n, 4), 2 per object; effects (n, 4), 2 per object."""
    g = torch.Generator().manual_seed(seed)
    x = torch.rand(n, 4, generator=g, dtype=torch.float64) * 2 - 1
    y1 = torch.stack([torch.sin(2 * x[:, 0]), 0.5 * x[:, 1]], dim=1)
    y2 = torch.stack([0.5 * y1[:, 0] * (x[:, 2] > 0), 0.3 * x[:, 3]], dim=1)
    y = torch.cat([y1, y2], dim=1)
    return x, y + 0.02 * torch.randn(n, 4, generator=g, dtype=torch.float64)


def test_monolithic_model_fits_whole_scenes_and_refuses_other_sizes(tmp_path):
    x, y = _scenes(50, 0)
    xt, yt = _scenes(30, 1)
    model = MonolithicTransitionModel(2, gp=replace(TRANSITION_GP, max_iter=20))
    history = fit_transition(model, x, y)
    assert set(history.objective) == {"effect"} and history.n_samples == 50
    assert model.effect_size == 2 and model.n_outputs == 4 and isinstance(model, PushModel)
    pred = model.predict(xt)
    assert pred.batch_shape == (30,) and pred.event_shape == (4,)
    assert _rmse(pred.mean, yt) < 0.5 * _rmse(y.mean(0).expand_as(yt), yt)
    expert = model.expert
    assert expert.n_outputs == 4  # one GP with 2 E outputs

    three_objects = torch.cat([xt, xt[:, :2]], dim=1)
    with pytest.raises(InputError, match="scenes of 2 objects with 4 features"):
        model.predict(three_objects)
    with pytest.raises(InputError, match="cannot predict a scene of another size"):
        model.predict(xt[:, :2])
    with pytest.raises(InputError, match="a push model cannot predict pick"):
        model.predict(xt, skill="pick")
    with pytest.raises(InputError, match="not n_objects=2 times"):
        fit_transition(MonolithicTransitionModel(2), x, y[:, :3])
    with pytest.raises(InputError, match="no backward component"):
        fit_transition(MonolithicTransitionModel(2), x, y, y[:, :1])
    with pytest.raises(InputError, match="n_objects"):
        MonolithicTransitionModel(2.5)

    save(model, tmp_path / "mono.pt")
    loaded = load(tmp_path / "mono.pt")
    assert type(loaded) is MonolithicTransitionModel and loaded.config() == model.config()
    _assert_same(model.predict(xt), loaded.predict(xt), xt, yt)
