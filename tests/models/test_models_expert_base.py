"""The shared base of the GP experts: the weighted training set and the settings."""

import numpy as np
import pytest
import torch

from probaff.errors import InputError
from probaff.models import GPExpert, ModelSettings
from probaff.models.experts.expert_base import WeightedExpert, noise_floor_vector
from probaff.models.experts.kernels import LENGTHSCALE_PRIOR_SCALE
from probaff.models.experts.sparse_expert import SparseGPExpert
from probaff.models.options import GPOptions


def test_both_experts_share_the_base_and_its_checks():
    x = torch.tensor([[0.0, 1.0], [1.0, 0.0], [2.0, 2.0], [3.0, 1.0]], dtype=torch.float64)
    y = torch.tensor([[1.0], [2.0], [2.0], [4.0]], dtype=torch.float64)
    w = torch.tensor([1.0, 0.0, 0.5, 2.0], dtype=torch.float64)
    for cls in (GPExpert, SparseGPExpert):
        expert = cls(2, 1, noise_floor=0.1)
        assert isinstance(expert, WeightedExpert)
        kx, ky, kw = expert.weighted_rows(x, y, w)
        # the zero-weight row is dropped; the scalers take the weighted moments of the rest
        torch.testing.assert_close(kx, x[[0, 2, 3]])
        torch.testing.assert_close(kw, w[[0, 2, 3]])
        mean = (kw[:, None] * ky).sum(0) / kw.sum()
        torch.testing.assert_close(expert.y_scaler.mean, mean)
        floor = (0.1 / expert.y_scaler.std).square()
        torch.testing.assert_close(expert.likelihood.noise_covar.floor[:, 0], floor)
        with pytest.raises(InputError, match="every weight is zero"):
            expert.weighted_rows(x, y, torch.zeros(4, dtype=torch.float64))
        with pytest.raises(InputError, match="weights must be >= 0"):
            expert.weighted_rows(x, y, -w)
        with pytest.raises(InputError, match="targets Y"):
            expert.weighted_rows(x, y[:3], None)
    base = WeightedExpert(3, 2, GPOptions(lengthscale_prior=True), 1e-6)
    assert base.kernel_prior() is not None and float(base.jitter) == 1e-6
    assert WeightedExpert(3, 2, GPOptions(), 1e-6).kernel_prior() is None


def test_a_prior_width_sets_the_log_length_scales_spread():
    """True is the default width; a number is the standard deviation of log length scales."""
    default = WeightedExpert(4, 1, GPOptions(lengthscale_prior=True), 1e-6).kernel_prior()
    wide = WeightedExpert(4, 1, GPOptions(lengthscale_prior=3.0**0.5), 1e-6).kernel_prior()
    assert float(default.scale) == LENGTHSCALE_PRIOR_SCALE
    assert float(wide.scale) == pytest.approx(3.0**0.5)
    assert float(wide.loc) == float(default.loc) == pytest.approx(2.0**0.5 + 0.5 * np.log(4))
    logs = torch.linspace(-1.0, 4.0, 11)
    # the same median, a wider spread: the wide prior penalises far length scales less
    far = wide.log_prob(logs.exp()[-1:]) - wide.log_prob(wide.loc.exp()[None])
    near = default.log_prob(logs.exp()[-1:]) - default.log_prob(default.loc.exp()[None])
    assert float(far) > float(near)
    assert ModelSettings(2, gp=GPOptions(lengthscale_prior=2)).gp.lengthscale_prior == 2.0
    for bad in (0.0, -1.0, float("nan"), float("inf"), "wide", None):
        with pytest.raises(InputError, match=r"lengthscale_prior must be True, False or the prior"):
            GPOptions(lengthscale_prior=bad)


def test_noise_floor_vector():
    torch.testing.assert_close(
        noise_floor_vector(0.5, 3), torch.full((3,), 0.5, dtype=torch.float64)
    )
    assert noise_floor_vector(None, 2).tolist() == [0.0, 0.0]
    for bad in (-1.0, float("nan"), [0.1, 0.2]):
        with pytest.raises(InputError, match="noise_floor"):
            noise_floor_vector(bad, 3)
