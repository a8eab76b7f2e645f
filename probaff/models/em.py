"""Expectation-maximisation for a mixture of GP experts, with restarts that cannot lose.

`fit_em` fits one mixture; `fit_em_path` fits `M = 1, 2, ...` together, each `M` grown from
the best `M - 1` solution, so that the training objective never falls as experts are added.
"""

from __future__ import annotations

import copy
import logging
import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import torch
from torch import Tensor

from probaff._checks import check_count, check_positive, check_probability
from probaff.errors import InputError
from probaff.models._tensors import as_matrix
from probaff.models.initialization import (
    check_initialization,
    initial_responsibilities,
    split_responsibilities,
)
from probaff.models.mixture import MixtureOfGPExperts

__all__ = ["EMHistory", "fit_em", "fit_em_path"]

logger = logging.getLogger(__name__)

# EM iterations of a single expert (its responsibilities are fixed at 1, so iterations only
# continue the hyperparameter fit: one full fit and one warm refinement).
_SINGLE_ITER = 2

# Iterations a split-and-merge trial runs before it must beat the current objective.
_SCREEN_ITER = 2

# Cold starts cycled through by `init="auto"` after the grown candidate.
_COLD_STARTS = ("joint", "effects")


@dataclass
class EMHistory:
    r"""Record of one EM fit.

    Attributes:
        objective: The training objective after each iteration of the kept run: the
            observed-data log-likelihood with leave-one-out expert densities,
            :math:`\sum_i \log \sum_j p(m=j|f_i)\, p_j(e_i|f_i, D_{-i})` (see
            `MixtureOfGPExperts.loo_log_joint`). When the length-scale prior is on, the
            experts' hyperparameters are its MAP estimates.
        best: The largest objective reached; the fitted model is the state that reached it.
        converged: Whether the change per sample fell below `tol` before `max_iter`.
        init: Initialisation of the kept run (``"effects"``, ``"joint"``, ``"grow"``, or
            ``"grow-copy"`` when no split improved on the `M - 1` solution, which is then
            kept with one expert duplicated).
        candidates: `(init, seed, objective)` of every start tried for this `M`
            (objective after screening, or after the full run for the kept one).
        splits: `(iteration, collapsed, donor)` for every collapsed expert that took half
            of a donor expert's samples (split/merge).
        reseeded: `(iteration, expert)` for every collapsed expert re-seeded from the
            worst-explained samples because no expert could donate.
        split_merge: `(merged, into, split, objective)` for every accepted split-and-merge
            move after convergence: experts `merged` and `into` became one, expert
            `split` was divided into the freed slot, and EM reached `objective`.
        responsibilities: Final responsibilities :math:`r_{ij}`, `(N, M)`.
    """

    objective: list[float] = field(default_factory=list)
    best: float = -math.inf
    converged: bool = False
    init: str = ""
    candidates: list[tuple[str, int, float]] = field(default_factory=list)
    splits: list[tuple[int, int, int]] = field(default_factory=list)
    reseeded: list[tuple[int, int]] = field(default_factory=list)
    split_merge: list[tuple[int, int, int, float]] = field(default_factory=list)
    responsibilities: Tensor = field(default_factory=lambda: torch.empty(0, 0))

    @property
    def n_iter(self) -> int:
        """Number of EM iterations run in the kept run."""
        return len(self.objective)


@dataclass(frozen=True)
class _Settings:
    max_iter: int
    tol: float
    n_init: int
    prune_below: float
    min_size: float
    first_iters: int
    warm_iters: int
    anneal: bool
    anneal_start: float
    anneal_iter: int


