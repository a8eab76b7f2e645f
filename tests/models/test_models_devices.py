"""Models fit and predict on the device of their data; unknown devices are refused."""

from dataclasses import replace

import numpy as np
import pytest
import torch
from device_checks import DEVICES, assert_on_device, elsewhere, tensors_in

from probaff.errors import InputError
from probaff.models import MIXTURE_GP, GPExpert, MixtureOfGPExperts, fit_em
from probaff.models.gates.gate import make_gate
from probaff.models.initialization import initial_responsibilities, split_responsibilities
from probaff.models.synthetic import regime_features
from probaff.models.tensors import as_matrix, as_vector, resolve_device, training_rows


@pytest.mark.parametrize("bad", ["cuda:7", "gpu", "cuda:x", 7])
def test_a_device_that_does_not_exist_is_refused_by_name(bad: object) -> None:
    if torch.cuda.device_count() > 7:
        pytest.skip("this machine has a CUDA device 7")
    with pytest.raises(InputError, match="device"):
        resolve_device("device", bad)  # type: ignore[arg-type]
    with pytest.raises(InputError, match="device"):
        GPExpert(2, 1).to(bad)
    with pytest.raises(InputError, match="device"):
        MixtureOfGPExperts(2).to(device=bad)


def test_cuda_on_a_machine_without_that_device_is_refused_by_name() -> None:
    if torch.cuda.device_count() > 7:
        pytest.skip("this machine has a CUDA device 7")
    x = torch.linspace(-1, 1, 20, dtype=torch.float64)[:, None]
    model = MixtureOfGPExperts(1, gp=replace(MIXTURE_GP, max_iter=5))
    fit_em(model, x, torch.sin(3 * x), init="effects", max_iter=1, n_restarts=1, split_merge=0)
    # without CUDA, .cuda() itself is refused; with it, an index this machine lacks
    index = 7 if torch.cuda.is_available() else None
    want = r"device 'cuda' does not exist: CUDA is unavailable; use 'cpu'\."
    match = "device 7 does not exist" if index is not None else want
    for module in (model, GPExpert(2, 1)):
        with pytest.raises(InputError, match=match):
            module.cuda(index)
        assert module.device.type == "cpu"  # left where it was


def test_resolve_device_accepts_the_cpu_in_every_spelling() -> None:
    for spelling in (None, "cpu", torch.device("cpu")):
        assert resolve_device("device", spelling) == torch.device("cpu")


@pytest.mark.parametrize("device", DEVICES)
def test_arrays_keep_or_take_the_device(device: str) -> None:
    dev = torch.device(device)
    t = torch.ones(3, 2, device=dev)
    assert as_matrix("x", t).device.type == dev.type  # a tensor keeps its device
    assert as_matrix("x", np.ones((3, 2))).device.type == "cpu"
    with elsewhere():  # a tensor made without the device asked for would land on meta
        assert_on_device(as_matrix("x", np.ones((3, 2)), device=dev), dev)
        assert_on_device(as_vector("w", [1.0, 2.0], n=2, device=dev), dev)
        assert_on_device(training_rows(t, np.zeros((3, 1)), "push"), dev)
    with pytest.raises(InputError, match="NaN"):
        as_matrix("x", torch.tensor([[float("nan")]], device=dev))


@pytest.mark.parametrize("device", DEVICES)
def test_gp_expert_fits_and_predicts_on_its_device(device: str) -> None:
    g = torch.Generator().manual_seed(0)
    x = torch.rand(40, 3, generator=g, dtype=torch.float64)
    y = torch.sin(3 * x[:, :1]) + 0.01 * torch.randn(40, 1, generator=g, dtype=torch.float64)
    w = torch.rand(40, generator=g, dtype=torch.float64)
    ref = GPExpert(3, 1, max_iter=10).fit(x, y, w)
    expert = GPExpert(3, 1, max_iter=10).to(device)
    assert expert.device.type == torch.device(device).type
    dev = x.to(device).device
    with elsewhere():  # what the fit makes without naming the device would land on meta
        expert.fit(x.to(device), y.to(device), w.to(device))
        pred = expert.predict(x[:5].numpy())  # arrays go to the expert's device
        loo = expert.loo_predict()
    assert_on_device(expert, dev)
    assert_on_device(pred, dev)  # loc and scale
    assert_on_device(loo, dev)
    torch.testing.assert_close(pred.loc.cpu(), ref.predict(x[:5]).loc, rtol=1e-6, atol=1e-8)
    torch.testing.assert_close(loo.scale.cpu(), ref.loo_predict().scale, rtol=1e-6, atol=1e-8)


