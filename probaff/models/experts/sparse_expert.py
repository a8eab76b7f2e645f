r"""One sparse GP expert: E inducing-point GPs (SGPR) with per-sample noise weights.

`SparseGPExpert` has the interface of `probaff.models.experts.gp_expert.GPExpert` (``condition``,
``fit``, ``predict``, ``loo_predict``, ``log_prob``, ``lengthscales``, ``noise``) but its fit
maximises Titsias's (2009) collapsed variational bound with `m` inducing inputs per output,

.. math::
    \mathcal F = \log \mathcal N(y;\, c,\, Q + \Lambda)
        - \tfrac12 \operatorname{tr}\!\left[\Lambda^{-1}(K - Q)\right],
    \qquad Q = K_{fu} K_{uu}^{-1} K_{uf},\quad \Lambda = \sigma^2 W^{-1},

computed in closed form from `m x m` Cholesky factors (Woodbury), so a fit costs
:math:`O(N m^2)` time and :math:`O(N m)` memory instead of the exact expert's :math:`O(N^3)`
and :math:`O(N^2)`. With the inducing inputs at the training inputs the bound is the exact
weighted marginal likelihood. The module also estimates the memory of exact and sparse fits
(`fit_memory_bytes`) and reads the memory available (`available_memory_bytes`).
"""

from __future__ import annotations

import math
import os
import warnings
from collections.abc import Iterator
from pathlib import Path
from typing import Any, NamedTuple, Self

import torch
from torch import Tensor
from torch.distributions import Normal

from probaff.errors import InputError, NotFittedError
from probaff.models.experts.expert_base import MIN_VARIANCE, WeightedExpert
from probaff.models.experts.kernels import ard_se_kernel
from probaff.models.experts.likelihood import weight_correction
from probaff.models.options import (
    DEFAULT_N_INDUCING,
    OUTPUTSCALE_BOUNDS,
    SparseGPOptions,
    resolve_options,
)
from probaff.models.tensors import as_matrix

__all__ = [
    "DEFAULT_N_INDUCING",
    "FitMemoryError",
    "SparseGPExpert",
    "available_memory_bytes",
    "fit_memory_bytes",
    "select_inducing",
]

# Diagonal jitter of K_uu, relative to the signal variance, tried in turn when a Cholesky
# factorisation fails.
_JITTERS = (1e-6, 1e-4, 1e-2)
# Box constraints (standardised units) that keep every length scale finite and positive.
_LENGTHSCALE_BOUNDS = (1e-3, 1e4)
# Rows per block in the no-gradient passes (prediction, leave-one-out), bounding memory.
_BLOCK = 4096
# Working copies of the (E, m, N) cross-covariance that one bound evaluation and its
# gradient hold (measured peak: 7.7 at N = 5,000, m = 256), and of an (E, N, N) matrix in
# an exact fit (kernel, covariance, Cholesky factor, gradient).
_SPARSE_COPIES = 8
_EXACT_COPIES = 4
# Working copies of an (E, m, block) matrix in a no-gradient pass (kernel, projection, solve).
_PASS_COPIES = 4


# ----------------------------------------------------------------- memory
class FitMemoryError(InputError, MemoryError):
    """A fit would need more memory than the machine has available (raised before it starts)."""


