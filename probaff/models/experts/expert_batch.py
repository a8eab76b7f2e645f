r"""Exact GP experts fitted and evaluated together, as one batch of shape `(M, E)`.

A mixture's M-step refits `M` exact `GPExpert`\ s, each `E` independent GPs. At the sizes
of the push-model studies one evaluation of an expert's marginal likelihood is mostly fixed
per-call overhead, so evaluating the `M` experts one by one costs about `M` times one batched
evaluation. `fit_exact_experts` runs every expert's own L-BFGS (exactly the optimiser of
`GPExpert.fit`, with its jitter fallback) in lock step: each optimiser is a coroutine
(`GPExpert.optimisation`) that yields the points it wants evaluated, and each round of
pending evaluations is computed as one batched marginal likelihood
(`stacked_log_likelihood`). The iterates are those of separate fits, up to the rounding of
batched arithmetic, so the fitted hyperparameters and everything downstream are the same.
`predict_exact_experts` computes every expert's predictive distribution in one batch.

Experts hold different numbers of samples (samples of weight 0 are removed). Their training
sets are padded to the longest with rows that are cut out of the problem exactly: a padded
row has no covariance with any other row, unit variance and a zero residual, and it is left
out of the weight correction and the normalisation, so each expert's value is that of
`GPExpert.marginal_log_likelihood`.
"""

from __future__ import annotations

import contextlib
import math
import warnings
from collections.abc import Iterator, Sequence
from contextvars import ContextVar
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import torch
from linear_operator.utils.errors import NanError, NotPSDError
from torch import Tensor
from torch.distributions import Normal

from probaff.errors import NotFittedError
from probaff.models.experts.expert_base import MIN_VARIANCE, out_of_sample
from probaff.models.experts.gaussian_density import loo_moments
from probaff.models.experts.gp_expert import FitRequest, GPExpert
from probaff.models.lbfgs import Evaluation, lockstep

__all__ = [
    "ExpertStack",
    "batching_enabled",
    "fit_exact_experts",
    "per_expert_fits",
    "predict_exact_experts",
    "predict_exact_experts_out_of_sample",
    "stacked_log_likelihood",
]

# Whether `fit_exact_experts` and `predict_exact_experts` batch the experts (see
# `per_expert_fits`).
_BATCHED: ContextVar[bool] = ContextVar("probaff_batched_experts", default=True)

# Jitter levels tried after the plain factorisation (as `psd_cholesky`).
_MAX_TRIES = 3
# Most entries of one block of cross-covariances when predicting (bounds the memory).
_PREDICT_BLOCK = 2**24
# An expert is batched with larger ones only if it holds this share of their samples...
_GROUP_RATIO = 0.75
# ... or if the largest holds at most this many (then fixed per-call costs dominate).
_GROUP_SMALL = 64
# Exponent of the SE kernel at padded rows: its exponential is 0 in every float type.
_PADDED = -1e4


@contextlib.contextmanager
def per_expert_fits() -> Iterator[None]:
    """Fit and predict the experts one at a time inside the block (the reference path).

    `MixtureOfGPExperts.fit_experts` and `expert_predictions` then call `GPExpert.fit` and
    `GPExpert.predict` expert by expert, as before batching; benchmarks compare the two.
    """
    token = _BATCHED.set(False)
    try:
        yield
    finally:
        _BATCHED.reset(token)


def batching_enabled() -> bool:
    """Whether experts are batched here (False inside `per_expert_fits`)."""
    return _BATCHED.get()


