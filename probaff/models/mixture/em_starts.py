"""The starts of EM for one mixture size: screened, finished, improved, never worse.

`fit_level` fits `M` experts: it tries the grown start (one expert of the `M - 1` solution
split in two) and cold starts, runs the best to convergence, tries split-and-merge moves,
and falls back on the `M - 1` solution with an expert duplicated when no run beats it.
"""

from __future__ import annotations

import copy
import math

import torch
from torch import Tensor

from probaff.models.initialization import initial_responsibilities, split_responsibilities
from probaff.models.mixture.em_run import EMHistory, EMRun, loo_terms
from probaff.models.mixture.model import MixtureOfGPExperts
from probaff.models.options import EMOptions

__all__ = ["fit_level"]

# EM iterations of a single expert (its responsibilities are fixed at 1, so iterations only
# continue the hyperparameter fit: one full fit and one warm refinement).
_SINGLE_ITER = 2

# Iterations a split-and-merge trial runs before it must beat the current objective.
_MOVE_SCREEN_ITER = 2

# Cold starts cycled through by `init="auto"` after the grown candidate.
_COLD_STARTS = ("joint", "effects")


def _fresh(
    template: MixtureOfGPExperts, n_experts: int, x: Tensor, y: Tensor
) -> MixtureOfGPExperts:
    """A new, built mixture like `template` with `n_experts` experts."""
    model = MixtureOfGPExperts(**{**template.config(), "n_experts": n_experts})
    model.build(x.shape[1], y.shape[1], template.resolve_noise_floor(y), n_samples=x.shape[0])
    return model


def _fit_matrix(resp: Tensor, log_lik: Tensor) -> Tensor:
    """Entry `(i, j)`: mean log density expert `j` gives to expert `i`'s samples, `(M, M)`.

    Samples count by their responsibilities `resp` `(N, M)`; the diagonal is how well each
    expert explains its own samples.
    """
    mass = resp.sum(0).clamp_min(1e-12)
    return (resp.T @ log_lik) / mass[:, None]


def _split_target(resp: Tensor, log_lik: Tensor, min_size: float) -> int:
    """The expert that explains its samples worst (lowest mean leave-one-out log density)."""
    mass = resp.sum(0)
    ok = [j for j in range(resp.shape[1]) if float(mass[j]) >= 2 * max(min_size, 1)]
    if not ok:
        return int(mass.argmax())
    own = _fit_matrix(resp, log_lik).diagonal()
    return min(ok, key=lambda j: float(own[j]))


def _residuals(model: MixtureOfGPExperts, expert: int, x: Tensor, y: Tensor) -> Tensor:
    """Residuals `(N, E)` of every sample under one expert (leave-one-out where it holds it)."""
    held = model.train_weights[:, expert] > 0
    residuals = y - model.expert_predictions(x).loc[:, expert]
    residuals[held] = y[held] - model.experts[expert].loo_predict().loc
    return residuals


