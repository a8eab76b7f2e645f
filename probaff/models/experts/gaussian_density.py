r"""Batched Gaussian log density with a closed-form gradient, for GP marginal likelihoods.

Back-propagating through a Cholesky factorisation costs several full triangular solves
and products. The gradient of :math:`\log \mathcal N(r; 0, A)` with respect to `A` has
the closed form :math:`\tfrac12(\alpha\alpha^\top - A^{-1})` with :math:`\alpha = A^{-1} r`,
which costs one `cholesky_inverse`. `gaussian_log_density` uses it, and so evaluates the
exact marginal likelihood of a GP (and its gradient) faster than differentiating
gpytorch's Cholesky-based `MultivariateNormal.log_prob`, with the same value.
"""

from __future__ import annotations

import math
from typing import Any

import torch
from linear_operator.utils.errors import NanError, NotPSDError
from torch import Tensor

__all__ = ["gaussian_log_density", "loo_moments", "psd_cholesky"]


def psd_cholesky(a: Tensor, jitter: float, max_tries: int = 3) -> Tensor:
    """Lower Cholesky factor of `a`, adding ``jitter * 10**k`` to the diagonal on failure.

    The same policy as gpytorch's ``psd_safe_cholesky``: `a` as it is first, then with
    `jitter`, `10 jitter`, ... up to `max_tries` times.

    Args:
        a: Symmetric positive (semi-)definite matrices, `(*b, n, n)`.
        jitter: First diagonal jitter.
        max_tries: Number of jitter levels tried after the plain factorisation.

    Returns:
        Lower-triangular factors, `(*b, n, n)`.

    Raises:
        NanError: If `a` holds NaN.
        NotPSDError: If every jitter level fails.
    """
    if bool(torch.isnan(a).any()):
        raise NanError("the covariance matrix holds NaN.")
    chol, info = torch.linalg.cholesky_ex(a)
    if not bool(info.any()):
        return chol
    eye = torch.eye(a.shape[-1], dtype=a.dtype, device=a.device)
    for k in range(max_tries):
        chol, info = torch.linalg.cholesky_ex(a + (jitter * 10.0**k) * eye)
        if not bool(info.any()):
            return chol
    raise NotPSDError(f"the covariance matrix is not positive definite even with jitter {jitter}.")


class _GaussianLogDensity(torch.autograd.Function):
    """``log N(r; 0, A)`` per batch member, with the closed-form backward pass."""

    @staticmethod
    def forward(ctx: Any, a: Tensor, r: Tensor, jitter: float) -> Tensor:
        chol = psd_cholesky(a, jitter)
        alpha = torch.cholesky_solve(r[..., None], chol)[..., 0]
        ctx.save_for_backward(chol, alpha)
        logdet = 2.0 * chol.diagonal(dim1=-2, dim2=-1).log().sum(-1)
        n = r.shape[-1]
        return -0.5 * ((r * alpha).sum(-1) + logdet + n * math.log(2.0 * math.pi))

    @staticmethod
    def backward(ctx: Any, grad: Tensor) -> tuple[Tensor | None, Tensor | None, None]:
        chol, alpha = ctx.saved_tensors
        grad_a = grad_r = None
        if ctx.needs_input_grad[0]:
            outer = alpha[..., :, None] * alpha[..., None, :]
            grad_a = (0.5 * grad)[..., None, None] * (outer - torch.cholesky_inverse(chol))
        if ctx.needs_input_grad[1]:
            grad_r = -grad[..., None] * alpha
        return grad_a, grad_r, None


def gaussian_log_density(a: Tensor, r: Tensor, jitter: float = 1e-8) -> Tensor:
    r"""Log density :math:`\log \mathcal N(r; 0, A)` of each batch member, differentiably.

    Args:
        a: Covariance matrices, `(*b, n, n)`, symmetric positive definite.
        r: Residuals (observations minus mean), `(*b, n)`.
        jitter: First diagonal jitter tried when the factorisation fails (see
            `psd_cholesky`).

    Returns:
        Log densities, `(*b,)`.

    Raises:
        NanError: If `a` holds NaN.
        NotPSDError: If `a` cannot be factorised at any jitter level.
    """
    out: Tensor = _GaussianLogDensity.apply(a, r, float(jitter))
    return out


def loo_moments(chol: Tensor, y: Tensor, alpha: Tensor, own: Tensor) -> tuple[Tensor, Tensor]:
    r"""Leave-one-out means and latent variances of GP regressions from their factors.

    Rasmussen & Williams (2006, eq. 5.12): with :math:`A = K + \sigma^2 W^{-1} = L L^T` and
    :math:`\alpha = A^{-1}(y - m)`, sample `i` given all others has mean
    :math:`y_i - \alpha_i / [A^{-1}]_{ii}` and latent variance
    :math:`1/[A^{-1}]_{ii} - \sigma^2 / w_i`.

    Args:
        chol: Lower Cholesky factors `L`, `(*b, n, n)`.
        y: Targets, `(*b, n)`.
        alpha: :math:`A^{-1}(y - m)`, `(*b, n)`.
        own: Each sample's own noise variance :math:`\sigma^2 / w_i`, `(*b, n)`.

    Returns:
        The means and the latent variances (not clamped), `(*b, n)` each.
    """
    eye = torch.eye(chol.shape[-1], dtype=chol.dtype, device=chol.device)
    chol_inv = torch.linalg.solve_triangular(chol, eye.expand_as(chol), upper=False)
    diag_inv = chol_inv.square().sum(-2)  # diag(A^-1)
    return y - alpha / diag_inv, 1.0 / diag_inv - own