def fit_memory_bytes(
    experts: str,
    n_samples: int,
    n_outputs: int,
    n_experts: int,
    n_inducing: int,
    *,
    n_features: int = 0,
    hyper_rows: int | None = None,
) -> int:
    """Estimated peak memory of fitting `n_experts` experts on `n_samples` rows (float64).

    An exact M-step fits the `M` experts as one batch and holds :math:`M E N^2` kernel
    entries with working copies of them (the covariance, its Cholesky factor and the
    gradient). Sparse experts are fitted one at a time: the bound and its gradient hold
    :math:`E m R` cross-covariance entries and their working copies for the `R` rows the
    hyperparameters are chosen on (`hyper_rows`, at most `N`), the passes over every row
    (posterior, prediction, leave-one-out) go in blocks of a few thousand rows, every
    expert keeps its `m x m` factors and its standardised copy of the `N` rows.

    Args:
        experts: ``"exact"`` or ``"sparse"``.
        n_samples: Training rows `N`.
        n_outputs: Outputs `E`.
        n_experts: Experts `M`.
        n_inducing: Inducing points `m` (ignored for ``"exact"``).
        n_features: Features `D` of the experts (their copies of the data).
        hyper_rows: Rows the sparse bound is maximised on; None for `N`.

    Returns:
        Bytes.
    """
    if experts == "exact":
        return 8 * n_experts * n_outputs * n_samples * n_samples * _EXACT_COPIES
    m, e = n_inducing, n_outputs
    rows = n_samples if hyper_rows is None else min(n_samples, hyper_rows)
    bound = m * rows * _SPARSE_COPIES
    passes = m * min(n_samples, _BLOCK) * _PASS_COPIES
    data = n_experts * n_samples * (n_features + n_outputs)
    return 8 * (e * (bound + passes + 4 * n_experts * m * m) + data)


def available_memory_bytes() -> int | None:
    """Memory available to a new allocation: ``MemAvailable`` of /proc/meminfo.

    Falls back to the free physical pages of ``os.sysconf``; None where neither exists.

    Returns:
        Bytes, or None when unknown.
    """
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemAvailable:"):
                return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return int(os.sysconf("SC_AVPHYS_PAGES")) * int(os.sysconf("SC_PAGE_SIZE"))
    except (ValueError, OSError, AttributeError):
        return None


# ---------------------------------------------------------------- algebra
def _se(
    a: Tensor, x: Tensor, inv_l2: Tensor, outputscale: Tensor, x_sq: Tensor | None = None
) -> Tensor:
    r"""SE-ARD cross-covariance of `a: (E, m, D)` and `x: (n, D)` (or `(E, n, D)`), `(E, m, n)`.

    `inv_l2` is :math:`1 / \ell^2`, `(E, 1, D)`; `x_sq` optionally the precomputed
    :math:`\sum_d x_d^2 / \ell_d^2`, `(E, n)`.
    """
    a_sq = (a.square() * inv_l2).sum(-1)  # (E, m)
    if x_sq is None:
        x_sq = (x.square() * inv_l2).sum(-1) if x.dim() == 3 else (x.square() @ inv_l2[:, 0].mT).mT
    cross = (a * inv_l2) @ x.mT  # (E, m, n)
    d2 = (a_sq[..., None] + x_sq[..., None, :] - 2.0 * cross).clamp_min(0.0)
    return outputscale[:, None, None] * torch.exp(-0.5 * d2)


def select_inducing(
    x: Tensor, weights: Tensor, lengthscale: Tensor, outputscale: Tensor, m: int
) -> Tensor:
    r"""Greedy weighted selection of `m` inducing inputs per output (pivoted Cholesky).

    For each output, the next inducing input is the training input with the largest
    :math:`w_i\,(k_{ii} - q_{ii})`, the weighted variance the inputs chosen so far leave
    unexplained: each pick greedily lowers the trace term of the weighted collapsed
    bound. Ties go to the first row, so the selection is deterministic.

    Args:
        x: Training inputs (standardised), `(n, D)`.
        weights: Positive sample weights, `(n,)`.
        lengthscale: Length scales of every output's kernel, `(E, D)`.
        outputscale: Signal variances, `(E,)`.
        m: Inducing points per output, at most `n`.

    Returns:
        Inducing inputs, `(E, m, D)`.
    """
    n_out, n = lengthscale.shape[0], x.shape[0]
    inv_l2 = lengthscale.square().reciprocal()[:, None, :]
    x_sq = x.square() @ inv_l2[:, 0].mT  # (n, E)
    x_sq = x_sq.mT.contiguous()  # (E, n)
    resid = outputscale[:, None].expand(n_out, n).clone()
    rows = x.new_zeros(n_out, m, n)
    taken = torch.zeros(n_out, n, dtype=torch.bool, device=x.device)
    picks = torch.empty(n_out, m, dtype=torch.long, device=x.device)
    out = torch.arange(n_out, device=x.device)
    tiny = 1e-12 * outputscale
    for k in range(m):
        score = torch.where(taken, -1.0, weights * resid)
        p = score.argmax(-1)
        picks[:, k] = p
        taken[out, p] = True
        kp = _se(x[p][:, None, :], x, inv_l2, outputscale, x_sq)[:, 0]  # (E, n)
        if k:
            kp = kp - (rows[out, :k, p][:, None, :] @ rows[:, :k])[:, 0]
        piv = resid[out, p]
        scale = torch.where(piv > tiny, piv.clamp_min(1e-300).rsqrt(), 0.0)
        rows[:, k] = kp * scale[:, None]
        resid = (resid - rows[:, k].square()).clamp_min(0.0)
    return x[picks]


