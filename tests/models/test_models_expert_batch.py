import copy
import math
import warnings
from dataclasses import replace

import numpy as np
import pytest
import torch
from device_checks import DEVICES, assert_on_device, elsewhere

from probaff.errors import InputError, NotFittedError
from probaff.models import MIXTURE_GP, GPExpert, MixtureOfGPExperts, fit_em
from probaff.models.experts.expert_batch import (
    ExpertStack,
    _Batch,
    _floors,
    batching_enabled,
    fit_exact_experts,
    per_expert_fits,
    predict_exact_experts,
    predict_exact_experts_out_of_sample,
    stacked_log_likelihood,
)
from probaff.models.lbfgs import flatten
from probaff.models.synthetic import regime_features


def _problem(
    n: int = 60, d: int = 4, e: int = 2, m: int = 3, seed: int = 0
) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    """Smooth data and soft weights with many exact zeros (experts hold different rows)."""
    g = torch.Generator().manual_seed(seed)
    x = torch.rand(n, d, generator=g, dtype=torch.float64) * 4 - 2
    f = torch.stack([torch.sin(2 * x[:, 0]) + x[:, 1], x[:, 0] * x[:, -1], x[:, 1].cos()], 1)
    y = f[:, :e] + 0.05 * torch.randn(n, e, generator=g, dtype=torch.float64)
    w = torch.rand(n, m, generator=g, dtype=torch.float64)
    w[w < 0.35] = 0.0
    w[0] = 1.0  # every expert keeps at least one row
    return x, y, w


def _experts(d: int, e: int, m: int, *, prior: bool = True, device: str = "cpu") -> list[GPExpert]:
    experts = [GPExpert(d, e, lengthscale_prior=prior, noise_floor=0.01) for _ in range(m)]
    for j, expert in enumerate(experts):
        with torch.no_grad():  # distinct hyperparameters per expert and output
            expert.gp.covar_module.base_kernel.raw_lengthscale.add_(0.3 * j - 0.2)
            expert.gp.covar_module.raw_outputscale.add_(torch.linspace(-0.5, 0.5, e) * (j + 1))
            expert.likelihood.noise_covar.raw_noise.add_(-0.4 * j)
            expert.gp.mean_module.constant.add_(0.1 * j)
    return [expert.to(device) for expert in experts]


@pytest.mark.parametrize("device", DEVICES)
@pytest.mark.parametrize("prior", [False, True])
def test_stacked_objective_equals_each_expert_exactly(device: str, prior: bool) -> None:
    x, y, w = _problem()
    experts = _experts(4, 2, 3, prior=prior, device=device)
    for j, expert in enumerate(experts):
        expert.condition(x.to(device), y.to(device), w[:, j].to(device))
    sizes = [expert.n_train for expert in experts]
    assert len(set(sizes)) > 1  # padding is exercised
    with elsewhere():  # a tensor made without the experts' device would land on meta
        value, nan, failed = stacked_log_likelihood(experts)
    assert_on_device((value, nan, failed), x.to(device).device)
    ref = torch.stack([expert.marginal_log_likelihood() for expert in experts])
    assert value.shape == (3, 2) and not bool(nan.any()) and not bool(failed.any())
    torch.testing.assert_close(value, ref, rtol=0, atol=1e-8)


def test_stacked_gradient_equals_autograd_of_each_expert() -> None:
    x, y, w = _problem(n=50, d=3)
    experts = _experts(3, 2, 3)
    for j, expert in enumerate(experts):
        expert.condition(x, y, w[:, j])
    value, _, _ = stacked_log_likelihood(experts)
    value.sum().backward()
    batched = [[p.grad.clone() for p in expert.parameters()] for expert in experts]
    for expert, grads in zip(experts, batched, strict=True):
        expert.zero_grad(set_to_none=True)
        expert.marginal_log_likelihood().sum().backward()
        for p, g in zip(expert.parameters(), grads, strict=True):
            torch.testing.assert_close(g, p.grad, rtol=1e-7, atol=1e-9)


