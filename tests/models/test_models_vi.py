import math

import pyro
import pytest
import torch
from pyro.infer import TraceEnum_ELBO
from torch.distributions import MixtureSameFamily

from probaff.errors import InputError
from probaff.models import MixtureOfGPExperts, NotFittedError, fit_em
from probaff.models.synthetic import piecewise_1d, regime_features
from probaff.models.variational.svi import SVIHistory, fit_svi
from probaff.models.variational.vi import SVGPExpert, VariationalMixtureOfGPExperts

pytestmark = pytest.mark.usefixtures("single_thread")


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
    history = fit_svi(vi, x, y, n_steps=40, batch_size=150, lr=0.01)
    assert isinstance(history, SVIHistory) and len(history.loss) == 40
    assert all(math.isfinite(v) for v in history.loss)
    # q(u) starts at its optimum given the EM start, and full-batch steps keep it there
    assert sum(history.loss[-10:]) < sum(history.loss[:10]) + 1e-6
    # global state is left alone
    assert torch.equal(torch.get_rng_state(), rng_state)
    assert set(pyro.get_param_store().keys()) == store_keys
    assert torch.get_default_dtype() == torch.float32

    nlpd = {
        name: -float(model.predict(xt).log_prob(yt).mean())
        for name, model in (("vi", vi), ("em", em), ("single", single))
    }
    assert abs(nlpd["vi"] - nlpd["em"]) < 0.1, nlpd  # nats per point
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


def _spike_ratio(loss: list[float], half_window: int = 5) -> float:
    """Largest distance of a step's loss from the median of the steps around it.

    Measured in units of the median absolute step-to-step change around it, so a steep
    but smooth descent scores a few units and an isolated jump scores its size over the
    local noise.

    Args:
        loss: Per-step losses, `(T,)`.
        half_window: Steps on either side of the window.

    Returns:
        The largest ratio over all steps.
    """
    v = torch.tensor(loss, dtype=torch.float64)
    jumps = v.diff().abs()
    worst = 0.0
    for i in range(len(v)):
        lo, hi = max(0, i - half_window), min(len(v), i + half_window + 1)
        scale = jumps[lo : hi - 1].median().clamp_min(1e-12)
        worst = max(worst, float((v[i] - v[lo:hi].median()).abs() / scale))
    return worst


def test_svi_loss_has_no_spikes():
    # With 10k rows Adam soon makes the Cholesky factor of q(u) ill-conditioned (condition
    # number > 1e16); a single-sample KL estimate, which solves with that factor, then
    # produced losses down to -1e126 per sample within these 30 steps.
    x, y, _ = regime_features(10_000, 15, 6, seed=0)
    vi = VariationalMixtureOfGPExperts(3, gate_features=[0, 1, 2], n_inducing=64)
    loss = fit_svi(vi, x, y, n_steps=30, batch_size=256, seed=0, init="effects").loss
    assert len(loss) == 30 and all(math.isfinite(v) for v in loss)
    # KL >= 0 and the gate penalty >= 0, so -ELBO / N is at least minus the largest
    # Gaussian log-density, which the noise floor of 1e-6 (standardised units) caps.
    floor = 0.5 * y.shape[1] * math.log(2 * math.pi * 1e-6)
    assert min(loss) >= floor, min(loss)
    assert _spike_ratio(loss) < 50, loss


def test_expert_kl_is_closed_form_for_ill_conditioned_factor():
    g = torch.Generator().manual_seed(0)
    n_outputs, k = 2, 24
    expert = SVGPExpert(torch.randn(n_outputs, k, 3, generator=g, dtype=torch.float64)).double()
    variational = expert.variational_strategy._variational_distribution
    diag = torch.full((n_outputs, k), 0.02, dtype=torch.float64)
    diag[:, ::5] = 1e-9
    chol = torch.diag_embed(diag) + 0.3 * torch.ones(k, k, dtype=torch.float64).tril(-1)
    mean = torch.randn(n_outputs, k, generator=g, dtype=torch.float64)
    with torch.no_grad():
        variational.chol_variational_covar.copy_(chol)
        variational.variational_mean.copy_(mean)
    assert float(torch.linalg.cond(chol).min()) > 1e16
    expected = 0.5 * (
        chol.square().sum((-2, -1)) + mean.square().sum(-1) - k - diag.square().log().sum(-1)
    )
    torch.testing.assert_close(expert.kl_divergence(), expected, rtol=1e-10, atol=1e-8)


