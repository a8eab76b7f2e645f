import numpy as np
import pytest
import torch

from probaff.errors import InputError
from probaff.maps import map_entropy, marginal_entropy


def test_entropy_matches_the_binary_entropy_formula():
    rng = np.random.default_rng(0)
    p = rng.uniform(0.0, 1.0, (3, 7))
    p[0, 0], p[1, 1] = 0.0, 1.0
    marginals = torch.tensor(np.stack([1 - p, p], axis=-1))
    with np.errstate(divide="ignore", invalid="ignore"):
        direct = -(np.nan_to_num(p * np.log(p)) + np.nan_to_num((1 - p) * np.log(1 - p)))
    ent = marginal_entropy(marginals)
    assert ent.shape == (3, 7)
    np.testing.assert_allclose(ent.numpy(), direct, atol=1e-12)
    assert ent[0, 0] == 0 and ent[1, 1] == 0
    np.testing.assert_allclose(map_entropy(marginals).numpy(), direct.sum(axis=1), atol=1e-12)
    np.testing.assert_allclose(float(marginal_entropy(torch.tensor([[0.5, 0.5]]))[0]), np.log(2))


def test_entropy_errors():
    with pytest.raises(InputError, match=r"\(\.\.\., V, 2\)"):
        marginal_entropy(torch.zeros(4, 3))
    with pytest.raises(InputError, match="NaN"):
        map_entropy(torch.tensor([[np.nan, 0.5]]))
    with pytest.raises(InputError, match=r"\[0, 1\]"):
        map_entropy(torch.tensor([[1.5, -0.5]]))
