"""Expectation-maximisation for a mixture of GP experts."""

from __future__ import annotations

import logging
import math
import warnings
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import torch
from sklearn.exceptions import ConvergenceWarning
from sklearn.mixture import GaussianMixture
from torch import Tensor

from probaff._checks import check_positive
from probaff.errors import InputError
from probaff.models.mixture import MixtureOfGPExperts

__all__ = ["EMHistory", "fit_em", "initial_responsibilities"]

logger = logging.getLogger(__name__)


@dataclass
class EMHistory:
    r"""Record of one EM fit.

    Attributes:
        log_likelihood: Observed-data log-likelihood
            :math:`\sum_i \log \sum_j p(m=j|f_i)\, p_j(e_i|f_i)` after each iteration.
        converged: Whether the change per sample fell below `tol` before `max_iter`.
        reseeded: `(iteration, expert)` for every expert re-seeded after collapsing
            (iteration 0 is the initialisation).
        responsibilities: Final responsibilities :math:`r_{ij}`, `(N, M)`.
    """

    log_likelihood: list[float] = field(default_factory=list)
    converged: bool = False
    reseeded: list[tuple[int, int]] = field(default_factory=list)
    responsibilities: Tensor = field(default_factory=lambda: torch.empty(0, 0))

    @property
    def n_iter(self) -> int:
        """Number of EM iterations run."""
        return len(self.log_likelihood)


def initial_responsibilities(
    Y: Tensor, n_experts: int, *, n_init: int = 5, seed: int = 0
) -> tuple[Tensor, Tensor]:
    """Responsibilities of a Gaussian mixture fitted in effect space.

    Args:
        Y: Effects, `(N, E)`.
        n_experts: Number of components `M`.
        n_init: Restarts of the Gaussian mixture (the best is kept).
        seed: Random seed of the Gaussian mixture.

    Returns:
        Responsibilities `(N, M)` and each sample's log density under the mixture `(N,)`.
    """
    n = Y.shape[0]
    if n_experts == 1:
        return torch.ones(n, 1, dtype=torch.float64), torch.zeros(n, dtype=torch.float64)
    y = Y.numpy()
    std = y.std(axis=0)
    z = (y - y.mean(axis=0)) / np.where(std > 0, std, 1.0)
    gmm = GaussianMixture(
        n_components=n_experts,
        covariance_type="full",
        n_init=n_init,
        random_state=seed,
        reg_covar=1e-6,
        max_iter=200,
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)
        gmm.fit(z)
    resp = torch.as_tensor(gmm.predict_proba(z), dtype=torch.float64)
    score = torch.as_tensor(gmm.score_samples(z), dtype=torch.float64)
    return resp, score


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


def fit_em(
    model: MixtureOfGPExperts,
    X: Any,
    Y: Any,
    *,
    max_iter: int = 10,
    tol: float = 1e-4,
    n_init: int = 5,
    seed: int = 0,
    prune_below: float = 1e-4,
    min_size: float = 3.0,
    gp_max_iter: int | None = None,
    warm_max_iter: int = 15,
) -> EMHistory:
    r"""Fit a mixture of GP experts by EM.

    Initialisation: responsibilities of a Gaussian mixture in (standardised) effect space
    with `n_init` restarts. Each iteration then runs

    * M-step: the gate is fitted to the responsibilities (weighted multinomial logistic
      regression) and expert `j` is refitted as a GP whose sample `i` has noise
      :math:`\sigma_j^2 / r_{ij}`, re-optimising its kernel hyperparameters by the
      weighted marginal likelihood. Responsibilities below `prune_below` are set to 0
      for the experts, which removes those samples from the expert's exact GP.
    * E-step: :math:`r_{ij} \propto p(m=j|f_i)\, p_j(e_i|f_i)` with the experts'
      predictive densities (noise included), and the observed-data log-likelihood
      :math:`\sum_i \log \sum_j p(m=j|f_i)\, p_j(e_i|f_i)`, logged every iteration.

    EM stops after `max_iter` iterations or once the log-likelihood changes by less than
    `tol` per sample. An expert whose pruned responsibilities sum to less than
    `min_size` has collapsed: it is re-seeded from the samples the current model explains
    worst (see the returned `reseeded`), with a `RuntimeWarning`. Kernel matrices that are
    numerically singular are factorised with increasing jitter.

    Args:
        model: The mixture to fit (its experts and gate are (re)built for the data sizes).
        X: Features, `(N, D)`.
        Y: Effects, `(N, E)`.
        max_iter: Maximum number of EM iterations.
        tol: Convergence tolerance on the mean log-likelihood per sample.
        n_init: Restarts of the Gaussian mixture used for initialisation.
        seed: Seed of the Gaussian mixture; the rest of EM is deterministic.
        prune_below: Responsibilities below this are 0 in the experts' M-step.
        min_size: Minimum summed responsibility of an expert before it is re-seeded.
        gp_max_iter: L-BFGS iterations of the first M-step; defaults to the model's
            `gp_max_iter`.
        warm_max_iter: L-BFGS iterations of later M-steps, warm-started from the
            previous hyperparameters.

    Returns:
        The per-iteration history.

    Raises:
        InputError: For NaN/inf, empty or mismatched inputs, an unknown feature group,
            or more experts than samples.
    """
    check_positive("max_iter", max_iter)
    check_positive("tol", tol, allow_zero=True)
    check_positive("n_init", n_init)
    check_positive("prune_below", prune_below, allow_zero=True)
    if prune_below >= 1.0 / model.n_experts:
        raise InputError(
            f"prune_below={prune_below} must be below 1/n_experts = {1.0 / model.n_experts:.4g}."
        )
    check_positive("min_size", min_size, allow_zero=True)
    check_positive("warm_max_iter", warm_max_iter)
    if gp_max_iter is not None:
        check_positive("gp_max_iter", gp_max_iter)
    x, y = model.check_data(X, Y)
    n = x.shape[0]
    history = EMHistory()
    resp, point_loglik = initial_responsibilities(y, model.n_experts, n_init=n_init, seed=seed)
    first_iters = model.gp_max_iter if gp_max_iter is None else int(gp_max_iter)
    for it in range(1, int(max_iter) + 1):
        reseeded = _reseed_collapsed(resp, point_loglik, min_size, prune_below)
        if reseeded:
            history.reseeded.extend((it - 1, j) for j in reseeded)
            warnings.warn(
                f"EM iteration {it}: expert(s) {reseeded} collapsed (summed responsibility "
                f"< {min_size}) and were re-seeded from the worst-explained samples.",
                RuntimeWarning,
                stacklevel=2,
            )
        weights = torch.where(resp >= prune_below, resp, torch.zeros_like(resp))
        model.fit_gate(x, resp)
        model.fit_experts(x, y, weights, max_iter=first_iters if it == 1 else warm_max_iter)
        log_joint = model.log_joint(x, y)
        point_loglik = torch.logsumexp(log_joint, dim=1)
        resp = torch.softmax(log_joint, dim=1)
        total = float(point_loglik.sum())
        history.log_likelihood.append(total)
        logger.info("EM iteration %d: observed-data log-likelihood %.6g", it, total)
        if it > 1 and abs(total - history.log_likelihood[-2]) <= tol * n:
            history.converged = True
            break
    history.responsibilities = resp
    return history
