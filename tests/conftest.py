import numpy as np
import pytest
import torch


@pytest.fixture(autouse=True)
def _deterministic_threads():
    """Single-threaded torch keeps batched IK bit-reproducible across tests."""
    before = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(before)


@pytest.fixture
def rng():
    return np.random.default_rng(1234)