def _reseed_collapsed(
    resp: Tensor, point_loglik: Tensor, min_size: float, prune_below: float
) -> list[int]:
    r"""Re-seed every collapsed expert from the worst-explained samples, in place.

    Expert `j` has collapsed when its pruned responsibilities sum to less than `min_size`
    (or to zero).
    It then takes (with responsibility 1) up to :math:`k = \max(\lceil N/2M \rceil,
    \lceil \text{min\_size} \rceil)`, at most :math:`\lfloor N/M \rfloor`, of the
    samples with the lowest log-likelihood under the current model, skipping samples whose
    loss would leave another expert without any sample or push a healthy expert below
    `min_size`, and samples already taken by another re-seeded expert. An expert left with
    no sample at all takes the single worst-explained sample that every other expert can
    spare (one exists because `N >= M`).

    Returns:
        The experts that received samples.
    """
    n, m = resp.shape
    k = max(1, min(max(math.ceil(n / (2 * m)), math.ceil(min_size)), n // m))
    order = torch.argsort(point_loglik, stable=True).tolist()
    taken = torch.zeros(n, dtype=torch.bool)
    reseeded: list[int] = []
    for j in range(m):
        w = torch.where(resp >= prune_below, resp, torch.zeros_like(resp))
        mass = w.sum(0)
        if float(mass[j]) >= min_size and float(mass[j]) > 0.0:
            continue
        support = (w > 0).sum(0)
        floor = torch.where(mass >= min_size, min_size, -math.inf)
        chosen: list[int] = []
        for i in order:
            if len(chosen) == k:
                break
            if taken[i] or float(resp[i, j]) == 1.0:
                continue
            owners = w[i] > 0
            owners[j] = False
            if bool((support[owners] < 2).any()) or bool(
                (mass[owners] - w[i, owners] < floor[owners]).any()
            ):
                continue
            chosen.append(i)
            support[owners] -= 1
            mass[owners] -= w[i, owners]
        if not chosen and float(mass[j]) == 0.0:
            spare = ((w > 0) & (support >= 2)) | (w == 0)
            spare[:, j] = True
            chosen = [next(i for i in order if bool(spare[i].all()))]
        if chosen:
            idx = torch.tensor(chosen)
            resp[idx] = 0.0
            resp[idx, j] = 1.0
            taken[idx] = True
            reseeded.append(j)
    return reseeded


def _pruned(resp: Tensor, prune_below: float) -> Tensor:
    return torch.where(resp >= prune_below, resp, torch.zeros_like(resp))


def _beta(settings: _Settings, iteration: int) -> float:
    """Inverse temperature of the E-step: geometric from `anneal_start` to 1."""
    if not settings.anneal or iteration > settings.anneal_iter:
        return 1.0
    frac = (iteration - 1) / settings.anneal_iter
    return float(settings.anneal_start ** (1.0 - frac))


class _Run:
    """One EM run from given responsibilities; it keeps the best state it reaches."""

    def __init__(
        self,
        model: MixtureOfGPExperts,
        x: Tensor,
        y: Tensor,
        resp: Tensor,
        settings: _Settings,
        *,
        init: str,
        seed: int,
        warm: bool = False,
    ) -> None:
        self.model, self.x, self.y, self.resp = model, x, y, resp
        self.settings, self.init, self.seed, self.warm = settings, init, seed, warm
        self.history = EMHistory(init=init)
        self.log_lik: Tensor | None = None  # (N, M) leave-one-out expert log densities
        self.best_state: tuple[dict[str, Any], Tensor, Tensor] | None = None
        self.iteration = 0
        self.done = False

    @property
    def best(self) -> float:
        return self.history.best

    def step(self, n_iter: int) -> _Run:
        """Run up to `n_iter` more iterations (fewer if converged or at `max_iter`)."""
        s = self.settings
        for _ in range(n_iter):
            if self.done or self.iteration >= s.max_iter:
                self.done = True
                break
            self.iteration += 1
            it = self.iteration
            self._repair(it)
            weights = _pruned(self.resp, s.prune_below)
            self.model.fit_gate(self.x, self.resp, reuse_choice=it > 1)
            iters = s.warm_iters if (self.warm or it > 1) else s.first_iters
            self.model.fit_experts(self.x, self.y, weights, max_iter=iters)
            log_joint, self.log_lik = _loo_terms(self.model, self.x, self.y)
            total = float(torch.logsumexp(log_joint, dim=1).sum())
            self.history.objective.append(total)
            logger.info("EM (%s) iteration %d: objective %.6g", self.init, it, total)
            if total > self.history.best:
                self.history.best = total
                self.best_state = (
                    copy.deepcopy(self.model.state_dict()),
                    weights.clone(),
                    torch.softmax(log_joint, dim=1),
                )
            self.resp = torch.softmax(_beta(s, it + 1) * log_joint, dim=1)
            prev = self.history.objective[-2] if it > 1 else None
            if (
                prev is not None
                and abs(total - prev) <= s.tol * self.x.shape[0]
                and _beta(s, it) == 1.0
            ):
                self.history.converged = True
                self.done = True
                break
        return self

    def _repair(self, it: int) -> None:
        """Split/merge every collapsed expert; re-seed it if no expert can donate."""
        s = self.settings
        m = self.resp.shape[1]
        if m == 1:
            return
        for j in range(m):
            mass = _pruned(self.resp, s.prune_below).sum(0)
            if float(mass[j]) >= s.min_size and float(mass[j]) > 0.0:
                continue
            donors = [d for d in range(m) if d != j and float(mass[d]) >= 2 * max(s.min_size, 1)]
            if not donors:
                continue
            if self.log_lik is not None:
                score = {
                    d: float((self.resp[:, d] * self.log_lik[:, d]).sum() / mass[d]) for d in donors
                }
                donor = min(donors, key=lambda d: score[d])
            else:
                donor = max(donors, key=lambda d: float(mass[d]))
            w = self.resp[:, donor] / self.resp[:, donor].sum()
            residuals = self.y - w @ self.y
            self.resp = split_responsibilities(
                self.resp,
                donor,
                self.x[:, self.model.gate_columns],
                residuals,
                into=j,
                seed=self.seed + it,
            )
            self.history.splits.append((it - 1, j, donor))
        reseeded = _reseed_collapsed(self.resp, self._point_log_lik(), s.min_size, s.prune_below)
        if reseeded:
            self.history.reseeded.extend((it - 1, j) for j in reseeded)
        if (self.history.splits and self.history.splits[-1][0] == it - 1) or reseeded:
            warnings.warn(
                f"EM iteration {it}: collapsed expert(s) (summed responsibility < "
                f"{s.min_size}) took samples from another expert.",
                RuntimeWarning,
                stacklevel=4,
            )

    def _point_log_lik(self) -> Tensor:
        if self.log_lik is None:
            return torch.zeros(self.resp.shape[0], dtype=torch.float64)
        return torch.logsumexp(self.log_lik + self.resp.clamp_min(1e-300).log(), dim=1)

    def finish(self) -> EMHistory:
        """Restore the best state into the model and return the history."""
        if self.best_state is not None:
            state, weights, resp = self.best_state
            self.model.condition(self.x, self.y, weights)
            self.model.load_state_dict(state)
            self.history.responsibilities = resp
        return self.history


def _fresh(
    template: MixtureOfGPExperts, n_experts: int, x: Tensor, y: Tensor
) -> MixtureOfGPExperts:
    """A new, built mixture like `template` with `n_experts` experts."""
    model = MixtureOfGPExperts(**{**template.config(), "n_experts": n_experts})
    model.build(x.shape[1], y.shape[1], template.resolve_noise_floor(y))
    return model


def _loo_terms(model: MixtureOfGPExperts, x: Tensor, y: Tensor) -> tuple[Tensor, Tensor]:
    """Leave-one-out log joint densities `(N, M)` and their experts' part `(N, M)`."""
    log_lik = model.loo_log_lik(x, y)
    log_gate = model.gate.log_proba(x[:, model.gate_columns])  # type: ignore[union-attr]
    return log_gate + log_lik, log_lik


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
    settings: _Settings,
    *,
    rounds: int,
    n_candidates: int,
    seed: int,
) -> tuple[MixtureOfGPExperts, EMHistory]:
    """Escape a local optimum by merging two experts and splitting a third (SMEM).

    After EM has converged, two experts that explain each other's samples best are merged
    (the smaller into the larger) and then either the merged expert or the expert that
    explains its own samples worst is split into the freed slot (Ueda et al., 2000, with
    the experts' leave-one-out densities as the criteria); EM then runs from there,
    warm-started. A move is kept only if it raises the objective, so the
    result is never worse than the input.
    """
    m = model.n_experts
    if m < 2 or rounds == 0:
        return model, history
    n = x.shape[0]
    for r in range(rounds):
        log_joint, log_lik = _loo_terms(model, x, y)
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
            run = _Run(trial, x, y, start, settings, init=history.init, seed=seed, warm=True)
            run.step(_SCREEN_ITER)
            if run.best <= history.best:
                continue
            trial_history = run.step(settings.max_iter).finish()
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
    prev: MixtureOfGPExperts, x: Tensor, y: Tensor, settings: _Settings, seed: int
) -> tuple[_Run, int]:
    """Start an EM run for `M` experts by splitting one expert of the `M - 1` solution."""
    m = prev.n_experts + 1
    log_joint, log_lik = _loo_terms(prev, x, y)
    resp = torch.softmax(log_joint, dim=1)
    target = _split_target(resp, log_lik, settings.min_size)
    split = split_responsibilities(
        resp, target, x[:, prev.gate_columns], _residuals(prev, target, x, y), seed=seed
    )
    model = _fresh(prev, m, x, y)
    for k, src in enumerate([*range(m - 1), target]):
        model.experts[k].load_state_dict(prev.experts[src].state_dict())
    return _Run(model, x, y, split, settings, init="grow", seed=seed, warm=True), target


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


