import math

import gpytorch
import pytest
import torch
from gpytorch.mlls import ExactMarginalLogLikelihood
from linear_operator.utils.errors import NotPSDError

from probaff.errors import InputError
from probaff.models import GPExpert, NotFittedError
from probaff.models.experts.gaussian_density import gaussian_log_density, loo_moments
from probaff.models.experts.gp_expert import exact_gp_settings
from probaff.models.experts.likelihood import WeightedNoise


def _data(n: int = 40, d: int = 3, e: int = 2, seed: int = 0) -> tuple[torch.Tensor, torch.Tensor]:
    g = torch.Generator().manual_seed(seed)
    x = torch.rand(n, d, generator=g, dtype=torch.float64) * 4 - 2
    y = torch.stack([torch.sin(2 * x[:, 0]) + x[:, 1], x[:, 0] * x[:, 2]], dim=1)[:, :e]
    return x, y + 0.05 * torch.randn(n, e, generator=g, dtype=torch.float64)


class _PlainBatchGP(gpytorch.models.ExactGP):
    def __init__(self, x, y, likelihood, d, e):
        super().__init__(x, y, likelihood)
        batch = torch.Size([e])
        self.mean_module = gpytorch.means.ConstantMean(batch_shape=batch)
        self.covar_module = gpytorch.kernels.ScaleKernel(
            gpytorch.kernels.RBFKernel(ard_num_dims=d, batch_shape=batch), batch_shape=batch
        )

    def forward(self, x):
        return gpytorch.distributions.MultivariateNormal(self.mean_module(x), self.covar_module(x))


def _plain_copy(expert: GPExpert):
    """A standard gpytorch ExactGP + GaussianLikelihood with the expert's hyperparameters."""
    e, d = expert.n_outputs, expert.n_features
    lik = gpytorch.likelihoods.GaussianLikelihood(batch_shape=torch.Size([e])).double()
    x = expert.gp.train_inputs[0].expand(e, -1, -1)
    ref = _PlainBatchGP(x, expert.gp.train_targets, lik, d, e).double()
    src = expert.gp.covar_module
    ref.covar_module.base_kernel.lengthscale = src.base_kernel.lengthscale.detach()
    ref.covar_module.outputscale = src.outputscale.detach()
    ref.mean_module.constant.data.copy_(expert.gp.mean_module.constant.detach())
    lik.noise = expert.likelihood.noise.detach()
    return ref, lik


def test_uniform_weights_match_plain_exact_gp():
    x, y = _data()
    xs, _ = _data(25, seed=1)
    expert = GPExpert(3, 2).fit(x, y, max_iter=30)
    ref, lik = _plain_copy(expert)
    ref.eval()
    lik.eval()
    with torch.no_grad(), exact_gp_settings():
        zs = expert.x_scaler(xs).expand(2, -1, -1)
        latent = ref(zs)
        noisy = lik(latent)
    std, mu = expert.y_scaler.std, expert.y_scaler.mean
    for include_noise, dist in ((True, noisy), (False, latent)):
        pred = expert.predict(xs, include_noise=include_noise)
        mean_err = (pred.mean - (dist.mean.T * std + mu)).abs().max()
        var_err = (pred.variance - dist.variance.T * std**2).abs().max()
        assert mean_err <= 1e-6 and var_err <= 1e-6, (mean_err, var_err)

    # same objective value too (the weight correction vanishes for unit weights)
    ref.train()
    lik.train()
    expert.train()
    with torch.no_grad(), exact_gp_settings():
        ours = ExactMarginalLogLikelihood(expert.likelihood, expert.gp)(
            expert.gp(expert.gp.train_inputs[0]), expert.gp.train_targets
        )
        theirs = ExactMarginalLogLikelihood(lik, ref)(ref(*ref.train_inputs), ref.train_targets)
    expert.eval()
    torch.testing.assert_close(ours, theirs, rtol=0, atol=1e-10)


