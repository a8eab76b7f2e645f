import pytest
import torch

from probaff.errors import InputError
from probaff.models.gate_penalty import (
    L1_SMOOTHING,
    check_strength,
    penalty_candidates,
    penalty_grad,
    penalty_paths,
    penalty_value,
    strength_grid,
)


def test_penalty_gradient_matches_autograd():
    w = torch.randn(3, 5, dtype=torch.float64, requires_grad=True)
    for penalty in ((0.3, 0.0), (0.0, 0.2), (0.1, 0.05)):
        (grad,) = torch.autograd.grad(penalty_value(w, penalty), w)
        torch.testing.assert_close(grad, penalty_grad(w.detach(), penalty))


def test_smoothed_lasso_is_the_l1_norm_away_from_zero():
    w = torch.tensor([[2.0, -3.0, 0.0]], dtype=torch.float64)
    value = float(penalty_value(w, (0.0, 0.5)))
    assert value == pytest.approx(0.5 * 5.0, abs=L1_SMOOTHING)
    assert float(penalty_value(w, (2.0, 0.0))) == pytest.approx(13.0)


def test_candidates_and_paths():
    ridge, lasso = (1.0, 0.1), (0.3, 0.01)
    both = penalty_candidates("cv", "cv", ridge, lasso)
    assert both == ((1.0, 0.0), (0.1, 0.0), (0.0, 0.3), (0.0, 0.01))
    assert penalty_paths(both) == [(0, 2), (2, 4)]
    assert penalty_candidates("cv", 0.0, ridge, lasso) == ((1.0, 0.0), (0.1, 0.0))
    assert penalty_candidates(0.5, "cv", ridge, lasso) == ((0.5, 0.3), (0.5, 0.01))
    assert penalty_candidates(0.5, 0.2, ridge, lasso) == ((0.5, 0.2),)
    assert penalty_paths(((0.5, 0.3), (0.5, 0.01))) == [(0, 2)]
    assert strength_grid("l1", "cv", [0.01, 0.3], (1.0,)) == (0.3, 0.01)


def test_bad_strengths_and_grids():
    assert check_strength("l1", 0) == 0.0 and check_strength("l1", "cv") == "cv"
    for bad in ("lasso", -1.0, float("nan")):
        with pytest.raises(InputError, match="l1"):
            check_strength("l1", bad)
    with pytest.raises(InputError, match="l1_grid is only used when l1='cv'"):
        strength_grid("l1", 0.1, [0.1], (1.0,))
    with pytest.raises(InputError, match="empty"):
        strength_grid("l1", "cv", [], (1.0,))
