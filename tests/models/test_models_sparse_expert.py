import copy
import math

import gpytorch
import pytest
import torch
from gpytorch.mlls import ExactMarginalLogLikelihood

from probaff.errors import InputError, NotFittedError
from probaff.models import GPExpert
from probaff.models.experts.gp_expert import exact_gp_settings
from probaff.models.experts.sparse_expert import (
    DEFAULT_N_INDUCING,
    FitMemoryError,
    SparseGPExpert,
    available_memory_bytes,
    fit_memory_bytes,
    select_inducing,
)
from probaff.models.options import SparseGPOptions


@pytest.fixture(autouse=True, scope="module")
def _single_thread():
    previous = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(previous)


def _data(n: int = 40, d: int = 3, seed: int = 0) -> tuple[torch.Tensor, torch.Tensor]:
    g = torch.Generator().manual_seed(seed)
    x = torch.rand(n, d, generator=g, dtype=torch.float64) * 4 - 2
    y = torch.stack([torch.sin(2 * x[:, 0]) + x[:, 1], x[:, 0] * x[:, 2]], dim=1)
    return x, y + 0.05 * torch.randn(n, 2, generator=g, dtype=torch.float64)


def _weights(n: int, seed: int = 3, zeros: int = 0) -> torch.Tensor:
    g = torch.Generator().manual_seed(seed)
    w = torch.rand(n, generator=g, dtype=torch.float64) * 0.95 + 0.05
    w[:zeros] = 0.0
    return w


def _copy_hyperparameters(sparse: SparseGPExpert, exact: GPExpert) -> None:
    """Give `sparse` the kernel, noise and mean of `exact`."""
    sparse.covar_module.load_state_dict(exact.gp.covar_module.state_dict())
    with torch.no_grad():
        sparse.likelihood.noise_covar.raw_noise.copy_(exact.likelihood.noise_covar.raw_noise)
        sparse.constant.copy_(exact.gp.mean_module.constant)


@pytest.mark.parametrize("prior", [False, True])
def test_bound_is_the_exact_weighted_likelihood_with_inducing_points_at_the_data(prior):
    x, y = _data()
    w = _weights(40, zeros=4)
    exact = GPExpert(3, 2, lengthscale_prior=prior, noise_floor=0.01).fit(x, y, w, max_iter=15)
    sparse = SparseGPExpert(3, 2, lengthscale_prior=prior, noise_floor=0.01, n_inducing=36)
    sparse.condition(x, y, w)
    assert sparse.n_train == 36 and sparse.n_inducing == 36
    _copy_hyperparameters(sparse, exact)
    with torch.no_grad():
        want = exact.marginal_log_likelihood()
        got = sparse.marginal_log_likelihood(jitter=1e-10)
    torch.testing.assert_close(got, want, rtol=0, atol=2e-6)

    # with fewer inducing points the bound lies below, and it grows with m (nested greedy sets)
    bounds = []
    for m in (3, 8, 16, 28):
        small = SparseGPExpert(3, 2, lengthscale_prior=prior, noise_floor=0.01, n_inducing=m)
        small.condition(x, y, w)
        _copy_hyperparameters(small, exact)
        with torch.no_grad():
            bounds.append(small.marginal_log_likelihood(jitter=1e-10))
    stacked = torch.stack([*bounds, got])
    assert bool((stacked[:-1] <= want + 1e-9).all())
    assert bool((stacked.diff(dim=0) >= -1e-9).all()), stacked


class _SGPR(gpytorch.models.ExactGP):
    def __init__(self, x, y, likelihood, z):
        super().__init__(x, y, likelihood)
        self.mean_module = gpytorch.means.ConstantMean()
        base = gpytorch.kernels.ScaleKernel(gpytorch.kernels.RBFKernel(ard_num_dims=x.shape[1]))
        self.base = base
        self.covar_module = gpytorch.kernels.InducingPointKernel(base, z, likelihood)

    def forward(self, x):
        return gpytorch.distributions.MultivariateNormal(self.mean_module(x), self.covar_module(x))


