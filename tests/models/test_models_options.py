"""Typed fit options: defaults equal to the fits' keywords, validation, options plus overrides."""

import dataclasses

import pytest
import torch

from probaff.errors import InputError
from probaff.models import (
    EMOptions,
    GPExpert,
    GPOptions,
    MixtureOfGPExperts,
    SVIOptions,
    fit_em,
    fit_em_path,
)
from probaff.models.options import SparseGPOptions, resolve_options


def _data(n=40, seed=0):
    g = torch.Generator().manual_seed(seed)
    x = torch.rand(n, 3, generator=g, dtype=torch.float64)
    y = torch.where(x[:, :1] > 0.5, 1.0, -1.0) + 0.05 * torch.randn(n, 1, generator=g)
    return x, y.to(torch.float64)


def test_defaults_are_the_fits_defaults():
    assert dataclasses.asdict(EMOptions()) == {
        "init": "auto",
        "n_restarts": 3,
        "screen_iter": 2,
        "n_finish": 1,
        "split_merge": 2,
        "max_iter": 10,
        "tol": 1e-3,
        "n_init": 20,
        "seed": 0,
        "prune_below": 1e-4,
        "min_size": 3.0,
        "gp_max_iter": None,
        "warm_max_iter": 8,
        "anneal": False,
        "anneal_start": 0.1,
        "anneal_iter": 4,
        "search_rows": 1000,
        "search_restarts": 6,
    }
    assert dataclasses.asdict(SVIOptions()) == {
        "n_steps": 1500,
        "batch_size": 64,
        "lr": 0.02,
        "n_init": 20,
        "seed": 0,
        "init": "auto",
        "init_rows": 2000,
        "natural_step": 0.1,
        "gate_lr_scale": 0.0,
        "hyper_lr_scale": 0.0,
    }
    assert dataclasses.asdict(GPOptions()) == {
        "max_iter": 50,
        "lengthscale_prior": False,
        "noise_floor": None,
        "outputscale": 1.0,
        "noise": 0.1,
    }
    assert dataclasses.asdict(SparseGPOptions()) == {
        **dataclasses.asdict(GPOptions()),
        "n_inducing": None,
        "learn_inducing": False,
        "hyper_rows": 2048,
    }


@pytest.mark.parametrize(
    ("cls", "field", "bad"),
    [
        (EMOptions, "max_iter", 0),
        (EMOptions, "n_restarts", 1.5),
        (EMOptions, "screen_iter", -1),
        (EMOptions, "split_merge", -1),
        (EMOptions, "tol", float("nan")),
        (EMOptions, "seed", -1),
        (EMOptions, "anneal", "yes"),
        (EMOptions, "anneal_start", 1.5),
        (EMOptions, "init", "kmeans"),
        (SVIOptions, "n_steps", 0),
        (SVIOptions, "lr", 0.0),
        (SVIOptions, "init_rows", True),
        (SVIOptions, "natural_step", 0.0),
        (SVIOptions, "natural_step", 1.5),
        (SVIOptions, "gate_lr_scale", -0.1),
        (SVIOptions, "hyper_lr_scale", float("inf")),
        (GPOptions, "max_iter", 2.5),
        (GPOptions, "noise_floor", -1.0),
        (GPOptions, "outputscale", 0.0),
        (GPOptions, "noise", 1e3),
        (SparseGPOptions, "n_inducing", 0),
        (SparseGPOptions, "n_inducing", 2.5),
        (SparseGPOptions, "hyper_rows", 0),
        (SparseGPOptions, "hyper_rows", 1.5),
        (SparseGPOptions, "learn_inducing", "no"),
        (SparseGPOptions, "noise", 0.0),
    ],
)
def test_a_bad_field_is_named(cls, field, bad):
    with pytest.raises(InputError, match=field if field != "init" else "initialisation"):
        cls(**{field: bad})


def test_options_are_frozen_and_normalised():
    opts = EMOptions(max_iter=4.0, tol=0, screen_iter=None)
    assert opts.max_iter == 4 and type(opts.max_iter) is int
    assert opts.tol == 0.0 and type(opts.tol) is float
    assert opts.screen_iter is None
    with pytest.raises(dataclasses.FrozenInstanceError):
        opts.max_iter = 5  # type: ignore[misc]
    assert GPOptions(noise_floor=torch.tensor([0.1, 0.2])).noise_floor == pytest.approx((0.1, 0.2))
    assert GPOptions(noise_floor=0.5).noise_floor == 0.5
    assert GPOptions(noise_floor="auto").noise_floor == "auto"  # 1 % of each output's std
    with pytest.raises(InputError, match="noise_floor must be 'auto', None or"):
        GPOptions(noise_floor="Auto")
    sparse = SparseGPOptions(n_inducing=64.0, learn_inducing=1, noise_floor=[0.1])
    assert sparse.n_inducing == 64 and type(sparse.n_inducing) is int
    assert sparse.learn_inducing is True and sparse.noise_floor == pytest.approx((0.1,))


def test_resolve_options_applies_overrides_and_refuses_unknown_names():
    base = EMOptions(max_iter=20)
    assert resolve_options(EMOptions, None, {}) == EMOptions()
    assert resolve_options(EMOptions, base, {}) is base
    assert resolve_options(EMOptions, base, {"seed": 3}) == EMOptions(max_iter=20, seed=3)
    assert resolve_options(EMOptions, base, {"screen_iter": None}).screen_iter is None
    with pytest.raises(InputError, match="unknown fitting option"):
        resolve_options(EMOptions, base, {"iterations": 3})
    with pytest.raises(InputError, match="EMOptions"):
        resolve_options(EMOptions, SVIOptions(), {})
    with pytest.raises(InputError, match="max_iter"):
        resolve_options(EMOptions, base, {"max_iter": 0})


def test_options_and_keywords_give_the_same_fit():
    x, y = _data()
    a, b = MixtureOfGPExperts(2), MixtureOfGPExperts(2)
    ha = fit_em(a, x, y, seed=1, max_iter=3, n_restarts=2)
    hb = fit_em(b, x, y, EMOptions(seed=1, max_iter=3), n_restarts=2)
    assert ha.objective == hb.objective
    assert torch.equal(a.predict(x).mean, b.predict(x).mean)
    path = fit_em_path(MixtureOfGPExperts(1), x, y, (2,), options=EMOptions(seed=1, max_iter=3))
    assert path[2][1].best == pytest.approx(
        fit_em_path(MixtureOfGPExperts(1), x, y, (2,), seed=1, max_iter=3)[2][1].best, abs=0
    )
    with pytest.raises(InputError, match="unknown fitting option"):
        fit_em(MixtureOfGPExperts(2), x, y, iterations=3)


def test_gp_expert_takes_options():
    x, y = _data()
    a = GPExpert(3, 1, GPOptions(max_iter=5, lengthscale_prior=True), noise_floor=0.01).fit(x, y)
    b = GPExpert(3, 1, max_iter=5, lengthscale_prior=True, noise_floor=0.01).fit(x, y)
    assert a.options == b.options
    assert torch.equal(a.predict(x).mean, b.predict(x).mean)