@dataclass(frozen=True)
class ExpertStack:
    """The standardised training sets of `B` experts, padded to the longest, `n` rows.

    Attributes:
        x: Inputs, `(B, n, D)`; padded rows are 0.
        y: Targets, `(B, E, n)`; padded entries are 0.
        weights: Sample weights, `(B, n)`; padded rows have weight 1.
        mask: 1 for real rows, 0 for padded ones, `(B, n)`.
        counts: Real rows per expert, `(B,)`.
    """

    x: Tensor
    y: Tensor
    weights: Tensor
    mask: Tensor
    counts: Tensor

    @classmethod
    def of(cls, experts: Sequence[GPExpert]) -> ExpertStack:
        """Stack the training data that the fitted `experts` hold.

        Raises:
            NotFittedError: If an expert has no training data.
        """
        for expert in experts:
            if not expert.is_fitted:
                raise NotFittedError("GPExpert has no training data; call fit first.")
        sizes = [expert.n_train for expert in experts]
        n, ref = max(sizes), experts[0]
        b, e, d = len(experts), ref.n_outputs, ref.n_features
        x = ref.jitter.new_zeros(b, n, d)
        y = ref.jitter.new_zeros(b, e, n)
        weights = ref.jitter.new_ones(b, n)
        mask = ref.jitter.new_zeros(b, n)
        for i, (expert, size) in enumerate(zip(experts, sizes, strict=True)):
            x[i, :size] = expert.gp.train_inputs[0]
            y[i, :, :size] = expert.gp.train_targets
            weights[i, :size] = expert.likelihood.weights
            mask[i, :size] = 1.0
        counts = ref.jitter.new_tensor(sizes)
        return cls(x, y, weights, mask, counts)

    def select(self, rows: Sequence[int]) -> ExpertStack:
        """The stack of the experts `rows` only, padded to the longest of them."""
        n = int(self.counts[list(rows)].max())
        if list(rows) == list(range(self.x.shape[0])) and n == self.x.shape[1]:
            return self
        idx = torch.as_tensor(list(rows), device=self.x.device)
        return ExpertStack(
            self.x[idx, :n],
            self.y[idx, :, :n],
            self.weights[idx, :n],
            self.mask[idx, :n],
            self.counts[idx],
        )

    def groups(self, rows: Sequence[int] | None = None) -> list[list[int]]:
        """Experts `rows` (all if None) in groups of similar size, largest first.

        A batch costs its longest member's size for every member, so an expert joins a
        group only if it holds at least `_GROUP_RATIO` of the group's largest size (or the
        group is small enough for fixed per-call costs to dominate).
        """
        order = sorted(
            range(self.x.shape[0]) if rows is None else rows,
            key=lambda j: -int(self.counts[j]),
        )
        out: list[list[int]] = []
        for j in order:
            size = int(self.counts[j])
            if out:
                top = int(self.counts[out[-1][0]])
                if size >= _GROUP_RATIO * top or top <= _GROUP_SMALL:
                    out[-1].append(j)
                    continue
            out.append([j])
        return out

    @property
    def noise_scale(self) -> Tensor:
        """``1 / w_i`` on real rows and 0 on padded ones, `(B, 1, n)`."""
        return (self.mask / self.weights)[:, None, :]


def _raw_parameters(experts: Sequence[GPExpert]) -> dict[str, Tensor]:
    """Every expert's trainable raw parameters, stacked by name, each `(B, *shape)`."""
    names = [name for name, _ in experts[0].named_trainable()]
    params = [dict(e.named_trainable()) for e in experts]
    return {n: torch.stack([p[n] for p in params]) for n in names}


def _floors(experts: Sequence[GPExpert]) -> Tensor:
    """Every expert's noise-variance floor, `(B, E)`."""
    return torch.stack([e.likelihood.noise_covar.floor[..., 0] for e in experts])


