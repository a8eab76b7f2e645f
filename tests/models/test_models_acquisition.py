"""The integrated variance reduction: an explicit posterior with one more row, and bad input.

Covers probaff.models.mixture.acquisition.
"""

import pytest
import torch

from probaff.errors import InputError
from probaff.models import MixtureOfGPExperts, fit_em
from probaff.models.mixture import integrated_variance_reduction
from probaff.models.synthetic import softmax_regimes

pytestmark = pytest.mark.usefixtures("single_thread")


def _posterior_variance(expert, train, query, noise):
    """(E, Q) posterior variance of `expert`'s kernel given `train` rows of `noise`, by solve."""
    kern = expert.gp.covar_module
    e = expert.n_outputs
    k_tt = kern(train.expand(e, *train.shape)).to_dense() + torch.diag_embed(noise)
    k_qt = kern(query.expand(e, *query.shape), train.expand(e, *train.shape)).to_dense()
    k_qq = kern(query.expand(e, *query.shape), diag=True)
    return k_qq - (k_qt * torch.linalg.solve(k_tt, k_qt.transpose(-1, -2)).transpose(-1, -2)).sum(
        -1
    )


@pytest.fixture(scope="module")
def single():
    g = torch.Generator().manual_seed(1)
    x = 4 * torch.rand(40, 2, generator=g, dtype=torch.float64) - 2
    y = torch.stack([torch.sin(x[:, 0]), x[:, 1] ** 2], -1)
    y = y + 0.05 * torch.randn(40, 2, generator=g, dtype=torch.float64)
    model = MixtureOfGPExperts(1)
    fit_em(model, x, y, n_restarts=1, split_merge=0)
    return model, x


def test_one_expert_matches_the_posterior_refitted_with_the_candidate(single):
    model, x = single
    expert = model.experts[0]
    g = torch.Generator().manual_seed(2)
    cand = 5 * torch.rand(6, 2, generator=g, dtype=torch.float64) - 2.5
    ref = 4 * torch.rand(30, 2, generator=g, dtype=torch.float64) - 2
    weights = torch.tensor([1.0, 3.0], dtype=torch.float64)
    ivr = integrated_variance_reduction(model, cand, ref, output_weights=weights)
    info = integrated_variance_reduction(model, cand, ref, measure="information")
    sx = expert.x_scaler
    train, rq = sx(x), sx(ref)
    noise = expert.likelihood.noise.expand(expert.n_outputs, x.shape[0])
    with torch.no_grad():
        before = _posterior_variance(expert, train, rq, noise)
        for i in range(cand.shape[0]):
            more = torch.cat([train, sx(cand[i : i + 1])])
            after = _posterior_variance(
                expert, more, rq, torch.cat([noise, expert.likelihood.noise], -1)
            )
            want = ((before - after).mean(-1) * expert.y_scaler.std**2 * weights).sum()
            torch.testing.assert_close(ivr[i], want, rtol=1e-5, atol=1e-10)
            nats = (0.5 * torch.log(before / after)).mean(-1).sum()
            torch.testing.assert_close(info[i], nats, rtol=1e-5, atol=1e-10)
    assert bool((ivr >= 0).all())


def test_a_candidate_far_from_the_reference_informs_it_least():
    x, y, _ = softmax_regimes(150, seed=0)
    model = MixtureOfGPExperts(2, gate_features=[0, 1])
    fit_em(model, x, y, n_restarts=1, split_merge=0)
    ref = x[:50]
    far = ref.mean(0, keepdim=True) + 50 * ref.std(0, keepdim=True)
    ivr = integrated_variance_reduction(model, torch.cat([ref[:1], far]), ref).detach()
    assert float(ivr[0]) > 0 and float(ivr[1]) < 1e-6 * float(ivr[0])


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"candidates": torch.full((2, 2), float("nan"))}, "candidates.*NaN|NaN.*candidates"),
        ({"reference": torch.zeros(3, 5)}, "reference"),
        ({"reference": torch.zeros(0, 2)}, "at least one row"),
        ({"output_weights": torch.tensor([1.0, -1.0])}, "output_weights"),
        ({"output_weights": torch.ones(3)}, "output_weights"),
        ({"output_weights": torch.tensor([1.0, float("inf")])}, "output_weights"),
        ({"measure": "entropy"}, "measure"),
    ],
)
def test_bad_input_names_the_argument(single, kwargs, match):
    model, x = single
    args = {"candidates": x[:2], "reference": x[:3]} | kwargs
    with pytest.raises(InputError, match=match):
        integrated_variance_reduction(model, **args)
