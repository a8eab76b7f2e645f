from dataclasses import replace

import pytest
import torch
from torch.distributions import Distribution

from probaff.errors import InputError
from probaff.models import (
    MIXTURE_GP,
    ClusteredGPModel,
    EMHistory,
    GatedMixture,
    GPOptions,
    MixtureOfGPExperts,
    PushModel,
    SVIHistory,
    VariationalMixtureOfGPExperts,
    fit_em,
    fit_svi,
    model_kind,
)
from probaff.models.experts.gp_expert import GPExpert
from probaff.models.gates.gated import ExpertList
from probaff.models.synthetic import piecewise_1d

pytestmark = pytest.mark.usefixtures("single_thread")


@pytest.fixture(scope="module")
def data():
    x, y, _ = piecewise_1d(50, seed=0)
    xt, yt, _ = piecewise_1d(20, seed=1)
    return x, y, xt, yt


def _fitted(name, x, y):
    if name == "em":
        model = MixtureOfGPExperts(2, gp=replace(MIXTURE_GP, max_iter=10))
        _fitter("em")(model, x, y, init="effects", max_iter=2, n_restarts=1, split_merge=0)
    elif name == "svi":
        model = VariationalMixtureOfGPExperts(2, n_inducing=8)
        _fitter("svi")(model, x, y, n_steps=5, batch_size=25, init="effects")
    else:
        model = ClusteredGPModel(2, gp=GPOptions(max_iter=10))
        assert _fitter("clustered")(model, x, y) is model
    return model


@pytest.mark.parametrize("name", ["em", "svi", "clustered"])
def test_every_fitted_model_is_a_push_model(data, name):
    x, y, xt, yt = data
    model = _fitted(name, x, y)
    assert isinstance(model, PushModel)
    assert model.n_outputs == y.shape[1]
    pred = model.predict(xt)
    assert isinstance(pred, Distribution)
    assert pred.batch_shape == (len(xt),) and pred.event_shape == (y.shape[1],)
    assert pred.mean.shape == yt.shape and pred.variance.shape == yt.shape
    assert bool((pred.variance > 0).all())
    log_prob = pred.log_prob(yt)
    assert log_prob.shape == (len(xt),) and bool(torch.isfinite(log_prob).all())
    hard = model.predict(xt, gating="hard")
    assert torch.equal(
        hard.mixture_distribution.probs.sum(1), torch.ones(len(xt), dtype=hard.mean.dtype)
    )
    with pytest.raises(InputError, match="gating"):
        model.predict(xt, gating="median")


def test_mixtures_share_the_gated_base(data):
    x, y, xt, _ = data
    for name in ("em", "svi"):
        model = _fitted(name, x, y)
        assert isinstance(model, GatedMixture)
        assert isinstance(model.experts, ExpertList) and len(model.experts) == 2
        probs = model.gate_probs(xt)
        torch.testing.assert_close(probs.sum(1), torch.ones(len(xt), dtype=torch.float64))
        assert model.expert_predictions(xt).loc.shape == (len(xt), 2, y.shape[1])
        assert model.config()["n_experts"] == 2
    em = _fitted("em", x, y)
    assert all(isinstance(e, GPExpert) for e in em.experts)
    assert isinstance(em.experts[0], GPExpert) and isinstance(em.experts[:1], ExpertList)
    assert em.train_weights.shape == (len(x), 2)
    # the state-dict keys are those of a plain ModuleList
    assert any(k.startswith("experts.0.") for k in em.state_dict())
    with pytest.raises(TypeError):
        GatedMixture(2)  # abstract


def test_unfitted_models_are_push_models_without_outputs():
    for model in (MixtureOfGPExperts(2), VariationalMixtureOfGPExperts(2), ClusteredGPModel(2)):
        assert isinstance(model, PushModel) and model.n_outputs is None
    assert not isinstance(object(), PushModel)


def _fitter(name):
    return model_kind(name).fit


def test_each_kind_fits_by_name(data):
    assert _fitter("em") is fit_em and _fitter("svi") is fit_svi
    x, y, _, _ = data
    assert isinstance(
        _fitter("em")(
            MixtureOfGPExperts(1, gp=replace(MIXTURE_GP, max_iter=5)),
            x,
            y,
            init="effects",
            max_iter=1,
            n_restarts=1,
            split_merge=0,
        ),
        EMHistory,
    )
    assert isinstance(
        _fitter("svi")(
            VariationalMixtureOfGPExperts(1, n_inducing=4), x, y, n_steps=2, init="effects"
        ),
        SVIHistory,
    )
    with pytest.raises(
        InputError,
        match=r"unknown model kind 'vb'; registered: \[.*'clustered'.*'svi'.*\]",
    ):
        _fitter("vb")
    with pytest.raises(InputError, match="ClusteredGPModel"):
        _fitter("clustered")(MixtureOfGPExperts(2), x, y)
