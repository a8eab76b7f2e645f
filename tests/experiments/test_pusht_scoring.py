"""How the Push-T study scores its models, against references that do not share its code.

- `predict_moments` against torch's `MixtureSameFamily` mean and variance (law of total
  variance, computed by torch), for a hand-made mixture and for a mixture `fit_learned` fits;
- `QuasiStaticTee.calibrate` against the root mean square of residuals built to have it;
- `evaluate` against the RMSE, the Gaussian NLPD and the 90 % interval written out by hand;
- the analytic model (`QuasiStaticTee.effects`) against gym-pusht's physics on recorded pushes.

Covers probaff.experiments.pusht.models.
"""

import math

import numpy as np
import pytest
import torch
from torch.distributions import Categorical, Independent, MixtureSameFamily, Normal

from probaff.errors import InputError
from probaff.experiments.pusht.data import push_dataset, record_chunk
from probaff.experiments.pusht.models import (
    FEATURES,
    LearnedModel,
    QuasiStaticTee,
    evaluate,
    fit_learned,
    predict_moments,
    push_effects,
    push_features,
)
from probaff.experiments.pusht.primitives import PrimitiveSettings
from probaff.models import EMOptions

Z90 = 1.6448536269514722  # the standard normal's 95 % quantile: a central 90 % interval


class _Fixed:
    """A model whose prediction is a given distribution."""

    def __init__(self, dist):
        self.dist = dist

    def predict(self, X):
        return self.dist


def _mixture(n=7, m=3, e=3, seed=0):
    g = torch.Generator().manual_seed(seed)
    logits = torch.randn(n, m, generator=g, dtype=torch.float64) * 2
    loc = torch.randn(n, m, e, generator=g, dtype=torch.float64) * 5
    scale = torch.rand(n, m, e, generator=g, dtype=torch.float64) * 2 + 0.1
    return MixtureSameFamily(Categorical(logits=logits), Independent(Normal(loc, scale), 1))