def test_zero_weight_removes_sample_exactly():
    x, y = _data(30)
    w = torch.linspace(0.2, 1.0, 30, dtype=torch.float64)
    w[[3, 11, 12, 25]] = 0.0
    keep = w > 0
    xs, _ = _data(10, seed=2)
    a = GPExpert(3, 2).fit(x, y, w, max_iter=20)
    b = GPExpert(3, 2).fit(x[keep], y[keep], w[keep], max_iter=20)
    pa, pb = a.predict(xs), b.predict(xs)
    assert a.n_train == b.n_train == 26
    assert torch.equal(pa.mean, pb.mean) and torch.equal(pa.stddev, pb.stddev)
    assert torch.equal(a.lengthscales, b.lengthscales)


def test_weight_scales_noise_and_tiny_weight_approaches_removal():
    noise = WeightedNoise(torch.Size([2]))
    noise.noise = 0.3
    noise.weights = torch.tensor([1.0, 0.5, 0.25], dtype=torch.float64)
    diag = noise(torch.zeros(3, 1), shape=torch.Size([3])).diagonal(dim1=-1, dim2=-2)
    torch.testing.assert_close(diag, torch.tensor([[0.3, 0.6, 1.2]] * 2, dtype=torch.float64))
    # a new set of another size gets weight 1
    other = noise(torch.zeros(5, 1), shape=torch.Size([5])).diagonal(dim1=-1, dim2=-2)
    torch.testing.assert_close(other, torch.full((2, 5), 0.3, dtype=torch.float64))

    # the weighted marginal likelihood (times N) tends to that without the sample
    x, y = _data(20)
    tiny = torch.ones(20, dtype=torch.float64)
    tiny[7] = 1e-12
    a = GPExpert(3, 2).fit(x, y, max_iter=10)
    a.condition(x, y, tiny)
    b = GPExpert(3, 2)
    b.load_state_dict(a.state_dict())
    keep = tiny > 1e-6
    b.condition(x[keep], y[keep])
    b.x_scaler.load_state_dict(a.x_scaler.state_dict())
    b.y_scaler.load_state_dict(a.y_scaler.state_dict())
    b.gp.set_train_data(a.gp.train_inputs[0][keep], a.gp.train_targets[:, keep], strict=False)
    values = []
    for m, n in ((a, 20), (b, 19)):
        m.train()
        with torch.no_grad(), exact_gp_settings():
            mll = ExactMarginalLogLikelihood(m.likelihood, m.gp)
            values.append(mll(m.gp(m.gp.train_inputs[0]), m.gp.train_targets) * n)
        m.eval()
    torch.testing.assert_close(values[0], values[1], rtol=0, atol=1e-6)


def test_lengthscales_rank_relevant_features():
    g = torch.Generator().manual_seed(3)
    x = torch.randn(60, 4, generator=g, dtype=torch.float64)
    y = torch.sin(2 * x[:, :1]) + 0.01 * torch.randn(60, 1, generator=g, dtype=torch.float64)
    expert = GPExpert(4, 1).fit(x, y)
    ls = expert.lengthscales
    assert ls.shape == (1, 4)
    assert int(ls.argmin()) == 0 and float(ls[0, 0]) * 5 < float(ls[0, 1:].min())


def test_singular_kernel_gives_finite_predictions():
    x = torch.zeros(12, 2, dtype=torch.float64)
    x[6:, 0] = 1.0  # two distinct inputs, each repeated; second column constant
    y = torch.cat([torch.zeros(6, 1), torch.ones(6, 1)]).double()
    expert = GPExpert(2, 1).fit(x, y)
    pred = expert.predict(torch.tensor([[0.0, 0.0], [0.5, 0.0], [1.0, 0.0]], dtype=torch.float64))
    assert torch.isfinite(pred.mean).all() and torch.isfinite(pred.stddev).all()
    assert (pred.stddev > 0).all()
    torch.testing.assert_close(
        pred.mean[[0, 2], 0], torch.tensor([0.0, 1.0]).double(), atol=1e-2, rtol=0
    )


def test_expert_input_errors():
    x, y = _data(10)
    expert = GPExpert(3, 2)
    with pytest.raises(NotFittedError, match="fit"):
        expert.predict(x)
    with pytest.raises(InputError, match="NaN"):
        expert.fit(torch.full((10, 3), math.nan), y)
    with pytest.raises(InputError, match="shape"):
        expert.fit(x, y[:9])
    with pytest.raises(InputError, match=">= 0"):
        expert.fit(x, y, -torch.ones(10))
    with pytest.raises(InputError, match="every weight is zero"):
        expert.fit(x, y, torch.zeros(10))
    with pytest.raises(InputError, match="zero samples"):
        expert.fit(x[:0], y[:0])