def test_padded_rows_have_no_effect() -> None:
    """An expert's value does not depend on the other experts it is stacked with."""
    x, y, w = _problem()
    experts = _experts(4, 2, 3)
    for j, expert in enumerate(experts):
        expert.condition(x, y, w[:, j])
    alone = torch.cat([stacked_log_likelihood([expert])[0] for expert in experts])
    together, _, _ = stacked_log_likelihood(experts)
    torch.testing.assert_close(together, alone, rtol=0, atol=1e-10)
    stack = ExpertStack.of(experts)
    assert stack.x.shape[1] == max(expert.n_train for expert in experts)
    torch.testing.assert_close(stack.mask.sum(1), stack.counts)


@pytest.mark.parametrize("device", DEVICES)
def test_batched_fit_matches_separate_fits(device: str) -> None:
    x, y, w = _problem(n=80, d=5, e=2)
    x, y, w = x.to(device), y.to(device), w.to(device)
    batched = _experts(5, 2, 3, device=device)
    separate = copy.deepcopy(batched)
    with elsewhere():  # a tensor made without the data's device would land on meta
        fit_exact_experts(batched, x, y, w, max_iter=15)
    assert_on_device(batched, x.device)
    for j, expert in enumerate(separate):
        expert.fit(x, y, w[:, j], max_iter=15)
    for a, b in zip(batched, separate, strict=True):
        fa = float(a.marginal_log_likelihood().sum().detach())
        fb = float(b.marginal_log_likelihood().sum().detach())
        assert fa >= fb - 1e-7
        assert math.isclose(fa, fb, rel_tol=1e-7, abs_tol=1e-7)
        torch.testing.assert_close(a.lengthscales, b.lengthscales, rtol=1e-5, atol=1e-6)
        torch.testing.assert_close(a.noise, b.noise, rtol=1e-5, atol=1e-9)
        assert float(a.jitter) == float(b.jitter)


def _conditioned(device: str) -> tuple[list[GPExpert], torch.Tensor]:
    """Three experts holding different rows of one problem, and 25 test inputs."""
    x, y, w = _problem(n=70, d=4, e=3)
    experts = _experts(4, 3, 3, device=device)
    for j, expert in enumerate(experts):
        expert.condition(x.to(device), y.to(device), w[:, j].to(device))
    x_test = torch.linspace(-1, 1, 4 * 25, dtype=torch.float64).reshape(25, 4).to(device)
    return experts, x_test


@pytest.mark.parametrize("device", DEVICES)
def test_batched_predictions_match_each_expert(device: str) -> None:
    experts, x_test = _conditioned(device)
    for noise in (True, False):
        with elsewhere():  # a tensor made without the data's device would land on meta
            pred = predict_exact_experts(experts, x_test, include_noise=noise)
        assert_on_device(pred, x_test.device)
        assert pred.loc.shape == (25, 3, 3)
        for j, expert in enumerate(experts):
            ref = expert.predict(x_test, include_noise=noise)
            torch.testing.assert_close(pred.loc[:, j], ref.loc, rtol=1e-9, atol=1e-9)
            torch.testing.assert_close(pred.scale[:, j], ref.scale, rtol=1e-9, atol=1e-9)


@pytest.mark.parametrize("device", DEVICES)
def test_batched_out_of_sample_matches_each_expert(device: str) -> None:
    """Leave-one-out where an expert holds a row, its prediction elsewhere."""
    x, y, w = _problem(n=70, d=4, e=3)
    w[:5, 0] = 1.0  # expert 0 holds the first rows, expert 1 none of them
    w[:5, 1] = 0.0
    w[:, 2] = 1.0  # expert 2 holds every row: nothing left for it to predict
    x, w = x.to(device), w.to(device)
    experts = _experts(4, 3, 3, device=device)
    for j, expert in enumerate(experts):
        expert.condition(x, y.to(device), w[:, j])
    held = w > 0
    assert len({e.n_train for e in experts}) > 1  # padded rows are cut out
    assert bool((~held[:, :2]).any()) and bool(held[:, 2].all())
    with elsewhere():  # a tensor made without the data's device would land on meta
        pred = predict_exact_experts_out_of_sample(experts, x, held)
    assert_on_device(pred, x.device)
    assert pred.loc.shape == (70, 3, 3)
    for j, expert in enumerate(experts):
        loo, plain = expert.loo_predict(), expert.predict(x)
        h = held[:, j]
        torch.testing.assert_close(pred.loc[h, j], loo.loc, rtol=1e-9, atol=1e-10)
        torch.testing.assert_close(pred.scale[h, j], loo.scale, rtol=1e-9, atol=1e-10)
        torch.testing.assert_close(pred.loc[~h, j], plain.loc[~h], rtol=1e-9, atol=1e-9)
        torch.testing.assert_close(pred.scale[~h, j], plain.scale[~h], rtol=1e-9, atol=1e-9)
    with per_expert_fits():  # the reference path gives the experts' own numbers
        serial = predict_exact_experts_out_of_sample(experts, x, held)
    torch.testing.assert_close(serial.loc, pred.loc, rtol=1e-9, atol=1e-10)
    torch.testing.assert_close(serial.scale, pred.scale, rtol=1e-9, atol=1e-10)


