"""Weighted standardisation (probaff.models._scaling)."""

import torch

from probaff.models._scaling import Standardizer


def test_weighted_moments_and_constant_columns():
    x = torch.tensor([[0.0, 5.0], [2.0, 5.0], [4.0, 5.0]], dtype=torch.float64)
    s = Standardizer(2).fit(x, torch.tensor([1.0, 0.0, 1.0], dtype=torch.float64))
    torch.testing.assert_close(s.mean, torch.tensor([2.0, 5.0], dtype=torch.float64))
    torch.testing.assert_close(s.std, torch.tensor([2.0, 1.0], dtype=torch.float64))
    torch.testing.assert_close(s(x)[:, 0], torch.tensor([-1.0, 0.0, 1.0], dtype=torch.float64))
