import pytest
import torch

import probaff.models.gates.gate as gate_module
from probaff.models import SoftmaxGate
from probaff.models.gates.gate_newton import _rescale_zeroed, newton_fit
from probaff.models.gates.gate_penalty import penalised_loss, penalty_grad, penalty_value


def _problem(n: int = 300, seed: int = 0) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Soft targets of three regimes set by two of 40 standardised columns."""
    g = torch.Generator().manual_seed(seed)
    x = torch.randn(n, 40, generator=g, dtype=torch.float64)
    logits = torch.stack([3.0 * x[:, 0], 3.0 * x[:, 1], torch.zeros(n, dtype=torch.float64)], 1)
    s = torch.full((n,), 1.0 / n, dtype=torch.float64)
    return x, torch.softmax(logits, 1), s


def _reference(x, r, s, penalty) -> float:
    """A long, tight torch L-BFGS run of the same convex objective (autograd gradients)."""
    weight = torch.zeros(3, x.shape[1], dtype=torch.float64, requires_grad=True)
    bias = torch.zeros(3, dtype=torch.float64, requires_grad=True)

    def closure() -> torch.Tensor:
        weight.grad = bias.grad = None
        log_p = torch.log_softmax(x @ weight.T + bias, -1)
        loss = -(s * (r * log_p).sum(-1)).sum() + penalty_value(weight, penalty)
        loss.backward()
        return loss

    torch.optim.LBFGS(
        [weight, bias],
        max_iter=5000,
        tolerance_grad=1e-12,
        tolerance_change=1e-15,
        history_size=100,
        line_search_fn="strong_wolfe",
    ).step(closure)
    return penalised_loss(x, r, s, penalty, weight.detach(), bias.detach())


@pytest.mark.parametrize("penalty", [(1e-3, 0.0), (1e-3, 1e-3), (0.0, 1e-2), (0.0, 1e-3)])
def test_newton_reaches_the_optimum_in_few_steps(penalty):
    x, r, s = _problem()
    weight = torch.zeros(3, 40, dtype=torch.float64)
    bias = torch.zeros(3, dtype=torch.float64)
    steps = newton_fit(
        x, r, s, penalty, weight, bias, max_iter=500, tolerance_grad=1e-8, tolerance_change=0.0
    )
    ours = penalised_loss(x, r, s, penalty, weight, bias)
    assert ours <= _reference(x, r, s, penalty) + 1e-10
    # the stationarity condition holds: the gradient (closed form) is below the tolerance
    log_p = torch.log_softmax(x @ weight.T + bias, -1)
    residual = log_p.exp() - r
    grad_w = (s[:, None] * residual).T @ x + penalty_grad(weight, penalty)
    grad_b = (s[:, None] * residual).sum(0)
    assert float(torch.cat([grad_w.reshape(-1), grad_b]).abs().max()) <= 1e-8
    assert 1 <= steps <= (20 if penalty[1] == 0.0 else 30)


@pytest.mark.parametrize(("seed", "l1"), [(0, 1e-2), (2, 1e-1), (3, 1e-2), (3, 1e-1)])
def test_newton_lasso_reaches_the_optimum_from_a_dense_start(seed, l1):
    # From weights far from the sparse optimum the smoothed lasso's curvature changes
    # within eps of zero and Newton's line search keeps shrinking the steps; the
    # continuation in the smoothing must still reach the optimum, with the small-drop
    # stop of a real fit in force.
    x, r, s = _problem(200, seed)
    g = torch.Generator().manual_seed(seed)
    weight = 0.3 * torch.randn(3, 40, generator=g, dtype=torch.float64)
    bias = torch.zeros(3, dtype=torch.float64)
    steps = newton_fit(
        x, r, s, (0.0, l1), weight, bias, max_iter=100, tolerance_grad=1e-6, tolerance_change=1e-9
    )
    assert steps <= 80
    ours = penalised_loss(x, r, s, (0.0, l1), weight, bias)
    assert abs(ours - _reference(x, r, s, (0.0, l1))) < 1e-8


@pytest.mark.parametrize("max_iter", [1, 2, 3])
def test_newton_lasso_never_ends_above_its_start(max_iter):
    # With few steps allowed, the continuation's stages may stop before they pass the
    # start; the fit then keeps the start rather than a worse point.
    x, r, s = _problem(200, 0)
    g = torch.Generator().manual_seed(0)
    weight = 0.3 * torch.randn(3, 40, generator=g, dtype=torch.float64)
    bias = torch.zeros(3, dtype=torch.float64)
    before = penalised_loss(x, r, s, (0.0, 1e-2), weight, bias)
    newton_fit(
        x,
        r,
        s,
        (0.0, 1e-2),
        weight,
        bias,
        max_iter=max_iter,
        tolerance_grad=1e-6,
        tolerance_change=1e-9,
    )
    assert penalised_loss(x, r, s, (0.0, 1e-2), weight, bias) <= before


def test_rescaled_zero_weights_keep_their_penalty_gradient():
    # At a fixed data gradient a weight the smoothed lasso holds near zero is proportional
    # to the smoothing, so the continuation's rescaling lands it on the stationary point
    # of the new smoothing: the lasso's gradient is unchanged.
    w = torch.tensor([[-3e-3, -1e-4, 0.0, 2e-4, 4e-3, 0.8]], dtype=torch.float64)
    v = torch.cat([w, torch.tensor([[0.5]], dtype=torch.float64)], dim=1)
    wide, narrow = 1e-2, 1e-4
    back = _rescale_zeroed(v, wide, narrow)
    torch.testing.assert_close(back[:, -1], v[:, -1])  # the intercept is kept
    assert float(back[0, -2]) == 0.8  # beyond the band: a weight the lasso does not zero
    zeroed = slice(0, 5)
    torch.testing.assert_close(
        penalty_grad(back[:, zeroed], (0.0, 1.0), smoothing=narrow),
        penalty_grad(w[:, zeroed], (0.0, 1.0), smoothing=wide),
    )


def test_newton_lasso_zeroes_the_irrelevant_columns():
    x, r, s = _problem()
    weight = torch.zeros(3, 40, dtype=torch.float64)
    bias = torch.zeros(3, dtype=torch.float64)
    newton_fit(
        x, r, s, (0.0, 1e-2), weight, bias, max_iter=200, tolerance_grad=1e-7, tolerance_change=0.0
    )
    assert float(weight[:, 2:].abs().max()) < 1e-3  # within the lasso's smoothing scale
    assert float(weight[:, :2].abs().max()) > 0.5


def test_newton_stops_at_once_at_an_optimum_and_keeps_a_start_it_cannot_improve():
    x, r, s = _problem()
    weight = torch.zeros(3, 40, dtype=torch.float64)
    bias = torch.zeros(3, dtype=torch.float64)
    kw = {"max_iter": 100, "tolerance_grad": 1e-9, "tolerance_change": 0.0}
    newton_fit(x, r, s, (1e-3, 0.0), weight, bias, **kw)
    before = weight.clone()
    assert newton_fit(x, r, s, (1e-3, 0.0), weight, bias, **kw) == 0
    assert torch.equal(weight, before)


def test_the_gate_uses_newton_when_small_and_lbfgs_when_large(monkeypatch):
    x, r, _ = _problem()
    small = SoftmaxGate(40, 3, l2=1e-3, l1=1e-3).fit(x, r)
    monkeypatch.setattr(gate_module, "NEWTON_MAX_PARAMETERS", 0)
    large = SoftmaxGate(40, 3, l2=1e-3, l1=1e-3).fit(x, r)
    s = torch.full((300,), 1.0 / 300, dtype=torch.float64)
    phi = small.scaler(x)
    newton = penalised_loss(phi, r, s, (1e-3, 1e-3), small.weight.detach(), small.bias.detach())
    lbfgs = penalised_loss(phi, r, s, (1e-3, 1e-3), large.weight.detach(), large.bias.detach())
    assert newton <= lbfgs + 1e-10
    assert lbfgs - newton < 1e-6  # the same convex optimum, to L-BFGS's tolerance


def test_the_gate_fit_reaches_the_optimum_of_a_long_torch_lbfgs_run():
    # a fitted gate (standardised basis, lasso and ridge) sits on the convex optimum
    x, r, s = _problem()
    gate = SoftmaxGate(40, 3, l2=1e-3, l1=1e-3).fit(x, torch.nn.functional.one_hot(r.argmax(1), 3))
    hard = torch.nn.functional.one_hot(r.argmax(1), 3).double()
    phi = gate.scaler(x)
    ours = penalised_loss(phi, hard, s, (1e-3, 1e-3), gate.weight.detach(), gate.bias.detach())
    assert abs(ours - _reference(phi, hard, s, (1e-3, 1e-3))) < 1e-7
