"""The GP experts' SE-ARD kernel (probaff.models.experts.kernels)."""

import math

import torch

from probaff.models.experts.kernels import ard_se_kernel


def test_ard_se_kernel_is_batched_with_one_length_scale_per_feature():
    k = ard_se_kernel(
        3, torch.Size([2]), lengthscale_bounds=(1e-3, 1e4), outputscale_bounds=(1e-4, 1e4)
    )
    assert k.base_kernel.lengthscale.shape == (2, 1, 3)
    x = torch.zeros(1, 3, dtype=torch.float64)
    y = torch.tensor([[1.0, 0.0, 0.0]], dtype=torch.float64)
    k = k.double()
    value = k(x, y).to_dense()
    ls = float(k.base_kernel.lengthscale[0, 0, 0])
    expected = float(k.outputscale[0]) * math.exp(-0.5 / ls**2)
    assert value.shape == (2, 1, 1)
    assert abs(float(value[0, 0, 0]) - expected) < 1e-10