def _hyperparameters(
    ref: GPExpert, raw: dict[str, Tensor], floor: Tensor
) -> tuple[Tensor, Tensor, Tensor, Tensor]:
    """Length scales `(B, E, D)`, amplitudes `(B, E)`, noise `(B, E)`, means `(B, E)`.

    From the raw parameters `raw` of `B` experts (`_raw_parameters`, or the batched flat
    vectors of `_split_flat`), through the constraints of `ref`; differentiable in `raw`.
    """
    kernel, noise_model = ref.gp.covar_module, ref.likelihood.noise_covar
    mean = ref.gp.mean_module
    lengthscale = kernel.base_kernel.raw_lengthscale_constraint.transform(
        raw["gp.covar_module.base_kernel.raw_lengthscale"][..., 0, :]
    )
    outputscale = kernel.raw_outputscale_constraint.transform(
        raw["gp.covar_module.raw_outputscale"]
    )
    noise = noise_model.raw_noise_constraint.transform(
        raw["likelihood.noise_covar.raw_noise"][..., 0]
    )
    constant = raw["gp.mean_module.raw_constant"]
    if hasattr(mean, "raw_constant_constraint"):
        constant = mean.raw_constant_constraint.transform(constant)
    return lengthscale, outputscale, noise + floor, constant


def _split_flat(ref: GPExpert, flat: Tensor) -> dict[str, Tensor]:
    """The raw parameters of `B` experts from their flat vectors `(B, P)` (views).

    The order is that of `GPExpert.trainable`, which `GPExpert.optimisation` flattens.
    """
    out, offset = {}, 0
    for name, p in ref.named_trainable():
        out[name] = flat[:, offset : offset + p.numel()].view(-1, *p.shape)
        offset += p.numel()
    return out


def _se_kernel(x1: Tensor, x2: Tensor, u: Tensor, mask1: Tensor | None = None) -> Tensor:
    """``exp(-sum_d u_d (x1_id - x2_jd)^2 / 2)`` for `x1: (B, n, D)`, `x2: (B, k, D)`.

    `u` holds the inverse squared length scales, `(B, E, D)`; the result is `(B, E, n, k)`.
    With the inputs scaled, ``s = x sqrt(u)``, the exponent is ``s_i . s_j - |s_i|^2 / 2 -
    |s_j|^2 / 2`` (the quadratic expansion that gpytorch's ``sq_dist`` uses), which one
    matrix product of ``[s_i, -|s_i|^2 / 2, 1]`` and ``[s_j, 1, -|s_j|^2 / 2]`` gives
    whole, so the `(n, k)` matrices are written once and exponentiated in place. Rows of
    `x1` where `mask1` `(B, n)` is 0 (and, when `x2` is `x1`, those columns) are 0.
    """
    root = u.sqrt()[:, :, None, :]  # (B, E, 1, D)
    s1 = x1[:, None] * root  # (B, E, n, D)
    half1 = s1.square().sum(-1, keepdim=True).mul_(-0.5)  # (B, E, n, 1)
    if mask1 is not None:  # exp(_PADDED) is 0: the masked rows drop out of the product
        half1 = torch.where(mask1[:, None, :, None] > 0, half1, _PADDED)
    one1 = torch.ones_like(half1)
    if x2 is x1:
        s2, half2, one2 = s1, half1, one1
    else:
        s2 = x2[:, None] * root
        half2 = s2.square().sum(-1, keepdim=True).mul_(-0.5)
        one2 = torch.ones_like(half2)
    exponent = torch.cat([s1, half1, one1], -1) @ torch.cat([s2, one2, half2], -1).mT
    if x2 is x1:  # exactly 0 on the diagonal (_PADDED on masked rows)
        diagonal = exponent.diagonal(dim1=-2, dim2=-1)
        if mask1 is None:
            diagonal.zero_()
        else:
            diagonal.copy_(torch.where(mask1[:, None, :] > 0, 0.0, _PADDED))
    return exponent.clamp_max_(0.0).exp_()