def _fit_level(
    template: MixtureOfGPExperts,
    x: Tensor,
    y: Tensor,
    m: int,
    prev: MixtureOfGPExperts | None,
    settings: _Settings,
    *,
    init: str | Tensor,
    n_restarts: int,
    screen_iter: int | None,
    n_finish: int,
    split_merge: int,
    seed: int,
) -> tuple[MixtureOfGPExperts, EMHistory]:
    """Fit `m` experts: screen every start, finish the best, never fall below `prev`."""
    if isinstance(init, Tensor):
        model = _fresh(template, m, x, y)
        run = _Run(model, x, y, init, settings, init="given", seed=seed)
        history = run.step(settings.max_iter).finish()
        history.candidates = [("given", seed, history.best)]
        return model, history
    if m == 1:
        model = _fresh(template, 1, x, y)
        run = _Run(
            model,
            x,
            y,
            torch.ones(x.shape[0], 1, dtype=torch.float64),
            settings,
            init="effects",
            seed=seed,
        )
        history = run.step(_SINGLE_ITER).finish()
        history.candidates = [("effects", seed, history.best)]
        return model, history
    grown = prev is not None and prev.n_experts == m - 1
    runs: list[_Run] = []
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
            run = _Run(model, x, y, resp, settings, init=name, seed=s, warm=warm)
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