def _split_merge(
    model: MixtureOfGPExperts,
    history: EMHistory,
    x: Tensor,
    y: Tensor,
    settings: EMOptions,
    *,
    rounds: int,
    n_candidates: int,
    seed: int,
) -> tuple[MixtureOfGPExperts, EMHistory]:
    """Escape a local optimum by merging two experts and splitting a third (SMEM).

    After EM has converged, two experts that explain each other's samples best are merged
    (the smaller into the larger) and then either the merged expert or the expert that
    explains its own samples worst is split into the freed slot (Ueda et al., 2000, with
    the experts' leave-one-out densities as the criteria). A move is screened by
    `_MOVE_SCREEN_ITER` partial EM iterations that refit and reassign only the two or three
    experts it touched (as in Ueda et al.'s partial EM), and full EM runs from those that
    raise the objective, warm-started. A move is kept only if it raises the objective, so the
    result is never worse than the input.
    """
    m = model.n_experts
    if m < 2 or rounds == 0:
        return model, history
    n = x.shape[0]
    for r in range(rounds):
        log_joint, log_lik = loo_terms(model, x, y)
        resp = torch.softmax(log_joint, dim=1)
        mass = resp.sum(0)
        cross = _fit_matrix(resp, log_lik)
        own = cross.diagonal()
        pairs = sorted(
            (
                (float(own[i] - cross[i, j] + own[j] - cross[j, i]), i, j)
                for i in range(m)
                for j in range(i + 1, m)
            ),
        )[:n_candidates]
        improved = False
        trials = []
        for _, a, b in pairs:
            i, j = (a, b) if float(mass[a]) >= float(mass[b]) else (b, a)
            others = [c for c in range(m) if c not in (i, j)]
            trials.append((i, j, i))
            if others:
                trials.append((i, j, min(others, key=lambda c: float(own[c]))))
        for i, j, k in trials:
            merged = resp.clone()
            merged[:, i] += merged[:, j]
            merged[:, j] = 0.0
            start = split_responsibilities(
                merged,
                k,
                x[:, model.gate_columns],
                _residuals(model, k, x, y),
                into=j,
                seed=seed + r,
            )
            trial = copy.deepcopy(model)
            trial.experts[j].load_state_dict(model.experts[k].state_dict())
            run = EMRun(
                trial,
                x,
                y,
                start,
                settings,
                init=history.init,
                seed=seed,
                warm=True,
                active=(i, j, k),
            )
            run.step(_MOVE_SCREEN_ITER)
            if run.best <= history.best:
                continue
            trial_history = run.release().step(settings.max_iter).finish()
            if trial_history.best > history.best + settings.tol * n:
                trial_history.candidates = history.candidates
                trial_history.split_merge = [*history.split_merge, (i, j, k, trial_history.best)]
                model, history, improved = trial, trial_history, True
                break
        if not improved:
            break
    return model, history


def _inherit_hyperparameters(
    model: MixtureOfGPExperts, prev: MixtureOfGPExperts, resp: Tensor
) -> None:
    """Start each expert of `model` from the `prev` expert that shares most of its samples.

    A cold start of `M` experts then needs only warm L-BFGS iterations: the `M - 1`
    solution's experts already hold hyperparameters fitted to the same data.
    """
    overlap = resp.T @ prev.train_weights
    for j, src in enumerate(overlap.argmax(dim=1).tolist()):
        model.experts[j].load_state_dict(prev.experts[src].state_dict())


def _grow(
    prev: MixtureOfGPExperts, x: Tensor, y: Tensor, settings: EMOptions, seed: int
) -> tuple[EMRun, int]:
    """Start an EM run for `M` experts by splitting one expert of the `M - 1` solution."""
    m = prev.n_experts + 1
    log_joint, log_lik = loo_terms(prev, x, y)
    resp = torch.softmax(log_joint, dim=1)
    target = _split_target(resp, log_lik, settings.min_size)
    split = split_responsibilities(
        resp, target, x[:, prev.gate_columns], _residuals(prev, target, x, y), seed=seed
    )
    model = _fresh(prev, m, x, y)
    for k, src in enumerate([*range(m - 1), target]):
        model.experts[k].load_state_dict(prev.experts[src].state_dict())
    return EMRun(model, x, y, split, settings, init="grow", seed=seed, warm=True), target


def _copy_state(prev: MixtureOfGPExperts, target: int, x: Tensor, y: Tensor) -> MixtureOfGPExperts:
    """The `M - 1` solution as an `M`-expert mixture with expert `target` duplicated.

    Both copies keep the original's training weights and hyperparameters, and the gate
    gives each half of the original's probability, so the predictive distribution (and the
    objective) is exactly that of the `M - 1` solution.
    """
    m = prev.n_experts + 1
    model = _fresh(prev, m, x, y)
    order = [*range(m - 1), target]
    w = prev.train_weights[:, order]
    model.condition(x, y, w)
    for k, src in enumerate(order):
        model.experts[k].load_state_dict(prev.experts[src].state_dict())
    gate_state = copy.deepcopy(prev.gate.state_dict())  # type: ignore[union-attr]
    gate_state["weight"] = gate_state["weight"][order]
    bias = gate_state["bias"][order].clone()
    bias[[target, m - 1]] -= math.log(2.0)
    gate_state["bias"] = bias
    model.gate.load_state_dict(gate_state)  # type: ignore[union-attr]
    return model