def _cholesky_per_member(a: Tensor, jitter: Tensor) -> tuple[Tensor, Tensor, Tensor]:
    """Lower Cholesky factors of `a: (B, E, n, n)` with the jitter policy of `psd_cholesky`.

    Expert `b` (all `E` of its matrices together, as one call of `psd_cholesky` would) is
    factorised as it is, then with ``jitter[b] * 10**k`` added for ``k < 3`` until it works.

    Returns:
        The factors `(B, E, n, n)` (identity for failed experts), and per expert `(B,)`
        whether its matrix held NaN and whether it failed at every jitter.
    """
    nan = torch.isnan(a.diagonal(dim1=-2, dim2=-1).sum(-1) + a.sum((-2, -1))).any(-1)
    eye = torch.eye(a.shape[-1], dtype=a.dtype, device=a.device)
    if bool(nan.any()):
        a = torch.where(nan[:, None, None, None], eye, a)
    chol, info = torch.linalg.cholesky_ex(a)
    failed = (info != 0).any(-1)
    for k in range(_MAX_TRIES):
        if not bool(failed.any()):
            break
        idx = failed.nonzero()[:, 0]
        shift = (jitter[idx] * 10.0**k)[:, None, None, None] * eye
        chol_k, info_k = torch.linalg.cholesky_ex(a[idx] + shift)
        chol = chol.index_copy(0, idx, chol_k)
        failed = failed.index_copy(0, idx, (info_k != 0).any(-1))
    if bool(failed.any()):
        chol = torch.where(failed[:, None, None, None], eye, chol)
    return chol, nan, failed & ~nan


def _train_factor(
    stack: ExpertStack,
    hyper: tuple[Tensor, Tensor, Tensor, Tensor],
    jitter: Tensor,
) -> tuple[Tensor, Tensor, Tensor, Tensor, Tensor, Tensor]:
    """Factorise the padded training covariances ``K + sigma^2 W^{-1}``, `(B, E, n, n)`.

    A padded row has no covariance with any other row, unit variance and a zero residual.

    Returns:
        The SE kernel without amplitude (0 at padded rows) `(B, E, n, n)`, the Cholesky
        factors, the residuals `(B, E, n)`, `alpha = A^{-1} r` `(B, E, n)`, and the NaN and
        failure flags `(B,)` of `_cholesky_per_member`.
    """
    lengthscale, outputscale, noise, constant = hyper
    kse = _se_kernel(stack.x, stack.x, lengthscale.square().reciprocal(), stack.mask)
    a = kse * outputscale[..., None, None]
    diag = noise[..., None] * stack.noise_scale + (1.0 - stack.mask)[:, None, :]
    a.diagonal(dim1=-2, dim2=-1).add_(diag)
    chol, nan, failed = _cholesky_per_member(a, jitter)
    resid = (stack.y - constant[..., None]) * stack.mask[:, None, :]
    half = torch.linalg.solve_triangular(chol, resid[..., None], upper=False)
    alpha = torch.linalg.solve_triangular(chol.mT, half, upper=True)[..., 0]
    return kse, chol, resid, alpha, nan, failed


