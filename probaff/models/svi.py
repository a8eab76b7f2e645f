"""Fitting a `VariationalMixtureOfGPExperts` by minibatch stochastic variational inference.

`fit_svi` initialises the model from responsibilities (those of an exact EM mixture by
default) and trains it with Pyro's `SVI` on `TraceEnum_ELBO`, which sums out every sample's
expert assignment; see `probaff.models.vi` for the model and its Pyro programs.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from dataclasses import dataclass, field
from typing import Any

import pyro
import torch
from pyro.infer import SVI, TraceEnum_ELBO
from pyro.optim import PyroOptim
from torch import Tensor

from probaff._checks import check_probability
from probaff.errors import InputError
from probaff.models.em import fit_em
from probaff.models.gated import mixture_payload
from probaff.models.initialization import check_initialization, initial_responsibilities
from probaff.models.mixture import MixtureOfGPExperts, training_data
from probaff.models.options import SVIOptions, resolve_options
from probaff.models.registry import Codec, ModelKind, ModelSettings, register_model_kind
from probaff.models.tensors import as_matrix
from probaff.models.vi import VariationalMixtureOfGPExperts

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
        lengthscale_prior=True,
    )
    fit_em(exact, x[rows], y[rows], init=init, n_init=n_init, seed=seed)
    return torch.softmax(exact.log_joint(x, y), dim=1), exact


def fit_svi(
    model: VariationalMixtureOfGPExperts,
    X: Any,
    Y: Any,
    options: SVIOptions | None = None,
    **overrides: Any,
) -> SVIHistory:
    """Fit a variational mixture of GP experts by minibatch SVI.

    The model is initialised from responsibilities (`init`), then trained with
    `pyro.infer.SVI` on `TraceEnum_ELBO`, which sums out every sample's expert assignment;
    Adam with step size `lr`. Parameters live in a private Pyro parameter-store scope, and
    the global random state is left untouched.

    Initialisations are those of `probaff.models.fit_em`: ``"effects"`` and ``"joint"``
    take the responsibilities of that Gaussian mixture; ``"grow"`` and ``"auto"`` fit an
    exact mixture by EM with that `init` on at most `init_rows` rows (a seeded random
    subset) and start from its responsibilities on every row and from its experts (their
    hyperparameters, and q(u) on their predictive means); a fitted `MixtureOfGPExperts`
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
    x_scaler, y_scaler = model.scalers()
    x_g = x[:, model.gate_columns]
    x_e = x_scaler(x[:, model.expert_columns])
    t = y_scaler(y)
    n = x.shape[0]
    b = min(opts.batch_size, n)
    history = SVIHistory()
    generator = torch.Generator().manual_seed(seed)
    model.train()
    with torch.random.fork_rng(), pyro.get_param_store().scope(), _default_dtype(torch.float64):
        torch.manual_seed(seed)
        svi = SVI(
            model.model,
            model.guide,
            PyroOptim(torch.optim.Adam, {"lr": opts.lr}),  # what pyro.optim.Adam builds
            loss=TraceEnum_ELBO(max_plate_nesting=1),
        )
        for _ in range(opts.n_steps):
            idx = torch.randperm(n, generator=generator)[:b]
            history.loss.append(svi.step(x_g, x_e, t, idx) / n)
    model.eval()
    model.fitted = True
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
    if settings.lengthscale_prior or settings.gp_max_iter is not None:
        raise InputError(
            "a VariationalMixtureOfGPExperts has sparse experts without a length-scale prior "
            "or L-BFGS iterations; leave lengthscale_prior and gp_max_iter unset."
        )
    return VariationalMixtureOfGPExperts(settings.n_experts, **settings.columns())


_FORMAT = "probaff.models.VariationalMixtureOfGPExperts/1"
_REQUIRED = ("config", "n_features", "n_outputs", "n_inducing", "state_dict")
_CODEC = Codec(_FORMAT, _dump, _restore, _REQUIRED)
register_model_kind(
    ModelKind("svi", VariationalMixtureOfGPExperts, fit_svi, SVIOptions, _CODEC, _build)
)
