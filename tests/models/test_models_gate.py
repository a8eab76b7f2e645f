import pytest
import torch

from probaff.errors import InputError
from probaff.models import NotFittedError, SoftmaxGate
from probaff.models.gates.gate import DEFAULT_L2_GRID, FourierGate, make_gate


def _soft_targets(n: int = 200, seed: int = 0) -> tuple[torch.Tensor, torch.Tensor]:
    g = torch.Generator().manual_seed(seed)
    x = torch.randn(n, 2, generator=g, dtype=torch.float64)
    w = torch.tensor([[2.0, 0.0], [-1.0, 1.5], [0.0, -2.0]], dtype=torch.float64)
    b = torch.tensor([0.5, 0.0, -0.5], dtype=torch.float64)
    return x, torch.softmax(x @ w.T + b, dim=1)


def test_gate_recovers_soft_targets():
    x, r = _soft_targets()
    gate = SoftmaxGate(2, 3, l2=0.0).fit(x, r)
    p = gate.predict_proba(x)
    assert p.shape == (200, 3)
    torch.testing.assert_close(p.sum(1), torch.ones(200, dtype=torch.float64))
    torch.testing.assert_close(p, r, atol=1e-4, rtol=0)


def test_gate_sample_weights_and_l2():
    x, r = _soft_targets()
    hard = torch.nn.functional.one_hot(r.argmax(1), 3).double()
    weak = SoftmaxGate(2, 3, l2=1.0).fit(x, hard)
    strong = SoftmaxGate(2, 3, l2=1e-4).fit(x, hard)
    assert weak.weight.norm() < strong.weight.norm()
    # zero sample weight on class 0 rows: the gate no longer predicts class 0 there
    s = (hard[:, 0] == 0).double()
    gate = SoftmaxGate(2, 3, l2=1e-2).fit(x, hard, sample_weight=s)
    assert float(gate.predict_proba(x)[hard[:, 0] == 1, 0].mean()) < 0.5


def test_gate_is_deterministic():
    x, r = _soft_targets()
    a = SoftmaxGate(2, 3).fit(x, r)
    b = SoftmaxGate(2, 3).fit(x, r)
    assert torch.equal(a.predict_proba(x), b.predict_proba(x))


def test_gate_errors():
    x, r = _soft_targets(10)
    gate = SoftmaxGate(2, 3)
    with pytest.raises(NotFittedError, match="fit"):
        gate.predict_proba(x)
    with pytest.raises(InputError, match=r"\[0, 1\]"):
        gate.fit(x, -r)
    with pytest.raises(InputError, match="shape"):
        gate.fit(x, r[:, :2])
    with pytest.raises(InputError):
        SoftmaxGate(0, 3)


# ---------------------------------------------------------------- cross-validated L2, Fourier gate