def _settings(
    model: MixtureOfGPExperts,
    *,
    max_iter: Any,
    tol: Any,
    n_init: Any,
    prune_below: Any,
    min_size: Any,
    gp_max_iter: Any,
    warm_max_iter: Any,
    anneal: bool,
    anneal_start: Any,
    anneal_iter: Any,
    n_restarts: Any,
    screen_iter: Any,
    init: str | Tensor,
) -> tuple[_Settings, int, int | None]:
    if not isinstance(init, Tensor):
        check_initialization(init)
    max_iter = check_count("max_iter", max_iter)
    check_positive("tol", tol, allow_zero=True)
    n_init = check_count("n_init", n_init)
    check_positive("prune_below", prune_below, allow_zero=True)
    if prune_below >= 1.0 / max(model.n_experts, 2):
        raise InputError(
            f"prune_below={prune_below} must be below 1/n_experts = "
            f"{1.0 / max(model.n_experts, 2):.4g}."
        )
    check_positive("min_size", min_size, allow_zero=True)
    warm = check_count("warm_max_iter", warm_max_iter)
    first = model.gp_max_iter if gp_max_iter is None else check_count("gp_max_iter", gp_max_iter)
    check_positive("anneal_start", anneal_start)
    if not anneal_start <= 1.0:
        raise InputError(f"anneal_start must be in (0, 1], got {anneal_start!r}.")
    anneal_iter = check_count("anneal_iter", anneal_iter)
    n_restarts = check_count("n_restarts", n_restarts)
    if screen_iter is not None:
        screen_iter = check_count("screen_iter", screen_iter)
    settings = _Settings(
        max_iter,
        float(tol),
        n_init,
        float(prune_below),
        float(min_size),
        first,
        warm,
        bool(anneal),
        float(anneal_start),
        anneal_iter,
    )
    return settings, n_restarts, screen_iter


