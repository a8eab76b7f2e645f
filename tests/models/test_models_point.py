"""The stacked point prediction: weights with a known answer, held-out RMSE, persistence."""

import pytest
import torch

from probaff.errors import InputError
from probaff.models import MixtureOfGPExperts, fit_em, load, point_prediction, save
from probaff.models.mixture.point import out_of_fold_gate, stacking_weights
from probaff.models.synthetic import softmax_regimes

pytestmark = pytest.mark.usefixtures("single_thread")


FAST = {"n_restarts": 1, "split_merge": 0}  # the point does not depend on the search


def _rmse(point, y):
    return ((point - y) ** 2).mean(0).sqrt()


def test_stacking_weights_recover_a_known_combination():
    g = torch.Generator().manual_seed(0)
    a = torch.randn(200, 3, generator=g, dtype=torch.float64)
    b = torch.randn(200, 3, generator=g, dtype=torch.float64)
    alpha = torch.tensor([0.3, 0.0, 1.0], dtype=torch.float64)
    y = alpha * a + (1 - alpha) * b
    torch.testing.assert_close(stacking_weights(a, b, y), alpha)
    # weights outside [0, 1] are clipped; identical predictions weigh the mixture 1
    assert float(stacking_weights(a[:, :1], b[:, :1], 2 * a[:, :1] - b[:, :1])) == 1.0
    assert float(stacking_weights(a[:, :1], b[:, :1], 2 * b[:, :1] - a[:, :1])) == 0.0
    assert float(stacking_weights(a[:, :1], a[:, :1], b[:, :1])) == 1.0


@pytest.fixture(scope="module")
def smooth():
    """One smooth function without regimes: the experts only split the data between them."""
    g = torch.Generator().manual_seed(3)
    x = 6 * torch.rand(200, 1, generator=g, dtype=torch.float64) - 3
    y = torch.sin(1.5 * x) + 0.1 * torch.randn(200, 1, generator=g, dtype=torch.float64)
    return x[:100], y[:100], x[100:], y[100:]


@pytest.fixture(scope="module")
def fitted(smooth):
    x, y, _, _ = smooth
    stacked = MixtureOfGPExperts(3, point="stacked")
    fit_em(stacked, x, y, seed=0, **FAST)
    mean = MixtureOfGPExperts(3)  # point="mean", the default
    fit_em(mean, x, y, seed=0, **FAST)
    single = MixtureOfGPExperts(1)
    fit_em(single, x, y, seed=0, **FAST)
    return stacked, mean, single


def test_stacked_point_is_no_worse_than_either_prediction_held_out(smooth, fitted):
    _, _, xt, yt = smooth
    stacked, mean_only, single = fitted
    # the point option does not change the fit or the predictive distribution
    torch.testing.assert_close(stacked.predict(xt).mean, mean_only.predict(xt).mean)
    assert stacked.point_weights is not None and stacked.point_weights.shape == (1,)
    point = _rmse(stacked.predict_point(xt), yt)
    mixture = _rmse(stacked.predict(xt).mean, yt)
    gp = _rmse(single.predict_point(xt), yt)
    assert float(point) <= min(float(mixture), float(gp)) * 1.02, (point, mixture, gp)


def test_gated_regimes_keep_the_mixtures_mean():
    x, y, _ = softmax_regimes(250, seed=0)
    xt, yt, _ = softmax_regimes(250, seed=1)
    model = MixtureOfGPExperts(3, point="stacked")
    fit_em(model, x, y, seed=0, **FAST)
    single = MixtureOfGPExperts(1)
    fit_em(single, x, y, seed=0, **FAST)
    assert model.point_weights is not None and bool((model.point_weights > 0.8).all())
    point = _rmse(model.predict_point(xt), yt)
    assert bool((point < 0.8 * _rmse(single.predict_point(xt), yt)).all())


def test_mean_option_single_expert_and_the_interface(smooth, fitted):
    _, _, xt, _ = smooth
    stacked, mean_only, single = fitted
    for model in (mean_only, single):
        assert model.point_expert is None
        torch.testing.assert_close(model.predict_point(xt), model.predict(xt).mean)
    mean = stacked.predict(xt).mean
    torch.testing.assert_close(stacked.predict_point(xt, mean=mean), stacked.predict_point(xt))
    torch.testing.assert_close(point_prediction(stacked, xt), stacked.predict_point(xt))
    with pytest.raises(InputError, match="point must be one of"):
        MixtureOfGPExperts(2, point="median")


def test_out_of_fold_gate_gives_probabilities(smooth, fitted):
    x, y, _, _ = smooth
    model = fitted[0]
    resp = torch.softmax(model.loo_log_joint(x, y), dim=1)
    probs = out_of_fold_gate(model.built_gate(), x, resp, seed=0)
    assert probs.shape == resp.shape
    torch.testing.assert_close(probs.sum(1), torch.ones(len(x), dtype=torch.float64))
    # the fitted gate is left as it was
    torch.testing.assert_close(model.gate_probs(x), model.gate_probs(x))


def test_saved_stacked_point_loads_and_predicts_the_same(smooth, fitted, tmp_path):
    _, _, xt, _ = smooth
    model = fitted[0]
    save(model, tmp_path / "stacked.pt")
    back = load(tmp_path / "stacked.pt")
    assert back.point == "stacked" and back.point_expert is not None
    torch.testing.assert_close(back.predict_point(xt), model.predict_point(xt))
