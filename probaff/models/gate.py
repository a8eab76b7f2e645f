"""Softmax gate: multinomial logistic regression fitted to soft assignment targets."""

from __future__ import annotations

from typing import Any

import torch
from torch import Tensor

from probaff._checks import check_positive, check_probability
from probaff.errors import NotFittedError
from probaff.models._scaling import Standardizer
from probaff.models._tensors import as_matrix, as_vector

__all__ = ["SoftmaxGate"]


class SoftmaxGate(torch.nn.Module):
    r"""Gate :math:`p(m = j \mid f) = \mathrm{softmax}(W z + b)_j` on standardised features `z`.

    Fitted by minimising the soft-target cross-entropy
    :math:`-\frac{1}{\sum_i s_i} \sum_i s_i \sum_j r_{ij} \log p(m = j \mid f_i)
    + \frac{\lambda}{2} \lVert W \rVert^2` (the intercept `b` is not penalised) with
    L-BFGS. The objective is convex, so the fit is unique up to the optimiser's tolerance
    and deterministic; it warm-starts from the current parameters.

    Args:
        n_features: Number of gate features `D`.
        n_experts: Number of experts `M`.
        l2: Penalty :math:`\lambda` on the weights.
        max_iter: L-BFGS iterations per call to `fit`.

    Attributes:
        weight: `W`, `(M, D)`.
        bias: `b`, `(M,)`.
    """

    def __init__(
        self, n_features: int, n_experts: int, *, l2: float = 1e-3, max_iter: int = 200
    ) -> None:
        super().__init__()
        check_positive("n_features", n_features)
        check_positive("n_experts", n_experts)
        check_positive("l2", l2, allow_zero=True)
        check_positive("max_iter", max_iter)
        self.n_features = int(n_features)
        self.n_experts = int(n_experts)
        self.l2 = float(l2)
        self.max_iter = int(max_iter)
        self.scaler = Standardizer(self.n_features)
        self.weight = torch.nn.Parameter(torch.zeros(self.n_experts, self.n_features).double())
        self.bias = torch.nn.Parameter(torch.zeros(self.n_experts).double())
        self.register_buffer("fitted", torch.tensor(False))

    def logits(self, x: Tensor) -> Tensor:
        """Differentiable gate logits `W z + b`.

        Args:
            x: Gate features as a float64 tensor, `(N, D)`.

        Returns:
            Logits, `(N, M)`.
        """
        return self.scaler(x) @ self.weight.T + self.bias

    def fit(self, X: Any, targets: Any, sample_weight: Any | None = None) -> SoftmaxGate:
        """Fit the gate to soft targets.

        Args:
            X: Gate features, `(N, D)`.
            targets: Target probabilities whose rows sum to 1, `(N, M)`.
            sample_weight: Non-negative weights `s`, `(N,)`; uniform if ``None``.

        Returns:
            This gate.
        """
        x = as_matrix("gate features X", X, n_cols=self.n_features)
        r = as_matrix("gate targets", targets, n_rows=x.shape[0], n_cols=self.n_experts)
        check_probability("gate targets", r)
        if sample_weight is None:
            s = torch.ones(x.shape[0], dtype=torch.float64)
        else:
            s = as_vector("sample_weight", sample_weight, n=x.shape[0]).clamp_min(0.0)
        s = s / s.sum().clamp_min(torch.finfo(torch.float64).tiny)
        self.scaler.fit(x)
        optimiser = torch.optim.LBFGS(
            [self.weight, self.bias],
            lr=1.0,
            max_iter=self.max_iter,
            line_search_fn="strong_wolfe",
            tolerance_grad=1e-9,
            tolerance_change=1e-12,
        )

        def closure() -> Tensor:
            optimiser.zero_grad()
            log_p = torch.log_softmax(self.logits(x), dim=-1)
            loss = -(s * (r * log_p).sum(-1)).sum() + 0.5 * self.l2 * self.weight.square().sum()
            loss.backward()
            return loss

        optimiser.step(closure)
        self.fitted.fill_(True)
        return self

    def log_proba(self, X: Any) -> Tensor:
        """Log gate probabilities.

        Args:
            X: Gate features, `(N, D)`.

        Returns:
            `log p(m = j | f_i)`, `(N, M)`.

        Raises:
            NotFittedError: If the gate was never fitted.
        """
        if not bool(self.fitted):
            raise NotFittedError("SoftmaxGate is not fitted; call fit first.")
        x = as_matrix("gate features X", X, n_cols=self.n_features)
        with torch.no_grad():
            return torch.log_softmax(self.logits(x), dim=-1)

    def predict_proba(self, X: Any) -> Tensor:
        """Gate probabilities.

        Args:
            X: Gate features, `(N, D)`.

        Returns:
            `p(m = j | f_i)`, rows summing to 1, `(N, M)`.
        """
        return self.log_proba(X).exp()
