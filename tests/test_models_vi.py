import math

import pyro
import pytest
import torch
from torch.distributions import MixtureSameFamily

from probaff._threads import torch_threads
from probaff.errors import InputError
from probaff.models import MixtureOfGPExperts, NotFittedError, fit_em
from probaff.models.synthetic import piecewise_1d
from probaff.models.vi import SVIHistory, VariationalMixtureOfGPExperts, fit_svi


@pytest.fixture(autouse=True, scope="module")
def _single_thread():
    with torch_threads(1):
        yield


def test_svi_matches_em_on_held_out_nlpd():
    x, y, _ = piecewise_1d(150, seed=0)
    xt, yt, _ = piecewise_1d(300, seed=1)
    em = MixtureOfGPExperts(3)
    fit_em(em, x, y)
    single = MixtureOfGPExperts(1)
    fit_em(single, x, y)

    rng_state = torch.get_rng_state()
    store_keys = set(pyro.get_param_store().keys())
    vi = VariationalMixtureOfGPExperts(3, n_inducing=16)
    history = fit_svi(vi, x, y, n_steps=300, batch_size=64, lr=0.05)
    assert isinstance(history, SVIHistory) and len(history.loss) == 300
    assert all(math.isfinite(v) for v in history.loss)
    assert sum(history.loss[-30:]) < sum(history.loss[:30])
    # global state is left alone
    assert torch.equal(torch.get_rng_state(), rng_state)
    assert set(pyro.get_param_store().keys()) == store_keys
    assert torch.get_default_dtype() == torch.float32

    nlpd = {
        name: -float(model.predict(xt).log_prob(yt).mean())
        for name, model in (("vi", vi), ("em", em), ("single", single))
    }
    assert abs(nlpd["vi"] - nlpd["em"]) < 0.5, nlpd
    assert nlpd["vi"] < nlpd["single"] - 0.75, nlpd

    dist = vi.predict(xt[:5])
    assert isinstance(dist, MixtureSameFamily)
    assert dist.mean.shape == (5, 2) and dist.log_prob(yt[:5]).shape == (5,)
    torch.testing.assert_close(vi.gate_probs(xt[:5]).sum(1), torch.ones(5, dtype=torch.float64))
    assert vi.expert_predictions(xt[:5]).mean.shape == (5, 3, 2)


def test_svi_is_deterministic_and_validates_inputs():
    x, y, _ = piecewise_1d(40, seed=2)
    runs = []
    for _ in range(2):
        model = VariationalMixtureOfGPExperts(2, n_inducing=8)
        history = fit_svi(model, x, y, n_steps=15, batch_size=16, seed=3)
        runs.append((history.loss, model.predict(x).mean))
    assert runs[0][0] == runs[1][0] and torch.equal(runs[0][1], runs[1][1])

    with pytest.raises(NotFittedError, match="fit_svi"):
        VariationalMixtureOfGPExperts(2).predict(x)
    with pytest.raises(InputError, match="exceeds"):
        fit_svi(VariationalMixtureOfGPExperts(41), x, y, n_steps=1)
    with pytest.raises(InputError, match="samples but effects Y"):
        fit_svi(VariationalMixtureOfGPExperts(2), x, y[:-1], n_steps=1)
    with pytest.raises(InputError, match="unknown feature group"):
        VariationalMixtureOfGPExperts(2, gate_features=("f_x",))