@pytest.mark.parametrize("device", DEVICES)
def test_gate_and_starts_follow_the_data(device: str) -> None:
    g = torch.Generator().manual_seed(1)
    x = torch.randn(60, 2, generator=g, dtype=torch.float64).to(device)
    r = torch.softmax(torch.stack([x[:, 0], -x[:, 0]], 1) * 3, 1)
    gate = make_gate("fourier", 2, 2, l2="cv", n_random_features=8)
    with elsewhere():  # what the fit makes without naming the device would land on meta
        gate.fit(x, r)
        proba = gate.predict_proba(x)
        start = initial_responsibilities("joint", x, x, 2, n_init=1)
        split = split_responsibilities(start, 0, x, x, seed=0, n_init=1)
    assert_on_device(gate, x.device)  # weights and every buffer (random features, scaling)
    assert_on_device((proba, start, split), x.device)
    assert split.shape == (60, 3)
    torch.testing.assert_close(proba.sum(1), torch.ones(60, dtype=x.dtype, device=x.device))


@pytest.mark.filterwarnings("ignore::RuntimeWarning")
@pytest.mark.parametrize("device", DEVICES)
def test_mixture_fits_on_the_device_of_its_data_with_the_cpu_result(device: str) -> None:
    x, y, _ = regime_features(90, 16, 2, seed=0)
    gp = replace(MIXTURE_GP, max_iter=8)
    kwargs = {"groups": {"f_x": slice(0, 3)}, "gate_features": ("f_x",), "gp": gp}
    opts = {"max_iter": 2, "n_restarts": 1, "init": "joint", "seed": 0}
    ref = MixtureOfGPExperts(2, **kwargs)
    ref_hist = fit_em(ref, x, y, **opts)
    model = MixtureOfGPExperts(2, **kwargs).to(device)
    hist = fit_em(model, x.to(device), y.to(device), **opts)
    dev = x.to(device).device
    assert model.device == dev
    # the fit builds gpytorch modules, which cannot be made on meta: its parameters and buffers
    # are checked whole; prediction runs with meta as the default device
    assert_on_device(model, dev)
    with elsewhere():
        pred = model.predict(x[:10].numpy())  # inputs move to the model's device
    assert_on_device(pred, dev)  # the mixture's weights and every component's loc and scale
    torch.testing.assert_close(
        torch.tensor(hist.objective), torch.tensor(ref_hist.objective), rtol=1e-6, atol=1e-6
    )
    torch.testing.assert_close(pred.mean.cpu(), ref.predict(x[:10]).mean, rtol=1e-5, atol=1e-6)


def test_the_device_check_finds_a_tensor_on_the_wrong_device() -> None:
    """The walk reaches nested tensors; one on another device fails the check by its path."""
    loc, scale = torch.zeros(4, 2, 3), torch.ones(4, 2, 3)
    good = torch.distributions.MixtureSameFamily(
        torch.distributions.Categorical(logits=torch.zeros(4, 2)),
        torch.distributions.Independent(torch.distributions.Normal(loc, scale), 1),
    )
    assert assert_on_device({"pred": good, "extra": [torch.ones(2)]}, "cpu") >= 4
    # one component scale, three levels down, moved to another device
    good.component_distribution.base_dist.scale = scale.to("meta")
    with pytest.raises(AssertionError, match=r"base_dist\.scale on meta"):
        assert_on_device(good, "cpu")
    expert = GPExpert(2, 1)
    expert.register_buffer("stray", torch.zeros(1, device="meta"))
    with pytest.raises(AssertionError, match=r"stray on meta"):
        assert_on_device(expert, "cpu")
    with pytest.raises(AssertionError, match="no tensor"):
        assert_on_device([1.0, "a"], "cpu")
    assert not list(tensors_in(None))


def test_a_tensor_made_without_a_device_is_caught_on_a_cpu_only_machine() -> None:
    """Under `elsewhere`, code that forgets ``device=`` yields meta tensors the check finds."""
    x = torch.ones(3, 2, dtype=torch.float64)

    def careless(x: torch.Tensor) -> torch.Tensor:
        return torch.zeros(x.shape[0], dtype=x.dtype)  # no device=x.device

    def careful(x: torch.Tensor) -> torch.Tensor:
        return torch.zeros(x.shape[0], dtype=x.dtype, device=x.device)

    assert_on_device(careless(x), x.device)  # outside: the CPU compared with the CPU
    with elsewhere():
        slip, right = careless(x), careful(x)
    assert_on_device(right, x.device)
    with pytest.raises(AssertionError, match="on meta"):
        assert_on_device(slip, x.device)
