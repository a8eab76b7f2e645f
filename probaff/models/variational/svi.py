"""Fitting a `VariationalMixtureOfGPExperts` by minibatch stochastic variational inference.

`fit_svi` initialises the model from responsibilities (those of an exact EM mixture by
default) and trains it on Pyro's `TraceEnum_ELBO`, which sums out every sample's expert
assignment: natural-gradient steps for every q(u) and Adam for the gate (and for the
hyperparameters when no exact mixture gave them); see `probaff.models.variational.vi` for the
model and its Pyro programs.
"""

from __future__ import annotations

import contextlib
import warnings
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any

import pyro
import torch
from pyro.infer import TraceEnum_ELBO
from torch import Tensor

from probaff._checks import check_probability
from probaff._threads import threads_by_rows
from probaff.errors import InputError
from probaff.models.gates.gated import mixture_payload
from probaff.models.initialization import check_initialization, initial_responsibilities
from probaff.models.mixture.em import fit_em
from probaff.models.mixture.model import MixtureOfGPExperts, training_data
from probaff.models.options import SVIOptions, resolve_options
from probaff.models.registry import Codec, ModelKind, ModelSettings, register_model_kind
from probaff.models.tensors import as_matrix
from probaff.models.variational.svi_fixed import FixedHyperparameterSVI
from probaff.models.variational.vi import VariationalMixtureOfGPExperts

__all__ = ["SVIHistory", "fit_svi"]


@contextlib.contextmanager
def _default_dtype(dtype: torch.dtype) -> Iterator[None]:
    """Pyro creates some tensors with the default dtype; match the model's within a block."""
    with contextlib.ExitStack() as restore:
        restore.callback(torch.set_default_dtype, torch.get_default_dtype())
        torch.set_default_dtype(dtype)
        yield


@dataclass
class SVIHistory:
    """Record of one SVI fit.

    Attributes:
        loss: Negative ELBO estimate (per training sample) of every step.
    """

    loss: list[float] = field(default_factory=list)


def _start(
    model: VariationalMixtureOfGPExperts,
    x: Tensor,
    y: Tensor,
    init: str | Tensor | MixtureOfGPExperts,
    *,
    n_init: int,
    seed: int,
    init_rows: int,
) -> tuple[Tensor, MixtureOfGPExperts | None]:
    """Starting responsibilities `(N, M)` of `fit_svi`, and the exact mixture behind them."""
    m = model.n_experts
    if isinstance(init, MixtureOfGPExperts):
        if init.n_experts != m or not init.is_fitted:
            raise InputError(
                f"init must be a fitted MixtureOfGPExperts with {m} experts; fit it with "
                "probaff.models.fit_em first."
            )
        return torch.softmax(init.log_joint(x, y), dim=1), init
    if isinstance(init, Tensor):
        resp = as_matrix("init responsibilities", init, n_rows=x.shape[0], n_cols=m)
        check_probability("init responsibilities", resp)
        return resp / resp.sum(1, keepdim=True).clamp_min(1e-300), None
    check_initialization(init)
    model.resolve_columns(x.shape[1])
    gate_cols = model.gate_columns
    if init in ("effects", "joint"):
        return initial_responsibilities(init, x[:, gate_cols], y, m, n_init=n_init, seed=seed), None
    rows = torch.randperm(x.shape[0], generator=torch.Generator().manual_seed(seed))[:init_rows]
    exact = MixtureOfGPExperts(
        m,
        groups=model.groups,
        gate_features=model.gate_features,
        expert_features=model.expert_features,
    )  # the experts' default settings, MIXTURE_GP (the length-scale prior on)
    fit_em(exact, x[rows], y[rows], init=init, n_init=n_init, seed=seed)
    return torch.softmax(exact.log_joint(x, y), dim=1), exact


@threads_by_rows("X")
def fit_svi(
    model: VariationalMixtureOfGPExperts,
    X: Any,
    Y: Any,
    options: SVIOptions | None = None,
    **overrides: Any,
) -> SVIHistory:
    """Fit a variational mixture of GP experts by minibatch SVI.

    The model is initialised from responsibilities (`init`; see
    `VariationalMixtureOfGPExperts.build`), then trained on Pyro's `TraceEnum_ELBO`, which
    sums out every sample's expert assignment. Each step draws a minibatch of `batch_size`
    rows, takes a natural-gradient step on every q(u) towards its optimum given the
    minibatch (`VariationalMixtureOfGPExperts.update_variational`; step 1, the exact update,
    when the minibatch is the whole training set) and, unless an exact mixture gave them,
    an Adam step of size `lr` on the gate, kernels, means, noise and inducing inputs. An
    exact mixture's gate and hyperparameters are kept: they come from a penalised fit (the
    gate's cross-validated penalty, the length-scale prior, leave-one-out
    responsibilities) that the ELBO lacks, and moving them by the ELBO made held-out
    predictions worse on chapter 5's pushes (by 0.3 nats per point for the
    hyperparameters, up to 0.09 for the gate). With nothing for Adam to move, every step
    runs on quantities computed once (`probaff.models.variational.svi_fixed.FixedHyperparameterSVI`:
    the same ELBO and updates, about 5x less time on chapter 5's pushes). A last
    full-data update sets every q(u) to its optimum. Parameters live in a private Pyro
    parameter-store scope, and the global random state is left untouched.

    Initialisations are those of `probaff.models.fit_em`: ``"effects"`` and ``"joint"``
    take the responsibilities of that Gaussian mixture; ``"grow"`` and ``"auto"`` fit an
    exact mixture by EM with that `init` on at most `init_rows` rows (a seeded random
    subset) and start from its responsibilities on every row, its gate and its experts'
    hyperparameters, with q(u) the optimum given them on every row; a fitted `MixtureOfGPExperts`
    with the same experts and expert columns is such a start already made; a tensor
    `(N, M)` gives the responsibilities directly.

    Args:
        model: The mixture to fit (rebuilt for the data).
        X: Features, `(N, D)`.
        Y: Effects, `(N, E)`.
        options: The SVI settings (`SVIOptions`: `n_steps`, `batch_size`, `lr`, `n_init`,
            `seed`, `init`, `init_rows`); None for `SVIOptions()`.
        **overrides: Fields of `SVIOptions` that replace those of `options`, e.g.
            ``fit_svi(model, X, Y, n_steps=500, init=fitted_mixture)``.

    Returns:
        The per-step losses.

    Raises:
        InputError: For NaN/inf, empty or mismatched inputs, more experts than samples, an
            unknown `init` or option, or an option out of range.
    """
    opts = resolve_options(SVIOptions, options, overrides)
    seed = opts.seed
    x, y = training_data(X, Y, model.n_experts)
    resp, exact = _start(
        model, x, y, opts.init, n_init=opts.n_init, seed=seed, init_rows=opts.init_rows
    )
    model.fitted = False
    model.build(x, y, resp, exact)
    history = _train(model, x, y, opts, _param_groups(model, opts, exact is not None))
    model.eval()
    model.fitted = True
    return history


