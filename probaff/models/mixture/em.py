"""Expectation-maximisation for a mixture of GP experts, with restarts that cannot lose.

`fit_em` fits one mixture; `fit_em_path` fits `M = 1, 2, ...` together, each `M` grown from
the best `M - 1` solution, so that the training objective never falls as experts are added.

The starts of `fit_em` (its option `init`; see `probaff.models.initialization`):

* ``"effects"``: a Gaussian mixture in effect space (the thesis's start);
* ``"joint"``: a Gaussian mixture on [gate features, effects];
* ``"grow"``: fit `M = 1`, then each `M` by splitting the expert of the `M - 1`
  solution that explains its samples worst and running EM from there; if no run beats
  the `M - 1` objective, that solution is kept with the expert duplicated, so the
  objective never falls as `M` grows;
* ``"auto"`` (default): at every `M` on the way up, the grown start and
  `n_restarts - 1` cold starts (``"joint"``, ``"effects"``, then again with the next
  seeds) each run EM (or only `screen_iter` iterations, after which the best
  `n_finish` run to convergence); the best by the objective is kept, and the grow
  guarantee holds as above.

Large training sets: with more than `search_rows` training rows (`EMOptions`), `fit_em`'s
whole search (the starts above, split-and-merge) runs on a seeded random subset of
`search_rows` rows with `search_restarts` starts (and the experts the whole set would get);
the kept fit then gives every row its responsibilities and its experts' hyperparameters
start one more run on the whole set, of up to `max_iter` iterations (coarse to fine).
Measured on `probaff.models.synthetic.regime_features` (see `benchmarks/mixture_scale.py`),
this keeps the search's cost fixed as `N` grows.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import Any

import torch
from torch import Tensor

from probaff._checks import check_count, check_probability
from probaff._threads import threads_by_rows
from probaff.errors import InputError
from probaff.models.gates.gated import mixture_payload
from probaff.models.mixture.em_run import EMHistory, EMRun
from probaff.models.mixture.em_starts import _fresh, fit_level
from probaff.models.mixture.model import FLAT_GP_KEYWORDS, MixtureOfGPExperts
from probaff.models.options import MIXTURE_GP, EMOptions, GPOptions, resolve_options
from probaff.models.registry import Codec, ModelKind, ModelSettings, register_model_kind
from probaff.models.tensors import as_matrix

__all__ = ["FORMAT", "EMHistory", "fit_em", "fit_em_path"]


def _check_prune(model: MixtureOfGPExperts, options: EMOptions) -> None:
    """Refuse a `prune_below` that would prune every expert of mixtures like `model`."""
    if options.prune_below >= 1.0 / max(model.n_experts, 2):
        raise InputError(
            f"prune_below={options.prune_below} must be below 1/n_experts = "
            f"{1.0 / max(model.n_experts, 2):.4g}."
        )


def _given_responsibilities(init: Tensor, n: int, sizes: list[int]) -> Tensor:
    """Validate responsibilities given as the start of EM."""
    if len(sizes) != 1:
        raise InputError("responsibilities given as init fit one mixture size only.")
    resp = as_matrix("init responsibilities", init, n_rows=n, n_cols=sizes[0])
    check_probability("init responsibilities", resp)
    if not torch.allclose(
        resp.sum(1), torch.ones(n, dtype=resp.dtype, device=resp.device), atol=1e-6
    ):
        raise InputError("init responsibilities must have rows that sum to 1.")
    return resp


@threads_by_rows("X")
def fit_em_path(
    model: MixtureOfGPExperts,
    X: Any,
    Y: Any,
    n_experts: Sequence[int],
    options: EMOptions | None = None,
    **overrides: Any,
) -> dict[int, tuple[MixtureOfGPExperts, EMHistory]]:
    """Fit mixtures of several sizes at once, each grown from the previous one.

    Every `M` from 1 to ``max(n_experts)`` is fitted as `fit_em` would fit it (the
    ``"grow"`` start of `M` splits the kept `M - 1` solution), so the path costs about as
    much as the largest fit alone and the training objective never falls along it.

    Args:
        model: A template mixture: its settings are used, its `n_experts` is ignored and it
            is left untouched.
        X: Features, `(N, D)`.
        Y: Effects, `(N, E)`.
        n_experts: The sizes `M` to return.
        options: The EM settings, as in `fit_em`; None for `EMOptions()`.
        **overrides: Fields of `EMOptions` that replace those of `options` (``init``,
            ``max_iter``, ``seed``, ...).

    Returns:
        `M -> (fitted mixture, history)` for every requested `M`.

    Raises:
        InputError: As `fit_em`, or for an empty or non-positive `n_experts`.
    """
    opts = resolve_options(EMOptions, options, overrides)
    sizes = sorted({check_count("n_experts", m) for m in n_experts})
    if not sizes:
        raise InputError("n_experts is empty; pass the mixture sizes to fit, e.g. (1, 2, 3).")
    template = MixtureOfGPExperts(**{**model.config(), "n_experts": sizes[-1]})
    _check_prune(template, opts)
    x, y = template.check_data(X, Y)
    init = opts.init
    if isinstance(init, Tensor):
        init = _given_responsibilities(init, x.shape[0], sizes)
    grows = isinstance(init, str) and init in ("auto", "grow")
    out: dict[int, tuple[MixtureOfGPExperts, EMHistory]] = {}
    prev: MixtureOfGPExperts | None = None
    for m in range(1, sizes[-1] + 1) if grows else sizes:
        fitted, history = fit_level(
            template,
            x,
            y,
            m,
            prev,
            opts,
            init=init,
        )
        prev = fitted
        if m in sizes:
            out[m] = (fitted, history)
    return out


@threads_by_rows("X")
def fit_em(
    model: MixtureOfGPExperts,
    X: Any,
    Y: Any,
    options: EMOptions | None = None,
    **overrides: Any,
) -> EMHistory:
    r"""Fit a mixture of GP experts by EM.

    Each iteration runs

    * M-step: the gate is fitted to the responsibilities (weighted multinomial logistic
      regression) and expert `j` is refitted as a GP whose sample `i` has noise
      :math:`\sigma_j^2 / r_{ij}`, re-optimising its kernel hyperparameters by the
      weighted marginal likelihood (plus the log prior when the length-scale prior is on).
      Responsibilities below `prune_below` are set to 0 for the experts, which removes
      those samples from the expert's exact GP.
    * E-step: :math:`r_{ij} \propto \left[p(m=j|f_i)\, p_j(e_i|f_i, D_{-i})\right]^\beta`
      with each expert's *leave-one-out* predictive density of the samples it holds
      (`MixtureOfGPExperts.loo_log_joint`), and the objective
      :math:`\sum_i \log \sum_j p(m=j|f_i)\, p_j(e_i|f_i, D_{-i})`, logged every
      iteration. :math:`\beta = 1` unless `anneal` (deterministic annealing: β rises
      geometrically from `anneal_start` to 1 over `anneal_iter` iterations).

    EM with GP experts is not guaranteed to increase its objective at every iteration, so
    the state with the largest objective is the one kept. EM stops after `max_iter`
    iterations or once the objective changes by less than `tol` per sample (at β = 1).
    An expert whose pruned responsibilities sum to less than `min_size` has collapsed:
    it takes half of the samples of the expert that explains its samples worst, divided
    by a Gaussian mixture on gate features and residuals (split/merge), with a
    `RuntimeWarning`; if no expert has enough samples to give, it is re-seeded from the
    samples the model explains worst.

    The starts (`init`) and how a large training set is searched are in the module's
    docstring (`probaff.models.mixture.em`).

    After the best run has converged, up to `split_merge` rounds of split-and-merge moves
    (merge the two experts that explain each other's samples best, split the one that
    explains its own worst, rerun EM; Ueda et al., 2000) are tried and kept only when they
    raise the objective.

    A tensor of responsibilities `(N, M)` starts one run from that assignment (for example
    the true one, on synthetic data).

    With the mixture's ``point="stacked"`` and `M > 1`, the `M = 1` fit (free on
    a growing start's way up; fitted on its own otherwise) becomes the single GP that
    `MixtureOfGPExperts.predict_point` stacks with the mixture's mean
    (`MixtureOfGPExperts.fit_point`).

    With ``"effects"`` or ``"joint"``, `n_restarts` starts of that kind (seeds `seed`,
    `seed + 1`, ...) are screened the same way. Everything is deterministic given `seed`.

    Args:
        model: The mixture to fit (its experts and gate are (re)built for the data sizes).
        X: Features, `(N, D)`.
        Y: Effects, `(N, E)`.
        options: The EM settings (`EMOptions`: `init`, `n_restarts`, `screen_iter`,
            `n_finish`, `split_merge`, `max_iter`, `tol`, `n_init`, `seed`, `prune_below`,
            `min_size`, `gp_max_iter`, `warm_max_iter`, `anneal`, `anneal_start`,
            `anneal_iter`); None for `EMOptions()`.
        **overrides: Fields of `EMOptions` that replace those of `options`, e.g.
            ``fit_em(model, X, Y, seed=3, max_iter=20)``.

    Returns:
        The history of the kept run.

    Raises:
        InputError: For NaN/inf, empty or mismatched inputs, an unknown feature group,
            initialisation or option, an option out of range, or more experts than samples.

    Example:
        One start, a few iterations (the defaults search more: three starts per `M`,
        split-and-merge):

        >>> from probaff.models import EMOptions, MixtureOfGPExperts, fit_em
        >>> from probaff.models.synthetic import softmax_regimes
        >>> x, y, _ = softmax_regimes(60, seed=0)
        >>> model = MixtureOfGPExperts(3, gate_features=[0, 1])
        >>> options = EMOptions(init="joint", n_restarts=1, split_merge=0, seed=0)
        >>> history = fit_em(model, x, y, options, max_iter=3)  # keywords override options
        >>> history.init, len(history.objective) <= 3, history.best == max(history.objective)
        ('joint', True, True)
        >>> tuple(history.responsibilities.shape)  # (N, M)
        (60, 3)
    """
    opts = resolve_options(EMOptions, options, overrides)
    x, y = model.check_data(X, Y)
    m = model.n_experts
    stack = model.point == "stacked" and m > 1
    path = _search(model, x, y, opts, (1, m) if stack else (m,))
    fitted, history = path[m]
    model.condition(x, y, fitted.train_weights)
    model.load_state_dict(fitted.state_dict())
    if stack:
        model.fit_point(path[1][0].experts[0], x, y, seed=opts.seed)
    return history


def _search(
    model: MixtureOfGPExperts, x: Tensor, y: Tensor, opts: EMOptions, sizes: tuple[int, ...]
) -> dict[int, tuple[MixtureOfGPExperts, EMHistory]]:
    """The fits of `sizes` as `fit_em` searches for them: on every row, or coarse to fine.

    A growing start fits `M = 1` on its way up, so the stacked point's single GP is free
    there; other starts fit it on its own, so that it does not change the `M` fit.
    """
    grows = isinstance(opts.init, str) and opts.init in ("auto", "grow")
    main = sizes if grows else sizes[-1:]
    rows = opts.search_rows
    if rows is None or x.shape[0] <= rows or isinstance(opts.init, Tensor):
        path = fit_em_path(model, x, y, main, opts)
    else:
        path = _coarse_to_fine(model, x, y, opts, rows, main)
    for m in set(sizes) - set(path):  # M = 1 beside a start that does not grow
        path[m] = fit_em_path(model, x, y, (m,), opts, init="effects")[m]
    return path


def _coarse_to_fine(
    model: MixtureOfGPExperts,
    x: Tensor,
    y: Tensor,
    opts: EMOptions,
    rows: int,
    sizes: Sequence[int],
) -> dict[int, tuple[MixtureOfGPExperts, EMHistory]]:
    """Search on `rows` random rows, then refine each kept fit of `sizes` on every row.

    See `fit_em`; returns `M -> (fitted mixture, history)` as `fit_em_path` does.
    """
    n = x.shape[0]
    template = MixtureOfGPExperts(**{**model.config(), "experts": model.resolve_expert_kind(n)})
    subset = torch.randperm(n, generator=torch.Generator().manual_seed(opts.seed))[:rows]
    subset = subset.sort().values.to(x.device)
    search = dataclasses.replace(opts, n_restarts=opts.search_restarts)
    coarse_path = fit_em_path(template, x[subset], y[subset], sizes, search)
    _check_prune(template, opts)
    out: dict[int, tuple[MixtureOfGPExperts, EMHistory]] = {}
    for m, (coarse, found) in coarse_path.items():
        fine = _fresh(template, m, x, y)
        for mine, theirs in zip(fine.experts, coarse.experts, strict=True):
            mine.load_state_dict(theirs.state_dict())
        resp = torch.softmax(coarse.log_joint(x, y), dim=1)
        run = EMRun(fine, x, y, resp, opts, init=found.init, seed=opts.seed, warm=True)
        history = run.step(opts.max_iter if m > 1 else 1).finish()
        history.candidates, history.split_merge = found.candidates, found.split_merge
        out[m] = (fine, history)
    return out


# ------------------------------------------------------------ the "em" kind
FORMAT = "probaff.models.MixtureOfGPExperts/1"
"""Identifier and version stored in every saved EM mixture."""


def _dump(model: MixtureOfGPExperts) -> dict[str, Any]:
    payload = mixture_payload(
        model,
        X=model.train_X,
        Y=model.train_Y,
        weights=model.train_weights,
        built_experts=model.built_expert_kind,
    )
    # The experts' GPOptions as its fields (builtins: noise_floor a float, tuple, "auto" or None).
    payload["config"]["gp"] = dataclasses.asdict(model.gp)
    return payload


def _saved_config(config: dict[str, Any]) -> dict[str, Any]:
    """A saved mixture's constructor arguments, its experts' settings as one `GPOptions`.

    Files written since the settings were one `GPOptions` hold its fields under ``gp``;
    older files hold the flat keys ``gp_max_iter``, ``lengthscale_prior`` and ``noise_floor``
    (`FLAT_GP_KEYWORDS`; a missing one takes `MIXTURE_GP`'s value, today's default).
    Files written before the gate had a lasso penalty hold a ridge-only gate (``gate_l1=0``).
    """
    out = {"gate_l1": 0.0, **config}
    flat = {new: out.pop(old) for old, new in FLAT_GP_KEYWORDS.items() if old in out}
    saved = out.get("gp")
    if saved is None:
        out["gp"] = dataclasses.replace(MIXTURE_GP, **flat)
    elif isinstance(saved, dict):
        out["gp"] = GPOptions(**saved)
    else:
        raise InputError(f"a saved mixture's gp must hold GPOptions' fields, got {saved!r}.")
    return out


def _restore(payload: dict[str, Any]) -> MixtureOfGPExperts:
    model = MixtureOfGPExperts(**_saved_config(payload["config"]))
    # The kind of experts the fit built ("exact" in files written before sparse experts).
    kind = payload.get("built_experts") or "exact"
    if kind not in ("exact", "sparse"):
        raise InputError(f"unknown kind of experts {kind!r} in a saved mixture.")
    model.built_expert_kind = kind
    model.build(payload["n_features"], payload["n_outputs"])
    model.condition(payload["X"], payload["Y"], payload["weights"])
    model.load_state_dict(payload["state_dict"])
    return model


def _build(settings: ModelSettings) -> MixtureOfGPExperts:
    # settings.gp whole; None is the mixture's default, MIXTURE_GP
    return MixtureOfGPExperts(settings.n_experts, **settings.columns(), gp=settings.gp)


_REQUIRED = ("config", "n_features", "n_outputs", "X", "Y", "weights", "state_dict")
_CODEC = Codec(FORMAT, _dump, _restore, _REQUIRED)
register_model_kind(ModelKind("em", MixtureOfGPExperts, fit_em, EMOptions, _CODEC, _build))