def test_moments_of_a_mixture_are_torchs_mixture_mean_and_variance():
    dist = _mixture()
    mean, std = predict_moments(_Fixed(dist), np.zeros((7, 5)))
    assert mean.shape == std.shape == (7, 3)
    np.testing.assert_allclose(mean, dist.mean.numpy(), rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(std, dist.variance.sqrt().numpy(), rtol=1e-10, atol=1e-12)
    # and a Monte Carlo check of torch's own formula, far from it by chance only
    torch.manual_seed(0)
    draws = dist.sample(torch.Size([40000])).numpy()
    np.testing.assert_allclose(draws.mean(0), mean, atol=0.15)
    np.testing.assert_allclose(draws.std(0), std, rtol=0.03)
    # one Normal (M = 1) has its own mean and scale
    loc, scale = dist.component_distribution.base_dist.loc[:, 0], torch.full((7, 3), 0.5)
    one_mean, one_std = predict_moments(_Fixed(Independent(Normal(loc, scale), 1)), None)
    np.testing.assert_array_equal(one_mean, loc.numpy())
    np.testing.assert_allclose(one_std, 0.5, rtol=1e-15)


def _smooth(n, seed):
    rng = np.random.default_rng(seed)
    X = np.column_stack(
        [rng.uniform(-60, 60, n), rng.uniform(-30, 90, n), *np.eye(2)[rng.integers(0, 2, n)].T]
    )
    X = np.column_stack([X, rng.uniform(10, 40, n)])
    across = 0.1 * X[:, 0] * X[:, 3]
    along = X[:, 4] * X[:, 2] + 2 * np.sin(X[:, 1] / 30)
    turn = -0.002 * X[:, 0] * X[:, 4] / 10
    Y = np.column_stack([across, along, turn]) + rng.normal(0, [0.2, 0.3, 0.002], (n, 3))
    return X, Y


def test_a_fitted_mixture_is_scored_with_its_own_moments():
    X, Y = _smooth(40, 0)
    em = EMOptions(max_iter=2, n_restarts=1, split_merge=0, n_init=2, seed=3)
    with torch.random.fork_rng():
        model, objective = fit_learned("moe", X, Y, experts=2, em=em)
    assert isinstance(model, LearnedModel) and model.features == FEATURES
    assert math.isfinite(objective)
    Xt, Yt = _smooth(15, 1)
    dist = model.predict(Xt)
    assert isinstance(dist, MixtureSameFamily)
    mean, std = predict_moments(model, Xt)
    np.testing.assert_allclose(mean, dist.mean.numpy(), rtol=1e-10, atol=1e-10)
    np.testing.assert_allclose(std, dist.variance.sqrt().numpy(), rtol=1e-8, atol=1e-10)
    # the fit learned something: far below the spread of the held-out effects
    scores = evaluate(model, Xt, Yt)
    assert scores["rmse_z"] < 0.5 * Yt[:, 1].std()
    assert all(math.isfinite(v) for v in scores.values())
    with pytest.raises(InputError, match="fitted on features"):
        LearnedModel("gp", model.model, features=("a",)).predict(Xt)


def _pushes(first: np.ndarray, last: np.ndarray) -> np.ndarray:
    """Push features `(N, 5)`: the given first and last columns, the middle three fixed."""
    n = len(first)
    return np.column_stack([first, np.full(n, -40.0), np.zeros(n), np.ones(n), last])


def test_calibrate_sets_the_residuals_root_mean_square():
    rng = np.random.default_rng(4)
    X = _pushes(rng.uniform(-80, 80, 50), rng.uniform(5, 40, 50))
    qs = QuasiStaticTee()
    with pytest.raises(InputError, match="calibrate"):
        predict_moments(qs, X)
    effects = qs.effects(X)
    # residuals of root mean square exactly (3, 2, 0.05): signs flipped at random, not zero-mean
    want = np.array([3.0, 2.0, 0.05])
    signs = rng.choice([-1.0, 1.0], (50, 3))
    signs[:30] = 1.0
    Y = effects - signs * want
    assert qs.calibrate(X, Y) is qs
    np.testing.assert_allclose(qs.sigma, want, rtol=0, atol=2e-6)
    mean, std = predict_moments(qs, X)
    np.testing.assert_array_equal(mean, effects)
    np.testing.assert_allclose(std, np.broadcast_to(want, (50, 3)), rtol=0, atol=2e-6)
    pred = qs.predict(X)
    np.testing.assert_array_equal(pred.mean.numpy(), effects)
    np.testing.assert_allclose(pred.stddev.numpy(), std, rtol=1e-15)


def test_evaluate_is_rmse_gaussian_nlpd_and_the_90_percent_interval():
    rng = np.random.default_rng(5)
    X = _pushes(rng.uniform(-60, 60, 400), np.full(400, 20.0))
    qs = QuasiStaticTee(sigma=np.array([1.5, 4.0, 0.1]))
    effects = qs.effects(X)
    Y = effects + rng.normal(0, [1.5, 4.0, 0.1], (400, 3)) * rng.choice([0.5, 1.6], (400, 3))
    scores = evaluate(qs, X, Y)
    r = Y - effects
    rms = np.sqrt((r**2).mean(0))
    assert scores["rmse_y"] == pytest.approx(rms[0], rel=1e-12)
    assert scores["rmse_z"] == pytest.approx(rms[1], rel=1e-12)
    assert scores["rmse_theta"] == pytest.approx(rms[2], rel=1e-12)
    z = r / qs.sigma
    nlpd = (0.5 * np.log(2 * np.pi * qs.sigma**2) + 0.5 * z**2).mean(0).sum()
    assert scores["nlpd"] == pytest.approx(nlpd, rel=1e-10)
    assert scores["coverage90"] == pytest.approx(np.mean(np.abs(z) <= Z90), abs=1e-12)
    assert 0.6 < scores["coverage90"] < 0.95  # heavier tails than the Normal: some fall out


def test_the_analytic_model_predicts_gym_pushts_pushes(pusht_python):
    """24 random pushes in the simulator: the quasi-static model explains >= 97 % of the
    variance of each effect (0.995 measured on these pushes), and calibrating it on them gives
    a residual scale well under the spread of the effects."""
    record = record_chunk("test", 0, 11, 24, settings=PrimitiveSettings(), python=pusht_python)
    ds = push_dataset([record], seed=11)
    X, Y = push_features(ds), push_effects(ds)
    qs = QuasiStaticTee()
    P = qs.effects(X)
    assert np.isfinite(P).all() and np.abs(Y[:, 1]).max() > 10  # the pushes moved the T
    r2 = 1 - ((P - Y) ** 2).sum(0) / ((Y - Y.mean(0)) ** 2).sum(0)
    assert (r2 >= 0.97).all(), r2
    turned = np.abs(Y[:, 2]) > 0.02
    assert np.array_equal(np.sign(P[turned, 2]), np.sign(Y[turned, 2]))
    qs.calibrate(X, Y)
    np.testing.assert_allclose(qs.sigma, np.sqrt(((P - Y) ** 2).mean(0)), rtol=1e-4)
    assert (qs.sigma < 0.15 * Y.std(0)).all()
    scores = evaluate(qs, X, Y)
    assert scores["coverage90"] >= 0.7 and math.isfinite(scores["nlpd"])