class _Factors(NamedTuple):
    """The `m x m` factors of the SGPR posterior of every output."""

    lu: Tensor  # chol(K_uu + jitter), (E, m, m)
    lb: Tensor  # chol(I + L_u^-1 K_uf W K_fu L_u^-T / sigma^2), (E, m, m)
    v: Tensor  # L_B^-1 L_u^-1 K_uf W r / sigma^2, (E, m, 1)


def _factors(lu: Tensor, gram: Tensor, proj: Tensor, noise: Tensor) -> _Factors:
    """Factors from `gram = A W A^T` `(E, m, m)` and `proj = A W r` `(E, m, 1)`, `A = L_u^-1 K_uf`.

    `A` is formed explicitly (rather than `L_u^-1 K_uf W K_fu L_u^-T` from the product)
    because that keeps `I + gram / sigma^2` positive definite in floating point when
    `K_uu` is badly conditioned.
    """
    eye = torch.eye(gram.shape[-1], dtype=gram.dtype, device=gram.device)
    lb = torch.linalg.cholesky(eye + gram / noise[:, None, None])
    v = torch.linalg.solve_triangular(lb, proj, upper=False) / noise[:, None, None]
    return _Factors(lu, lb, v)


def _blocks(n: int) -> Iterator[slice]:
    for start in range(0, n, _BLOCK):
        yield slice(start, min(start + _BLOCK, n))


