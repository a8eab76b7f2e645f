import copy

import pyro
import pytest
import torch
from pyro.infer import TraceEnum_ELBO

from probaff.models import MixtureOfGPExperts, fit_em
from probaff.models.synthetic import softmax_regimes
from probaff.models.variational import svi_fixed
from probaff.models.variational.svi import fit_svi
from probaff.models.variational.svi_fixed import FixedHyperparameterSVI
from probaff.models.variational.vi import VariationalMixtureOfGPExperts, WhitenedQ

pytestmark = pytest.mark.usefixtures("single_thread")


def _built(n_inducing: int = 10):
    x, y, _ = softmax_regimes(90, seed=3)
    em = MixtureOfGPExperts(3, gate_features=[0, 1])
    fit_em(em, x, y, n_restarts=1, split_merge=0, max_iter=3)
    vi = VariationalMixtureOfGPExperts(3, gate_features=[0, 1], n_inducing=n_inducing)
    vi.build(x, y, torch.softmax(em.log_joint(x, y), dim=1), em)
    x_scaler, y_scaler = vi.scalers()
    return vi, x[:, vi.gate_columns], x_scaler(x[:, vi.expert_columns]), y_scaler(y)


def _q(model: VariationalMixtureOfGPExperts) -> list[torch.Tensor]:
    out = []
    for expert in model.experts:
        variational = expert.variational_strategy._variational_distribution
        out += [variational.variational_mean.detach(), variational.chol_variational_covar.detach()]
    return out


def test_a_step_is_pyros_elbo_and_the_natural_update():
    vi, x_g, x_e, t = _built()
    with torch.no_grad():  # away from the optimum, so that the step moves q(u)
        for expert in vi.experts:
            expert.variational_strategy._variational_distribution.variational_mean.add_(0.2)
    reference = copy.deepcopy(vi)
    idx = torch.tensor([3, 17, 40, 41, 59, 88, 5, 70])
    n, scale = x_g.shape[0], x_g.shape[0] / 8
    with pyro.get_param_store().scope(), torch.no_grad():
        pyro_loss = float(
            TraceEnum_ELBO(max_plate_nesting=1).loss(
                reference.model, reference.guide, x_g, x_e, t, idx
            )
        )
    reference.update_variational(x_g[idx], x_e[idx], t[idx], scale=scale, step=0.3)
    fixed = FixedHyperparameterSVI(vi, x_g, x_e, t)
    loss = fixed.step(idx, scale=scale, step=0.3)
    fixed.store()
    assert loss == pytest.approx(pyro_loss, rel=1e-10, abs=1e-8 * n)
    for ours, theirs in zip(_q(vi), _q(reference), strict=True):
        torch.testing.assert_close(ours, theirs, rtol=1e-8, atol=1e-10)
    # the moments from the projection are gpytorch's
    expert = vi.experts[1]
    mean, var = expert.moments(x_e[idx])
    a = expert.projection(x_e[idx], expert.inducing_factor())
    torch.testing.assert_close(expert.projected_moments(x_e[idx], a), (mean, var))


def test_fit_svi_from_an_exact_mixture_takes_the_fixed_path():
    x, y, _ = softmax_regimes(90, seed=3)
    xt, yt, _ = softmax_regimes(300, seed=4)
    em = MixtureOfGPExperts(3, gate_features=[0, 1])
    fit_em(em, x, y, n_restarts=1, split_merge=0, max_iter=3)
    fits = []
    for _ in range(2):
        vi = VariationalMixtureOfGPExperts(3, gate_features=[0, 1], n_inducing=30)
        history = fit_svi(vi, x, y, n_steps=30, batch_size=16, init=em)
        fits.append((history.loss, vi.predict(xt).log_prob(yt)))
    assert fits[0][0] == fits[1][0]  # deterministic
    torch.testing.assert_close(fits[0][1], fits[1][1], rtol=0, atol=0)
    assert len(fits[0][0]) == 30 and bool(torch.isfinite(torch.tensor(fits[0][0])).all())
    nlpd_vi = -float(fits[0][1].mean())
    nlpd_em = -float(em.predict(xt).log_prob(yt).mean())
    assert nlpd_vi < nlpd_em + 0.1, (nlpd_vi, nlpd_em)  # held out


def test_whitened_q_holds_gpytorchs_kl_and_moves_linearly():
    vi, _, _, _ = _built()
    expert = vi.experts[0]
    with torch.no_grad():
        expert.variational_strategy._variational_distribution.variational_mean.add_(0.3)
    q = WhitenedQ.of(expert)
    assert q.kl == pytest.approx(float(expert.kl_divergence().sum()), rel=1e-10)
    torch.testing.assert_close(q.root.mT @ q.root, torch.linalg.inv(q.precision))
    eye = torch.eye(q.precision.shape[-1], dtype=q.precision.dtype).expand_as(q.precision)
    target = WhitenedQ(2.0 * eye, torch.zeros_like(q.shift))
    half = q.moved(target.precision, target.shift, 0.5)
    torch.testing.assert_close(half.precision, 0.5 * (q.precision + target.precision))
    full = q.moved(target.precision, target.shift, 1.0)
    torch.testing.assert_close(full.mean, torch.zeros_like(q.mean))


def test_projections_kept_or_recomputed_give_the_same_steps(monkeypatch):
    losses = []
    for cache in (svi_fixed._PROJECTION_CACHE_BYTES, 0):
        monkeypatch.setattr(svi_fixed, "_PROJECTION_CACHE_BYTES", cache)
        vi, x_g, x_e, t = _built()
        fixed = FixedHyperparameterSVI(vi, x_g, x_e, t)
        assert (fixed.projections is None) == (cache == 0)
        g = torch.Generator().manual_seed(0)
        steps = [fixed.step(torch.randperm(90, generator=g)[:16], scale=90 / 16, step=0.2)]
        steps += [fixed.step(torch.randperm(90, generator=g)[:16], scale=90 / 16, step=0.2)]
        fixed.store()
        losses.append((steps, _q(vi)))
    assert losses[0][0] == pytest.approx(losses[1][0], rel=1e-12)
    for ours, theirs in zip(losses[0][1], losses[1][1], strict=True):
        torch.testing.assert_close(ours, theirs)