class _StackedLogDensity(torch.autograd.Function):
    r"""``log N(y; c, os K_se(u) + noise W^{-1})`` per expert and output, fused.

    Inputs are the inverse squared length scales `u: (B, E, D)`, the amplitudes, noise
    variances and means `(B, E)`, the per-expert jitters `(B,)` and the `ExpertStack`. The
    gradient is the closed form of `probaff.models.experts.gaussian_density` carried through the
    SE kernel by hand: with :math:`G = \tfrac12(\alpha\alpha^\top - A^{-1})` and
    :math:`H = G \circ K`, :math:`\partial/\partial u_d = -\sum_i (H 1)_i x_{id}^2 +
    \sum_i x_{id} (H x)_{id}`. Experts that cannot be factorised get the value 0 and are
    named by the two returned flags instead of raising.
    """

    @staticmethod
    def forward(
        ctx: Any,
        u: Tensor,
        outputscale: Tensor,
        noise: Tensor,
        constant: Tensor,
        jitter: Tensor,
        stack: ExpertStack,
    ) -> tuple[Tensor, Tensor, Tensor]:
        hyper = (u.rsqrt(), outputscale, noise, constant)
        kse, chol, resid, alpha, nan, failed = _train_factor(stack, hyper, jitter)
        ctx.save_for_backward(kse, chol, alpha, outputscale)
        ctx.stack = stack
        logdet = 2.0 * chol.diagonal(dim1=-2, dim2=-1).log().sum(-1)
        n = resid.shape[-1]
        out = -0.5 * ((resid * alpha).sum(-1) + logdet + n * math.log(2.0 * math.pi))
        ctx.mark_non_differentiable(nan, failed)
        return out, nan, failed

    @staticmethod
    def backward(ctx: Any, grad: Tensor, *_: Tensor) -> tuple[Tensor | None, ...]:
        kse, chol, alpha, outputscale = ctx.saved_tensors
        stack: ExpertStack = ctx.stack
        half = 0.5 * grad
        n = chol.shape[-1]
        ainv = torch.cholesky_inverse(chol)
        diag_g = half[..., None] * (alpha.square() - ainv.diagonal(dim1=-2, dim2=-1))
        grad_noise = (diag_g * stack.noise_scale).sum(-1)
        # alpha alpha^T - A^{-1} (= 2 G / grad) in place, then its product with K_se.
        col = alpha.reshape(-1, n, 1)
        g = ainv.view(-1, n, n).baddbmm_(col, col.mT, beta=-1.0).view_as(kse).mul_(kse)
        x = stack.x
        # (G o K_se) [x, 1]: the row sums ride along as a last column of ones.
        hx = g @ torch.cat([x, torch.ones_like(x[..., :1])], -1)[:, None]  # (B, E, n, D + 1)
        rows = hx[..., -1]  # (B, E, n)
        grad_os = half * rows.sum(-1)
        scale = (half * outputscale)[..., None]
        grad_u = scale * ((hx[..., :-1] * x[:, None]).sum(-2) - rows @ x.square())
        grad_c = grad * alpha.sum(-1)
        return grad_u, grad_os, grad_noise, grad_c, None, None


def stacked_log_likelihood(
    experts: Sequence[GPExpert], stack: ExpertStack | None = None, jitter: Tensor | None = None
) -> tuple[Tensor, Tensor, Tensor]:
    """Every expert's `GPExpert.marginal_log_likelihood`, computed as one batch.

    Args:
        experts: `B` fitted experts with the same `D`, `E` and options.
        stack: Their training data (`ExpertStack.of(experts)` if None).
        jitter: First fallback jitter of each expert, `(B,)`; their current ones if None.

    Returns:
        The weighted log marginal likelihood plus log prior over `n` per expert and output,
        `(B, E)`, differentiable in every expert's hyperparameters (0 for an expert that
        failed), and per expert `(B,)` whether its covariance held NaN and whether it could
        not be factorised at any jitter.
    """
    stack = ExpertStack.of(experts) if stack is None else stack
    if jitter is None:
        jitter = torch.stack([e.jitter for e in experts])
    hyper = _hyperparameters(experts[0], _raw_parameters(experts), _floors(experts))
    return _stacked_value(experts[0], hyper, stack, jitter)


def _stacked_value(
    ref: GPExpert,
    hyper: tuple[Tensor, Tensor, Tensor, Tensor],
    stack: ExpertStack,
    jitter: Tensor,
) -> tuple[Tensor, Tensor, Tensor]:
    """`stacked_log_likelihood` from the hyperparameters `hyper` (`_hyperparameters`)."""
    lengthscale, outputscale, noise, constant = hyper
    u = lengthscale.square().reciprocal()
    value, nan, failed = _StackedLogDensity.apply(u, outputscale, noise, constant, jitter, stack)
    n = stack.counts[:, None]  # (B, 1)
    padded = stack.mask.shape[-1] - n
    value = value + 0.5 * padded * math.log(2.0 * math.pi)
    w_real = stack.weights.log().mul(stack.mask).sum(-1, keepdim=True)  # (B, 1)
    unused = (stack.mask * (1.0 - stack.weights)).sum(-1, keepdim=True)  # (B, 1)
    value = value + 0.5 * (unused * torch.log(2 * math.pi * noise) - w_real)
    prior = getattr(ref.gp.covar_module.base_kernel, "lengthscale_prior", None)
    if prior is not None:
        value = value + prior.log_prob(lengthscale).sum(-1)
    bad = nan | failed
    if bool(bad.any()):
        value = torch.where(bad[:, None], torch.zeros_like(value), value)
    return value / n, nan, failed


