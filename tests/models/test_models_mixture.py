import itertools
import math
from dataclasses import replace

import pytest
import torch
from torch.distributions import MixtureSameFamily

from probaff.errors import InputError
from probaff.models import (
    EMHistory,
    GPExpert,
    GPOptions,
    MixtureOfGPExperts,
    NotFittedError,
    SparseGPOptions,
    fit_em,
    fit_em_path,
)
from probaff.models.experts.sparse_expert import FitMemoryError, SparseGPExpert
from probaff.models.mixture import model as mixture_module
from probaff.models.mixture.model import AUTO_SPARSE_ABOVE, MIXTURE_GP
from probaff.models.synthetic import piecewise_1d

pytestmark = pytest.mark.usefixtures("single_thread")


@pytest.fixture(scope="module")
def data():
    return piecewise_1d(150, seed=0), piecewise_1d(300, seed=1)


@pytest.fixture(scope="module")
def fitted(data):
    (x, y, _), _ = data
    model = MixtureOfGPExperts(3)
    history = fit_em(model, x, y, seed=0)
    return model, history


def _accuracy(assign: torch.Tensor, labels: torch.Tensor, m: int) -> float:
    return max(
        float((torch.tensor(p)[assign] == labels).double().mean())
        for p in itertools.permutations(range(m))
    )


def test_em_recovers_assignments_and_beats_single_gp(data, fitted):
    (x, y, labels), (xt, yt, _) = data
    model, history = fitted
    assert isinstance(history, EMHistory)
    assert 1 <= history.n_iter <= 10
    assert all(math.isfinite(v) for v in history.objective)
    accuracy = _accuracy(history.responsibilities.argmax(1), labels, 3)
    assert accuracy >= 0.95, accuracy

    single = MixtureOfGPExperts(1)
    fit_em(single, x, y)
    nlpd_mix = -float(model.predict(xt).log_prob(yt).mean())
    nlpd_one = -float(single.predict(xt).log_prob(yt).mean())
    assert nlpd_mix < nlpd_one - 0.75, (nlpd_mix, nlpd_one)


def test_predictive_distribution_api(data, fitted):
    (_, _, _), (xt, yt, _) = data
    model, _ = fitted
    xs = xt[:7]
    dist = model.predict(xs)
    assert isinstance(dist, MixtureSameFamily)
    assert dist.batch_shape == (7,) and dist.event_shape == (2,)
    assert dist.mean.shape == dist.variance.shape == (7, 2)
    assert dist.sample(torch.Size([4])).shape == (4, 7, 2)
    assert dist.log_prob(yt[:7]).shape == (7,)
    probs = model.gate_probs(xs)
    torch.testing.assert_close(probs.sum(1), torch.ones(7, dtype=torch.float64))
    experts = model.expert_predictions(xs)
    assert experts.mean.shape == (7, 3, 2)
    torch.testing.assert_close(dist.mean, (probs[:, :, None] * experts.mean).sum(1))
    assert [ls.shape for ls in model.lengthscales()] == [(2, 1)] * 3


def test_same_seed_same_fit(data, fitted):
    (x, y, _), (xt, _, _) = data
    model, history = fitted
    again = MixtureOfGPExperts(3)
    history2 = fit_em(again, x, y, seed=0)
    assert history.objective == history2.objective
    assert torch.equal(history.responsibilities, history2.responsibilities)
    a, b = model.predict(xt), again.predict(xt)
    assert torch.equal(a.mean, b.mean) and torch.equal(a.variance, b.variance)


def test_feature_groups_select_columns():
    (x1, y, labels) = piecewise_1d(90, seed=3)
    noise = torch.randn(90, 2, generator=torch.Generator().manual_seed(0), dtype=torch.float64)
    x = torch.cat([noise[:, :1], x1, noise[:, 1:]], dim=1)
    groups = {"f_junk": [0, 2], "f_x": slice(1, 2)}
    model = MixtureOfGPExperts(3, groups=groups, gate_features=("f_x",), expert_features="f_x")
    history = fit_em(model, x, y, max_iter=5)
    assert model.gate_columns == [1] and model.expert_columns == [1]
    assert _accuracy(history.responsibilities.argmax(1), labels, 3) >= 0.9
    assert model.config()["groups"] == {"f_junk": [0, 2], "f_x": [1]}


