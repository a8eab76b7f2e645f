import itertools
import math

import pytest
import torch
from torch.distributions import MixtureSameFamily

from probaff._threads import torch_threads
from probaff.errors import InputError
from probaff.models import EMHistory, MixtureOfGPExperts, NotFittedError, fit_em
from probaff.models.synthetic import piecewise_1d


@pytest.fixture(autouse=True, scope="module")
def _single_thread():
    with torch_threads(1):
        yield


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
