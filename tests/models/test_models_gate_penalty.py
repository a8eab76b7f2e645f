import pytest
import torch

from probaff.errors import InputError
from probaff.models.gates.gate_penalty import (
    L1_SMOOTHING,
    check_strength,
    log_softmax_last,
    penalised_gradient,
    penalised_loss,
    penalised_objective,
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


def test_objective_gradient_matches_autograd():
    g = torch.Generator().manual_seed(0)
    phi = torch.randn(40, 4, dtype=torch.float64, generator=g)
    r = torch.softmax(torch.randn(40, 3, dtype=torch.float64, generator=g), -1)
    s = torch.rand(40, dtype=torch.float64, generator=g)
    s = s / s.sum()
    w = torch.randn(3, 4, dtype=torch.float64, generator=g, requires_grad=True)
    b = torch.randn(3, dtype=torch.float64, generator=g, requires_grad=True)
    for penalty in ((0.3, 0.0), (0.1, 0.05)):
        loss, log_p = penalised_objective(phi, r, s, penalty, w, b)
        torch.testing.assert_close(log_p, torch.log_softmax(phi @ w.T + b, -1))
        expected = -(s * (r * log_p).sum(-1)).sum() + penalty_value(w, penalty)
        torch.testing.assert_close(loss, expected)
        assert penalised_loss(phi, r, s, penalty, w, b) == pytest.approx(float(loss))
        grads = torch.autograd.grad(loss, [w, b])
        ours = penalised_gradient(phi, r, s, penalty, w.detach(), log_p.detach())
        for auto, closed in zip(grads, ours, strict=True):
            torch.testing.assert_close(closed, auto)


def test_short_log_softmax_is_stable():
    logits = torch.tensor([[1e4, 0.0, -1e4], [0.5, 0.25, 0.0]], dtype=torch.float64)
    torch.testing.assert_close(log_softmax_last(logits), torch.log_softmax(logits, -1))


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