@dataclass(frozen=True)
class _Batch:
    """What every round of a lockstep fit shares: the experts, their data and noise floors."""

    experts: Sequence[GPExpert]
    stack: ExpertStack
    floor: Tensor
    # The stacks of the groups met so far (a group's experts recur round after round).
    selected: dict[tuple[int, ...], ExpertStack] = field(
        default_factory=dict, compare=False, repr=False
    )

    def evaluate(self, batch: dict[int, FitRequest]) -> dict[int, Evaluation | BaseException]:
        """Every pending evaluation of `GPExpert.optimisation` in `batch`, computed together.

        The flat parameter vectors of each group of similar-sized experts form one leaf
        tensor `(B, P)`, so the experts' own parameters are not touched and one backward
        pass gives every gradient.

        Args:
            batch: Each pending expert's request ``(jitter, x)``, by index.

        Returns:
            Each expert's ``(loss, grad)`` as `GPExpert.evaluate` computes it, or the
            ``NanError`` or ``NotPSDError`` it would raise.
        """
        ref = self.experts[0]
        out: dict[int, Evaluation | BaseException] = {}
        for rows in self.stack.groups(list(batch)):
            flat = torch.from_numpy(np.stack([batch[j][1] for j in rows]))
            flat = flat.to(device=ref.device, dtype=ref.jitter.dtype).requires_grad_(True)
            hyper = _hyperparameters(ref, _split_flat(ref, flat), self.floor[rows])
            jitter = self.stack.x.new_tensor([batch[j][0] for j in rows])
            key = tuple(rows)
            if key not in self.selected:
                self.selected[key] = self.stack.select(rows)
            value, nan, failed = _stacked_value(ref, hyper, self.selected[key], jitter)
            loss = -value.sum(-1)  # (B,)
            (grad,) = torch.autograd.grad(loss.sum(), flat)
            losses, grads = loss.detach().cpu().numpy(), grad.cpu().numpy()
            for i, j in enumerate(rows):
                if bool(nan[i]):
                    out[j] = NanError("the covariance matrix holds NaN.")
                elif bool(failed[i]):
                    out[j] = NotPSDError(
                        f"the covariance matrix is not positive definite even with jitter "
                        f"{batch[j][0]}."
                    )
                else:
                    out[j] = (float(losses[i]), np.asarray(grads[i], dtype=np.float64))
        return out


def fit_exact_experts(
    experts: Sequence[GPExpert],
    X: Tensor,
    Y: Tensor,
    weights: Tensor,
    *,
    max_iter: int | None = None,
) -> None:
    """Fit every expert on its weighted data, as `GPExpert.fit` would one by one.

    Each expert runs its own L-BFGS with its own jitter fallback (`GPExpert.optimisation`);
    their evaluations are batched (see the module docstring). Inside `per_expert_fits` the
    experts are fitted one after another by `GPExpert.fit`.

    Args:
        experts: `M` experts with the same `D`, `E` and options.
        X: Expert features, `(N, D)`.
        Y: Targets, `(N, E)`.
        weights: Non-negative weight of each sample for each expert, `(N, M)`.
        max_iter: L-BFGS iterations per expert; defaults to each expert's `max_iter`.

    Raises:
        InputError: On malformed inputs, or an expert whose weights are all zero.
    """
    if not batching_enabled():
        for j, expert in enumerate(experts):
            expert.fit(X, Y, weights[:, j], max_iter=max_iter)
        return
    for j, expert in enumerate(experts):
        expert.condition(X, Y, weights[:, j])
    fits = _Batch(experts, ExpertStack.of(experts), _floors(experts).detach())
    runs = [e.optimisation(e.max_iter if max_iter is None else int(max_iter)) for e in experts]
    with torch.enable_grad():
        ok = lockstep(runs, fits.evaluate)
    if not all(ok):
        warnings.warn(
            "GP hyperparameter optimisation failed at every jitter level; the previous "
            "hyperparameters are kept.",
            RuntimeWarning,
            stacklevel=3,
        )