def _param_groups(
    model: VariationalMixtureOfGPExperts, opts: SVIOptions, from_exact: bool
) -> list[dict[str, Any]]:
    """Adam's parameter groups: the gate, then everything else but q(u); none with step 0."""
    variational = {
        id(p)
        for expert in model.experts
        for p in expert.variational_strategy._variational_distribution.parameters()
    }
    gate = list(model.built_gate().parameters())
    skip = variational | {id(p) for p in gate}
    rest = [p for p in model.parameters() if id(p) not in skip]
    scales = (opts.gate_lr_scale, opts.hyper_lr_scale) if from_exact else (1.0, 1.0)
    steps = (opts.lr * scales[0], opts.lr * scales[1])
    return [
        {"params": params, "lr": step}
        for params, step in zip((gate, rest), steps, strict=True)
        if step > 0
    ]


def _train(
    model: VariationalMixtureOfGPExperts,
    x: Tensor,
    y: Tensor,
    opts: SVIOptions,
    groups: list[dict[str, Any]],
) -> SVIHistory:
    """The SVI loop on a built model; every parameter outside `groups` but q(u) stays put."""
    x_scaler, y_scaler = model.scalers()
    x_g = x[:, model.gate_columns]
    x_e = x_scaler(x[:, model.expert_columns])
    t = y_scaler(y)
    n = x.shape[0]
    b = min(opts.batch_size, n)
    step = 1.0 if b >= n else opts.natural_step
    trained = {id(p) for g in groups for p in g["params"]}
    history = SVIHistory()
    generator = torch.Generator().manual_seed(opts.seed)
    elbo = TraceEnum_ELBO(max_plate_nesting=1)
    model.train()
    with contextlib.ExitStack() as stack:
        stack.enter_context(torch.random.fork_rng())
        stack.enter_context(pyro.get_param_store().scope())
        stack.enter_context(_default_dtype(torch.float64))
        stack.enter_context(warnings.catch_warnings())
        warnings.filterwarnings("ignore", message=".*not registered in the param store")
        for p in model.parameters():
            p.requires_grad_(id(p) in trained)
        stack.callback(lambda: [p.requires_grad_(True) for p in model.parameters()])
        torch.manual_seed(opts.seed)
        optimiser = torch.optim.Adam(groups) if groups else None
        fixed = None if optimiser else FixedHyperparameterSVI(model, x_g, x_e, t)
        for _ in range(opts.n_steps):
            idx = torch.randperm(n, generator=generator)[:b]
            if fixed is not None:
                history.loss.append(fixed.step(idx, scale=n / b, step=step) / n)
                continue
            assert optimiser is not None
            optimiser.zero_grad()
            loss = elbo.differentiable_loss(model.model, model.guide, x_g, x_e, t, idx)
            loss.backward()
            optimiser.step()
            model.update_variational(x_g[idx], x_e[idx], t[idx], scale=n / b, step=step)
            history.loss.append(float(loss.detach()) / n)
        if fixed is not None:
            fixed.store()
        model.update_variational(x_g, x_e, t)
    return history


# ----------------------------------------------------------- the "svi" kind
def _dump(model: VariationalMixtureOfGPExperts) -> dict[str, Any]:
    return mixture_payload(model, n_inducing=model.inducing_size)


def _restore(payload: dict[str, Any]) -> VariationalMixtureOfGPExperts:
    model = VariationalMixtureOfGPExperts(**payload["config"])
    model.build_empty(payload["n_features"], payload["n_outputs"], payload["n_inducing"])
    model.load_state_dict(payload["state_dict"])
    model.fitted = True
    model.eval()
    return model


def _build(settings: ModelSettings) -> VariationalMixtureOfGPExperts:
    if settings.gp is not None:
        raise InputError(
            "a VariationalMixtureOfGPExperts has sparse experts without a length-scale prior "
            "or L-BFGS iterations; leave gp unset."
        )
    return VariationalMixtureOfGPExperts(settings.n_experts, **settings.columns())


_FORMAT = "probaff.models.VariationalMixtureOfGPExperts/1"
_REQUIRED = ("config", "n_features", "n_outputs", "n_inducing", "state_dict")
_CODEC = Codec(_FORMAT, _dump, _restore, _REQUIRED)
register_model_kind(
    ModelKind("svi", VariationalMixtureOfGPExperts, fit_svi, SVIOptions, _CODEC, _build)
)
