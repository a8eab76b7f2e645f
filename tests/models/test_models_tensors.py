"""Validated float64 tensors (probaff.models.tensors)."""

import numpy as np
import pytest
import torch

from probaff.errors import InputError
from probaff.models.tensors import as_matrix, as_vector


def test_as_matrix_and_as_vector():
    m = as_matrix("X", [[1, 2], [3, 4]])
    assert m.dtype == torch.float64 and m.shape == (2, 2)
    assert as_vector("w", np.ones(3), n=3).shape == (3,)
    with pytest.raises(InputError, match="2-D"):
        as_matrix("X", [1.0, 2.0])
    with pytest.raises(InputError, match="zero samples"):
        as_matrix("X", np.zeros((0, 2)))
    with pytest.raises(InputError, match="X"):
        as_matrix("X", [[1.0, np.nan]])
    with pytest.raises(InputError, match="w"):
        as_vector("w", [1.0, 2.0], n=3)
