"""Starting responsibilities for EM and SVI, and the split of one expert into two.

Named initialisations (`INITIALIZATIONS`):

* ``"effects"``: the thesis's start, a Gaussian mixture fitted to the standardised effects.
* ``"joint"``: a Gaussian mixture on standardised [gate features, effects]. Wide gate
  features are first reduced by PCA to the components that explain 90 % of their variance
  (at most `MAX_GATE_COMPONENTS`), and the gate block is scaled so that it weighs as much as
  the effect block. Regimes that overlap in effect space but are decided by the gate's
  inputs are separated by this start and not by ``"effects"``.
* ``"grow"``: fit `M` experts from the `M - 1` solution by splitting one expert
  (`split_responsibilities`); `probaff.models.mixture.em.fit_em` runs it.
"""

from __future__ import annotations

import warnings

import numpy as np
import torch
from sklearn.decomposition import PCA
from sklearn.exceptions import ConvergenceWarning
from sklearn.mixture import GaussianMixture
from torch import Tensor

from probaff._checks import check_count
from probaff.errors import InputError

__all__ = [
    "INITIALIZATIONS",
    "MAX_GATE_COMPONENTS",
    "check_initialization",
    "initial_responsibilities",
    "split_responsibilities",
]

INITIALIZATIONS = ("effects", "joint", "grow")
"""Names of the initialisation strategies."""

MAX_GATE_COMPONENTS = 8
"""Most principal components of the gate features that the ``"joint"`` start keeps."""

GMM_MAX_ITER = 200
"""EM iterations of a start's Gaussian mixture (at most)."""

GMM_SCREEN_ITER = 10
"""EM iterations every restart of a cold start's Gaussian mixture runs before the most likely
runs on to convergence. On RAND HIE's visits (15 seeded 1,000-row subsets, 20 restarts) the
screened restarts found the 1-visit spike as often as restarts run to convergence (25 of 30
starts either way) for 0.6 times the CPU time."""


def check_initialization(init: str, *, allow_auto: bool = True) -> str:
    """Return `init` if it names an initialisation, else raise `InputError`.

    Args:
        init: A name from `INITIALIZATIONS`, or ``"auto"`` (restarts across all of them).
        allow_auto: Accept ``"auto"``.
    """
    known = (("auto",) if allow_auto else ()) + INITIALIZATIONS
    if init not in known:
        raise InputError(f"unknown initialisation {init!r}; use one of {list(known)}.")
    return init


def _standardise(a: np.ndarray) -> np.ndarray:
    std = a.std(axis=0)
    return (a - a.mean(axis=0)) / np.where(std > 1e-12, std, 1.0)


def _gate_block(x_gate: np.ndarray, seed: int) -> np.ndarray:
    """Standardised gate features, PCA-reduced when wide, `(N, K)`."""
    z = _standardise(x_gate)
    if z.shape[1] > MAX_GATE_COMPONENTS:
        pca = PCA(n_components=min(MAX_GATE_COMPONENTS, *z.shape), random_state=seed).fit(z)
        keep = int(np.searchsorted(np.cumsum(pca.explained_variance_ratio_), 0.9) + 1)
        z = _standardise(pca.transform(z)[:, : max(1, min(keep, MAX_GATE_COMPONENTS))])
    return z


def _gmm_responsibilities(
    z: np.ndarray,
    n_components: int,
    *,
    n_init: int,
    seed: int,
    weights: np.ndarray | None = None,
    drawn: bool = False,
) -> Tensor:
    """Responsibilities `(N, K)` of a full-covariance Gaussian mixture fitted to `z`.

    With `weights`, the mixture is fitted to the rows whose weight is at least half the
    largest, then evaluated on every row. Without `drawn`, the mixture is fitted `n_init`
    times from k-means and the most likely fit is kept. With `drawn`, the first start is
    seeded by k-means and the other `n_init - 1` by `n_components` rows drawn from the data;
    every start runs `GMM_SCREEN_ITER` EM iterations, and the most likely then runs to
    convergence.
    """
    fit_rows = z if weights is None else z[weights >= 0.5 * weights.max()]
    if len(fit_rows) < n_components:
        fit_rows = z
    if drawn:
        seedings, max_iter = [("kmeans", 1), ("random_from_data", n_init - 1)], GMM_SCREEN_ITER
    else:
        seedings, max_iter = [("kmeans", n_init)], GMM_MAX_ITER
    best: GaussianMixture | None = None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ConvergenceWarning)
        for init_params, count in seedings:
            if count == 0:
                continue
            gmm = GaussianMixture(
                n_components=n_components,
                covariance_type="full",
                n_init=count,
                random_state=seed,
                reg_covar=1e-4,
                max_iter=max_iter,
                init_params=init_params,
            ).fit(fit_rows)
            if best is None or gmm.lower_bound_ > best.lower_bound_:
                best = gmm
        assert best is not None
        if max_iter < GMM_MAX_ITER:  # the screened winner runs on from where it stopped
            best.set_params(warm_start=True, n_init=1, max_iter=GMM_MAX_ITER).fit(fit_rows)
    return torch.as_tensor(best.predict_proba(z), dtype=torch.float64, device=torch.device("cpu"))


