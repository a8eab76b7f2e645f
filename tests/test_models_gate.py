import pytest
import torch

from probaff.errors import InputError
from probaff.models import NotFittedError, SoftmaxGate


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