def test_duplicate_inputs_and_single_expert_stay_finite():
    x, y, _ = piecewise_1d(20, seed=5)
    x = torch.cat([x, x])
    y = torch.cat([y, y])
    for m in (1, 2):
        model = MixtureOfGPExperts(m)
        history = fit_em(model, x, y, max_iter=3)
        assert all(math.isfinite(v) for v in history.objective)
        assert torch.isfinite(model.predict(x).log_prob(y)).all()


def test_bad_inputs_raise_clear_errors():
    x, y, _ = piecewise_1d(12, seed=6)
    bad = x.clone()
    bad[3, 0] = math.nan
    with pytest.raises(InputError, match="NaN"):
        fit_em(MixtureOfGPExperts(2), bad, y)
    inf_y = y.clone()
    inf_y[0, 1] = math.inf
    with pytest.raises(InputError, match="infinite"):
        fit_em(MixtureOfGPExperts(2), x, inf_y)
    with pytest.raises(
        InputError, match=r"12 samples but effects Y has 11|11 samples but effects Y has 12"
    ):
        fit_em(MixtureOfGPExperts(2), x[:11], y)
    with pytest.raises(InputError, match="zero samples"):
        fit_em(MixtureOfGPExperts(1), x[:0], y[:0])
    with pytest.raises(InputError, match="exceeds the 12 training samples"):
        fit_em(MixtureOfGPExperts(13), x, y)
    with pytest.raises(InputError, match="2-D"):
        fit_em(MixtureOfGPExperts(2), x[:, 0], y)
    with pytest.raises(InputError, match=r"unknown feature group.*known groups: f_x"):
        MixtureOfGPExperts(2, groups={"f_x": [0]}, gate_features=("f_o",))
    with pytest.raises(InputError):
        MixtureOfGPExperts(0)
    with pytest.raises(NotFittedError, match="fit_em"):
        MixtureOfGPExperts(2).predict(x)
    model = MixtureOfGPExperts(2)
    fit_em(model, x, y, max_iter=1, min_size=1.0)
    with pytest.raises(InputError, match="shape"):
        model.predict(torch.zeros(3, 2, dtype=torch.float64))


def test_expert_kind_is_chosen_by_training_size():
    model = MixtureOfGPExperts(2)
    assert model.config()["experts"] == "auto" and model.config()["n_inducing"] is None
    model.build(3, 2, n_samples=AUTO_SPARSE_ABOVE)
    assert all(isinstance(e, GPExpert) for e in model.experts)
    model.build(3, 2, n_samples=AUTO_SPARSE_ABOVE + 1)
    assert all(isinstance(e, SparseGPExpert) for e in model.experts)
    model.build(3, 2)  # without a size, the last kind is kept
    assert model.built_expert_kind == "sparse" and isinstance(model.experts[1], SparseGPExpert)
    sparse = MixtureOfGPExperts(2, experts="sparse", n_inducing=7)
    sparse.build(3, 2, n_samples=10)
    assert isinstance(sparse.experts[0], SparseGPExpert)
    assert sparse.experts[0].options.n_inducing == 7
    rebuilt = MixtureOfGPExperts(**sparse.config())
    assert rebuilt.config() == sparse.config()
    exact = MixtureOfGPExperts(2, experts="exact")
    exact.build(3, 2, n_samples=AUTO_SPARSE_ABOVE + 1)
    assert isinstance(exact.experts[0], GPExpert)


