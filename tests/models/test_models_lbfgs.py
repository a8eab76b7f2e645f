import pytest
import torch

from probaff.models.lbfgs import minimise


@pytest.mark.parametrize("dtype", [torch.float64, torch.float32])
def test_minimise_solves_a_convex_quadratic_on_either_path(dtype):
    # float64 on the CPU takes scipy's L-BFGS-B, float32 torch's L-BFGS
    g = torch.Generator().manual_seed(0)
    a = torch.randn(8, 5, generator=g, dtype=torch.float64)
    hessian = (a.T @ a + 0.1 * torch.eye(5, dtype=torch.float64)).to(dtype)
    target = torch.randn(5, generator=g, dtype=torch.float64).to(dtype)
    x = torch.zeros(3, dtype=dtype)
    y = torch.zeros(2, dtype=dtype)

    def closure() -> torch.Tensor:
        z = torch.cat([x, y]) - target
        grad = hessian @ z
        x.grad, y.grad = grad[:3].clone(), grad[3:].clone()
        return 0.5 * z @ grad

    minimise([x, y], closure, max_iter=200, tolerance_grad=1e-10, tolerance_change=1e-14)
    tol = 1e-8 if dtype == torch.float64 else 1e-3
    torch.testing.assert_close(torch.cat([x, y]), target, rtol=0, atol=tol)


def test_minimise_keeps_the_start_when_the_closure_goes_non_finite():
    x = torch.ones(2, dtype=torch.float64)

    def closure() -> torch.Tensor:
        x.grad = torch.full_like(x, float("nan"))
        return torch.tensor(float("nan"), dtype=torch.float64)

    minimise([x], closure, max_iter=5, tolerance_grad=1e-8, tolerance_change=1e-12)
    assert torch.isfinite(x).all()