def _given_responsibilities(init: Tensor, n: int, sizes: list[int]) -> Tensor:
    """Validate responsibilities given as the start of EM."""
    if len(sizes) != 1:
        raise InputError("responsibilities given as init fit one mixture size only.")
    resp = as_matrix("init responsibilities", init, n_rows=n, n_cols=sizes[0])
    check_probability("init responsibilities", resp)
    if not torch.allclose(resp.sum(1), torch.ones(n, dtype=resp.dtype), atol=1e-6):
        raise InputError("init responsibilities must have rows that sum to 1.")
    return resp


def fit_em_path(
    model: MixtureOfGPExperts,
    X: Any,
    Y: Any,
    n_experts: Sequence[int],
    *,
    init: str | Tensor = "auto",
    n_restarts: int = 3,
    screen_iter: int | None = 2,
    n_finish: int = 1,
    split_merge: int = 2,
    max_iter: int = 10,
    tol: float = 1e-3,
    n_init: int = 5,
    seed: int = 0,
    prune_below: float = 1e-4,
    min_size: float = 3.0,
    gp_max_iter: int | None = None,
    warm_max_iter: int = 8,
    anneal: bool = False,
    anneal_start: float = 0.1,
    anneal_iter: int = 4,
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
        init: As in `fit_em`.
        n_restarts: As in `fit_em`.
        screen_iter: As in `fit_em`.
        n_finish: As in `fit_em`.
        split_merge: As in `fit_em`.
        max_iter: As in `fit_em`.
        tol: As in `fit_em`.
        n_init: As in `fit_em`.
        seed: As in `fit_em`.
        prune_below: As in `fit_em`.
        min_size: As in `fit_em`.
        gp_max_iter: As in `fit_em`.
        warm_max_iter: As in `fit_em`.
        anneal: As in `fit_em`.
        anneal_start: As in `fit_em`.
        anneal_iter: As in `fit_em`.

    Returns:
        `M -> (fitted mixture, history)` for every requested `M`.

    Raises:
        InputError: As `fit_em`, or for an empty or non-positive `n_experts`.
    """
    sizes = sorted({check_count("n_experts", m) for m in n_experts})
    if not sizes:
        raise InputError("n_experts is empty; pass the mixture sizes to fit, e.g. (1, 2, 3).")
    template = MixtureOfGPExperts(**{**model.config(), "n_experts": sizes[-1]})
    settings, n_restarts, screen_iter = _settings(
        template,
        max_iter=max_iter,
        tol=tol,
        n_init=n_init,
        prune_below=prune_below,
        min_size=min_size,
        gp_max_iter=gp_max_iter,
        warm_max_iter=warm_max_iter,
        anneal=anneal,
        anneal_start=anneal_start,
        anneal_iter=anneal_iter,
        n_restarts=n_restarts,
        screen_iter=screen_iter,
        init=init,
    )
    x, y = template.check_data(X, Y)
    if isinstance(init, Tensor):
        init = _given_responsibilities(init, x.shape[0], sizes)
    grows = isinstance(init, str) and init in ("auto", "grow")
    out: dict[int, tuple[MixtureOfGPExperts, EMHistory]] = {}
    prev: MixtureOfGPExperts | None = None
    for m in range(1, sizes[-1] + 1) if grows else sizes:
        fitted, history = _fit_level(
            template,
            x,
            y,
            m,
            prev,
            settings,
            init=init,
            n_restarts=n_restarts,
            screen_iter=screen_iter,
            n_finish=check_count("n_finish", n_finish),
            split_merge=check_count("split_merge", split_merge, minimum=0),
            seed=seed,
        )
        prev = fitted
        if m in sizes:
            out[m] = (fitted, history)
    return out


def fit_em(
    model: MixtureOfGPExperts,
    X: Any,
    Y: Any,
    *,
    init: str | Tensor = "auto",
    n_restarts: int = 3,
    screen_iter: int | None = 2,
    n_finish: int = 1,
    split_merge: int = 2,
    max_iter: int = 10,
    tol: float = 1e-3,
    n_init: int = 5,
    seed: int = 0,
    prune_below: float = 1e-4,
    min_size: float = 3.0,
    gp_max_iter: int | None = None,
    warm_max_iter: int = 8,
    anneal: bool = False,
    anneal_start: float = 0.1,
    anneal_iter: int = 4,
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

    Initialisation (`init`, see `probaff.models.initialization`):

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

    After the best run has converged, up to `split_merge` rounds of split-and-merge moves
    (merge the two experts that explain each other's samples best, split the one that
    explains its own worst, rerun EM; Ueda et al., 2000) are tried and kept only when they
    raise the objective.

    A tensor of responsibilities `(N, M)` starts one run from that assignment (for example
    the true one, on synthetic data).

    With ``"effects"`` or ``"joint"``, `n_restarts` starts of that kind (seeds `seed`,
    `seed + 1`, ...) are screened the same way. Everything is deterministic given `seed`.

    Args:
        model: The mixture to fit (its experts and gate are (re)built for the data sizes).
        X: Features, `(N, D)`.
        Y: Effects, `(N, E)`.
        init: ``"auto"``, ``"effects"``, ``"joint"``, ``"grow"``, or responsibilities
            `(N, M)`.
        n_restarts: Starts tried for each `M` (the grown one counts).
        screen_iter: Iterations every start runs before only the best `n_finish` are run
            to convergence (the "small EM" strategy of Biernacki et al., 2003); ``None`` runs
            every start to convergence.
        n_finish: Screened starts run to convergence, the best by their screened
            objective first; the best of them is kept. The first gets `split_merge` rounds,
            the others one. A grown start is warm and can lead the screening although a
            cold start would end higher; finishing two catches that, for about a third more
            time.
        split_merge: Rounds of split-and-merge moves tried after convergence (0: none).
        max_iter: Maximum number of EM iterations of a run.
        tol: Convergence tolerance on the objective per sample.
        n_init: Restarts of each initial Gaussian mixture.
        seed: Seed of the initialisations; the rest of EM is deterministic.
        prune_below: Responsibilities below this are 0 in the experts' M-step.
        min_size: Minimum summed responsibility of an expert before it is repaired.
        gp_max_iter: L-BFGS iterations of the first M-step of a cold start; defaults to
            the model's `gp_max_iter`.
        warm_max_iter: L-BFGS iterations of later M-steps (and of every M-step of a grown
            start), warm-started from the previous hyperparameters.
        anneal: Temper the E-step (deterministic annealing).
        anneal_start: First inverse temperature β of the annealing, in (0, 1].
        anneal_iter: Iterations over which β rises to 1.

    Returns:
        The history of the kept run.

    Raises:
        InputError: For NaN/inf, empty or mismatched inputs, an unknown feature group or
            initialisation, non-integer counts, or more experts than samples.
    """
    path = fit_em_path(
        model,
        X,
        Y,
        (model.n_experts,),
        init=init,
        n_restarts=n_restarts,
        screen_iter=screen_iter,
        n_finish=n_finish,
        split_merge=split_merge,
        max_iter=max_iter,
        tol=tol,
        n_init=n_init,
        seed=seed,
        prune_below=prune_below,
        min_size=min_size,
        gp_max_iter=gp_max_iter,
        warm_max_iter=warm_max_iter,
        anneal=anneal,
        anneal_start=anneal_start,
        anneal_iter=anneal_iter,
    )
    fitted, history = path[model.n_experts]
    x, y = model.check_data(X, Y)
    model.condition(x, y, fitted.train_weights)
    model.load_state_dict(fitted.state_dict())
    return history