def test_sparse_experts_fit_by_em_and_the_path_never_falls():
    (x, y, _), (xt, yt, _) = piecewise_1d(90, seed=0), piecewise_1d(300, seed=1)
    template = MixtureOfGPExperts(
        1, experts="sparse", n_inducing=15, gp=replace(MIXTURE_GP, max_iter=20)
    )
    quick = {"max_iter": 3, "n_restarts": 2, "split_merge": 1}
    path = fit_em_path(template, x, y, (1, 2, 3), **quick)
    best = [path[m][1].best for m in (1, 2, 3)]
    assert best[0] <= best[1] + 1e-9 <= best[2] + 2e-9, best
    model, _ = path[3]
    assert all(isinstance(e, SparseGPExpert) for e in model.experts)
    assert all(e.n_inducing <= 15 for e in model.experts)
    loo = model.loo_log_lik(x, y)
    assert loo.shape == (90, 3) and bool(torch.isfinite(loo).all())
    # a held sample is scored by its leave-one-out density, any other by the predictive
    pred = model.expert_predictions(x)
    for j, expert in enumerate(model.experts):
        held = model.train_weights[:, j] > 0
        out = expert.loo_predict()
        want = pred.log_prob(y[:, None, :]).sum(-1)[:, j]
        want[held] = out.log_prob(y[held]).sum(-1)
        torch.testing.assert_close(loo[:, j], want, rtol=1e-10, atol=1e-10)
    sparse_lp = float(model.predict(xt).log_prob(yt).mean())
    exact = MixtureOfGPExperts(3, experts="exact", gp=replace(MIXTURE_GP, max_iter=20))
    fit_em(exact, x, y, **quick)
    exact_lp = float(exact.predict(xt).log_prob(yt).mean())
    # 15 inducing points per output summarise a 1-D regime almost exactly
    assert sparse_lp > exact_lp - 0.1, (sparse_lp, exact_lp)


def test_bad_expert_settings_raise_clear_errors(monkeypatch):
    x, y, _ = piecewise_1d(30, seed=6)
    with pytest.raises(InputError, match=r"experts must be one of \['auto', 'exact', 'sparse'\]"):
        MixtureOfGPExperts(2, experts="fitc")
    for bad in (0, -2, 1.5, "64"):
        with pytest.raises(InputError, match="n_inducing"):
            MixtureOfGPExperts(2, n_inducing=bad)
    with pytest.raises(InputError, match="n_inducing=31 exceeds the 30 training rows"):
        fit_em(MixtureOfGPExperts(2, experts="sparse", n_inducing=31), x, y)
    with pytest.raises(FitMemoryError, match="experts='sparse'"):
        MixtureOfGPExperts(3, experts="exact").build(101, 6, n_samples=10**6)
    monkeypatch.setattr(mixture_module, "available_memory_bytes", lambda: 10**5)
    with pytest.raises(FitMemoryError, match="smaller n_inducing"):
        fit_em(MixtureOfGPExperts(2, experts="sparse"), x, y)
    with pytest.raises(FitMemoryError, match="GiB of memory is available"):
        fit_em(MixtureOfGPExperts(2), x, y)


def test_lasso_gate_is_the_default_and_chosen_by_cross_validation():
    from probaff.models.synthetic import regime_features

    x, y, _ = regime_features(160, 40, 2, seed=0)
    model = MixtureOfGPExperts(3, gp=replace(MIXTURE_GP, max_iter=10))
    assert model.config()["gate_l1"] == "cv" and model.config()["gate_l2"] == "cv"
    fit_em(model, x, y, seed=0, max_iter=3, n_restarts=1, split_merge=0)
    gate = model.built_gate()
    assert gate.l1 == "cv" and gate.l2 == "cv"
    assert len(gate.penalties_) == len(gate.l2_grid_) + len(gate.l1_grid_)
    ridge = MixtureOfGPExperts(3, gp=replace(MIXTURE_GP, max_iter=10), gate_l1=0.0)
    assert len(ridge.config()) == len(model.config())
    with pytest.raises(InputError, match="gate_l1"):
        MixtureOfGPExperts(3, gate_l1="lasso")
    with pytest.raises(InputError, match="gate_l1"):
        MixtureOfGPExperts(3, gate_l1=-0.5)