def test_singular_expert_uses_the_jitter_of_a_separate_fit() -> None:
    """Repeated inputs with exact targets: each expert keeps its own jitter choice."""
    x = torch.zeros(24, 2, dtype=torch.float64)
    x[12:, 0] = 1.0  # two distinct inputs, each repeated; second column constant
    y = torch.cat([torch.zeros(12, 1), torch.ones(12, 1)]).double()
    w = torch.ones(24, 2, dtype=torch.float64)
    w[::3, 1] = 0.0
    experts = [GPExpert(2, 1, noise=2e-6) for _ in range(2)]
    separate = copy.deepcopy(experts)
    fit_exact_experts(experts, x, y, w, max_iter=5)
    for j, expert in enumerate(separate):
        expert.fit(x, y, w[:, j], max_iter=5)
    for a, b in zip(experts, separate, strict=True):
        assert float(a.jitter) == float(b.jitter)
        torch.testing.assert_close(
            a.marginal_log_likelihood(), b.marginal_log_likelihood(), rtol=1e-6, atol=1e-6
        )
        pred = predict_exact_experts(experts, x[[0, -1]])
        assert bool(torch.isfinite(pred.scale).all())
        torch.testing.assert_close(
            pred.loc[:, :, 0], torch.tensor([[0.0] * 2, [1.0] * 2]).double(), atol=1e-2, rtol=0
        )


def test_failing_expert_warns_and_keeps_hyperparameters_others_fit() -> None:
    x, y, w = _problem(n=40, d=2, e=1, m=2)
    experts = [GPExpert(2, 1) for _ in range(2)]
    for expert in experts:
        expert.condition(x, y)
    before = [copy.deepcopy(e.state_dict()) for e in experts]
    y_bad = y.clone()
    w_bad = w.clone()
    # Weights of 1e-300 make the noise variance overflow to inf: NaN in the covariance.
    w_bad[:, 0] = torch.where(w_bad[:, 0] > 0, torch.full_like(w_bad[:, 0], 1e-320), w_bad[:, 0])
    w_bad[0, 0] = 1.0
    with pytest.warns(RuntimeWarning, match="failed at every jitter"):
        fit_exact_experts(experts, x, y_bad, w_bad, max_iter=5)
    for name, value in before[0].items():
        if name.endswith("raw_lengthscale"):
            torch.testing.assert_close(experts[0].state_dict()[name], value)
    moved = experts[1].state_dict()["gp.covar_module.base_kernel.raw_lengthscale"]
    assert not torch.equal(moved, before[1]["gp.covar_module.base_kernel.raw_lengthscale"])


def test_bad_weights_raise_before_any_fit() -> None:
    x, y, w = _problem(n=30, d=2, e=1, m=2)
    w[:, 1] = 0.0
    experts = [GPExpert(2, 1) for _ in range(2)]
    with pytest.raises(InputError, match="every weight is zero"):
        fit_exact_experts(experts, x, y, w)
    with pytest.raises(NotFittedError):
        predict_exact_experts(experts, x)


def test_reference_path_is_reachable_and_agrees() -> None:
    x, y, w = _problem(n=60, d=3, e=2)
    batched = _experts(3, 2, 3)
    reference = copy.deepcopy(batched)
    assert batching_enabled()
    fit_exact_experts(batched, x, y, w, max_iter=10)
    with per_expert_fits():
        assert not batching_enabled()
        fit_exact_experts(reference, x, y, w, max_iter=10)
        ref_pred = predict_exact_experts(reference, x)
    assert batching_enabled()
    pred = predict_exact_experts(batched, x)
    torch.testing.assert_close(pred.loc, ref_pred.loc, rtol=1e-6, atol=1e-7)
    torch.testing.assert_close(pred.scale, ref_pred.scale, rtol=1e-6, atol=1e-7)