def initial_responsibilities(
    init: str, x_gate: Tensor, Y: Tensor, n_experts: int, *, n_init: int = 20, seed: int = 0
) -> Tensor:
    """Responsibilities of a cold start (``"effects"`` or ``"joint"``).

    Args:
        init: ``"effects"`` or ``"joint"``.
        x_gate: The gate's features, `(N, D_g)`.
        Y: Effects, `(N, E)`.
        n_experts: Number of experts `M`.
        n_init: Restarts of the Gaussian mixture: one seeded by k-means, the others by
            rows drawn from the data (the most likely is kept; see `_gmm_responsibilities`).
        seed: Random seed of the Gaussian mixture and the PCA.

    Returns:
        Rows summing to 1, `(N, M)`.

    Raises:
        InputError: For an unknown `init` (``"grow"`` is not a cold start).
    """
    n_experts = check_count("n_experts", n_experts)
    n_init = check_count("n_init", n_init)
    if init not in ("effects", "joint"):
        raise InputError(f"initial_responsibilities takes 'effects' or 'joint', got {init!r}.")
    n = Y.shape[0]
    if n_experts == 1:
        return torch.ones(n, 1, dtype=torch.float64, device=Y.device)
    z = _standardise(Y.detach().cpu().numpy())
    if init == "joint":
        g = _gate_block(x_gate.detach().cpu().numpy(), seed)
        z = np.concatenate([g * np.sqrt(z.shape[1] / g.shape[1]), z], axis=1)
    return _gmm_responsibilities(z, n_experts, n_init=n_init, seed=seed, drawn=True).to(Y.device)


def split_responsibilities(
    resp: Tensor,
    expert: int,
    x_gate: Tensor,
    residuals: Tensor,
    *,
    into: int | None = None,
    seed: int = 0,
    n_init: int = 3,
) -> Tensor:
    """Split one expert's responsibilities between it and a new (or an emptied) expert.

    The expert's samples are divided by a two-component Gaussian mixture on their
    standardised gate features (PCA-reduced when wide) and their standardised residuals
    under that expert, so the two halves differ where the gate can see it or where one
    function does not fit both. Sample `i` then gives `resp[i, expert] * q_i0` to the old
    expert and `resp[i, expert] * q_i1` to the new one; the other experts keep theirs.

    Args:
        resp: Responsibilities, `(N, M)`.
        expert: Index of the expert to split.
        x_gate: The gate's features, `(N, D_g)`.
        residuals: Each sample's residual under that expert (target minus its
            leave-one-out mean), `(N, E)`.
        into: Column that receives the second half (its current responsibilities are
            dropped); ``None`` appends a new column.
        seed: Seed of the Gaussian mixture.
        n_init: Restarts of the Gaussian mixture.

    Returns:
        Responsibilities, `(N, M + 1)`, or `(N, M)` with `into`.
    """
    w = resp[:, expert].detach().cpu().numpy()
    z = np.concatenate(
        [
            _gate_block(x_gate.detach().cpu().numpy(), seed),
            _standardise(residuals.detach().cpu().numpy()),
        ],
        axis=1,
    )
    q = _gmm_responsibilities(z, 2, n_init=n_init, seed=seed, weights=w).to(resp.device)
    if into is None:
        out = torch.cat([resp, resp.new_zeros(resp.shape[0], 1)], dim=1)
        into = out.shape[1] - 1
    else:
        out = resp.clone()
        out[:, into] = 0.0
        out = out / out.sum(1, keepdim=True).clamp_min(torch.finfo(out.dtype).tiny)
    share = out[:, expert].clone()
    out[:, expert] = share * q[:, 0]
    out[:, into] = share * q[:, 1]
    return out