def _ring(n: int, seed: int) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Two regimes in 2-D: inside the unit circle or outside it."""
    g = torch.Generator().manual_seed(seed)
    x = torch.randn(n, 2, generator=g, dtype=torch.float64) * 1.2
    label = (x.norm(dim=1) < 1.0).long()
    return x, torch.nn.functional.one_hot(label, 2).double(), label


def _noisy_linear(n: int, seed: int, *, noisy: bool = True) -> tuple[torch.Tensor, torch.Tensor]:
    """Soft targets linear in 2 of 20 features, blurred by sampled labels: the penalty matters.

    With ``noisy=False`` the targets are the true probabilities.
    """
    g = torch.Generator().manual_seed(seed)
    x = torch.randn(n, 20, generator=g, dtype=torch.float64)
    w = torch.tensor([[2.0, 0.0], [-1.0, 1.5], [0.0, -2.0]], dtype=torch.float64)
    p = torch.softmax(x[:, :2] @ w.T, dim=1)
    if not noisy:
        return x, p
    label = torch.multinomial(p, 1, generator=g)[:, 0]
    return x, 0.5 * p + 0.5 * torch.nn.functional.one_hot(label, 3).double()


def _cross_entropy(gate: SoftmaxGate, x: torch.Tensor, r: torch.Tensor) -> float:
    return float(-(r * gate.log_proba(x)).sum(1).mean())


def test_fourier_gate_separates_a_ring_the_linear_gate_cannot():
    x, r, _ = _ring(400, 0)
    x_test, _, label_test = _ring(1000, 1)
    majority = max(float(label_test.double().mean()), 1.0 - float(label_test.double().mean()))
    accuracy = {}
    for kind in ("linear", "fourier"):
        gate = make_gate(kind, 2, 2, l2="cv").fit(x, r)
        hit = gate.predict_proba(x_test).argmax(1) == label_test
        accuracy[kind] = float(hit.double().mean())
    assert accuracy["linear"] <= majority + 0.05
    assert accuracy["fourier"] >= 0.9


def test_cv_l2_matches_the_best_fixed_penalty_on_the_grid():
    x, r = _noisy_linear(150, 0)
    x_test, r_test = _noisy_linear(2000, 1, noisy=False)
    s = 0.5 + torch.rand(150, generator=torch.Generator().manual_seed(2), dtype=torch.float64)
    gate = SoftmaxGate(20, 3, l2="cv").fit(x, r, sample_weight=s)
    assert gate.l2_ in DEFAULT_L2_GRID
    assert gate.cv_scores_ is not None and gate.cv_scores_.shape == (1, len(DEFAULT_L2_GRID))
    fixed = [
        _cross_entropy(SoftmaxGate(20, 3, l2=l2).fit(x, r, sample_weight=s), x_test, r_test)
        for l2 in DEFAULT_L2_GRID
    ]
    assert _cross_entropy(gate, x_test, r_test) <= min(fixed) + 0.02
    # the choice is not at either end of the grid here: the penalty matters
    assert DEFAULT_L2_GRID[-1] < gate.l2_ < DEFAULT_L2_GRID[0]


def test_fixed_l2_gate_state_is_unchanged():
    x, r = _soft_targets()
    gate = SoftmaxGate(2, 3, l2=1e-2).fit(x, r)
    assert gate.l2_ == 1e-2
    assert gate.cv_scores_ is None
    assert set(gate.state_dict()) == {"weight", "bias", "fitted", "scaler.mean", "scaler.std"}


def test_cv_gate_refits_warm_and_custom_grid():
    x, r = _soft_targets(120)
    gate = SoftmaxGate(2, 3, l2="cv", l2_grid=[1e-3, 1.0], n_folds=4, seed=3)
    with pytest.raises(NotFittedError, match="fit"):
        _ = gate.l2_
    first = gate.fit(x, r).predict_proba(x)
    assert gate.l2_ in (1e-3, 1.0)
    again = gate.fit(x, r).predict_proba(x)
    torch.testing.assert_close(first, again, atol=1e-4, rtol=0)


def test_gates_are_deterministic_per_seed():
    x, r, _ = _ring(200, 0)
    a = FourierGate(2, 2, seed=5).fit(x, r)
    b = FourierGate(2, 2, seed=5).fit(x, r)
    c = FourierGate(2, 2, seed=6)
    assert torch.equal(a.predict_proba(x), b.predict_proba(x))
    assert a.l2_ == b.l2_ and a.lengthscale_ == b.lengthscale_
    assert not torch.equal(a.omega, c.omega)
    assert not torch.equal(a.phase, c.phase)
    lin_a = SoftmaxGate(2, 2, l2="cv", seed=1).fit(x, r)
    lin_b = SoftmaxGate(2, 2, l2="cv", seed=1).fit(x, r)
    assert torch.equal(lin_a.predict_proba(x), lin_b.predict_proba(x))


def test_state_dict_round_trip():
    x, r, _ = _ring(200, 0)
    for fitted, fresh in [
        (FourierGate(2, 2, seed=1, lengthscale="cv").fit(x, r), FourierGate(2, 2, seed=9)),
        (SoftmaxGate(2, 2, l2="cv").fit(x, r), SoftmaxGate(2, 2, l2="cv")),
    ]:
        fresh.load_state_dict(fitted.state_dict())
        assert torch.equal(fresh.predict_proba(x), fitted.predict_proba(x))
        assert fresh.l2_ == fitted.l2_
    assert fresh.fitted


def test_fourier_gate_interface():
    x, r, _ = _ring(100, 0)
    gate = make_gate("fourier", 2, 2, l2=1e-2, seed=0, n_random_features=16, lengthscale=0.7)
    assert isinstance(gate, FourierGate)
    assert gate.weight.shape == (2, 18) and gate.bias.shape == (2,)
    assert gate.n_features == 2 and gate.n_experts == 2 and gate.n_basis == 18
    assert not gate.fitted
    gate.fit(x, r)
    assert gate.fitted and gate.lengthscale_ == 0.7 and gate.l2_ == 1e-2
    logits = gate.logits(x[:5])
    assert logits.shape == (5, 2) and logits.dtype == torch.float64
    logits.sum().backward()
    assert gate.weight.grad is not None
    torch.testing.assert_close(gate.log_proba(x).exp(), gate.predict_proba(x))
    assert isinstance(make_gate("linear", 3, 2), SoftmaxGate)


def test_new_gate_errors():
    x, r, _ = _ring(30, 0)
    bad = x.clone()
    bad[3, 1] = float("nan")
    for gate in (SoftmaxGate(2, 2, l2="cv"), FourierGate(2, 2)):
        with pytest.raises(InputError, match="NaN"):
            gate.fit(bad, r)
        with pytest.raises(InputError, match="shape"):
            gate.fit(x[:, :1], r)
        with pytest.raises(InputError, match="shape"):
            gate.fit(x, r[:10])
        gate.fit(x, r)
        with pytest.raises(InputError, match="NaN"):
            gate.predict_proba(bad)
        with pytest.raises(InputError, match="2-D"):
            gate.predict_proba(x[0])
    with pytest.raises(InputError, match="l2"):
        SoftmaxGate(2, 2, l2=-1)
    with pytest.raises(InputError, match="'cv'"):
        make_gate("fourier", 2, 2, l2="auto")
    with pytest.raises(InputError, match="n_features"):
        SoftmaxGate(0.5, 2)  # type: ignore[arg-type]
    with pytest.raises(InputError, match="n_features"):
        FourierGate(0.5, 2)  # type: ignore[arg-type]
    with pytest.raises(InputError, match="n_random_features"):
        FourierGate(2, 2, n_random_features=0)
    with pytest.raises(InputError, match="lengthscale"):
        FourierGate(2, 2, lengthscale=-1.0)
    with pytest.raises(InputError, match="n_folds"):
        SoftmaxGate(2, 2, l2="cv", n_folds=1)
    with pytest.raises(InputError, match="n_folds"):
        SoftmaxGate(2, 2, l2="cv", n_folds=5).fit(x[:4], r[:4])
    with pytest.raises(InputError, match="l2_grid"):
        SoftmaxGate(2, 2, l2=1e-3, l2_grid=[1e-2])
    with pytest.raises(InputError, match="l2_grid"):
        SoftmaxGate(2, 2, l2="cv", l2_grid=[])
    with pytest.raises(InputError, match="'linear', 'fourier'"):
        make_gate("rbf", 2, 2)
    with pytest.raises(InputError, match="n_random_features"):
        make_gate("linear", 2, 2, n_random_features=8)


def _sparse_regimes(n: int, seed: int = 0) -> tuple[torch.Tensor, torch.Tensor]:
    """Three classes set by two of 60 standard-normal columns."""
    g = torch.Generator().manual_seed(seed)
    x = torch.randn(n, 60, generator=g, dtype=torch.float64)
    labels = torch.bucketize(x[:, 0] + 0.5 * x[:, 1], torch.tensor([-0.5, 0.5]).double())
    return x, torch.nn.functional.one_hot(labels, 3).double()


def test_lasso_gate_finds_the_few_relevant_columns():
    x, r = _sparse_regimes(1200)
    train, test = slice(0, 200), slice(200, None)
    ridge = SoftmaxGate(60, 3, l2="cv").fit(x[train], r[train])
    lasso = SoftmaxGate(60, 3, l2="cv", l1="cv").fit(x[train], r[train])

    def accuracy(gate: SoftmaxGate) -> float:
        return float((gate.predict_proba(x[test]).argmax(1) == r[test].argmax(1)).double().mean())

    assert accuracy(lasso) > accuracy(ridge) + 0.05
    assert lasso.l1_ > 0.0 and lasso.l2_ == 0.0
    # most weights of the 58 irrelevant columns are (smoothed) zeros; the ridge has none
    lasso_zeros = (lasso.weight.detach()[:, 2:].abs() < 1e-2).double().mean()
    ridge_zeros = (ridge.weight.detach()[:, 2:].abs() < 1e-2).double().mean()
    assert float(lasso_zeros) > 0.7 and float(ridge_zeros) < 0.3
    assert lasso.cv_scores_ is not None
    assert lasso.cv_scores_.shape == (1, len(lasso.penalties_))
    assert len(lasso.penalties_) == len(lasso.l2_grid_) + len(lasso.l1_grid_)


def test_fixed_l1_and_its_errors():
    x, r = _sparse_regimes(300)
    gate = SoftmaxGate(60, 3, l2=0.0, l1=0.02).fit(x, r)
    assert gate.l1_ == 0.02 and gate.penalties_ == ((0.0, 0.02),)
    with pytest.raises(InputError, match="l1"):
        SoftmaxGate(60, 3, l1="lasso")
    with pytest.raises(InputError, match="l1"):
        SoftmaxGate(60, 3, l1=-1.0)
    with pytest.raises(InputError, match="l1_grid"):
        SoftmaxGate(60, 3, l1=0.1, l1_grid=[0.1])
    with pytest.raises(NotFittedError, match="l1"):
        _ = SoftmaxGate(60, 3, l1="cv").l1_
    state = gate.state_dict()
    copy = SoftmaxGate(60, 3, l2=0.0, l1=0.02)
    copy.load_state_dict(state)
    torch.testing.assert_close(copy.weight, gate.weight)
