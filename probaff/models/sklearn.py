"""A scikit-learn regressor around the mixture of GP experts fitted by EM.

`MixtureOfGPExpertsRegressor` takes numpy arrays in and gives numpy arrays out, so the mixture
(`MixtureOfGPExperts` + `fit_em`) drops into `cross_val_score`, `GridSearchCV` (e.g. over
``n_experts``) and a `Pipeline` after a `StandardScaler`::

    search = GridSearchCV(MixtureOfGPExpertsRegressor(random_state=0), {"n_experts": [1, 2, 3]})
    search.fit(X, y)  # X: (N, D), y: (N,) or (N, T)
    mean, std = search.predict(X_new, return_std=True)

The constructor stores its arguments unchanged (scikit-learn's convention); they are checked
when `fit` builds the mixture and its `EMOptions`. The fitted mixture and its EM history are
`model_` and `history_`.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import torch
from sklearn.base import BaseEstimator, RegressorMixin
from sklearn.exceptions import NotFittedError as SklearnNotFittedError
from sklearn.pipeline import Pipeline
from sklearn.utils import check_random_state
from sklearn.utils.validation import check_is_fitted, validate_data

from probaff._checks import as_float_array, check_count
from probaff._threads import threads_by_rows
from probaff.errors import InputError, NotFittedError
from probaff.models.mixture.em import fit_em
from probaff.models.mixture.em_run import EMHistory
from probaff.models.mixture.model import FLAT_GP_KEYWORDS, MixtureOfGPExperts
from probaff.models.options import EMOptions, GPOptions

__all__ = [
    "EstimatorNotFittedError",
    "MixtureOfGPExpertsRegressor",
    "mean_log_predictive_density",
]

_SEED_BOUND = 2**31 - 1  # seeds drawn from a RandomState lie in [0, _SEED_BOUND)

# The estimator's arguments passed on unchanged to `MixtureOfGPExperts` (after `n_experts`)
# and to `EMOptions` (besides `init` and `seed`), under the same names.
_MIXTURE_ARGS = (
    "gate",
    "gate_l2",
    "gate_l1",
    "groups",
    "gate_features",
    "expert_features",
    "experts",
    "n_inducing",
    "point",
)
_EM_ARGS = ("n_restarts", "screen_iter", "split_merge", "max_iter", "tol", "n_init", "anneal")


class EstimatorNotFittedError(NotFittedError, SklearnNotFittedError):
    """`MixtureOfGPExpertsRegressor` asked to predict before `fit`.

    Both probaff's `NotFittedError` and scikit-learn's ``sklearn.exceptions.NotFittedError``,
    so either ``except`` clause catches it.
    """


def _validated(estimator: BaseEstimator, *arrays: Any, **kwargs: Any) -> Any:
    """`validate_data` whose `ValueError` becomes an `InputError` naming the array.

    An array of strings makes numpy's "could not convert string to float" refused by
    `as_float_array` instead, naming ``X`` (or ``y``); other errors keep scikit-learn's
    message (its `TypeError` for objects that are not numbers too, as its estimator checks
    expect).
    """
    try:
        return validate_data(estimator, *arrays, **kwargs)
    except InputError:
        raise
    except ValueError as err:
        for name, arr in zip(("X", "y"), arrays, strict=False):
            # sparse matrices and a missing y keep scikit-learn's message
            if arr is not None and not hasattr(arr, "tocsr"):
                as_float_array(name, arr)
        raise InputError(str(err)) from err


class MixtureOfGPExpertsRegressor(RegressorMixin, BaseEstimator):
    """Mixture of GP experts fitted by EM, as a scikit-learn regressor.

    `fit` builds a `MixtureOfGPExperts` from the mixture's arguments and fits it with
    `fit_em` under the `EMOptions` made from the EM arguments (the other fields of
    `EMOptions` keep their defaults). With an integer `random_state` the fit is exactly
    ``fit_em(model, X, y, options)`` with ``seed=random_state``, and deterministic; with None
    or a ``numpy.random.RandomState`` a seed is drawn from it at every fit. Targets are
    fitted jointly: every expert models the `T` targets as independent GPs sharing its
    samples, and the gate decides the expert for all of them.

    Args:
        n_experts: Number of experts `M`.
        gate: ``"linear"`` (softmax on the gate features) or ``"fourier"`` (softmax on random
            Fourier features); see `MixtureOfGPExperts`.
        gate_l2: L2 penalty of the gate's weights, or ``"cv"`` to choose it by inner
            cross-validation.
        gate_l1: L1 penalty of the gate's weights, or ``"cv"`` (cross-validated together
            with `gate_l2`); see `MixtureOfGPExperts`.
        groups: Named column groups of `X` (slices or index lists), for `gate_features` and
            `expert_features`; None for none.
        gate_features: Columns of `X` the gate sees: None (all), group name(s) or column
            indices.
        expert_features: Columns of `X` every expert sees, in the same forms.
        gp_max_iter: L-BFGS iterations of an expert's first fit (``GPOptions.max_iter``).
        lengthscale_prior: Give the experts' length scales the dimension-scaled log-normal
            prior (default, as in `MixtureOfGPExperts`); True puts it at the default width,
            a number > 0 at that width (`GPOptions`).
        noise_floor: Smallest noise standard deviation of every expert, in target units:
            ``"auto"`` (1 % of each target's standard deviation), one value, one per target,
            or None. These three are flat, as scikit-learn's `get_params` / `set_params`
            (and so `GridSearchCV`) need; the defaults are those of
            `probaff.models.options.MIXTURE_GP`, and `fit` hands the mixture one `GPOptions`
            of them (`gp_options`).
        experts: ``"auto"``, ``"exact"`` or ``"sparse"`` GP experts (see
            `MixtureOfGPExperts`).
        n_inducing: Inducing points of sparse experts; None for the default.
        point: What `predict` returns: ``"mean"`` (default), the mixture's predictive mean,
            or ``"stacked"``, the mean stacked with a single GP (see `MixtureOfGPExperts`).
        init: EM start: ``"auto"``, ``"grow"``, ``"joint"`` or ``"effects"`` (see `fit_em`).
        n_restarts: EM starts tried for each mixture size.
        screen_iter: Iterations every start runs before only the best is run to convergence;
            None runs every start to convergence.
        split_merge: Rounds of split-and-merge moves after convergence (0: none).
        max_iter: Maximum EM iterations of a run.
        tol: Convergence tolerance on the objective per sample.
        n_init: Restarts of each initial Gaussian mixture.
        anneal: Temper the E-step (deterministic annealing).
        random_state: Integer seed (>= 0), ``numpy.random.RandomState`` or None.

    Attributes:
        model_: The fitted `MixtureOfGPExperts`.
        history_: Its `EMHistory` (objective per iteration, starts tried, repairs).
        n_features_in_: Number of columns `D` of `X` seen by `fit`.
        n_targets_: Number of targets `T` (1 for a 1-D `y`).
        n_iter_: EM iterations of the kept run (`history_.n_iter`).
        seed_: The `EMOptions.seed` of the fit.
        feature_names_in_: Column names of `X`, when `fit` was given a DataFrame with string
            column names.

    Example:
        Two regimes along one input, numpy in and out:

        >>> import numpy as np
        >>> from probaff.models import MixtureOfGPExpertsRegressor
        >>> X = np.linspace(0.0, 1.0, 40)[:, None]  # (40, 1)
        >>> y = np.where(X[:, 0] < 0.5, np.sin(6.0 * X[:, 0]), 1.0)  # (40,)
        >>> reg = MixtureOfGPExpertsRegressor(
        ...     n_experts=2, init="joint", n_restarts=1, split_merge=0, max_iter=5, random_state=0
        ... ).fit(X, y)
        >>> mean, std = reg.predict(X[:3], return_std=True)
        >>> mean.shape, std.shape, reg.n_features_in_
        ((3,), (3,), 1)
    """

    def __init__(
        self,
        n_experts: int = 2,
        *,
        gate: str = "linear",
        gate_l2: float | str = "cv",
        gate_l1: float | str = "cv",
        groups: dict[str, slice | Sequence[int]] | None = None,
        gate_features: str | Sequence[str] | Sequence[int] | None = None,
        expert_features: str | Sequence[str] | Sequence[int] | None = None,
        gp_max_iter: int = 50,
        lengthscale_prior: bool | float = True,
        noise_floor: float | Sequence[float] | str | None = "auto",
        experts: str = "auto",
        n_inducing: int | None = None,
        point: str = "mean",
        init: str = "auto",
        n_restarts: int = 3,
        screen_iter: int | None = 2,
        split_merge: int = 2,
        max_iter: int = 10,
        tol: float = 1e-3,
        n_init: int = 20,
        anneal: bool = False,
        random_state: int | np.random.RandomState | None = None,
    ) -> None:
        self.n_experts = n_experts
        self.gate = gate
        self.gate_l2 = gate_l2
        self.gate_l1 = gate_l1
        self.groups = groups
        self.gate_features = gate_features
        self.expert_features = expert_features
        self.gp_max_iter = gp_max_iter
        self.lengthscale_prior = lengthscale_prior
        self.noise_floor = noise_floor
        self.experts = experts
        self.n_inducing = n_inducing
        self.point = point
        self.init = init
        self.n_restarts = n_restarts
        self.screen_iter = screen_iter
        self.split_merge = split_merge
        self.max_iter = max_iter
        self.tol = tol
        self.n_init = n_init
        self.anneal = anneal
        self.random_state = random_state

    def __sklearn_tags__(self) -> Any:
        """scikit-learn's tags: one target or several at once; NaN and inf are refused."""
        tags = super().__sklearn_tags__()
        tags.target_tags.single_output = True
        tags.target_tags.multi_output = True
        tags.input_tags.allow_nan = False
        return tags

    # ------------------------------------------------------------------ build
    def _seed(self) -> int:
        """`EMOptions.seed` of a fit: the integer `random_state`, or one drawn from it."""
        state = self.random_state
        if isinstance(state, (int, np.integer)) and not isinstance(state, bool):
            if state < 0:
                raise InputError(f"random_state must be >= 0, None or a RandomState, got {state}.")
            return int(state)
        if state is not None and not isinstance(state, np.random.RandomState):
            raise InputError(
                f"random_state must be an integer >= 0, None or a numpy RandomState, got "
                f"{type(state).__name__}."
            )
        return int(check_random_state(state).randint(_SEED_BOUND))

    def _check_init(self) -> str:
        """`init` as a name; responsibilities are refused (they fit one training set only)."""
        if not isinstance(self.init, str):
            raise InputError(
                f"init must be 'auto', 'grow', 'joint' or 'effects', got "
                f"{type(self.init).__name__}; use probaff.models.fit_em to start from "
                "responsibilities."
            )
        return self.init

    def em_options(self, seed: int = 0) -> EMOptions:
        """The `EMOptions` of a fit with the given seed.

        Args:
            seed: `EMOptions.seed` (`fit` passes `seed_`).

        Returns:
            Validated options: `init`, `n_restarts`, `screen_iter`, `split_merge`,
            `max_iter`, `tol`, `n_init` and `anneal` from the estimator, the rest default.

        Raises:
            InputError: Naming the first EM argument out of range.
        """
        em = {name: getattr(self, name) for name in _EM_ARGS}
        return EMOptions(init=self._check_init(), seed=seed, **em)

    def make_model(self) -> MixtureOfGPExperts:
        """A fresh, unfitted `MixtureOfGPExperts` with the estimator's mixture arguments.

        Returns:
            The mixture `fit` fits.

        Raises:
            InputError: For an unknown gate or feature group, or a value out of range.
        """
        mixture = {name: getattr(self, name) for name in _MIXTURE_ARGS}
        return MixtureOfGPExperts(self.n_experts, **mixture, gp=self.gp_options())

    def gp_options(self) -> GPOptions:
        """The experts' settings of a fit: `gp_max_iter`, `lengthscale_prior`, `noise_floor`.

        Returns:
            One `GPOptions` (its other fields `GPOptions`' defaults, as `MIXTURE_GP`'s).

        Raises:
            InputError: Naming the first argument out of range.
        """
        check_count("gp_max_iter", self.gp_max_iter)
        return GPOptions(**{field: getattr(self, arg) for arg, field in FLAT_GP_KEYWORDS.items()})

    # -------------------------------------------------------------------- fit
    @threads_by_rows("X")
    def fit(self, X: Any, y: Any) -> MixtureOfGPExpertsRegressor:
        """Fit the mixture to `X` and `y` by EM.

        Args:
            X: Features, array-like `(N, D)`, N >= 2.
            y: Targets, `(N,)` or `(N, T)`.

        Returns:
            The fitted estimator.

        Raises:
            InputError: For NaN/inf, non-numeric, empty or mismatched inputs, more experts
                than samples, or an argument out of range.
        """
        X, y = _validated(
            self, X, y, multi_output=True, y_numeric=True, dtype=np.float64, ensure_min_samples=2
        )
        y2 = as_float_array("y", y).reshape(len(y), -1)  # strings pass y_numeric
        seed = self._seed()
        options = self.em_options(seed)
        model = self.make_model()
        self.history_: EMHistory = fit_em(model, torch.tensor(X), torch.tensor(y2), options)
        self.model_ = model
        self.seed_ = seed
        self.n_iter_ = self.history_.n_iter
        self.n_targets_ = int(y2.shape[1])
        return self

    # ---------------------------------------------------------------- predict
    @threads_by_rows("X")
    def predict(self, X: Any, return_std: bool = False) -> Any:
        """Point prediction (and predictive standard deviation) of the targets.

        The point is `MixtureOfGPExperts.predict_point` (``point="mean"``: the mixture's
        mean; ``point="stacked"``: the mean stacked with a single GP).

        Shapes follow scikit-learn's `GaussianProcessRegressor`: one target (a 1-D `y`, or
        a `y` of one column) gives `(N,)` arrays, `T > 1` targets give `(N, T)`.

        Args:
            X: Features, array-like `(N, D)` with the columns seen by `fit`.
            return_std: Also return the predictive standard deviation of each target: the
                mixture's (gate-weighted experts, observation noise included), in target
                units.

        Returns:
            The point, float64 `(N,)` or `(N, T)`; with `return_std`, ``(point, std)`` of
            the same shape.

        Raises:
            EstimatorNotFittedError: Before `fit`.
            InputError: For NaN/inf, non-numeric input or a wrong number of columns.
        """
        self._check_fitted()
        X = _validated(self, X, dtype=np.float64, reset=False)
        with torch.no_grad():
            dist = self.model_.predict(torch.tensor(X))
            mean = self.model_.predict_point(torch.tensor(X), mean=dist.mean).numpy()
            std = dist.variance.clamp_min(0.0).sqrt().numpy() if return_std else None
        squeeze = self.n_targets_ == 1
        mean = mean[:, 0] if squeeze else mean
        if std is None:
            return mean
        return mean, std[:, 0] if squeeze else std

    @threads_by_rows("X")
    def log_predictive_density(self, X: Any, y: Any) -> np.ndarray:
        """Log density of each sample's targets under the mixture's predictive distribution.

        Args:
            X: Features, array-like `(N, D)` with the columns seen by `fit`.
            y: Targets, `(N,)` or `(N, T)` with the `T` targets seen by `fit`.

        Returns:
            `log p(y_i | x_i)` in nats (joint over the targets), float64 `(N,)`.

        Raises:
            EstimatorNotFittedError: Before `fit`.
            InputError: For NaN/inf, non-numeric or mismatched inputs, or another number of
                targets than `fit` saw.
        """
        self._check_fitted()
        X, y = _validated(
            self, X, y, reset=False, multi_output=True, y_numeric=True, dtype=np.float64
        )
        y2 = as_float_array("y", y).reshape(len(y), -1)
        if y2.shape[1] != self.n_targets_:
            raise InputError(
                f"y has {y2.shape[1]} target(s), but {type(self).__name__} was fitted on "
                f"{self.n_targets_}."
            )
        with torch.no_grad():
            return self.model_.predict(torch.tensor(X)).log_prob(torch.tensor(y2)).numpy()

    def _check_fitted(self) -> None:
        try:
            check_is_fitted(self, "model_")
        except SklearnNotFittedError as err:
            raise EstimatorNotFittedError(
                f"this {type(self).__name__} is not fitted; call fit(X, y) before predict."
            ) from err


def mean_log_predictive_density(estimator: Any, X: Any, y: Any) -> float:
    """Scorer: the mean log predictive density of `y` per sample, in nats (higher is better).

    For ``scoring=`` of `cross_val_score` or `GridSearchCV`, where the default R² judges only
    the predictive mean; this judges the whole predictive distribution (the spread of the
    noise and the experts' weights), which is what extra experts change.

    Args:
        estimator: A fitted `MixtureOfGPExpertsRegressor`, or a fitted `Pipeline` whose last
            step is one (the earlier steps transform `X`).
        X: Features, `(N, D)`.
        y: Targets, `(N,)` or `(N, T)`, in the units `fit` saw.

    Returns:
        The mean over the samples of `MixtureOfGPExpertsRegressor.log_predictive_density`.

    Raises:
        InputError: If `estimator` is neither, or as `log_predictive_density`.
    """
    final = estimator
    if isinstance(estimator, Pipeline):
        final = estimator[-1]
        X = estimator[:-1].transform(X)
    if not isinstance(final, MixtureOfGPExpertsRegressor):
        raise InputError(
            f"mean_log_predictive_density scores a MixtureOfGPExpertsRegressor or a Pipeline "
            f"ending in one, got {type(final).__name__}."
        )
    return float(np.mean(final.log_predictive_density(X, y)))