def test_lengthscale_prior_curbs_overfitting_in_high_dimension():
    g = torch.Generator().manual_seed(4)
    x = torch.randn(260, 30, generator=g, dtype=torch.float64)
    y = torch.sin(2 * x[:, :1]) + 0.1 * torch.randn(260, 1, generator=g, dtype=torch.float64)
    nlpd = {}
    for prior in (False, True):
        expert = GPExpert(30, 1, lengthscale_prior=prior).fit(x[:60], y[:60], max_iter=100)
        nlpd[prior] = -float(expert.log_prob(x[60:], y[60:]).mean())
    assert nlpd[True] < nlpd[False] - 1.0, nlpd


def test_marginal_log_likelihood_matches_gpytorch_value_and_gradient():
    x, y = _data(40)
    w = torch.linspace(0.05, 1.0, 40, dtype=torch.float64)
    expert = GPExpert(3, 2, lengthscale_prior=True, noise_floor=0.01).fit(x, y, w, max_iter=5)
    params = [p for p in expert.parameters() if p.requires_grad]
    expert.train()
    grads = []
    with exact_gp_settings():
        for value in (
            lambda: expert.marginal_log_likelihood(),
            lambda: ExactMarginalLogLikelihood(expert.likelihood, expert.gp)(
                expert.gp(expert.gp.train_inputs[0]), expert.gp.train_targets
            ),
        ):
            expert.zero_grad()
            v = value()
            v.sum().backward()
            grads.append((v.detach(), [p.grad.clone() for p in params]))
    expert.eval()
    (ours, g_ours), (theirs, g_theirs) = grads
    assert ours.shape == (2,)
    torch.testing.assert_close(ours, theirs, rtol=0, atol=1e-10)
    for a, b in zip(g_ours, g_theirs, strict=True):
        torch.testing.assert_close(a, b, rtol=1e-8, atol=1e-10)


def test_gaussian_log_density_gradient_is_exact():
    g = torch.Generator().manual_seed(0)
    b = torch.randn(2, 5, 5, generator=g, dtype=torch.float64)
    a = (b @ b.mT + 5 * torch.eye(5, dtype=torch.float64)).requires_grad_(True)
    r = torch.randn(2, 5, generator=g, dtype=torch.float64, requires_grad=True)
    ref = torch.distributions.MultivariateNormal(torch.zeros(5, dtype=torch.float64), a)
    torch.testing.assert_close(gaussian_log_density(a, r), ref.log_prob(r))
    # the closed form is the gradient for symmetric perturbations of A
    assert torch.autograd.gradcheck(
        lambda m, v: gaussian_log_density(0.5 * (m + m.mT), v), (a, r), eps=1e-6, atol=1e-6
    )
    with pytest.raises(NotPSDError):
        gaussian_log_density(-a.detach(), r.detach())


def test_loo_moments_equal_conditioning_on_the_other_samples():
    g = torch.Generator().manual_seed(1)
    x = torch.rand(7, 1, generator=g, dtype=torch.float64)
    k = torch.exp(-0.5 * (x - x.T).square() / 0.3**2)
    own = torch.rand(7, generator=g, dtype=torch.float64) * 0.1 + 0.01
    y = torch.randn(7, generator=g, dtype=torch.float64)
    a = k + torch.diag(own)
    chol = torch.linalg.cholesky(a)
    mean, latent = loo_moments(chol, y, torch.cholesky_solve(y[:, None], chol)[:, 0], own)
    for i in range(7):
        rest = [j for j in range(7) if j != i]
        solve = torch.linalg.solve(a[rest][:, rest], torch.stack([y[rest], k[rest, i]], 1))
        assert float(mean[i]) == pytest.approx(float(k[i, rest] @ solve[:, 0]), rel=1e-9)
        expected = float(k[i, i] - k[i, rest] @ solve[:, 1])
        assert float(latent[i]) == pytest.approx(expected, rel=1e-9, abs=1e-12)