def _predict_block(
    stack: ExpertStack,
    z_test: Tensor,
    hyper: tuple[Tensor, Tensor, Tensor, Tensor],
    alpha: Tensor,
    chol: Tensor,
) -> tuple[Tensor, Tensor]:
    """Latent mean and variance `(B, E, k)` at standardised inputs `z_test: (B, k, D)`.

    `hyper` is `_hyperparameters`' result, `chol` the training factors `(B, E, n, n)` and
    `alpha` the training residuals solved against them, `(B, E, n)`.
    """
    lengthscale, outputscale, _, constant = hyper
    u = lengthscale.square().reciprocal()
    cross = _se_kernel(stack.x, z_test, u, stack.mask)
    cross.mul_(outputscale[..., None, None])  # (B, E, n, k)
    mean = constant[..., None] + (alpha[..., None, :] @ cross)[..., 0, :]
    v = torch.linalg.solve_triangular(chol, cross, upper=False)
    var = outputscale[..., None] - v.square().sum(-2)
    return mean, var


def predict_exact_experts(
    experts: Sequence[GPExpert], X: Tensor, *, include_noise: bool = True
) -> Normal:
    """Every expert's `GPExpert.predict` at the same inputs, computed as one batch.

    Args:
        experts: `M` fitted experts with the same `D`, `E` and options.
        X: Expert features, `(N, D)`, on the experts' device.
        include_noise: Add each expert's observation noise (weight 1).

    Returns:
        Normals with loc and scale `(N, M, E)`, in output units.

    Raises:
        NotFittedError: If an expert has no training data.
        NotPSDError: If a training covariance cannot be factorised at any jitter.
    """
    if not batching_enabled():
        preds = [e.predict(X, include_noise=include_noise) for e in experts]
        return Normal(
            torch.stack([p.loc for p in preds], dim=1), torch.stack([p.scale for p in preds], dim=1)
        )
    stack = ExpertStack.of(experts)
    n_test, e = X.shape[0], stack.y.shape[1]
    loc = X.new_empty(n_test, len(experts), e)
    scale = X.new_empty(n_test, len(experts), e)
    with torch.no_grad():
        for rows in stack.groups():
            group = [experts[j] for j in rows]
            mean, std, _ = _predict_group(group, stack.select(rows), X, include_noise)
            loc[:, rows], scale[:, rows] = mean, std
    return Normal(loc, scale)


def predict_exact_experts_out_of_sample(
    experts: Sequence[GPExpert], X: Tensor, held: Tensor
) -> Normal:
    """Every expert's predictive distribution of every training row without that row.

    Where expert `j` holds row `i` (``held[i, j]``) it is `GPExpert.loo_predict`'s
    leave-one-out normal; elsewhere `GPExpert.predict`'s (noise included), which is already
    out of sample. Both come from one factorisation of each expert's training covariance
    (batched), and each expert predicts only the rows it does not hold. The result and errors
    are those of `predict_exact_experts`.

    Args:
        experts: `M` fitted experts with the same `D`, `E` and options.
        X: Expert features of the training rows, `(N, D)`, on the experts' device.
        held: Whether each expert holds each row (its training rows, in order), `(N, M)`.
    """
    if not batching_enabled():
        return out_of_sample(experts, X, held)
    loc = X.new_empty(X.shape[0], len(experts), experts[0].n_outputs)
    scale = torch.empty_like(loc)
    free = [(~held[:, j]).nonzero()[:, 0] for j in range(len(experts))]
    stack = ExpertStack.of(experts)
    with torch.no_grad():
        for rows in stack.groups():
            group = [experts[j] for j in rows]
            mean, std, loos = _predict_group(
                group, stack.select(rows), X, True, True, [free[j] for j in rows]
            )
            for b, j in enumerate(rows):
                k = len(free[j])
                loc[free[j], j], scale[free[j], j] = mean[:k, b], std[:k, b]
                loc[held[:, j], j], scale[held[:, j], j] = loos[b].loc, loos[b].scale
    return Normal(loc, scale)


