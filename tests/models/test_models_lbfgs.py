from collections.abc import Generator

import numpy as np
import pytest
import torch

from probaff.models.lbfgs import (
    assign,
    drive,
    flat_grad,
    flatten,
    lbfgs_coroutine,
    lockstep,
    minimise,
)


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


def _rosenbrock(x: torch.Tensor) -> torch.Tensor:
    return (1 - x[:-1]).pow(2).sum() + 100 * (x[1:] - x[:-1].pow(2)).pow(2).sum()


def _evaluate_rosenbrock(x: np.ndarray) -> tuple[float, np.ndarray]:
    t = torch.from_numpy(x).requires_grad_(True)
    loss = _rosenbrock(t)
    loss.backward()
    return float(loss.detach()), t.grad.numpy()


@pytest.mark.parametrize("max_iter", [1, 3, 20, 100])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_coroutine_takes_the_steps_of_torch_lbfgs(seed: int, max_iter: int) -> None:
    x0 = torch.randn(6, generator=torch.Generator().manual_seed(seed), dtype=torch.float64)
    p = x0.clone().requires_grad_(True)
    optimiser = torch.optim.LBFGS(
        [p], max_iter=max_iter, line_search_fn="strong_wolfe", tolerance_grad=1e-6
    )
    torch_points: list[np.ndarray] = []

    def closure() -> torch.Tensor:
        optimiser.zero_grad()
        torch_points.append(p.detach().numpy().copy())
        loss = _rosenbrock(p)
        loss.backward()
        return loss

    optimiser.step(closure)
    points: list[np.ndarray] = []

    def evaluate(x: np.ndarray) -> tuple[float, np.ndarray]:
        points.append(x)
        return _evaluate_rosenbrock(x)

    x, loss = drive(lbfgs_coroutine(x0.numpy(), max_iter=max_iter, tolerance_grad=1e-6), evaluate)
    assert len(points) == len(torch_points)
    np.testing.assert_allclose(np.stack(points), np.stack(torch_points), rtol=0, atol=1e-9)
    np.testing.assert_allclose(x, p.detach().numpy(), rtol=0, atol=1e-9)
    # the final point is one that was evaluated, and its loss is returned
    assert any(np.array_equal(x, q) for q in points)
    assert loss == pytest.approx(float(_rosenbrock(torch.from_numpy(x))), abs=1e-12)


def test_lockstep_batches_each_round_and_equals_separate_runs() -> None:
    starts = [np.array([-1.2, 1.0, 0.5]), np.array([0.3, -0.4, 2.0]), np.array([1.0, 1.0, 1.0])]
    alone = [drive(lbfgs_coroutine(s, max_iter=30), _evaluate_rosenbrock) for s in starts]
    rounds: list[list[int]] = []

    def evaluate(batch: dict[int, np.ndarray]) -> dict[int, tuple[float, np.ndarray]]:
        rounds.append(sorted(batch))
        return {i: _evaluate_rosenbrock(x) for i, x in batch.items()}

    together = lockstep([lbfgs_coroutine(s, max_iter=30) for s in starts], evaluate)
    for (x1, f1), (x2, f2) in zip(alone, together, strict=True):
        np.testing.assert_array_equal(x1, x2)
        assert f1 == f2
    assert rounds[0] == [0, 1, 2]  # every run's first evaluation in one batch
    assert max(len(r) for r in rounds) == 3 and len(rounds) < sum(len(r) for r in rounds)


def test_a_failed_evaluation_is_thrown_into_its_coroutine() -> None:
    def run() -> Generator[float, float, str]:
        try:
            yield 1.0
        except ValueError as exc:
            return f"caught {exc}"
        return "no error"

    def evaluate(x: float) -> float:
        raise ValueError("bad point")

    assert drive(run(), evaluate, (ValueError,)) == "caught bad point"
    with pytest.raises(ValueError, match="bad point"):
        drive(run(), evaluate)  # not listed as a failure: raised to the caller


def test_flatten_assign_and_flat_grad_round_trip() -> None:
    a = torch.zeros(2, 3, dtype=torch.float64, requires_grad=True)
    b = torch.zeros(4, dtype=torch.float64, requires_grad=True)
    assign([a, b], np.arange(10.0))
    np.testing.assert_array_equal(flatten([a, b]), np.arange(10.0))
    (a.sum() * 2).backward()  # b keeps no gradient: zeros
    np.testing.assert_array_equal(flat_grad([a, b]), [2.0] * 6 + [0.0] * 4)