def test_unit_weights_reproduce_gpytorch_sgpr():
    x, y = _data(50)
    xs, _ = _data(20, seed=1)
    sparse = SparseGPExpert(3, 2, n_inducing=10).fit(x, y, max_iter=10)
    sparse.jitter.fill_(1e-12)
    with torch.no_grad():
        ours = sparse.marginal_log_likelihood()
    pred = sparse.predict(xs)
    latent = sparse.predict(xs, include_noise=False)
    zs = sparse.x_scaler(xs)
    for e in range(2):
        lik = gpytorch.likelihoods.GaussianLikelihood().double()
        lik.noise = sparse.likelihood.noise[e].detach()
        ref = _SGPR(sparse.train_x, sparse.train_y[e], lik, sparse.inducing[e].detach()).double()
        ref.base.base_kernel.lengthscale = sparse.lengthscales[e]
        ref.base.outputscale = sparse.covar_module.outputscale[e].detach()
        ref.mean_module.constant.data.fill_(float(sparse.constant[e].detach()))
        ref.train()
        with torch.no_grad(), exact_gp_settings(1e-12):
            mll = ExactMarginalLogLikelihood(lik, ref)(ref(sparse.train_x), sparse.train_y[e])
        torch.testing.assert_close(ours[e], mll, rtol=0, atol=1e-7)
        ref.eval()
        # gpytorch's eval mode adds diag(K - Q) to the training covariance too (FITC-like);
        # without it, its predictive is the DTC one, and SGPR's adds k** - q** to the variance
        with (
            torch.no_grad(),
            exact_gp_settings(1e-12),
            gpytorch.settings.sgpr_diagonal_correction(False),
        ):
            post = ref(zs)
            correction = ref.base(zs, diag=True) - ref.covar_module(zs, diag=True)
        std, mu = sparse.y_scaler.std[e], sparse.y_scaler.mean[e]
        var = post.variance + correction
        torch.testing.assert_close(pred.mean[:, e], post.mean * std + mu, rtol=0, atol=1e-6)
        torch.testing.assert_close(latent.variance[:, e], var * std**2, rtol=0, atol=1e-6)
        torch.testing.assert_close(
            pred.variance[:, e], (var + lik.noise[0]) * std**2, rtol=0, atol=1e-6
        )


def _dense_sgpr(expert: SparseGPExpert, keep: torch.Tensor, i: int) -> tuple[torch.Tensor, ...]:
    """SGPR predictive (standardised, weight-1 noise) at training row `i` from rows `keep`."""
    z, x = expert.inducing.detach(), expert.train_x
    kernel = expert.covar_module
    with torch.no_grad():
        kuu = kernel(z).to_dense()
        eye = torch.eye(z.shape[1], dtype=torch.float64)
        kuu = kuu + float(expert.jitter) * kernel.outputscale[:, None, None] * eye
        kuf = kernel(z, x.expand(2, -1, -1)).to_dense()
        q = kuf.mT @ torch.linalg.solve(kuu, kuf)  # (E, n, n), dense
        noise = expert.likelihood.noise  # (E, 1)
        lam = noise / expert.likelihood.weights
        r = expert.train_y - expert.constant[:, None]
        a = q[:, keep][:, :, keep] + torch.diag_embed(lam[:, keep])
        qi = q[:, i, keep]  # (E, k)
        sol = torch.linalg.solve(a, torch.stack([r[:, keep], qi], dim=-1))
        mean = expert.constant + (qi * sol[..., 0]).sum(-1)
        k_ii = kernel.outputscale
        var = k_ii - q[:, i, i] + q[:, i, i] - (qi * sol[..., 1]).sum(-1) + noise[:, 0]
    return mean, var


def test_loo_predict_matches_brute_force_leave_one_out():
    x, y = _data(30)
    w = _weights(30, zeros=3)
    expert = SparseGPExpert(3, 2, n_inducing=8).fit(x, y, w, max_iter=8)
    loo = expert.loo_predict()
    n = expert.n_train
    assert loo.loc.shape == (n, 2) == (27, 2)
    std, mu = expert.y_scaler.std, expert.y_scaler.mean
    for i in range(n):
        keep = torch.tensor([j for j in range(n) if j != i])
        mean, var = _dense_sgpr(expert, keep, i)
        torch.testing.assert_close(loo.mean[i], mean * std + mu, rtol=0, atol=1e-7)
        torch.testing.assert_close(loo.variance[i], var * std**2, rtol=1e-6, atol=1e-9)
    # it is not the in-sample predictive
    assert float((loo.mean - expert.predict(x[3:]).mean).abs().max()) > 1e-3


