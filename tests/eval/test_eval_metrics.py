import math
import statistics

import pytest
import torch
from torch.distributions import Categorical, Independent, MixtureSameFamily, Normal

from probaff.errors import InputError
from probaff.eval.metrics import (
    corrected_halfwidth,
    interval_coverage,
    mean_and_halfwidth,
    mean_halfwidth,
    nlpd,
    rmse,
)


def _mixture(n=4000, seed=0):
    w = torch.tensor([0.3, 0.7], dtype=torch.float64).expand(n, 2)
    loc = torch.tensor([[-1.0, 0.0], [2.0, 5.0]], dtype=torch.float64).expand(n, 2, 2)
    scale = torch.tensor([[0.5, 1.0], [1.0, 0.2]], dtype=torch.float64).expand(n, 2, 2)
    dist = MixtureSameFamily(Categorical(probs=w), Independent(Normal(loc, scale), 1))
    torch.manual_seed(seed)
    return dist, dist.sample()


def test_normal_metrics_match_closed_forms():
    loc = torch.zeros(5000, 2, dtype=torch.float64)
    scale = torch.ones(5000, 2, dtype=torch.float64) * torch.tensor([1.0, 2.0])
    torch.manual_seed(1)
    y = Normal(loc, scale).sample()
    dist = Normal(loc, scale)
    assert torch.allclose(rmse(dist, y), y.pow(2).mean(0).sqrt())
    expected = -Normal(loc, scale).log_prob(y).mean(0)
    assert torch.allclose(nlpd(dist, y), expected)
    cov = interval_coverage(dist, y, 0.9)
    assert torch.all((cov - 0.9).abs() < 0.02)


def test_mixture_coverage_is_calibrated_and_nlpd_matches_log_prob():
    dist, y = _mixture()
    cov = interval_coverage(dist, y, 0.9)
    assert torch.all((cov - 0.9).abs() < 0.02)
    # the sum of per-dimension NLPDs equals the joint NLPD only for independent dimensions;
    # check each marginal against a direct 1-D mixture
    for e in range(2):
        comp = Normal(
            dist.component_distribution.base_dist.loc[..., e],
            dist.component_distribution.base_dist.scale[..., e],
        )
        marg = MixtureSameFamily(dist.mixture_distribution, comp)
        assert math.isclose(
            nlpd(dist, y)[e].item(), -marg.log_prob(y[:, e]).mean().item(), rel_tol=1e-12
        )


def test_bad_targets():
    dist, y = _mixture(10)
    with pytest.raises(InputError, match="shape"):
        rmse(dist, y[:, :1])
    y[0, 0] = float("nan")
    with pytest.raises(InputError, match="NaN"):
        nlpd(dist, y)
    with pytest.raises(InputError, match="level"):
        interval_coverage(dist, y.nan_to_num(), 1.5)


def test_corrected_halfwidth_widens_the_plain_t_interval_by_nadeau_and_bengio():
    from scipy.stats import t

    values = [0.3, -0.1, 0.4, 0.2, 0.0, 0.5]  # J = 6 splits: 2 repeats of 3 folds
    sd = statistics.stdev(values)
    plain = t.ppf(0.975, 5) * sd / math.sqrt(6)
    assert mean_halfwidth(values) == pytest.approx(plain)
    assert corrected_halfwidth(values, 0.0) == pytest.approx(plain)
    # 3 folds: a test fold is half the size of its training rows
    want = t.ppf(0.975, 5) * sd * math.sqrt(1 / 6 + 1 / 2)
    assert corrected_halfwidth(values, 0.5) == pytest.approx(want)
    assert corrected_halfwidth([1.0], 0.5) == 0.0  # one split: no interval
    for bad in (-0.5, math.nan, math.inf):
        with pytest.raises(InputError, match="test_to_train"):
            corrected_halfwidth(values, bad)


def test_mean_and_halfwidth_pairs_the_mean_with_its_t_interval():
    values = [0.3, -0.1, 0.4, 0.2, 0.0, 0.5]
    mean, half = mean_and_halfwidth(values)
    assert type(mean) is float and mean == pytest.approx(statistics.mean(values))
    assert half == mean_halfwidth(values)
    assert mean_and_halfwidth(values, 0.5)[1] == mean_halfwidth(values, 0.5) < half
    assert mean_and_halfwidth([2.0]) == (2.0, 0.0)
    with pytest.raises(InputError, match=r"confidence must lie in \(0, 1\)"):
        mean_and_halfwidth(values, 1.5)
