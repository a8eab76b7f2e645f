"""Gates: multinomial logistic regression fitted to soft assignment targets.

`SoftmaxGate` is linear in the standardised gate features; `FourierGate` runs the same
regression on random Fourier features of them, for regimes that no hyperplane separates.
Either chooses its L2 penalty by inner K-fold cross-validation when built with ``l2="cv"``.
`make_gate` builds either by name.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import torch
from torch import Tensor

from probaff._checks import check_count, check_positive, check_probability
from probaff.errors import InputError, NotFittedError
from probaff.models._scaling import Standardizer
from probaff.models.gates.gate_newton import NEWTON_MAX_PARAMETERS, newton_fit
from probaff.models.gates.gate_penalty import (
    DEFAULT_L1_GRID,
    DEFAULT_L2_GRID,
    Penalty,
    check_grid,
    check_strength,
    log_softmax_last,
    penalised_gradient,
    penalised_loss,
    penalised_objective,
    penalty_candidates,
    penalty_grad,
    penalty_paths,
    penalty_value,
    strength_grid,
)
from probaff.models.lbfgs import minimise
from probaff.models.tensors import as_matrix, as_vector

__all__ = [
    "DEFAULT_L1_GRID",
    "DEFAULT_L2_GRID",
    "GATE_KINDS",
    "FourierGate",
    "SoftmaxGate",
    "make_gate",
]

GATE_KINDS: tuple[str, ...] = ("linear", "fourier")
"""Gate kinds `make_gate` builds."""

_TINY = torch.finfo(torch.float64).tiny

# L-BFGS curvature pairs kept by cross-validated fits (a short history keeps iterations cheap).
_CV_HISTORY = 10
# Gradient tolerance of the refit that ends a cross-validated fit.
_CV_TOLERANCE = 1e-6

# Relative loss change that ends the fit of one penalty (Newton's method or L-BFGS).
_FIT_TOLERANCE_CHANGE = 1e-12

# Most rows used by the median heuristic; larger data sets use a seeded subset.
_MEDIAN_ROWS = 1000


class SoftmaxGate(torch.nn.Module):
    r"""Linear gate :math:`p(m = j \mid f) = \mathrm{softmax}(W \phi(z) + b)_j` on features `f`.

    Here `z` is `f` standardised and :math:`\phi(z) = z`. Fitted by minimising the
    soft-target cross-entropy :math:`-\frac{1}{\sum_i s_i} \sum_i s_i \sum_j r_{ij} \log p(m
    = j \mid f_i) + \frac{\lambda}{2} \lVert W \rVert^2 + \lambda_1 \lVert W \rVert_1` (the
    intercept `b` is not penalised) by Newton's method (`probaff.models.gates.gate_newton`; L-BFGS
    for gates of more than `NEWTON_MAX_PARAMETERS` parameters and on the cross-validation
    paths); the lasso term is smoothed within 1e-4 of
    zero (`probaff.models.gates.gate_penalty.penalty_value`). The objective is convex, so the fit
    is unique up to the optimiser's tolerance. The lasso (`l1`) keeps a gate on many
    features to the few that separate the experts: on
    `probaff.models.synthetic.regime_features` (two of 101 columns set the regime) logistic
    regression with 250 rows classifies 1,000 held-out rows 91 % right with a
    cross-validated lasso against 63 % with a cross-validated ridge.

    With fixed `l2` and `l1`, `fit` warm-starts from the current parameters. With
    ``l2="cv"`` and/or ``l1="cv"``, `fit` chooses the penalty by `n_folds`-fold
    cross-validation from the candidates: the ridge strengths of `l2_grid` (with `l1`, or
    with no lasso when `l1` is ``"cv"`` too) and the lasso strengths of `l1_grid` (with
    `l2`, or with no ridge when `l2` is ``"cv"`` too); the
    folds (stratified by each row's most likely expert, drawn from `seed`) are fitted
    together along the grid from the strongest penalty to the weakest, each step
    warm-started from the last and capped at `cv_max_iter` iterations; the penalty with the
    lowest pooled held-out weighted cross-entropy wins (ties go to the stronger penalty).
    The gate is then refitted on all rows with it (to a gradient tolerance of 1e-6),
    starting from whichever of the current parameters and the all-rows solution of the
    same path has the lower objective; a fresh gate's result thus depends only on the data
    and `seed`, and refits in a loop start close to their optimum. The standardisation is
    computed once from all rows and shared by the folds.

    Args:
        n_features: Number of gate features `D`.
        n_experts: Number of experts `M`.
        l2: Ridge penalty :math:`\lambda` on the weights, or ``"cv"`` to choose it per
            `fit`.
        max_iter: Newton (or L-BFGS) iterations of the final fit in each call to `fit`.
        l2_grid: Penalties tried by ``l2="cv"``; `DEFAULT_L2_GRID` if ``None``. Only
            allowed with ``l2="cv"``.
        l1: Lasso penalty :math:`\lambda_1` on the weights (0: none), or ``"cv"``.
        l1_grid: Penalties tried by ``l1="cv"``; `DEFAULT_L1_GRID` if ``None``. Only
            allowed with ``l1="cv"``.
        n_folds: Folds of the inner cross-validation (at least 2).
        cv_max_iter: L-BFGS iterations per penalty on the cross-validation path.
        seed: Seed of the fold assignment.

    Attributes:
        weight: `W`, `(M, D_basis)`; `D_basis = D` here.
        bias: `b`, `(M,)`.
        fitted: Boolean buffer, true once `fit` has run.
        n_features: `D`.
        n_experts: `M`.
        n_basis: `D_basis`, the width of :math:`\phi(z)`.
        l2_grid_: The ridge penalties cross-validation tries, strongest first.
        l1_grid_: The lasso penalties cross-validation tries, strongest first.
        penalties_: Every `(l2, l1)` candidate of cross-validation, in the order tried
            (ridge path first), `L` of them; the one fixed pair without cross-validation.
        cv_scores_: Held-out cross-entropy of the last cross-validated `fit`, one row per
            basis setting (one row here) and one column per entry of `penalties_`,
            `(G, L)`; ``None`` before such a fit. Not saved in the state dict.
    """

    fitted: Tensor
    chosen_l2: Tensor
    chosen_l1: Tensor

    def __init__(
        self,
        n_features: int,
        n_experts: int,
        *,
        l2: float | str = 1e-3,
        max_iter: int = 200,
        l2_grid: Sequence[float] | None = None,
        n_folds: int = 3,
        cv_max_iter: int = 10,
        seed: int = 0,
        l1: float | str = 0.0,
        l1_grid: Sequence[float] | None = None,
    ) -> None:
        super().__init__()
        self.n_features = check_count("n_features", n_features)
        self.n_experts = check_count("n_experts", n_experts)
        self.l2: float | str = check_strength("l2", l2)
        self.l1: float | str = check_strength("l1", l1)
        self.max_iter = check_count("max_iter", max_iter)
        self.l2_grid_ = strength_grid("l2", self.l2, l2_grid, DEFAULT_L2_GRID)
        self.l1_grid_ = strength_grid("l1", self.l1, l1_grid, DEFAULT_L1_GRID)
        self.penalties_ = penalty_candidates(self.l2, self.l1, self.l2_grid_, self.l1_grid_)
        self.n_folds = check_count("n_folds", n_folds, minimum=2)
        self.cv_max_iter = check_count("cv_max_iter", cv_max_iter)
        self.seed = check_count("seed", seed, minimum=0)
        self.scaler = Standardizer(self.n_features)
        self.register_buffer("fitted", torch.tensor(False))
        if self.l2 == "cv":
            self.register_buffer("chosen_l2", torch.tensor(math.nan, dtype=torch.float64))
        if self.l1 == "cv":
            self.register_buffer("chosen_l1", torch.tensor(math.nan, dtype=torch.float64))
        self.cv_scores_: Tensor | None = None
        self._reset_parameters(self.n_features)

    def _reset_parameters(self, n_basis: int) -> None:
        """Create zero `weight` `(M, n_basis)` and `bias` `(M,)`."""
        self.n_basis = int(n_basis)
        self.weight = torch.nn.Parameter(torch.zeros(self.n_experts, self.n_basis).double())
        self.bias = torch.nn.Parameter(torch.zeros(self.n_experts).double())

    # ----------------------------------------------------------------- basis hooks

    def _expand(self, z: Tensor, setting: float | None) -> Tensor:
        r"""The basis :math:`\phi(z)` under one basis setting.

        Args:
            z: Standardised features, `(N, D)`.
            setting: Basis hyperparameter (unused by the linear gate).

        Returns:
            `(N, D_basis)`.
        """
        return z

    def _settings(self, z: Tensor) -> list[float | None]:
        """Candidate basis settings for a fit on standardised data `z` `(N, D)`."""
        return [None]

    def _apply_setting(self, setting: float | None) -> None:
        """Make `setting` the basis used by `logits`."""

    def _current_setting(self) -> float | None:
        return None

    # ------------------------------------------------------------------ public API

    @property
    def l2_(self) -> float:
        """The ridge penalty of the last fit: `l2` itself, or the one cross-validation chose.

        Raises:
            NotFittedError: If ``l2="cv"`` and the gate was never fitted.
        """
        return self._penalty("l2")

    @property
    def l1_(self) -> float:
        """The lasso penalty of the last fit: `l1` itself, or the one cross-validation chose.

        Raises:
            NotFittedError: If ``l1="cv"`` and the gate was never fitted.
        """
        return self._penalty("l1")

    def _penalty(self, name: str) -> float:
        """The penalty `name` (``"l1"`` or ``"l2"``), or the one cross-validation chose."""
        value = getattr(self, name)
        if value != "cv":
            return float(value)
        if not bool(self.fitted):
            raise NotFittedError(
                f"{type(self).__name__} chooses {name} by cross-validation in fit; call fit first."
            )
        return float(getattr(self, f"chosen_{name}"))

    def basis(self, x: Tensor) -> Tensor:
        r"""Differentiable basis :math:`\phi(z)` of raw gate features.

        Args:
            x: Gate features as a float64 tensor, `(N, D)`.

        Returns:
            `(N, D_basis)`.
        """
        return self._expand(self.scaler(x), self._current_setting())

    def logits(self, x: Tensor) -> Tensor:
        r"""Differentiable gate logits :math:`W \phi(z) + b`.

        Args:
            x: Gate features as a float64 tensor, `(N, D)`.

        Returns:
            Logits, `(N, M)`.
        """
        return self.basis(x) @ self.weight.T + self.bias

    def fit(
        self, X: Any, targets: Any, sample_weight: Any | None = None, *, reuse_choice: bool = False
    ) -> SoftmaxGate:
        """Fit the gate to soft targets.

        Args:
            X: Gate features, `(N, D)`.
            targets: Target probabilities whose rows sum to 1, `(N, M)`.
            sample_weight: Non-negative weights `s`, `(N,)`; uniform if ``None``.
            reuse_choice: Keep the penalty (and basis setting) that the last
                cross-validated fit chose instead of cross-validating again; EM uses this
                between the iterations of one run. Ignored before the first fit.

        Returns:
            This gate.

        Raises:
            InputError: For malformed inputs, or fewer rows than `n_folds` when
                cross-validating.
        """
        x = as_matrix("gate features X", X, n_cols=self.n_features)
        self.to(x.device)  # the gate fits where its data lives
        r = as_matrix(
            "gate targets", targets, n_rows=x.shape[0], n_cols=self.n_experts, device=x.device
        )
        check_probability("gate targets", r)
        if sample_weight is None:
            s = torch.ones(x.shape[0], dtype=torch.float64, device=x.device)
        else:
            s = as_vector("sample_weight", sample_weight, n=x.shape[0], device=x.device)
            s = s.clamp_min(0.0)
        s = s / s.sum().clamp_min(_TINY)
        self.scaler.fit(x)
        z = self.scaler(x)
        if reuse_choice and bool(self.fitted):
            self._fit_fixed(
                self._expand(z, self._current_setting()),
                r,
                s,
                (self.l2_, self.l1_),
                history_size=_CV_HISTORY,
                tolerance_grad=_CV_TOLERANCE,
            )
            return self
        settings = self._settings(z)
        if len(self.penalties_) > 1 or len(settings) > 1:
            self._fit_cv(z, r, s, settings)
        else:
            self._apply_setting(settings[0])
            self._fit_fixed(self._expand(z, settings[0]), r, s, self.penalties_[0])
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
            raise NotFittedError(f"{type(self).__name__} is not fitted; call fit first.")
        x = as_matrix("gate features X", X, n_cols=self.n_features, device=self.weight.device)
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

    # -------------------------------------------------------------------- fitting

    def _fit_fixed(
        self,
        phi: Tensor,
        r: Tensor,
        s: Tensor,
        penalty: Penalty,
        *,
        history_size: int = 100,
        tolerance_grad: float = 1e-9,
    ) -> None:
        """Fit `weight` and `bias` from their current values with strengths `penalty`.

        Newton's method (`probaff.models.gates.gate_newton`) while the gate has at most
        `NEWTON_MAX_PARAMETERS` parameters, L-BFGS above.

        Args:
            phi: Basis, `(N, D_basis)`.
            r: Targets, `(N, M)`.
            s: Sample weights summing to 1, `(N,)`.
            penalty: Ridge and lasso strengths `(l2, l1)`.
            history_size: Curvature pairs kept by L-BFGS.
            tolerance_grad: Stop when the largest gradient entry is below this.
        """
        if self.n_experts * (phi.shape[1] + 1) <= NEWTON_MAX_PARAMETERS:
            newton_fit(
                phi,
                r,
                s,
                penalty,
                self.weight,
                self.bias,
                max_iter=self.max_iter,
                tolerance_grad=tolerance_grad,
                tolerance_change=_FIT_TOLERANCE_CHANGE,
            )
            return

        def closure() -> Tensor:  # the loss, with its gradient in closed form
            with torch.no_grad():
                loss, log_p = penalised_objective(phi, r, s, penalty, self.weight, self.bias)
                grads = penalised_gradient(phi, r, s, penalty, self.weight, log_p)
                self.weight.grad, self.bias.grad = grads
            return loss

        minimise(
            [self.weight, self.bias],
            closure,
            max_iter=self.max_iter,
            tolerance_grad=tolerance_grad,
            tolerance_change=_FIT_TOLERANCE_CHANGE,
            history_size=history_size,
        )

    def _folds(self, r: Tensor) -> Tensor:
        """Fold of each row, `(N,)`, stratified by the row's most likely expert."""
        n = r.shape[0]
        if n < self.n_folds:
            raise InputError(
                f"gate features X has {n} row(s), fewer than n_folds={self.n_folds}; use "
                "fewer folds or fixed penalties (l2 and l1 numbers)."
            )
        g = torch.Generator().manual_seed(self.seed)  # folds are drawn on the CPU on any device
        cpu = torch.device("cpu")
        perm = torch.randperm(n, generator=g, device=cpu)
        order = perm[torch.argsort(r.argmax(1).cpu()[perm], stable=True)]
        folds = torch.empty(n, dtype=torch.long, device=cpu)
        folds[order] = torch.arange(n, device=cpu) % self.n_folds
        return folds.to(r.device)

    def _cv_path(
        self, phi: Tensor, r: Tensor, s: Tensor, folds: Tensor, grid: Sequence[Penalty]
    ) -> tuple[Tensor, list[tuple[Tensor, Tensor]]]:
        """Fit every fold and all rows together along `grid`, each step warm-started.

        Args:
            phi: Basis, `(N, P)`.
            r: Targets, `(N, M)`.
            s: Sample weights summing to 1, `(N,)`.
            folds: Fold of each row, `(N,)`.
            grid: Penalties `(l2, l1)`, `L` of them, in the order to fit them.

        Returns:
            Pooled held-out cross-entropy per penalty `(L,)`, and the all-rows
            `(weight (M, P), bias (M,))` per penalty.
        """
        k, m = self.n_folds, self.n_experts
        n, width = phi.shape
        held = folds[:, None] == torch.arange(k, device=phi.device)[None, :]  # (N, K)
        train = torch.cat([~held, torch.ones(n, 1, dtype=torch.bool, device=phi.device)], dim=1)
        w_train = s[:, None] * train  # (N, K + 1)
        w_train = (w_train / w_train.sum(0).clamp_min(_TINY))[..., None]
        w_held = (s[:, None] * held)[..., None]  # (N, K, 1)
        target = r[:, None, :]  # (N, 1, M)
        # Problem p (fold p left out; p = K: all rows) owns columns p*M .. p*M + M - 1.
        weight = torch.zeros(width, (k + 1) * m, dtype=torch.float64, device=phi.device)
        bias = torch.zeros((k + 1) * m, dtype=torch.float64, device=phi.device)

        def log_proba() -> Tensor:
            return log_softmax_last(torch.addmm(bias, phi, weight).view(n, k + 1, m))

        scores = torch.empty(len(grid), dtype=torch.float64, device=phi.device)
        solutions: list[tuple[Tensor, Tensor]] = []
        for i, penalty in enumerate(grid):

            def closure(penalty: Penalty = penalty) -> Tensor:
                log_p = log_proba()
                loss = -(w_train * (target * log_p)).sum() + penalty_value(weight, penalty)
                residual = ((log_p.exp() - target) * w_train).view(n, (k + 1) * m)
                weight.grad = penalty_grad(weight, penalty) + phi.T @ residual
                bias.grad = residual.sum(0)
                return loss

            minimise(
                [weight, bias],
                closure,
                max_iter=self.cv_max_iter,
                tolerance_grad=1e-7,
                tolerance_change=1e-10,
                history_size=_CV_HISTORY,
            )
            log_p = log_proba()
            scores[i] = -(w_held * (target * log_p[:, :k])).sum()
            solutions.append((weight[:, k * m :].T.clone(), bias[k * m :].clone()))
        return scores, solutions

    def _fit_cv(self, z: Tensor, r: Tensor, s: Tensor, settings: list[float | None]) -> None:
        """Choose the basis setting and penalty by cross-validation, then refit on all rows."""
        grid = self.penalties_
        folds = self._folds(r)
        scores = torch.empty(len(settings), len(grid), dtype=torch.float64, device=z.device)
        best: tuple[float, int, int] | None = None
        best_solution: tuple[Tensor, Tensor] | None = None
        paths = penalty_paths(grid)
        for g, setting in enumerate(settings):
            phi = self._expand(z, setting)
            solutions: list[tuple[Tensor, Tensor]] = []
            for lo, hi in paths:
                scores[g, lo:hi], part = self._cv_path(phi, r, s, folds, grid[lo:hi])
                solutions.extend(part)
            for i in range(len(grid)):
                if best is None or float(scores[g, i]) < best[0]:
                    best = (float(scores[g, i]), g, i)
                    best_solution = solutions[i]
        assert best is not None and best_solution is not None
        _, g_best, i_best = best
        penalty = grid[i_best]
        phi = self._expand(z, settings[g_best])
        with torch.no_grad():
            keep_current = bool(self.fitted) and penalised_loss(
                phi, r, s, penalty, self.weight, self.bias
            ) < penalised_loss(phi, r, s, penalty, *best_solution)
            if not keep_current:
                self.weight.copy_(best_solution[0])
                self.bias.copy_(best_solution[1])
        self._apply_setting(settings[g_best])
        if self.l2 == "cv":
            self.chosen_l2.fill_(penalty[0])
        if self.l1 == "cv":
            self.chosen_l1.fill_(penalty[1])
        self.cv_scores_ = scores
        self._fit_fixed(phi, r, s, penalty, history_size=_CV_HISTORY, tolerance_grad=_CV_TOLERANCE)


class FourierGate(SoftmaxGate):
    r"""Softmax gate on random Fourier features of the standardised gate features.

    The basis is :math:`\phi(z) = [z, \sqrt{2/K} \cos(z \Omega / \ell + b_\phi)]` with
    :math:`\Omega \sim \mathcal{N}(0, I)` `(D, K)` and :math:`b_\phi \sim U[0, 2\pi)` `(K,)`
    drawn from `seed` (buffers, so they are saved in the state dict), approximating a
    squared-exponential kernel of lengthscale :math:`\ell` next to the linear terms. The
    regression, its penalty (fixed or ``"cv"``) and its fitting are those of `SoftmaxGate`.

    Args:
        n_features: Number of gate features `D`.
        n_experts: Number of experts `M`.
        l2: Penalty :math:`\lambda` on all weights, or ``"cv"``.
        n_random_features: `K`.
        lengthscale: :math:`\ell` in standardised units; ``"median"`` for the median
            pairwise distance of the standardised rows of each `fit`; ``"cv"`` to choose it
            by the same cross-validation as `l2` from that median times each of
            `lengthscale_factors`.
        lengthscale_factors: Multiples of the median tried by ``lengthscale="cv"``.
        **fit_settings: `SoftmaxGate`'s ``l1``, ``max_iter``, ``l2_grid``, ``l1_grid``,
            ``n_folds``, ``cv_max_iter`` and ``seed`` (here also the seed of :math:`\Omega` and
            :math:`b_\phi`).

    Attributes:
        weight: `W`, `(M, D + K)`.
        bias: `b`, `(M,)`.
        omega: :math:`\Omega`, `(D, K)`.
        phase: :math:`b_\phi`, `(K,)`.
        chosen_lengthscale: :math:`\ell` in use (NaN before a rule-based fit), scalar.
    """

    omega: Tensor
    phase: Tensor
    chosen_lengthscale: Tensor

    def __init__(
        self,
        n_features: int,
        n_experts: int,
        *,
        l2: float | str = "cv",
        n_random_features: int = 128,
        lengthscale: float | str = "median",
        lengthscale_factors: Sequence[float] = (0.5, 1.0, 2.0),
        **fit_settings: Any,
    ) -> None:
        super().__init__(n_features, n_experts, l2=l2, **fit_settings)
        self.n_random_features = check_count("n_random_features", n_random_features)
        if isinstance(lengthscale, str):
            if lengthscale not in ("median", "cv"):
                raise InputError(
                    "lengthscale must be a number > 0, 'median' (median heuristic) or 'cv' "
                    f"(cross-validated), got {lengthscale!r}."
                )
            initial = math.nan
        else:
            check_positive("lengthscale", lengthscale)
            initial = float(lengthscale)
        self.lengthscale: float | str = lengthscale if isinstance(lengthscale, str) else initial
        self.lengthscale_factors = check_grid(
            "lengthscale_factors", lengthscale_factors, allow_zero=False
        )
        g = torch.Generator().manual_seed(self.seed)
        k = self.n_random_features
        self.register_buffer(
            "omega", torch.randn(self.n_features, k, generator=g, dtype=torch.float64)
        )
        self.register_buffer(
            "phase", 2.0 * math.pi * torch.rand(k, generator=g, dtype=torch.float64)
        )
        self.register_buffer("chosen_lengthscale", torch.tensor(initial, dtype=torch.float64))
        self._reset_parameters(self.n_features + k)

    @property
    def lengthscale_(self) -> float:
        """The lengthscale in use, in standardised units.

        Raises:
            NotFittedError: If it is set by a rule and the gate was never fitted.
        """
        value = float(self.chosen_lengthscale)
        if math.isnan(value):
            raise NotFittedError("FourierGate sets its lengthscale in fit; call fit first.")
        return value

    def _expand(self, z: Tensor, setting: float | None) -> Tensor:
        assert setting is not None
        k = self.n_random_features
        waves = math.sqrt(2.0 / k) * torch.cos(z @ self.omega / setting + self.phase)
        return torch.cat([z, waves], dim=-1)

    def _settings(self, z: Tensor) -> list[float | None]:
        if not isinstance(self.lengthscale, str):
            return [self.lengthscale]
        median = self._median_distance(z)
        if self.lengthscale == "median":
            return [median]
        return [median * f for f in self.lengthscale_factors]

    def _apply_setting(self, setting: float | None) -> None:
        assert setting is not None
        self.chosen_lengthscale.fill_(setting)

    def _current_setting(self) -> float | None:
        return self.lengthscale_

    def _median_distance(self, z: Tensor) -> float:
        """Median pairwise Euclidean distance of the rows of `z` `(N, D)` (1 if undefined)."""
        if z.shape[0] > _MEDIAN_ROWS:
            g = torch.Generator().manual_seed(self.seed)
            rows = torch.randperm(z.shape[0], generator=g, device=torch.device("cpu"))
            z = z[rows[:_MEDIAN_ROWS].to(z.device)]
        if z.shape[0] < 2:
            return 1.0
        median = float(torch.pdist(z).median())
        return median if median > 0.0 else 1.0


_OPTIONS: dict[str, tuple[type[SoftmaxGate], tuple[str, ...]]] = {
    "linear": (SoftmaxGate, ("max_iter", "l2_grid", "l1_grid", "n_folds", "cv_max_iter")),
    "fourier": (
        FourierGate,
        (
            "max_iter",
            "l2_grid",
            "l1_grid",
            "n_folds",
            "cv_max_iter",
            "n_random_features",
            "lengthscale",
            "lengthscale_factors",
        ),
    ),
}


def make_gate(
    kind: str,
    n_features: int,
    n_experts: int,
    *,
    l2: float | str = "cv",
    l1: float | str = 0.0,
    seed: int = 0,
    **options: Any,
) -> SoftmaxGate:
    """Build a gate by name.

    Args:
        kind: ``"linear"`` (`SoftmaxGate`) or ``"fourier"`` (`FourierGate`).
        n_features: Number of gate features `D`.
        n_experts: Number of experts `M`.
        l2: Ridge penalty on the weights, or ``"cv"`` to choose it by cross-validation.
        l1: Lasso penalty on the weights (0: none), or ``"cv"``.
        seed: Seed of the folds (and of the random features of ``"fourier"``).
        **options: Further keyword arguments of the gate's class.

    Returns:
        An unfitted gate.

    Raises:
        InputError: For an unknown `kind` or option, or a bad argument value.
    """
    if not isinstance(kind, str) or kind not in _OPTIONS:
        raise InputError(
            f"kind must be one of {', '.join(repr(k) for k in GATE_KINDS)}, got {kind!r}."
        )
    cls, allowed = _OPTIONS[kind]
    unknown = sorted(set(options) - set(allowed))
    if unknown:
        raise InputError(
            f"unknown option(s) {', '.join(unknown)} for a {kind!r} gate; it accepts "
            f"{', '.join(allowed)}."
        )
    return cls(n_features, n_experts, l2=l2, l1=l1, seed=seed, **options)