def test_fit_is_deterministic_raises_the_bound_and_can_learn_inducing_points():
    x, y = _data(60)
    w = _weights(60)
    first = SparseGPExpert(3, 2, n_inducing=12)
    first.condition(x, y, w)
    with torch.no_grad():
        start = first.marginal_log_likelihood().sum()
    first.fit(x, y, w, max_iter=15)
    again = SparseGPExpert(3, 2, n_inducing=12).fit(x, y, w, max_iter=15)
    assert torch.equal(first.inducing, again.inducing)
    assert torch.equal(first.predict(x).mean, again.predict(x).mean)
    with torch.no_grad():
        fixed = first.marginal_log_likelihood().sum()
    assert fixed > start

    learned = SparseGPExpert(3, 2, n_inducing=12, learn_inducing=True).fit(x, y, w, max_iter=15)
    assert learned.inducing.requires_grad and not first.inducing.requires_grad
    assert float((learned.inducing - first.inducing).abs().max()) > 1e-3
    with torch.no_grad():
        assert learned.marginal_log_likelihood().sum() > fixed - 1e-3
    assert learned.lengthscales.shape == (2, 3) and bool((learned.noise > 0).all())


def test_selection_is_greedy_weighted_and_distinct():
    x, _ = _data(50)
    w = torch.ones(50, dtype=torch.float64)
    w[7] = 100.0  # the heaviest sample is picked first
    z = select_inducing(x, w, torch.ones(2, 3, dtype=torch.float64), torch.ones(2), 20)
    assert z.shape == (2, 20, 3)
    assert torch.equal(z[:, 0], x[7].expand(2, 3))
    assert torch.unique(z[0], dim=0).shape[0] == 20


def test_state_dict_round_trip_resizes_inducing_points():
    x, y = _data(40)
    w = _weights(40)
    fitted = SparseGPExpert(3, 2, n_inducing=9).fit(x, y, w, max_iter=5)
    fresh = SparseGPExpert(3, 2, n_inducing=9)
    fresh.condition(x, y, w)
    fresh.load_state_dict(fitted.state_dict())
    xs, _ = _data(10, seed=2)
    assert torch.equal(fresh.predict(xs).mean, fitted.predict(xs).mean)
    assert torch.equal(fresh.predict(xs).stddev, fitted.predict(xs).stddev)
    # a state with another number of inducing points loads too
    other = SparseGPExpert(3, 2, n_inducing=5)
    other.condition(x, y, w)
    other.load_state_dict(fitted.state_dict())
    assert other.n_inducing == 9
    assert torch.equal(other.log_prob(xs, y[:10]), fitted.log_prob(xs, y[:10]))


def test_default_inducing_count_and_bad_inputs():
    x, y = _data(30)
    expert = SparseGPExpert(3, 2)
    with pytest.raises(NotFittedError):
        expert.predict(x)
    with pytest.raises(NotFittedError):
        expert.loo_predict()
    assert not expert.is_fitted and expert.n_train == 0
    expert.condition(x, y, _weights(30, zeros=5))
    assert expert.n_inducing == min(DEFAULT_N_INDUCING, 25)
    for bad in (0, -3, 2.5, True, "many"):
        with pytest.raises(InputError, match="n_inducing"):
            SparseGPExpert(3, 2, n_inducing=bad)
    # at most the samples of non-zero weight serve as inducing points
    assert SparseGPExpert(3, 2, n_inducing=31).fit(x, y, max_iter=2).n_inducing == 30
    with pytest.raises(InputError, match="learn_inducing"):
        SparseGPOptions(learn_inducing="yes")
    with pytest.raises(InputError, match="weights"):
        SparseGPExpert(3, 2).fit(x, y, -torch.ones(30))
    with pytest.raises(InputError, match="every weight is zero"):
        SparseGPExpert(3, 2).fit(x, y, torch.zeros(30))


def test_memory_estimates():
    exact = fit_memory_bytes("exact", 10_000, 6, 3, 256)
    sparse = fit_memory_bytes("sparse", 10_000, 6, 3, 256)
    assert exact >= 3 * 6 * 10_000**2 * 8
    assert sparse < exact / 20
    # the sparse estimate grows linearly in N, the exact one quadratically
    sizes = [fit_memory_bytes("sparse", n, 6, 3, 256) for n in (10_000, 20_000, 30_000)]
    assert sizes[2] - sizes[1] == sizes[1] - sizes[0] > 0
    assert 1.5 * sparse < sizes[1] <= 2 * sparse
    assert fit_memory_bytes("exact", 20_000, 6, 3, 256) == 4 * exact
    # with the bound on hyper_rows rows, N adds only the experts' copies of the data
    big = [
        fit_memory_bytes("sparse", n, 6, 3, 128, n_features=101, hyper_rows=2048)
        for n in (100_000, 200_000)
    ]
    assert big[1] - big[0] == 8 * 3 * 100_000 * (101 + 6)
    assert big[0] < 2**30  # 100,000 rows of 101 features: well under 1 GiB
    free = available_memory_bytes()
    assert free is None or free > 0
    assert issubclass(FitMemoryError, InputError) and issubclass(FitMemoryError, MemoryError)
    assert math.isfinite(float(sparse))


