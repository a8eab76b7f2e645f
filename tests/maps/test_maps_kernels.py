"""The shared BP kernels of probaff.maps._kernels, against their closed forms."""

import math

import pytest
import torch

from probaff.errors import InputError
from probaff.maps._kernels import (
    check_log_potentials,
    clamp_fields,
    damped_update_,
    ising_messages_,
    marginals_from_fields,
)


def test_clamp_fields_sets_infinities_and_keeps_free_values():
    fields = torch.tensor([0.5, -0.2, 0.1])
    free = clamp_fields(fields, torch.full((2, 3), -1, dtype=torch.int8))
    assert free.shape == (2, 3) and torch.equal(free[1], fields)
    out = clamp_fields(fields, torch.tensor([[1, 0, -1]], dtype=torch.int8))
    assert out[0, 0] == math.inf and out[0, 1] == -math.inf and out[0, 2] == fields[2]


def test_ising_messages_and_damping():
    cavity = torch.tensor([0.3, -1.0, math.inf])
    out = ising_messages_(cavity.clone(), math.tanh(0.4))
    expected = torch.atanh(math.tanh(0.4) * torch.tanh(torch.tensor([0.3, -1.0, math.inf])))
    torch.testing.assert_close(out, expected)
    messages, proposals = torch.tensor([0.0, 1.0]), torch.tensor([1.0, 0.0])
    assert damped_update_(messages, proposals, 0.25) == 1.0
    torch.testing.assert_close(messages, torch.tensor([0.75, 0.25]))
    assert damped_update_(torch.zeros(0), torch.zeros(0), 0.3) == 0.0


def test_marginals_from_fields_and_log_potential_checks():
    marg = marginals_from_fields(torch.tensor([0.0, math.inf, -math.inf]))
    torch.testing.assert_close(marg, torch.tensor([[0.5, 0.5], [0.0, 1.0], [1.0, 0.0]]))
    unary = torch.tensor([[0.0, -math.inf], [-math.inf, -math.inf]])
    assert check_log_potentials(unary).tolist() == [False, True]
    with pytest.raises(InputError, match="NaN or \\+inf"):
        check_log_potentials(torch.tensor([[0.0, math.nan]]))