def test_start_from_em_reproduces_em_predictions():
    # With every training row an inducing point, q(u) set to the collapsed optimum given EM's
    # weights and hyperparameters is EM's exact weighted posterior, and the gate is EM's.
    x, y, _ = piecewise_1d(60, seed=0)
    xt, yt, _ = piecewise_1d(50, seed=1)
    em = MixtureOfGPExperts(2)
    fit_em(em, x, y)
    vi = VariationalMixtureOfGPExperts(2, n_inducing=60)
    vi.build(x, y, em.train_weights, em)
    vi.fitted = True
    ours, exact = vi.expert_predictions(xt), em.expert_predictions(xt)
    torch.testing.assert_close(ours.loc, exact.loc, rtol=0, atol=0.02 * float(exact.scale.min()))
    torch.testing.assert_close(ours.scale, exact.scale, rtol=1e-3, atol=0)
    torch.testing.assert_close(vi.gate_probs(xt), em.gate_probs(xt), rtol=0, atol=1e-12)

    # SVI from the EM fit keeps its gate and hyperparameters and moves only q(u)
    lengthscale = vi.experts[0].covar_module.base_kernel.lengthscale.detach().clone()
    fit_svi(vi, x, y, n_steps=5, batch_size=20, init=em)
    torch.testing.assert_close(vi.gate_probs(xt), em.gate_probs(xt), rtol=0, atol=1e-12)
    torch.testing.assert_close(vi.experts[0].covar_module.base_kernel.lengthscale, lengthscale)
    nlpd_vi, nlpd_em = (-float(m.predict(xt).log_prob(yt).mean()) for m in (vi, em))
    assert abs(nlpd_vi - nlpd_em) < 0.05, (nlpd_vi, nlpd_em)

    # a gate and kernel step relative to lr (SVIOptions.gate_lr_scale, hyper_lr_scale) moves them
    moved = VariationalMixtureOfGPExperts(2, n_inducing=60)
    fit_svi(moved, x, y, n_steps=5, batch_size=20, init=em, gate_lr_scale=1.0, hyper_lr_scale=1.0)
    assert float((moved.gate_probs(xt) - em.gate_probs(xt)).abs().max()) > 1e-6
    assert not torch.equal(moved.experts[0].covar_module.base_kernel.lengthscale, lengthscale)


def test_inducing_points_cover_the_weighted_samples():
    x = torch.linspace(-3, 3, 40, dtype=torch.float64)[:, None]
    weights = (x[:, 0] > 0).double()  # 20 samples with weight 1, 20 with weight 0
    expert = SVGPExpert(torch.zeros(2, 8, 1, dtype=torch.float64)).double()
    expert.covar_module.base_kernel.lengthscale = 0.5
    expert.place_inducing(x, weights)
    z = expert.variational_strategy.inducing_points.detach()[..., 0]  # (E, K)
    assert bool((z > 0).all())  # only samples the expert holds
    assert all(len(set(row.tolist())) == 8 for row in z)  # no repeats
    # spread over the weighted half rather than bunched: the largest gap stays small
    gaps = z.sort(-1).values.diff(dim=-1)
    assert float(gaps.max()) < 1.0 and float(z.min()) < 0.5 and float(z.max()) > 2.5


def test_full_natural_update_never_lowers_the_elbo():
    x, y, _ = piecewise_1d(80, seed=4)
    vi = VariationalMixtureOfGPExperts(2, n_inducing=12)
    fit_svi(vi, x, y, n_steps=3, batch_size=20, lr=0.05, init="effects")
    x_scaler, y_scaler = vi.scalers()
    x_g, x_e, t = x[:, vi.gate_columns], x_scaler(x[:, vi.expert_columns]), y_scaler(y)
    idx = torch.arange(x.shape[0])
    elbo = TraceEnum_ELBO(max_plate_nesting=1)

    def loss() -> float:
        with pyro.get_param_store().scope(), torch.no_grad():
            return float(elbo.loss(vi.model, vi.guide, x_g, x_e, t, idx))

    expert = vi.experts[0]
    variational = expert.variational_strategy._variational_distribution
    with torch.no_grad():  # move q(u) away from its optimum
        variational.variational_mean.add_(0.3)
    before = loss()
    vi.update_variational(x_g, x_e, t)
    after = loss()
    assert after < before - 1e-3, (before, after)
    # a half step lands between the two in natural parameters and in the loss
    with torch.no_grad():
        variational.variational_mean.add_(0.3)
    vi.update_variational(x_g, x_e, t, step=0.5)
    assert after - 1e-3 <= loss() < before