def _candidates(init: str, n_restarts: int, seed: int, grown: bool) -> list[tuple[str, int]]:
    """The starts `(init, seed)` tried for one `M`."""
    if init == "grow":
        return [("grow", seed)] if grown else [("effects", seed)]
    cold = [init] if init in _COLD_STARTS else list(_COLD_STARTS)
    out = [("grow", seed)] if init == "auto" and grown else []
    k = 0
    while len(out) < n_restarts:
        out.append((cold[k % len(cold)], seed + k // len(cold)))
        k += 1
    return out


def fit_level(
    template: MixtureOfGPExperts,
    x: Tensor,
    y: Tensor,
    m: int,
    prev: MixtureOfGPExperts | None,
    settings: EMOptions,
    *,
    init: str | Tensor,
) -> tuple[MixtureOfGPExperts, EMHistory]:
    """Fit `m` experts: screen every start, finish the best, never fall below `prev`.

    `settings` are the fit's `EMOptions` whole (`n_restarts`, `screen_iter`, `n_finish`,
    `split_merge`, `seed`, ...); `init` is its start, responsibilities already checked.
    """
    n_restarts, screen_iter, n_finish = settings.n_restarts, settings.screen_iter, settings.n_finish
    split_merge, seed = settings.split_merge, settings.seed
    if isinstance(init, Tensor):
        model = _fresh(template, m, x, y)
        run = EMRun(model, x, y, init, settings, init="given", seed=seed)
        history = run.step(settings.max_iter).finish()
        history.candidates = [("given", seed, history.best)]
        return model, history
    if m == 1:
        model = _fresh(template, 1, x, y)
        run = EMRun(
            model,
            x,
            y,
            torch.ones(x.shape[0], 1, dtype=torch.float64, device=x.device),
            settings,
            init="effects",
            seed=seed,
        )
        history = run.step(_SINGLE_ITER).finish()
        history.candidates = [("effects", seed, history.best)]
        return model, history
    grown = prev is not None and prev.n_experts == m - 1
    runs: list[EMRun] = []
    target = -1
    for name, s in _candidates(init, n_restarts, seed, grown):
        if name == "grow":
            assert prev is not None
            run, target = _grow(prev, x, y, settings, s)
        else:
            model = _fresh(template, m, x, y)
            resp = initial_responsibilities(
                name, x[:, model.gate_columns], y, m, n_init=settings.n_init, seed=s
            )
            warm = prev is not None
            if prev is not None:
                _inherit_hyperparameters(model, prev, resp)
            run = EMRun(model, x, y, resp, settings, init=name, seed=s, warm=warm)
        runs.append(run.step(settings.max_iter if screen_iter is None else screen_iter))
    finished = []
    for rank, run in enumerate(sorted(runs, key=lambda r: r.best, reverse=True)[:n_finish]):
        run.step(settings.max_iter)
        finished.append(
            _split_merge(
                run.model,
                run.finish(),
                x,
                y,
                settings,
                rounds=split_merge if rank == 0 else min(split_merge, 1),
                n_candidates=2,
                seed=seed,
            )
        )
    model, history = max(finished, key=lambda pair: pair[1].best)
    history.candidates = [(r.init, r.seed, r.best) for r in runs]
    if grown and prev is not None:
        floor = _objective(prev, x, y)
        if history.best < floor:
            model = _copy_state(prev, target, x, y)
            log_joint = model.loo_log_joint(x, y)
            history = EMHistory(
                objective=[float(torch.logsumexp(log_joint, 1).sum())],
                best=floor,
                converged=True,
                init="grow-copy",
                candidates=history.candidates,
                responsibilities=torch.softmax(log_joint, dim=1),
            )
    return model, history


def _objective(model: MixtureOfGPExperts, x: Tensor, y: Tensor) -> float:
    return float(torch.logsumexp(model.loo_log_joint(x, y), dim=1).sum())