def test_hyper_rows_fits_on_a_fixed_subset_and_conditions_on_every_row():
    x, y = _data(n=600, seed=5)
    xt, yt = _data(n=300, seed=6)
    w = _weights(600)
    full = SparseGPExpert(3, 2, n_inducing=30, hyper_rows=None, max_iter=30).fit(x, y, w)
    sub = SparseGPExpert(3, 2, n_inducing=30, hyper_rows=150, max_iter=30).fit(x, y, w)
    again = SparseGPExpert(3, 2, n_inducing=30, hyper_rows=150, max_iter=30).fit(x, y, w)
    rows = sub._hyper_subset()
    assert rows is not None and rows.numel() == 150 and bool((rows.diff() > 0).all())
    # the inducing inputs are chosen among the subset's rows
    chosen = sub.inducing.detach()[:, :, None, :] == sub.train_x[rows][None, None]
    assert bool(chosen.all(-1).any(-1).all())
    # every row is conditioned on, and the same data gives the same fit
    assert sub.n_train == 600
    assert torch.equal(sub.predict(xt).loc, again.predict(xt).loc)
    # a subset of a quarter of the rows keeps the held-out density close to the full fit's
    lp_full = float(full.log_prob(xt, yt).mean())
    lp_sub = float(sub.log_prob(xt, yt).mean())
    assert lp_sub > lp_full - 0.1, (lp_sub, lp_full)
    # with at least as many rows as samples, the subset is every row
    whole = SparseGPExpert(3, 2, n_inducing=30, hyper_rows=600, max_iter=30).fit(x, y, w)
    assert whole._hyper_subset() is None
    assert torch.equal(whole.predict(xt).loc, full.predict(xt).loc)
    with pytest.raises(InputError, match="hyper_rows"):
        SparseGPOptions(hyper_rows=0)


def test_hyper_rows_below_the_inducing_points_are_refused_by_name():
    from probaff.models import MixtureOfGPExperts

    too_few = r"hyper_rows=1 is below the 128 inducing points \(the default n_inducing\)"
    for make in (
        lambda: SparseGPOptions(hyper_rows=1),
        lambda: SparseGPExpert(3, 2, hyper_rows=1),
        lambda: MixtureOfGPExperts(2, experts="sparse", hyper_rows=1),
    ):
        with pytest.raises(InputError, match=too_few + r".*give hyper_rows >= 128"):
            make()
    with pytest.raises(InputError, match=r"hyper_rows=20 is below the 30 inducing points"):
        SparseGPOptions(n_inducing=30, hyper_rows=20)
    # the floor is the inducing points asked for: as many rows, or None, are accepted
    assert SparseGPOptions(n_inducing=30, hyper_rows=30).hyper_rows == 30
    assert MixtureOfGPExperts(2, n_inducing=16, hyper_rows=16).hyper_rows == 16
    assert SparseGPOptions(hyper_rows=None).hyper_rows is None


def test_posterior_is_kept_until_a_tensor_it_depends_on_changes():
    x, y = _data(n=80)
    expert = SparseGPExpert(3, 2, n_inducing=20, max_iter=5).fit(x, y)
    first = expert.predict(x[:5]).loc
    assert expert._posterior()[0] is expert._posterior()[0]

    def fresh(e: SparseGPExpert) -> torch.Tensor:
        clone = copy.deepcopy(e)
        clone.__dict__.pop("_cached_posterior", None)
        return clone.predict(x[:5]).loc

    with torch.no_grad():  # a parameter written in place
        expert.covar_module.base_kernel.raw_lengthscale.add_(0.3)
    moved = expert.predict(x[:5]).loc
    assert not torch.equal(first, moved) and torch.equal(moved, fresh(expert))
    expert.condition(x[:60], y[:60])  # new training data
    fewer = expert.predict(x[:5]).loc
    assert not torch.equal(fewer, moved) and torch.equal(fewer, fresh(expert))
    expert.inducing.data = expert.inducing.data[:, :10].clone()  # replaced storage
    assert torch.equal(expert.predict(x[:5]).loc, fresh(expert))
