"""One EM run of a mixture of GP experts from given responsibilities, and its record.

`EMRun` alternates the M-step (gate and experts refitted to the responsibilities) and the
E-step (leave-one-out responsibilities), repairs collapsed experts, and keeps the best state
it reaches; `EMHistory` records the kept run. `probaff.models.mixture.em` drives the runs.
"""

from __future__ import annotations

import logging
import math
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import torch
from torch import Tensor

from probaff.models.initialization import split_responsibilities
from probaff.models.mixture.model import MixtureOfGPExperts
from probaff.models.options import EMOptions

__all__ = ["EMHistory", "EMRun", "loo_terms"]

# EM logs under the module users call.
logger = logging.getLogger("probaff.models.mixture.em")


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
    taken = torch.zeros(n, dtype=torch.bool, device=resp.device)
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
            idx = torch.tensor(chosen, device=resp.device)
            resp[idx] = 0.0
            resp[idx, j] = 1.0
            taken[idx] = True
            reseeded.append(j)
    return reseeded


def _pruned(resp: Tensor, prune_below: float) -> Tensor:
    return torch.where(resp >= prune_below, resp, torch.zeros_like(resp))


def _beta(settings: EMOptions, iteration: int) -> float:
    """Inverse temperature of the E-step: geometric from `anneal_start` to 1."""
    if not settings.anneal or iteration > settings.anneal_iter:
        return 1.0
    frac = (iteration - 1) / settings.anneal_iter
    return float(settings.anneal_start ** (1.0 - frac))


class EMRun:
    """One EM run from given responsibilities; it keeps the best state it reaches.

    With `active` experts the run starts with partial iterations (Ueda et al.'s partial EM
    of split-and-merge): only those experts are refitted, and only they share out again
    the responsibility they hold together; the other experts keep their hyperparameters
    and responsibilities. `release` turns later iterations into full ones.

    `settings` are the fit's `EMOptions` whole; its `gp_max_iter` (None: the mixture's
    ``gp.max_iter``) sets the first M-step of a cold start, `warm_max_iter` every later one.
    """

    def __init__(
        self,
        model: MixtureOfGPExperts,
        x: Tensor,
        y: Tensor,
        resp: Tensor,
        settings: EMOptions,
        *,
        init: str,
        seed: int,
        warm: bool = False,
        active: Sequence[int] | None = None,
    ) -> None:
        self.model, self.x, self.y, self.resp = model, x, y, resp
        self.settings, self.init, self.seed, self.warm = settings, init, seed, warm
        self.first_iters = (
            model.gp.max_iter if settings.gp_max_iter is None else settings.gp_max_iter
        )
        self.active = None if active is None else sorted(set(active))
        self.history = EMHistory(init=init)
        self.log_lik: Tensor | None = None  # (N, M) leave-one-out expert log densities
        self.best_state: tuple[dict[str, Any], Tensor, Tensor] | None = None
        self.iteration = 0
        self.done = False

    def release(self) -> EMRun:
        """End the partial phase: later iterations refit and reassign every expert."""
        if self.active is not None:
            self.active = None
            self.done = self.iteration >= self.settings.max_iter
            self.history.converged = False
        return self

    @property
    def best(self) -> float:
        """The largest objective the run has reached."""
        return self.history.best

    def step(self, n_iter: int) -> EMRun:
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
            iters = s.warm_max_iter if (self.warm or it > 1) else self.first_iters
            self.model.fit_experts(self.x, self.y, weights, max_iter=iters, only=self.active)
            log_joint, self.log_lik = loo_terms(self.model, self.x, self.y)
            total = float(torch.logsumexp(log_joint, dim=1).sum())
            self.history.objective.append(total)
            logger.info("EM (%s) iteration %d: objective %.6g", self.init, it, total)
            if total > self.history.best:
                self.history.best = total
                self.best_state = (
                    {k: v.clone() for k, v in self.model.state_dict().items()},
                    weights.clone(),
                    torch.softmax(log_joint, dim=1),
                )
            self.resp = self._e_step(_beta(s, it + 1) * log_joint)
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

    def _e_step(self, log_joint: Tensor) -> Tensor:
        """New responsibilities `(N, M)` from log joint densities `(N, M)`.

        In the partial phase only the active experts are reassigned, within the
        responsibility they hold together (Ueda et al., 2000); the others keep theirs.
        """
        if self.active is None:
            return torch.softmax(log_joint, dim=1)
        resp = self.resp.clone()
        mass = resp[:, self.active].sum(1, keepdim=True)
        share = mass * torch.softmax(log_joint[:, self.active], dim=1)
        resp[:, self.active] = share.clamp_max_(1.0)  # a product may round just above 1
        return resp

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
            return self.resp.new_zeros(self.resp.shape[0])
        return torch.logsumexp(self.log_lik + self.resp.clamp_min(1e-300).log(), dim=1)

    def finish(self) -> EMHistory:
        """Restore the best state into the model and return the history."""
        if self.best_state is not None:
            state, weights, resp = self.best_state
            self.model.condition(self.x, self.y, weights)
            self.model.load_state_dict(state)
            self.history.responsibilities = resp
        return self.history


def loo_terms(model: MixtureOfGPExperts, x: Tensor, y: Tensor) -> tuple[Tensor, Tensor]:
    """Leave-one-out log joint densities `(N, M)` and their experts' part `(N, M)`."""
    log_lik = model.loo_log_lik(x, y)
    log_gate = model.gate.log_proba(x[:, model.gate_columns])  # type: ignore[union-attr]
    return log_gate + log_lik, log_lik