@pytest.mark.parametrize(("defaults", "tol"), [(False, 1e-6), (True, 5e-3)])
def test_em_fit_is_unchanged_by_batching(defaults: bool, tol: float) -> None:
    """EM on regime data: the same objective path and held-out NLPD as one expert at a time.

    With a ridge gate of cross-validated strength and no length-scale prior the paths agree
    to 1e-6. The default settings (a gate choosing among ridge and lasso penalties, the
    prior) meet the batched fit's rounding differences at more discrete choices, which EM's
    later iterations amplify, hence the looser tolerance.
    """
    x, y, _ = regime_features(160, 16, 2, seed=3)
    x_tr, y_tr, x_te, y_te = x[:120], y[:120], x[120:], y[120:]

    def fit() -> tuple[list[float], float]:
        model = MixtureOfGPExperts(
            3,
            groups={"f_x": slice(0, 3)},
            gate_features=("f_x",),
            gp=replace(MIXTURE_GP, max_iter=20, lengthscale_prior=defaults),
            **({} if defaults else {"gate_l1": 0.0}),
        )
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            history = fit_em(model, x_tr, y_tr, max_iter=4, n_restarts=1, init="joint", seed=0)
        return history.objective, -float(model.predict(x_te).log_prob(y_te).mean())

    objective, nlpd = fit()
    with per_expert_fits():
        ref_objective, ref_nlpd = fit()
    assert len(objective) == len(ref_objective)
    for a, b in zip(objective, ref_objective, strict=True):
        assert math.isclose(a, b, rel_tol=tol, abs_tol=tol)
    assert math.isclose(nlpd, ref_nlpd, rel_tol=tol, abs_tol=tol)


def test_experts_of_very_different_sizes_are_batched_apart() -> None:
    """Padding a small expert to a large one's size would waste its cubic cost."""
    g = torch.Generator().manual_seed(5)
    x = torch.rand(200, 2, generator=g, dtype=torch.float64)
    y = torch.sin(4 * x[:, :1])
    w = torch.zeros(200, 4, dtype=torch.float64)
    w[:, 0] = 1.0  # 200 rows
    w[:190, 1] = 0.5  # 190 rows: batched with the first
    w[:100, 2] = 1.0  # 100 rows: its own batch
    w[:90, 3] = 1.0  # 90 rows: with the third
    experts = [GPExpert(2, 1) for _ in range(4)]
    for j, expert in enumerate(experts):
        expert.condition(x, y, w[:, j])
    stack = ExpertStack.of(experts)
    assert stack.groups() == [[0, 1], [2, 3]]
    assert stack.select([2, 3]).x.shape[1] == 100
    pred = predict_exact_experts(experts, x[:7])
    for j, expert in enumerate(experts):
        torch.testing.assert_close(pred.loc[:, j], expert.predict(x[:7]).loc, rtol=1e-9, atol=1e-9)


@pytest.mark.parametrize("device", DEVICES)
def test_batched_evaluations_equal_each_experts_own(device: str) -> None:
    # the lockstep fit evaluates flat parameter vectors without touching the experts
    x, y, w = (t.to(device) for t in _problem())
    experts = _experts(4, 2, 3, device=device)
    for j, expert in enumerate(experts):
        expert.condition(x, y, w[:, j])
    starts = [flatten(e.trainable()) for e in experts]
    requests = {j: (1e-6, s + 0.05 * (j + 1)) for j, s in enumerate(starts)}
    together = _Batch(experts, ExpertStack.of(experts), _floors(experts)).evaluate(requests)
    for j, expert in enumerate(experts):
        np.testing.assert_array_equal(flatten(expert.trainable()), starts[j])  # untouched
        loss, grad = expert.evaluate(requests[j])
        assert together[j][0] == pytest.approx(loss, rel=1e-10)
        np.testing.assert_allclose(together[j][1], grad, rtol=1e-8, atol=1e-10)