def _loo_group(
    experts: Sequence[GPExpert],
    stack: ExpertStack,
    hyper: tuple[Tensor, Tensor, Tensor, Tensor],
    chol: Tensor,
    alpha: Tensor,
) -> list[Normal]:
    """`GPExpert.loo_predict` of a batch of experts from their training factors.

    The moments are `probaff.models.experts.gaussian_density.loo_moments`', in output units.
    """
    noise = hyper[2]  # (B, E)
    own = noise[..., None] * stack.noise_scale  # sigma^2 / w_i on real rows, (B, E, n)
    mean, latent = loo_moments(chol, stack.y, alpha, own)  # (B, E, n) each
    var = latent.clamp_min(MIN_VARIANCE) + noise[..., None]
    out = []
    for b, expert in enumerate(experts):
        n = int(stack.counts[b])
        out.append(expert.output_normal(mean[b, :, :n], var[b, :, :n]))
    return out


def _predict_group(
    experts: Sequence[GPExpert],
    stack: ExpertStack,
    X: Tensor,
    include_noise: bool,
    loo: bool = False,
    rows: Sequence[Tensor] | None = None,
) -> tuple[Tensor, Tensor, list[Normal]]:
    """Predictive means and standard deviations `(N, B, E)` of a batch of experts.

    With `loo`, also each expert's leave-one-out normals (`_loo_group`); else an empty list.
    With `rows` (per expert, indices into `X`), expert `b` predicts only ``X[rows[b]]``,
    and the first ``len(rows[b])`` of the `K = max len(rows[b])` rows returned are its
    `(K, B, E)`.
    """
    hyper = _hyperparameters(experts[0], _raw_parameters(experts), _floors(experts))
    jitter = torch.stack([e.jitter for e in experts])
    _, chol, _, alpha, nan, failed = _train_factor(stack, hyper, jitter)
    if bool((nan | failed).any()):
        raise NotPSDError("a GP expert's training covariance is not positive definite.")
    mean_x = torch.stack([e.x_scaler.mean for e in experts])[:, None, :]
    std_x = torch.stack([e.x_scaler.std for e in experts])[:, None, :]
    b, e, n = stack.y.shape
    if rows is None:
        x = X[None]  # (1, N, D), the same rows for every expert
    else:  # each expert's own rows, padded with row 0 to the longest
        index = torch.zeros(b, max(len(r) for r in rows), dtype=torch.long, device=X.device)
        for i, r in enumerate(rows):
            index[i, : len(r)] = r
        x = X[index]  # (B, K, D)
    step = max(1, _PREDICT_BLOCK // max(1, b * e * n))
    means, variances = [X.new_empty(b, e, 0)], [X.new_empty(b, e, 0)]
    for start in range(0, x.shape[1], step):
        z = (x[:, start : start + step] - mean_x) / std_x
        mean, var = _predict_block(stack, z, hyper, alpha, chol)
        means.append(mean)
        variances.append(var)
    mean, var = torch.cat(means, -1), torch.cat(variances, -1)  # (B, E, K)
    if include_noise:
        var = var + hyper[2][..., None]
    var = var.clamp_min(MIN_VARIANCE)
    y_mean = torch.stack([e.y_scaler.mean for e in experts])[..., None]
    y_std = torch.stack([e.y_scaler.std for e in experts])[..., None]
    loos = _loo_group(experts, stack, hyper, chol, alpha) if loo else []
    return (
        (mean * y_std + y_mean).permute(2, 0, 1),
        (var.sqrt() * y_std).permute(2, 0, 1),
        loos,
    )