def test_files_without_a_lasso_gate_load_as_ridge_gates(tmp_path):
    from probaff.models import load, save
    from probaff.models.mixture.em import _dump, _restore

    x, y, _ = piecewise_1d(40, seed=2)
    model = MixtureOfGPExperts(2, gate_l1=0.0, gp=replace(MIXTURE_GP, max_iter=5))
    fit_em(model, x, y, max_iter=2, n_restarts=1, split_merge=0)
    payload = _dump(model)
    del payload["config"]["gate_l1"]  # as written before the gate had a lasso penalty
    restored = _restore(payload)
    assert restored.gate_l1 == 0.0
    torch.testing.assert_close(restored.predict(x).mean, model.predict(x).mean)
    save(model, tmp_path / "m.pt")
    assert load(tmp_path / "m.pt").config() == model.config()


def test_the_experts_settings_travel_whole_as_one_gp_options():
    x, y, _ = piecewise_1d(40, seed=2)
    assert MixtureOfGPExperts(2).gp is MIXTURE_GP  # the default: prior on, floor "auto"
    assert GPOptions(max_iter=50, lengthscale_prior=True, noise_floor="auto") == MIXTURE_GP
    gp = GPOptions(max_iter=7, lengthscale_prior=0.5, noise_floor=[0.01, 0.02], noise=0.2)
    model = MixtureOfGPExperts(2, gp=gp)
    assert model.gp is gp and model.config()["gp"] is gp
    fit_em(model, x, y, max_iter=2, n_restarts=1, split_merge=0)
    for expert in model.experts:  # every field reaches the experts, the floor resolved
        assert expert.options == gp and expert.max_iter == 7
        assert expert.lengthscale_prior == 0.5 and expert.initial_noise == 0.2
        assert expert.noise_floor.tolist() == [0.01, 0.02]
    sparse = MixtureOfGPExperts(2, gp=gp, experts="sparse", n_inducing=10, hyper_rows=None)
    fit_em(sparse, x, y, max_iter=1, n_restarts=1, split_merge=0)
    for expert in sparse.experts:
        assert isinstance(expert, SparseGPExpert)
        options = expert.options
        assert isinstance(options, SparseGPOptions)
        assert (options.max_iter, options.lengthscale_prior, options.noise) == (7, 0.5, 0.2)
        assert (options.n_inducing, options.hyper_rows) == (10, None)
    # "auto": 1 % of each effect's std over the whole training set, for every expert
    auto = MixtureOfGPExperts(2)
    fit_em(auto, x, y, max_iter=1, n_restarts=1, split_merge=0)
    want = 0.01 * y.std(dim=0, correction=0)
    for expert in auto.experts:
        assert torch.equal(expert.noise_floor, want)


def test_the_old_keywords_and_other_options_are_refused_by_name():
    for old, field in (
        ("gp_max_iter", "max_iter"),
        ("lengthscale_prior", "lengthscale_prior"),
        ("noise_floor", "noise_floor"),
    ):
        with pytest.raises(
            InputError, match=rf"use gp=GPOptions\({field}=\.\.\.\) instead of {old}"
        ):
            MixtureOfGPExperts(2, **{old: 1})
    with pytest.raises(InputError, match="gp must be GPOptions"):
        MixtureOfGPExperts(2, gp={"max_iter": 5})
    with pytest.raises(InputError, match="n_inducing and hyper_rows as its own arguments"):
        MixtureOfGPExperts(2, gp=SparseGPOptions(n_inducing=10))


def test_a_single_expert_resolves_the_auto_noise_floor_as_a_mixture_does():
    x, y, _ = piecewise_1d(40, seed=3)
    weights = torch.linspace(0.0, 1.0, 40, dtype=torch.float64)  # the first row weighs 0
    expert = GPExpert(1, 2, GPOptions(noise_floor="auto", max_iter=3)).fit(x, y, weights)
    # every row given counts, whatever its weight: the mixture's experts get the whole set
    assert torch.equal(expert.noise_floor, 0.01 * y.std(dim=0, correction=0))
    expert.condition(x[:20], y[:20])
    assert torch.equal(expert.noise_floor, 0.01 * y[:20].std(dim=0, correction=0))
    assert GPExpert(1, 2, noise_floor="auto").noise_floor.tolist() == [0.0, 0.0]  # until data