class SparseGPExpert(WeightedExpert):
    r"""Multi-output sparse GP regressor (SGPR) with SE-ARD kernels and per-sample weights.

    Each of the `E` outputs is an inducing-point GP (constant mean, amplitude times an ARD
    squared-exponential kernel, Gaussian noise) with its own hyperparameters and its own
    `m` inducing inputs, batched over the outputs. Inputs and outputs are standardised with
    the weighted moments of the training data, exactly as in `GPExpert`. Sample `i` with
    weight :math:`w_i > 0` has noise variance :math:`\sigma^2 / w_i`; samples of weight 0
    are removed. Hyperparameters maximise Titsias's collapsed bound under that noise plus
    the `WeightCorrection` term (and the log length-scale prior, with `lengthscale_prior`),
    so the objective is the exact expert's weighted marginal likelihood when the inducing
    inputs are the training inputs, and below it otherwise. One bound evaluation costs
    :math:`O(N m^2)` and never forms an `N x N` matrix.

    Inducing inputs are chosen from the expert's weighted samples by `select_inducing`
    (greedy pivoted Cholesky on the current kernel, deterministic) at every `fit`, and are
    optimised with the hyperparameters when `learn_inducing` is set. An expert holding more
    than `hyper_rows` samples chooses its inducing inputs and hyperparameters on a uniform
    random subset of that many (with their weights), then conditions on every sample (the
    predictive, the leave-one-out densities): the cost of a fit then grows as :math:`N m^2`
    from the no-gradient passes only. Predictions are the
    SGPR predictive (latent mean and variance of the collapsed posterior, with the
    diagonal correction :math:`k_{**} - q_{**}`, plus the noise).

    Args:
        n_features: Number of input features `D`.
        n_outputs: Number of outputs `E`.
        options: The settings (`SparseGPOptions`: those of `GPOptions` and `n_inducing`,
            `learn_inducing`); None for `SparseGPOptions()`.
        **overrides: Fields of `SparseGPOptions` that replace those of `options`.

    Attributes:
        covar_module: The batched SE-ARD kernel (`probaff.models.experts.kernels.ard_se_kernel`).
        likelihood: Its weighted Gaussian likelihood.
        inducing: Inducing inputs in standardised feature units, `(E, m, D)`.
    """

    train_x: Tensor
    train_y: Tensor
    options: SparseGPOptions

    def __init__(
        self,
        n_features: int,
        n_outputs: int,
        options: SparseGPOptions | None = None,
        **overrides: Any,
    ) -> None:
        resolved = resolve_options(SparseGPOptions, options, overrides)
        super().__init__(n_features, n_outputs, resolved, _JITTERS[0])
        self.covar_module = ard_se_kernel(
            self.n_features,
            torch.Size([self.n_outputs]),
            lengthscale_bounds=_LENGTHSCALE_BOUNDS,
            outputscale_bounds=OUTPUTSCALE_BOUNDS,
            lengthscale_prior=self.kernel_prior(),
        )
        self.constant = torch.nn.Parameter(torch.zeros(self.n_outputs, dtype=torch.float64))
        self.inducing = torch.nn.Parameter(
            torch.zeros(self.n_outputs, 0, self.n_features, dtype=torch.float64),
            requires_grad=self.options.learn_inducing,
        )
        self.register_buffer("train_x", torch.zeros(0, self.n_features), persistent=False)
        self.register_buffer("train_y", torch.zeros(self.n_outputs, 0), persistent=False)
        self.to(torch.float64)
        self.reset_hyperparameters()
        self.eval()

    # ------------------------------------------------------------------ setup
    def reset_hyperparameters(self) -> None:
        """Set length scales to sqrt(D), amplitudes and noise to their initial values, means to 0.

        The inducing inputs are kept. All values are in standardised units.
        """
        kernel = self.covar_module
        kernel.base_kernel.lengthscale = torch.full_like(
            kernel.base_kernel.lengthscale, math.sqrt(self.n_features)
        )
        kernel.outputscale = torch.full_like(kernel.outputscale, self.options.outputscale)
        self.likelihood.noise = self.options.noise
        self.constant.data.zero_()

    def _load_from_state_dict(self, state_dict: Any, prefix: str, *args: Any) -> None:
        """Resize the inducing inputs to the saved ones before the state is copied."""
        saved = state_dict.get(prefix + "inducing")
        if isinstance(saved, Tensor) and saved.shape != self.inducing.shape:
            self.inducing.data = self.inducing.data.new_zeros(saved.shape)
        super()._load_from_state_dict(state_dict, prefix, *args)

    @property
    def is_fitted(self) -> bool:
        """Whether training data has been set with `fit` or `condition`."""
        return self.train_y.shape[-1] > 0

    @property
    def n_train(self) -> int:
        """Number of training samples with non-zero weight held by the expert."""
        return int(self.train_y.shape[-1])

    @property
    def n_inducing(self) -> int:
        """Inducing points per output in use, `m` (0 before the first fit)."""
        return int(self.inducing.shape[1])

    def _target_inducing(self, n_kept: int) -> int:
        """The `m` of `n_inducing` for `n_kept` samples of non-zero weight."""
        asked = self.options.n_inducing
        rows = self.options.hyper_rows
        return min(DEFAULT_N_INDUCING if asked is None else asked, n_kept, rows or n_kept)

    def _hyper_subset(self) -> Tensor | None:
        """Rows the bound is maximised on (`hyper_rows` of them, uniformly), None for all.

        The subset is a function of the number of samples only, so the same data gives the
        same subset.
        """
        k, n = self.options.hyper_rows, self.n_train
        if k is None or n <= k:
            return None
        g = torch.Generator().manual_seed(n)
        return torch.randperm(n, generator=g)[:k].sort().values.to(self.train_x.device)

    def condition(self, X: Any, Y: Any, weights: Any | None = None) -> Self:
        """Set the training data without changing the hyperparameters.

        The inducing inputs are kept when their number is still ``min(n_inducing, n)`` for
        the `n` samples of non-zero weight, and chosen by `select_inducing` otherwise (e.g.
        on the first call). The arguments, result and errors are those of
        `WeightedExpert.condition`.
        """
        x, y, _ = self.weighted_rows(X, Y, weights)
        m = self._target_inducing(x.shape[0])
        self.train_x = self.x_scaler(x).to(self.jitter)
        self.train_y = self.y_scaler(y).T.contiguous().to(self.jitter)
        if self.n_inducing != m:
            self._select(m, self._hyper_subset())
        return self

    def _select(self, m: int, rows: Tensor | None) -> None:
        kernel = self.covar_module
        x, w = self.train_x, self.likelihood.weights
        if rows is not None:
            x, w = x[rows], w[rows]
        with torch.no_grad():
            z = select_inducing(
                x,
                w,
                kernel.base_kernel.lengthscale.reshape(self.n_outputs, self.n_features),
                kernel.outputscale,
                m,
            )
            self.inducing.data = z

    # ---------------------------------------------------------------- fitting
    def _fit_hyperparameters(self, max_iter: int) -> None:
        """`fit`'s search: choose the inducing inputs, then maximise the bound."""
        rows = self._hyper_subset()
        self._select(self._target_inducing(self.n_train), rows)
        self._optimise(max_iter, rows)

    def _kernel_parts(self) -> tuple[Tensor, Tensor, Tensor]:
        """`1 / l^2` `(E, 1, D)`, the signal variances `(E,)` and `K_uu + jitter` `(E, m, m)`."""
        kernel = self.covar_module
        inv_l2 = kernel.base_kernel.lengthscale.square().reciprocal()
        s = kernel.outputscale
        z = self.inducing
        return inv_l2, s, _se(z, z, inv_l2, s)

    def marginal_log_likelihood(self, jitter: float | None = None) -> Tensor:
        r"""Weighted collapsed bound (plus log prior) per output, divided by `n`.

        :math:`\log \mathcal N(y; c, Q + \sigma^2 W^{-1}) - \tfrac12 \sum_i w_i
        (k_{ii} - q_{ii}) / \sigma^2`, plus the likelihood's `WeightCorrection` and the log
        priors, over the number of training samples: the counterpart of
        `GPExpert.marginal_log_likelihood`, which it equals when the inducing inputs are the
        training inputs (up to the jitter) and bounds from below otherwise.

        The result and errors are those of `WeightedExpert.marginal_log_likelihood`.

        Args:
            jitter: Diagonal jitter of :math:`K_{uu}`, relative to the signal variance;
                defaults to the expert's current jitter.
        """
        if not self.is_fitted:
            raise NotFittedError("SparseGPExpert has no training data; call fit first.")
        eps = float(self.jitter) if jitter is None else float(jitter)
        return self._bound(self.train_x, self.train_y, self.likelihood.weights, eps)

    def _bound(self, x: Tensor, y: Tensor, w: Tensor, eps: float) -> Tensor:
        """The bound of `marginal_log_likelihood` on the rows `x (n, D)`, `y (E, n)`, `w (n,)`."""
        n = y.shape[-1]
        inv_l2, s, kuu = self._kernel_parts()
        eye = torch.eye(kuu.shape[-1], dtype=kuu.dtype, device=kuu.device)
        lu = torch.linalg.cholesky(kuu + eps * s[:, None, None] * eye)
        a = torch.linalg.solve_triangular(lu, _se(self.inducing, x, inv_l2, s), upper=False)
        r = y - self.constant[:, None]
        a_w = a * w
        noise = self.likelihood.noise[..., 0]
        f = _factors(lu, a_w @ a.mT, a_w @ r[..., None], noise)
        quad = (w * r.square()).sum(-1) / noise - f.v.square().sum((-2, -1))
        logdet_b = 2 * f.lb.diagonal(dim1=-2, dim2=-1).log().sum(-1)
        logdet = n * noise.log() - w.log().sum() + logdet_b
        trace = (s * w.sum() - (a_w * a).sum((-2, -1))) / noise
        res = -0.5 * (n * math.log(2 * math.pi) + logdet + quad + trace)
        res = res + weight_correction(w, noise)
        for _, module, prior, closure, _ in self.covar_module.named_priors():
            log_p = prior.log_prob(closure(module))
            res = res + log_p.reshape(self.n_outputs, -1).sum(-1)
        return res / n

    def _optimise(self, max_iter: int, rows: Tensor | None) -> None:
        params = [p for p in self.parameters() if p.requires_grad]
        start = [p.detach().clone() for p in params]
        x, y, w = self.train_x, self.train_y, self.likelihood.weights
        data = (x, y, w) if rows is None else (x[rows], y[:, rows], w[rows])
        for jitter in _JITTERS:
            try:
                ok = self._lbfgs(params, max_iter, jitter, data)
            except (torch.linalg.LinAlgError, RuntimeError):
                ok = False
            if ok:
                self.jitter.fill_(jitter)
                return
            with torch.no_grad():
                for p, p0 in zip(params, start, strict=True):
                    p.copy_(p0)
        self.jitter.fill_(_JITTERS[-1])
        warnings.warn(
            "sparse GP hyperparameter optimisation failed at every jitter level; the previous "
            "hyperparameters are kept.",
            RuntimeWarning,
            stacklevel=4,  # the caller of `fit`
        )

    def _lbfgs(
        self,
        params: list[torch.nn.Parameter],
        max_iter: int,
        jitter: float,
        data: tuple[Tensor, Tensor, Tensor],
    ) -> bool:
        """Minimise the negative bound on `data`; return whether everything stayed finite."""
        optimiser = torch.optim.LBFGS(
            params,
            lr=1.0,
            max_iter=max_iter,
            line_search_fn="strong_wolfe",
            tolerance_grad=1e-6,
            tolerance_change=1e-9,
        )

        def closure() -> Tensor:
            optimiser.zero_grad()
            loss = -self._bound(*data, jitter).sum()
            loss.backward()
            return loss

        optimiser.step(closure)
        with torch.no_grad():
            final = -self._bound(*data, jitter).sum()
        return bool(torch.isfinite(final)) and all(bool(torch.isfinite(p).all()) for p in params)

    # ------------------------------------------------------------- prediction
    def _state_key(self) -> tuple[tuple[Tensor, int, int], ...]:
        """Every tensor the posterior depends on, its storage and its version.

        Any write changes the key: in place (the version), by ``.data =`` (the storage, as
        the old one is alive when the new one is made) or by assignment (the tensor).
        """
        tensors = [*self.parameters(), *self.buffers(), self.likelihood.weights]
        return tuple((t, t.data_ptr(), t._version) for t in tensors)

    def _posterior(self) -> tuple[_Factors, Tensor, Tensor]:
        """The posterior factors, `1 / l^2` and the signal variances (no gradient).

        Kept until a parameter, buffer or the training data changes: the E-step of EM
        predicts and leaves one out with the same posterior.
        """
        if not self.is_fitted:
            raise NotFittedError("SparseGPExpert has no training data; call fit first.")
        key = self._state_key()
        cached = self.__dict__.get("_cached_posterior")
        if cached is not None and len(cached[0]) == len(key):
            same = all(a[0] is b[0] and a[1:] == b[1:] for a, b in zip(cached[0], key, strict=True))
            if same:
                return cached[1]
        result = self._compute_posterior()
        self.__dict__["_cached_posterior"] = (key, result)
        return result

    def _compute_posterior(self) -> tuple[_Factors, Tensor, Tensor]:
        with torch.no_grad():
            inv_l2, s, kuu = self._kernel_parts()
            m = kuu.shape[-1]
            eye = torch.eye(m, dtype=kuu.dtype, device=kuu.device)
            lu = torch.linalg.cholesky(kuu + float(self.jitter) * s[:, None, None] * eye)
            gram = kuu.new_zeros(self.n_outputs, m, m)
            proj = kuu.new_zeros(self.n_outputs, m, 1)
            r = self.train_y - self.constant[:, None]
            w = self.likelihood.weights
            for rows in _blocks(self.n_train):
                kuf = _se(self.inducing, self.train_x[rows], inv_l2, s)
                a = torch.linalg.solve_triangular(lu, kuf, upper=False)
                a_w = a * w[rows]
                gram += a_w @ a.mT
                proj += a_w @ r[:, rows, None]
            return _factors(lu, gram, proj, self.likelihood.noise[..., 0]), inv_l2, s

    def predict(self, X: Any, *, include_noise: bool = True) -> Normal:
        """Predictive distribution of the outputs at `X` (the SGPR predictive).

        The arguments, result and errors are those of `WeightedExpert.predict`.
        """
        f, inv_l2, s = self._posterior()
        x = self.x_scaler(as_matrix("features X", X, n_cols=self.n_features)).to(self.jitter)
        means, variances = [], []
        with torch.no_grad():
            for rows in _blocks(x.shape[0]):
                a = torch.linalg.solve_triangular(
                    f.lu, _se(self.inducing, x[rows], inv_l2, s), upper=False
                )
                g = torch.linalg.solve_triangular(f.lb, a, upper=False)
                means.append(self.constant[:, None] + (g * f.v).sum(-2))
                variances.append(s[:, None] - a.square().sum(-2) + g.square().sum(-2))
            mean, var = torch.cat(means, -1), torch.cat(variances, -1)
            if include_noise:
                var = var.clamp_min(0.0) + self.likelihood.noise
        return self.output_normal(mean, var)

    def loo_predict(self) -> Normal:
        r"""Leave-one-out predictive distribution of every training sample.

        The exact leave-one-out predictive of the SGPR model with the inducing inputs and
        hyperparameters held fixed: for sample `i`, the SGPR predictive at :math:`x_i`
        (noise of weight 1) of the model conditioned on every *other* sample. With
        :math:`A = Q + \Lambda`, :math:`\mu_{-i} = y_i - [A^{-1} r]_i / [A^{-1}]_{ii}` and
        the latent variance :math:`1/[A^{-1}]_{ii} - \lambda_i + k_{ii} - q_{ii}`, where
        :math:`\operatorname{diag}(A^{-1})` comes from the Woodbury identity through the
        `m x m` factors: with :math:`g_i = L_B^{-1} L_u^{-1} k_{ui}` and the leverage
        :math:`h_i = \lVert g_i \rVert^2 / \lambda_i`, :math:`\mu_{-i} = y_i - (r_i -
        g_i^\top v) / (1 - h_i)` and :math:`1/[A^{-1}]_{ii} = \lambda_i / (1 - h_i)`. It costs
        :math:`O(N m^2)`, like one bound evaluation. (The inducing inputs were chosen with
        sample `i` among the candidates; that choice is not undone.) The result and errors are
        those of `WeightedExpert.loo_predict`.
        """
        f, inv_l2, s = self._posterior()
        noise = self.likelihood.noise  # (E, 1)
        lam = noise / self.likelihood.weights  # (E, n)
        means, variances = [], []
        with torch.no_grad():
            for rows in _blocks(self.n_train):
                a = torch.linalg.solve_triangular(
                    f.lu, _se(self.inducing, self.train_x[rows], inv_l2, s), upper=False
                )
                g = torch.linalg.solve_triangular(f.lb, a, upper=False)
                y = self.train_y[:, rows]
                r = y - self.constant[:, None]
                h = (g.square().sum(-2) / lam[:, rows]).clamp_max(1.0 - 1e-12)
                means.append(y - (r - (g * f.v).sum(-2)) / (1.0 - h))
                latent = lam[:, rows] * h / (1.0 - h) + s[:, None] - a.square().sum(-2)
                variances.append(latent.clamp_min(MIN_VARIANCE) + noise)
        return self.output_normal(torch.cat(means, -1), torch.cat(variances, -1))

    # ------------------------------------------------------------ relevances
    @property
    def lengthscales(self) -> Tensor:
        """ARD length scales in standardised feature units, `(E, D)`; short means relevant."""
        return self.covar_module.base_kernel.lengthscale.detach().reshape(
            self.n_outputs, self.n_features
        )
