"""Side-by-side cross-validation of probaff's push-effect models against standard peers.

Every model is fitted on the same K folds (``KFold(shuffle=True, random_state=seed)``) of
each data set, in the same run, and scored on the held-out fold by

* NLPD per test point (nats): the per-output marginal NLPDs of `probaff.eval.metrics.nlpd`
  summed over the outputs, averaged over test points; the joint ``-log p(y)`` of the full
  predictive is recorded too (``nlpd_joint``; equal to NLPD for a single Gaussian);
* RMSE of the predictive mean per output, and their mean after dividing each by the standard
  deviation of that output over the whole data set (``srmse``); the point is the model's
  point prediction (`probaff.models.point_prediction`: ``em_stacked``'s stacked point, see
  `probaff.models.mixture.point`; the predictive mean for every other model), and ``srmse_mean``
  (in ``peers.csv``) is the same for the predictive mean;
* coverage of the central 90 % predictive interval, averaged over the outputs;
* wall-clock seconds of fit plus predict (one torch and one BLAS thread per task; each
  process first fits every model once on a tiny problem, untimed, so that imports and other
  one-time costs do not land on the first fold).

Models (``MODELS``; each is ``fit_predict(X_train, Y_train, X_test, seed, *, n_experts,
budget) -> Prediction``: a distribution with batch shape ``(N_test,)`` and event shape
``(E,)``, or that distribution and the model's point prediction ``(N_test, E)``):

* ``single_gp``: one `GPExpert` (independent SE-ARD GPs per output, length-scale prior).
* ``ccr``: cluster-classify-regress. ``[X, Y]`` are standardised jointly and clustered by a
  ``GaussianMixture`` with M components and 10 restarts (full covariances when the training
  fold has at least ``2 * M * (D + E)`` rows, diagonal ones otherwise); a multinomial
  ``LogisticRegression`` (C = 1) on standardised X is the gate; each cluster gets one
  scikit-learn ``GaussianProcessRegressor`` per output dimension (``ConstantKernel * RBF``
  with one length scale per feature, ``+ WhiteKernel``, ``normalize_y=True``, 2 optimizer
  restarts) on standardised X. The prediction mixes the clusters' Gaussian predictive
  distributions (noise included) with the gate's probabilities.
* ``clustered``: chapter 4's `ClusteredGPModel` with the SVM's calibrated probabilities as a
  soft gate, clustering on effect columns (0, 1) (column 0 for one-output data).
* ``em``: `MixtureOfGPExperts` fitted by `fit_em` with its defaults. When `fit_em` takes an
  ``init`` argument, ``em_effects``, ``em_joint`` and ``em_grow`` run it with that
  initialisation.
* ``em_finish2``: the default EM with its two best screened starts run to convergence
  (``n_finish=2``).
* ``em_stacked``: the default EM fit of a mixture with ``point="stacked"``: the same
  distribution (NLPD) as ``em``, with RMSE scored on the mean stacked with a single GP
  (`probaff.models.mixture.point`).
* ``vi``: `VariationalMixtureOfGPExperts` (``min(32, N)`` inducing points) fitted by
  `fit_svi`.

Every mixture uses the data set's M (3 for all data sets below) so that the comparison is of
methods, not of model sizes. Gates and experts see every feature column.

Data sets (fixed data, seed 0; the CLI seed sets folds and fits only):

* ``ch5``: 321 simulated two-object pushes (poses observed with `PoseNoise()`, whose
  effect noise is every GP model's noise floor), features f_o & f_c (21 columns), 6 effects
  (dy, dz, dth of both objects); generated under ``OUT/data/`` on first use (about 15 s).
* ``ch4``: 120 simulated single-object pushes near an obstacle, f_o & f_c (55 columns),
  3 effects.
* ``synthetic``: ``softmax_regimes(400, seed=0)``, three softmax-gated regimes that overlap
  in output space (4 inputs, 2 outputs).
* ``diabetes``: scikit-learn's diabetes data (442 patients, 10 standardised baseline
  variables, disease progression after one year).
* ``engel``: statsmodels' Engel data (235 Belgian households in 1857, food expenditure
  against income), kept in its original units (Belgian francs) so that the spread of food
  expenditure growing with income stays in the data; every model standardises internally.

Results: ``OUT/tasks/`` holds one JSON file per (data set, model, fold), written as soon as
that fit is scored, so an interrupted run resumes where it stopped; a fit that raises is
stored with its error (delete its file to retry). ``OUT/peers.csv`` has one row per data
set, model and fold, ``OUT/peers.md`` the mean and a 95 % t-interval over folds per data set
(best NLPD in bold), and ``OUT/peers.png`` NLPD by model per data set.

Usage::

    python benchmarks/mixture_peers.py [--datasets ch5,synthetic] [--models em,ccr]
        [--folds 5] [--seed 0] [--out results/mixture_peers] [--workers 0] [--smoke]
        [--rows N] [--write-reference FILE] [--reference FILE [--tolerance NATS]
        [--rmse-tolerance REL]]

``--smoke`` uses 60 rows per data set, 2 folds (unless ``--folds`` is given) and a few
optimiser iterations; ``--rows N`` caps the rows per data set at N with the full optimiser
budget (ch5 and ch4 generate N pushes); ``--workers K`` runs the fits on a local Dask cluster
of K processes.

Regression guard: ``--write-reference FILE`` writes the run's means with their 95 %
half-widths per data set, model and metric (NLPD, SRMSE, RMSE per output; `reference_text`),
headed by the run's settings (folds, seed, rows, smoke, budget, data sets, models and the
data sets' shapes), atomically. ``--reference FILE`` checks before any fit that the table was
made with the same folds, seed, rows, smoke and budget, on data of the same shapes, and holds
every (data set, model) of the run; after the run it prints (and saves as
``OUT/peers_vs_reference.md``) each mean beside the reference's, and exits with status 1 if a
mean NLPD exceeds the reference's by more than ``--tolerance`` (`NLPD_TOLERANCE`, 0.05 nats
per test point), a mean SRMSE or per-output RMSE exceeds the reference's times ``1 +
--rmse-tolerance`` (`RMSE_TOLERANCE`, 0.05), or fewer folds were scored
(`compare_with_reference`). The folds, seeds and data are fixed, so an unchanged code base
reproduces its reference; the tolerances absorb platform rounding, not sampling noise.
Committed references live in ``benchmarks/reference/``: ``mixture_peers_fast.csv`` (CI's
subset, checked by ``tests/test_benchmark_mixture_peers.py``)::

    python benchmarks/mixture_peers.py --datasets engel,motorcycle,synthetic \
        --models em,single_gp --folds 2 --rows 200 --out results/mixture_peers_fast \
        --write-reference benchmarks/reference/mixture_peers_fast.csv

and ``mixture_peers.csv`` (every data set and model, 5 folds; 20+ minutes)::

    python benchmarks/mixture_peers.py --out results/mixture_peers \
        --write-reference benchmarks/reference/mixture_peers.csv

Exit status: 0, 1 for a regression (or a reference left unwritten because a fit failed), 2
for a user's error (one line on stderr).
"""

from __future__ import annotations

import argparse
import contextlib
import csv
import dataclasses
import functools
import hashlib
import inspect
import io
import json
import math
import sys
import time
import warnings
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch
from matplotlib.figure import Figure
from scipy import stats
from sklearn.model_selection import KFold
from threadpoolctl import threadpool_limits
from torch.distributions import Distribution, Independent, Normal

from probaff._checks import check_output_file
from probaff._io import atomic_save_figure, atomic_write_text, read_user_text
from probaff._threads import limit_threads
from probaff.errors import InputError
from probaff.eval.metrics import interval_coverage, nlpd, rmse
from probaff.eval.tasks import ResultStore, run_tasks
from probaff.models import (
    ClusteredGPModel,
    GPExpert,
    GPOptions,
    MixtureOfGPExperts,
    VariationalMixtureOfGPExperts,
    fit_em,
    fit_svi,
    point_prediction,
)
from probaff.models.mixture.model import mixture_distribution

Prediction = Distribution | tuple[Distribution, torch.Tensor]
"""What a model of the benchmark returns: its distribution, or it and its point prediction."""

SMOKE_ROWS = 60
"""Rows per data set under ``--smoke``."""


# ------------------------------------------------------------------------------ budgets
@dataclass(frozen=True)
class Budget:
    """Optimiser effort shared by every model.

    Attributes:
        gp_iter: L-BFGS iterations per probaff GP expert fit.
        em_iter: EM iterations.
        svi_steps: SVI steps.
        sk_restarts: Optimizer restarts of each scikit-learn GP.
    """

    gp_iter: int = 50
    em_iter: int = 10
    svi_steps: int = 1500
    sk_restarts: int = 2


FULL = Budget()
SMOKE = Budget(gp_iter=5, em_iter=2, svi_steps=20, sk_restarts=0)


# ------------------------------------------------------------------------------- models
@dataclass(frozen=True)
class Fold:
    """What a model sees of one fold.

    Attributes:
        X_train: Training features, `(N, D)`.
        Y_train: Training targets, `(N, E)`.
        X_test: Held-out features to predict at, `(N_test, D)`.
        seed: Seed of the fit.
        n_experts: M of the mixture models.
        budget: Optimiser effort.
        noise_floor: Known noise standard deviation per output, or ``None``.
    """

    X_train: np.ndarray
    Y_train: np.ndarray
    X_test: np.ndarray
    seed: int
    n_experts: int = 3
    budget: Budget = FULL
    noise_floor: list[float] | None = None


@dataclass(frozen=True)
class FitPredict:
    """Fit on a training fold and return the predictive distribution at the test inputs.

    Called as ``model(X_train, Y_train, X_test, seed, *, n_experts, budget, noise_floor)``;
    the distribution has batch shape ``(N_test,)`` and event shape ``(E,)``.

    Attributes:
        fit_predict: The model, on a `Fold`.
    """

    fit_predict: Callable[[Fold], Prediction]

    def __call__(
        self,
        X_train: np.ndarray,
        Y_train: np.ndarray,
        X_test: np.ndarray,
        seed: int,
        *,
        n_experts: int = 3,
        budget: Budget = FULL,
        noise_floor: list[float] | None = None,
    ) -> Distribution:
        return self.fit_predict(
            Fold(X_train, Y_train, X_test, seed, n_experts, budget, noise_floor)
        )


@FitPredict
def single_gp(fold: Fold) -> Distribution:
    """One probaff GP expert over all the data (`seed` and `n_experts` are unused)."""
    gp = GPExpert(
        fold.X_train.shape[1],
        fold.Y_train.shape[1],
        max_iter=fold.budget.gp_iter,
        lengthscale_prior=True,
        noise_floor=fold.noise_floor,
    ).fit(fold.X_train, fold.Y_train)
    return Independent(gp.predict(fold.X_test), 1)


@FitPredict
def ccr(fold: Fold) -> Distribution:
    """Cluster [X, Y] with a GMM, gate with logistic regression, one sklearn GP per cluster."""
    from sklearn.gaussian_process import GaussianProcessRegressor
    from sklearn.gaussian_process.kernels import RBF, ConstantKernel, WhiteKernel
    from sklearn.linear_model import LogisticRegression
    from sklearn.mixture import GaussianMixture
    from sklearn.preprocessing import StandardScaler

    n, d = fold.X_train.shape
    e = fold.Y_train.shape[1]
    joint = StandardScaler().fit_transform(np.hstack([fold.X_train, fold.Y_train]))
    covariance = "full" if n >= 2 * fold.n_experts * (d + e) else "diag"
    gmm = GaussianMixture(
        fold.n_experts,
        covariance_type=covariance,
        n_init=10,
        random_state=fold.seed,
        reg_covar=1e-6,
    )
    labels = gmm.fit_predict(joint)
    classes = np.unique(labels)
    x_scaler = StandardScaler().fit(fold.X_train)
    xs, xt = x_scaler.transform(fold.X_train), x_scaler.transform(fold.X_test)
    if len(classes) > 1:
        gate = LogisticRegression(C=1.0, max_iter=1000).fit(xs, labels)
        probs = gate.predict_proba(xt)  # columns in the order of `classes`
    else:
        probs = np.ones((len(fold.X_test), 1))
    loc = np.empty((len(fold.X_test), len(classes), e))
    scale = np.empty_like(loc)
    for k, c in enumerate(classes):
        rows = labels == c
        for j in range(e):
            kernel = ConstantKernel(1.0) * RBF(
                np.ones(d), length_scale_bounds=(1e-3, 1e5)
            ) + WhiteKernel(0.1, noise_level_bounds=(1e-6, 1e1))
            gpr = GaussianProcessRegressor(
                kernel,
                normalize_y=True,
                random_state=fold.seed,
                n_restarts_optimizer=fold.budget.sk_restarts,
            )
            gpr.fit(xs[rows], fold.Y_train[rows, j])
            mean, std = gpr.predict(xt, return_std=True)
            loc[:, k, j], scale[:, k, j] = mean, np.maximum(std, 1e-9)
    return mixture_distribution(
        torch.as_tensor(probs, dtype=torch.float64),
        Normal(torch.as_tensor(loc), torch.as_tensor(scale)),
    )


@FitPredict
def clustered(fold: Fold) -> Distribution:
    """Chapter 4's GMM-clustered GP experts with a soft (calibrated SVM) gate."""
    dims = (0, 1) if fold.Y_train.shape[1] > 1 else (0,)
    model = ClusteredGPModel(
        fold.n_experts,
        cluster_dims=dims,
        seed=fold.seed,
        soft_gate=True,
        gp=GPOptions(
            max_iter=fold.budget.gp_iter, lengthscale_prior=True, noise_floor=fold.noise_floor
        ),
    )
    return model.fit(fold.X_train, fold.Y_train).predict(fold.X_test)


def _em(fold: Fold, fit: Callable[..., Any] = fit_em, point: str = "mean") -> Prediction:
    """probaff's mixture of GP experts fitted by EM (`fit` is `fit_em` or a partial of it)."""
    gp = GPOptions(
        max_iter=fold.budget.gp_iter,
        lengthscale_prior=True,
        noise_floor="auto" if fold.noise_floor is None else fold.noise_floor,
    )
    model = MixtureOfGPExperts(
        fold.n_experts, gp=gp, **({} if point == "mean" else {"point": point})
    )
    fit(model, fold.X_train, fold.Y_train, seed=fold.seed, max_iter=fold.budget.em_iter)
    return model.predict(fold.X_test), point_prediction(model, fold.X_test)


em = FitPredict(_em)


@FitPredict
def vi(fold: Fold) -> Distribution:
    """probaff's mixture of sparse variational GP experts fitted by Pyro SVI."""
    model = VariationalMixtureOfGPExperts(fold.n_experts, n_inducing=min(32, len(fold.X_train)))
    fit_svi(model, fold.X_train, fold.Y_train, seed=fold.seed, n_steps=fold.budget.svi_steps)
    return model.predict(fold.X_test)


def fit_em_accepts(name: str) -> bool:
    """Whether this probaff's `fit_em` takes the option `name` (as a keyword or an
    `EMOptions` field), so that the benchmark also runs against earlier versions."""
    import probaff.models

    options = getattr(probaff.models, "EMOptions", None)
    fields = {f.name for f in dataclasses.fields(options)} if options is not None else set()
    return name in inspect.signature(fit_em).parameters or name in fields


EM_INITS = ("effects", "joint", "grow")
"""Initialisations of `fit_em` benchmarked as ``em_<name>`` when `fit_em` accepts ``init``."""

MODELS: dict[str, FitPredict] = {
    "single_gp": single_gp,
    "ccr": ccr,
    "clustered": clustered,
    "em": em,
}
if fit_em_accepts("init"):
    for _init in EM_INITS:
        MODELS[f"em_{_init}"] = FitPredict(
            functools.partial(_em, fit=functools.partial(fit_em, init=_init))
        )
if fit_em_accepts("n_finish"):
    MODELS["em_finish2"] = FitPredict(
        functools.partial(_em, fit=functools.partial(fit_em, n_finish=2))
    )
if "point" in inspect.signature(MixtureOfGPExperts).parameters:
    MODELS["em_stacked"] = FitPredict(functools.partial(_em, point="stacked"))
MODELS["vi"] = vi


# ----------------------------------------------------------------------------- data sets
@dataclass(frozen=True)
class Dataset:
    """A regression data set.

    Attributes:
        name: Short name (used in keys and tables).
        X: Features, `(N, D)` float64.
        Y: Targets, `(N, E)` float64.
        outputs: Names of the E targets.
        n_experts: M used by every mixture model on this data set.
        noise_floor: Known measurement-noise standard deviation per output (the GP models'
            noise floor), or ``None``.
        about: One-line description.
    """

    name: str
    X: np.ndarray
    Y: np.ndarray
    outputs: tuple[str, ...]
    n_experts: int = 3
    about: str = ""
    noise_floor: list[float] | None = None


def _subsample(X: np.ndarray, Y: np.ndarray, rows: int | None) -> tuple[np.ndarray, np.ndarray]:
    """At most `rows` rows, drawn without replacement with a fixed seed."""
    X, Y = np.asarray(X, dtype=np.float64), np.asarray(Y, dtype=np.float64)
    if Y.ndim == 1:
        Y = Y[:, None]
    if rows is None or rows >= len(X):
        return X, Y
    keep = np.sort(np.random.default_rng(0).choice(len(X), rows, replace=False))
    return X[keep], Y[keep]


def _noisy_pushes(kind: str, n: int, data_root: Path, progress: bool) -> Any:
    """`n` simulated pushes of scene `kind` (seed 0, poses observed with `PoseNoise()`),
    generated under `data_root` on first use and read back afterwards."""
    from probaff.data.generation import GenerateConfig, generate
    from probaff.data.noise import PoseNoise

    return generate(
        GenerateConfig(kind, n, seed=0, pose_noise=PoseNoise()),
        data_root / f"{kind}-noisy-n{n}",
        workers=0,
        resume=True,
        progress=progress,
    )


def load_ch5(data_root: Path, rows: int | None, progress: bool) -> Dataset:
    """Chapter 5 two-object pushes: f_o & f_c features, (dy, dz, dth) of both objects."""
    from probaff.data.noise import PoseNoise
    from probaff.features import chapter5_features

    n = rows or 321
    ds = _noisy_pushes("two_objects", n, data_root, progress)
    X = chapter5_features(ds).select("f_o", "f_c")
    Y = ds["effect"][:, :2].reshape(len(ds), 6)
    return Dataset(
        "ch5",
        *_subsample(X, Y, None),
        ("o1.dy", "o1.dz", "o1.dth", "o2.dy", "o2.dz", "o2.dth"),
        about=f"{n} simulated two-object pushes, f_o & f_c, poses observed with PoseNoise()",
        noise_floor=PoseNoise().effect_std(2),
    )


def load_ch4(data_root: Path, rows: int | None, progress: bool) -> Dataset:
    """Chapter 4 single-object pushes near an obstacle: f_o & f_c, (dy, dz, dth)."""
    from probaff.data.noise import PoseNoise
    from probaff.features import chapter4_features

    n = rows or 120
    ds = _noisy_pushes("near_obstacle", n, data_root, progress)
    X = chapter4_features(ds).select("f_o", "f_c")
    return Dataset(
        "ch4",
        *_subsample(X, ds["effect"][:, 0], None),
        ("dy", "dz", "dth"),
        about=f"{n} simulated single-object pushes near an obstacle, f_o & f_c, "
        "poses observed with PoseNoise()",
        noise_floor=PoseNoise().effect_std(1),
    )


def load_synthetic(data_root: Path, rows: int | None, progress: bool) -> Dataset:
    """Three softmax-gated regimes overlapping in output space."""
    from probaff.models.synthetic import softmax_regimes

    x, y, _ = softmax_regimes(rows or 400, seed=0)
    return Dataset(
        "synthetic",
        x.numpy(),
        y.numpy(),
        ("y0", "y1"),
        about="softmax_regimes(seed=0): 3 gated regimes, 4 inputs",
    )


def load_diabetes(data_root: Path, rows: int | None, progress: bool) -> Dataset:
    """scikit-learn's diabetes progression data (442 x 10)."""
    from sklearn.datasets import load_diabetes as sk_diabetes

    bunch = sk_diabetes()
    return Dataset(
        "diabetes",
        *_subsample(bunch.data, bunch.target, rows),
        ("progression",),
        about="sklearn diabetes: 10 baseline variables -> progression after 1 year",
    )


def load_engel(data_root: Path, rows: int | None, progress: bool) -> Dataset:
    """statsmodels' Engel food-expenditure data (235 x 1), heteroscedastic, original units."""
    from statsmodels.datasets import engel

    frame = engel.load().data
    return Dataset(
        "engel",
        *_subsample(frame[["income"]].to_numpy(), frame["foodexp"].to_numpy(), rows),
        ("foodexp",),
        about="statsmodels engel: food expenditure vs income, Belgian francs",
    )


def load_motorcycle(data_root: Path, rows: int | None, progress: bool) -> Dataset:
    """Silverman's motorcycle crash data (133 x 1): regimes of the acceleration curve, each
    with its own noise, as statsmodels ships it (time after impact in ms -> head
    acceleration in g)."""
    from importlib.resources import files

    text = (files("statsmodels") / "gam/tests/results/motorcycle.csv").read_text()
    data = np.loadtxt(text.splitlines(), delimiter=",", skiprows=1)
    return Dataset(
        "motorcycle",
        *_subsample(data[:, :1], data[:, 1], rows),
        ("accel",),
        about="statsmodels motorcycle: head acceleration (g) vs time after impact (ms)",
    )


Loader = Callable[[Path, int | None, bool], Dataset]

DATASETS: dict[str, Loader] = {
    "ch5": load_ch5,
    "ch4": load_ch4,
    "synthetic": load_synthetic,
    "diabetes": load_diabetes,
    "engel": load_engel,
    "motorcycle": load_motorcycle,
}


# -------------------------------------------------------------------------------- tasks
_WARMED: set[str] = set()


def _warm_up(model: str) -> None:
    """Run `model` once per process on a tiny problem so one-time costs are not timed."""
    if model in _WARMED:
        return
    _WARMED.add(model)
    rng = np.random.default_rng(0)
    x = rng.uniform(-1, 1, (24, 2))
    y = np.sin(3 * x[:, :1]) + 0.1 * rng.standard_normal((24, 1))
    # A failure here is ignored: only the timing of the real fit is at stake.
    with warnings.catch_warnings(), contextlib.suppress(Exception):
        warnings.simplefilter("ignore")
        MODELS[model](x[:16], y[:16], x[16:], 0, n_experts=2, budget=SMOKE)


def _split_prediction(pred: Prediction) -> tuple[Distribution, torch.Tensor | None]:
    """A model's distribution and its point prediction (None: the distribution's mean)."""
    if isinstance(pred, tuple):
        dist, point = pred
        return dist, torch.as_tensor(point, dtype=torch.float64).detach()
    return pred, None


def fit_and_score(task: dict[str, Any]) -> dict[str, Any]:
    """Fit one model on one training fold and score it on the held-out fold."""
    X, Y = np.asarray(task["X"]), np.asarray(task["Y"])
    train, test = np.asarray(task["train"]), np.asarray(task["test"])
    outputs: list[str] = list(task["outputs"])
    row: dict[str, Any] = {
        "dataset": task["dataset"],
        "model": task["model"],
        "fold": int(task["fold"]),
        "n_train": len(train),
        "n_test": len(test),
        "M": int(task["M"]),
        "outputs": outputs,
        "seconds": None,
        "nlpd": None,
        "nlpd_joint": None,
        "srmse": None,
        "coverage90": None,
        "rmse": None,
        "warnings": 0,
        "error": "",
    }
    fn = MODELS[task["model"]]
    budget = Budget(**task["budget"])
    with limit_threads(1), threadpool_limits(1), warnings.catch_warnings(record=True) as caught:
        _warm_up(task["model"])
        warnings.simplefilter("always")
        start = time.perf_counter()
        try:
            pred, point = _split_prediction(
                fn(
                    X[train],
                    Y[train],
                    X[test],
                    int(task["seed"]),
                    n_experts=int(task["M"]),
                    budget=budget,
                    noise_floor=task["noise_floor"],
                )
            )
            seconds = time.perf_counter() - start
            n_test, e = len(test), Y.shape[1]
            if tuple(pred.batch_shape) != (n_test,) or tuple(pred.event_shape) != (e,):
                raise ValueError(
                    f"prediction has batch {tuple(pred.batch_shape)} and event "
                    f"{tuple(pred.event_shape)}, expected ({n_test},) and ({e},)"
                )
            y = torch.as_tensor(Y[test], dtype=torch.float64)
            with torch.no_grad():
                per_output_rmse = rmse(pred if point is None else point, y).numpy()
                y_std = np.asarray(task["y_std"])
                row.update(
                    seconds=seconds,
                    nlpd=float(nlpd(pred, y).sum()),
                    nlpd_joint=float(-pred.log_prob(y).mean()),
                    srmse=float(np.mean(per_output_rmse / y_std)),
                    srmse_mean=float(np.mean(rmse(pred, y).numpy() / y_std)),
                    coverage90=float(interval_coverage(pred, y, 0.9).mean()),
                    rmse=[float(v) for v in per_output_rmse],
                )
        except Exception as exc:  # a failed fit is a result of the benchmark too
            row["error"] = f"{type(exc).__name__}: {exc}"[:500]
    row["warnings"] = len(caught)
    return row


def _fingerprint(ds: Dataset, folds: int, seed: int, budget: Budget) -> str:
    """Short hash of the settings that shape a task's result."""
    settings = {
        "folds": folds,
        "seed": seed,
        "budget": asdict(budget),
        "M": ds.n_experts,
        "shape": [list(ds.X.shape), list(ds.Y.shape)],
        "data": hashlib.sha1(
            np.ascontiguousarray(ds.X).tobytes() + np.ascontiguousarray(ds.Y).tobytes()
        ).hexdigest(),
    }
    return hashlib.sha1(json.dumps(settings, sort_keys=True).encode()).hexdigest()[:8]


def make_tasks(
    ds: Dataset, models: list[str], folds: int, seed: int, budget: Budget
) -> list[tuple[str, tuple[Any, ...]]]:
    """One task per model and fold; every model gets the same folds."""
    splits = list(KFold(folds, shuffle=True, random_state=seed).split(ds.X))
    tag = _fingerprint(ds, folds, seed, budget)
    y_std = ds.Y.std(axis=0)
    tasks = []
    for model in models:
        for f, (train, test) in enumerate(splits):
            task = {
                "dataset": ds.name,
                "model": model,
                "fold": f,
                "seed": seed,
                "M": ds.n_experts,
                "noise_floor": ds.noise_floor,
                "X": ds.X,
                "Y": ds.Y,
                "train": train,
                "test": test,
                "outputs": list(ds.outputs),
                "y_std": np.where(y_std > 0, y_std, 1.0),
                "budget": asdict(budget),
            }
            tasks.append((f"{ds.name}.{model}.fold{f}.{tag}", (task,)))
    return tasks


# ------------------------------------------------------------------------------ reports
def _csv(results: list[dict[str, Any]], datasets: list[Dataset]) -> str:
    """One row per data set, model and fold; RMSE columns are ``rmse.<output>``."""
    rmse_cols = list(dict.fromkeys(f"rmse.{o}" for ds in datasets for o in ds.outputs))
    fields = [
        "dataset",
        "model",
        "fold",
        "n_train",
        "n_test",
        "M",
        "nlpd",
        "nlpd_joint",
        "srmse",
        "srmse_mean",
        "coverage90",
        "seconds",
        *rmse_cols,
        "warnings",
        "error",
    ]
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=fields, extrasaction="ignore", restval="")
    writer.writeheader()
    for r in results:
        flat = {k: ("" if v is None else v) for k, v in r.items()}
        for name, v in zip(r["outputs"], r["rmse"] or [], strict=False):
            flat[f"rmse.{name}"] = v
        writer.writerow(flat)
    return buf.getvalue()


def mean_ci(values: list[float]) -> tuple[float, float]:
    """Mean and half-width of the 95 % Student-t interval (NaN for fewer than 2 values)."""
    a = np.asarray(values, dtype=np.float64)
    if a.size == 0:
        return math.nan, math.nan
    if a.size < 2:
        return float(a.mean()), math.nan
    half = stats.t.ppf(0.975, a.size - 1) * a.std(ddof=1) / math.sqrt(a.size)
    return float(a.mean()), float(half)


def summarise(results: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Per (data set, model): folds scored, mean and 95 % t-interval of each metric.

    ``rmse`` and ``rmse_ci`` are lists, one mean and half-width per output.
    """
    groups: dict[tuple[str, str], list[dict[str, Any]]] = {}
    for r in results:
        groups.setdefault((r["dataset"], r["model"]), []).append(r)
    rows = []
    for (dataset, model), rs in groups.items():
        ok = [r for r in rs if not r["error"]]
        row: dict[str, Any] = {
            "dataset": dataset,
            "model": model,
            "folds": len(ok),
            "of": len(rs),
            "outputs": rs[0]["outputs"],
            "errors": sorted({r["error"] for r in rs if r["error"]}),
        }
        for metric in ("nlpd", "nlpd_joint", "srmse", "coverage90", "seconds"):
            row[metric], row[f"{metric}_ci"] = mean_ci([r[metric] for r in ok])
        per_output = [mean_ci([r["rmse"][j] for r in ok]) for j in range(len(row["outputs"]))]
        row["rmse"] = [m for m, _ in per_output]
        row["rmse_ci"] = [h for _, h in per_output]
        rows.append(row)
    return rows


def _fmt(mean: float, half: float, digits: int) -> str:
    if math.isnan(mean):
        return "n/a"
    return f"{mean:.{digits}f}" if math.isnan(half) else f"{mean:.{digits}f} ± {half:.{digits}f}"


def _markdown(
    rows: list[dict[str, Any]],
    datasets: list[Dataset],
    folds: int,
    seed: int,
    budget: Budget,
    smoke: bool,
) -> str:
    """One table per data set, best mean NLPD in bold."""
    lines = [
        "# Mixture models and their peers, side by side",
        "",
        f"{folds}-fold cross-validation (seed {seed}), the same folds for every model; "
        f"budget {asdict(budget)}{' (smoke run)' if smoke else ''}.",
        "Cells: mean over folds ± half-width of the 95 % t-interval. NLPD: per test point, "
        "per-output marginal NLPDs summed over outputs (nats); NLPD joint: "
        "-log p(y) of the full predictive; SRMSE: mean over outputs of RMSE / std of the "
        "output; cov90: coverage of the central 90 % interval; s: fit + predict seconds.",
        "",
    ]
    for ds in datasets:
        sub = [r for r in rows if r["dataset"] == ds.name]
        if not sub:
            continue
        n, d = ds.X.shape
        lines += [
            f"## {ds.name}",
            "",
            f"{ds.about}; N = {n}, D = {d}, E = {ds.Y.shape[1]}, M = {ds.n_experts}.",
            "",
        ]
        scored = [r["nlpd"] for r in sub if not math.isnan(r["nlpd"])]
        best = min(scored) if scored else math.nan
        head = [
            "model",
            "folds",
            "NLPD",
            "NLPD joint",
            "SRMSE",
            "cov90",
            "s",
            *[f"RMSE {o}" for o in ds.outputs],
        ]
        lines += ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
        for r in sub:
            nl = _fmt(r["nlpd"], r["nlpd_ci"], 3)
            if r["nlpd"] == best:
                nl = f"**{nl}**"
            cells = [
                r["model"],
                f"{r['folds']}/{r['of']}",
                nl,
                _fmt(r["nlpd_joint"], r["nlpd_joint_ci"], 3),
                _fmt(r["srmse"], r["srmse_ci"], 3),
                _fmt(r["coverage90"], r["coverage90_ci"], 2),
                _fmt(r["seconds"], math.nan, 1),
                *[f"{v:.4g}" for v in r["rmse"]],
            ]
            lines.append("| " + " | ".join(cells) + " |")
        errors = [f"- {r['model']}: {e}" for r in sub for e in r["errors"]]
        lines += ["", *(["Failed fits:", "", *errors, ""] if errors else [])]
    return "\n".join(lines)


def plot(
    results: list[dict[str, Any]], rows: list[dict[str, Any]], datasets: list[Dataset], path: Path
) -> None:
    """Per data set: NLPD of every fold (grey) and the mean with its 95 % t-interval."""
    names = [ds.name for ds in datasets if any(r["dataset"] == ds.name for r in rows)]
    cols = min(3, max(1, len(names)))
    n_rows = max(1, math.ceil(len(names) / cols))
    fig = Figure(figsize=(4.5 * cols, 0.6 + 2.6 * n_rows))
    axes = fig.subplots(n_rows, cols, squeeze=False)
    for ax, name in zip(axes.flat, names, strict=False):
        sub = [r for r in rows if r["dataset"] == name]
        for i, r in enumerate(sub):
            folds = [
                x["nlpd"]
                for x in results
                if (x["dataset"], x["model"]) == (name, r["model"]) and not x["error"]
            ]
            ax.plot(folds, [i] * len(folds), "o", color="0.7", ms=4, zorder=1)
            half = 0.0 if math.isnan(r["nlpd_ci"]) else r["nlpd_ci"]
            ax.errorbar(
                [r["nlpd"]], [i], xerr=[[half], [half]], fmt="o", color="k", capsize=3, zorder=2
            )
        ax.set_yticks(range(len(sub)), [r["model"] for r in sub])
        ax.invert_yaxis()
        ax.set_title(name)
        ax.set_xlabel("held-out NLPD per point, nats (lower is better)")
        ax.grid(axis="x", alpha=0.3)
    for ax in list(axes.flat)[len(names) :]:
        ax.set_visible(False)
    fig.tight_layout()
    atomic_save_figure(fig, path, dpi=120)


# ---------------------------------------------------------------------------- reference
REFERENCE_VERSION = 1
"""Format version of a reference table (`reference_text`, `parse_reference`)."""

NLPD_TOLERANCE = 0.05
"""Default ``--tolerance``: nats per test point by which a mean NLPD may exceed the reference's.

The folds, seeds and data are fixed, so a rerun of unchanged code on the same platform
reproduces the reference to a few digits; the tolerance absorbs the last digits of other BLAS
builds and CPUs, not sampling noise, and is far below the differences between models
(tenths of a nat)."""

RMSE_TOLERANCE = 0.05
"""Default ``--rmse-tolerance``: relative amount (5 %) by which a mean SRMSE or per-output
RMSE may exceed the reference's."""

REFERENCE_COLUMNS = ("dataset", "model", "metric", "folds", "mean", "half_width")
"""Columns of a reference table: one row per data set, model and metric (``nlpd``, ``srmse``,
``rmse.<output>``), the folds scored, the mean over folds and the 95 % t half-width."""

_SETTINGS_LINE = "# settings: "
_LIKE_WITH_LIKE = ("folds", "seed", "rows", "smoke", "budget")
"""Settings a run must share with its reference (the data sets' shapes are checked too)."""


@dataclass(frozen=True)
class Regression:
    """A mean that is worse than its reference beyond the tolerance.

    Attributes:
        dataset: Data set.
        model: Model.
        metric: ``nlpd``, ``srmse``, ``rmse.<output>``, or ``folds`` (fits that failed).
        reference: The reference's value.
        now: This run's value.
        limit: The worst value accepted.
    """

    dataset: str
    model: str
    metric: str
    reference: float
    now: float
    limit: float

    def __str__(self) -> str:
        return (
            f"{self.dataset}/{self.model} {self.metric}: now {self.now:.4g}, reference "
            f"{self.reference:.4g}, worst accepted {self.limit:.4g}"
        )


def check_tolerance(option: str, value: Any) -> float:
    """`value` as a float, or `InputError` naming `option` unless it is a finite number >= 0.

    Args:
        option: The option's name (``"--tolerance"``).
        value: The number, or its text as typed.

    Returns:
        The tolerance.
    """
    try:
        tol = float(value)
    except (TypeError, ValueError):
        tol = math.nan
    if isinstance(value, bool) or not math.isfinite(tol) or tol < 0:
        raise InputError(f"{option} must be a finite number >= 0, got {value!r}.")
    return tol


def run_settings(
    datasets: list[Dataset],
    models: list[str],
    folds: int,
    seed: int,
    rows: int | None,
    smoke: bool,
    budget: Budget,
) -> dict[str, Any]:
    """The settings a reference records, so that a comparison compares like with like."""
    return {
        "version": REFERENCE_VERSION,
        "folds": folds,
        "seed": seed,
        "rows": rows,
        "smoke": smoke,
        "budget": asdict(budget),
        "datasets": [ds.name for ds in datasets],
        "models": list(models),
        "shapes": {ds.name: [*ds.X.shape, ds.Y.shape[1]] for ds in datasets},
    }


def _metrics(row: dict[str, Any]) -> list[tuple[str, float, float]]:
    """(metric, mean, half-width) of a summary row: NLPD, SRMSE, then RMSE per output."""
    halves = row.get("rmse_ci") or [math.nan] * len(row["rmse"])
    return [
        ("nlpd", row["nlpd"], row["nlpd_ci"]),
        ("srmse", row["srmse"], row["srmse_ci"]),
        *((f"rmse.{o}", m, h) for o, m, h in zip(row["outputs"], row["rmse"], halves, strict=True)),
    ]


def reference_text(settings: dict[str, Any], rows: list[dict[str, Any]]) -> str:
    """A reference table: comment lines, the settings as JSON, then `REFERENCE_COLUMNS`.

    Args:
        settings: `run_settings` of the run.
        rows: `summarise` rows of the run.
    """
    buf = io.StringIO()
    buf.write(
        "# Reference of benchmarks/mixture_peers.py (written by --write-reference; compared by "
        "--reference). Lower is better for every metric.\n"
    )
    buf.write(_SETTINGS_LINE + json.dumps(settings, sort_keys=True) + "\n")
    writer = csv.writer(buf, lineterminator="\n")
    writer.writerow(REFERENCE_COLUMNS)
    for row in rows:
        for metric, mean, half in _metrics(row):
            writer.writerow(
                [row["dataset"], row["model"], metric, row["folds"], f"{mean:.8g}", f"{half:.8g}"]
            )
    return buf.getvalue()


def _parse_settings(lines: list[str], name: str) -> dict[str, Any]:
    """The settings line of a reference table, checked."""
    found = [line[len(_SETTINGS_LINE) :] for line in lines if line.startswith(_SETTINGS_LINE)]
    if len(found) != 1:
        raise InputError(
            f"{name} has {len(found)} '{_SETTINGS_LINE.strip()}' lines, not one; it is not a "
            "reference table of --write-reference (write it again)."
        )
    try:
        settings = json.loads(found[0])
    except json.JSONDecodeError as exc:
        raise InputError(
            f"{name}: its settings line is not JSON ({exc}); write it again."
        ) from None
    kinds: dict[str, Any] = {
        "version": int,
        "folds": int,
        "seed": int,
        "rows": (int, type(None)),
        "smoke": bool,
        "budget": dict,
        "datasets": list,
        "models": list,
        "shapes": dict,
    }
    bad = [
        k
        for k, t in kinds.items()
        if not isinstance(settings, dict) or k not in settings or not isinstance(settings[k], t)
    ]
    if bad:
        raise InputError(
            f"{name}: its settings lack or mistype {bad}; write it again with --write-reference."
        )
    if settings["version"] != REFERENCE_VERSION:
        raise InputError(
            f"{name} is of format version {settings['version']}, this script reads version "
            f"{REFERENCE_VERSION}; write it again with --write-reference."
        )
    return settings


def _parse_record(record: dict[str, Any], where: str) -> tuple[str, str, str, int, float, float]:
    """One line of a reference table: (dataset, model, metric, folds, mean, half-width)."""
    dataset, model, metric = record["dataset"], record["model"], record["metric"]
    if not dataset or not model or not (metric in ("nlpd", "srmse") or metric.startswith("rmse.")):
        raise InputError(f"{where}: expected a data set, a model and a metric, got {record}.")
    try:
        folds, mean, half = int(record["folds"]), float(record["mean"]), float(record["half_width"])
    except (TypeError, ValueError):
        raise InputError(
            f"{where}: folds, mean and half_width must be numbers, got {record}."
        ) from None
    if folds < 1 or not math.isfinite(mean) or half < 0:
        raise InputError(
            f"{where}: needs folds >= 1, a finite mean and a half-width >= 0, got {record}."
        )
    return dataset, model, metric, folds, mean, half


def parse_reference(text: str, name: str = "--reference") -> tuple[dict[str, Any], list[dict]]:
    """Read a reference table (`reference_text`).

    Args:
        text: The file's text.
        name: How errors name it (the option and the file).

    Returns:
        The settings and one row per (data set, model) with the keys of a `summarise` row
        that a comparison reads: ``folds``, ``nlpd``, ``nlpd_ci``, ``srmse``, ``srmse_ci``,
        ``outputs``, ``rmse`` and ``rmse_ci``.

    Raises:
        InputError: For a table that is not one, or is damaged.
    """
    lines = text.splitlines()
    settings = _parse_settings(lines, name)
    reader = csv.DictReader([line for line in lines if not line.startswith("#")])
    if tuple(reader.fieldnames or ()) != REFERENCE_COLUMNS:
        raise InputError(
            f"{name}: its columns are {reader.fieldnames}, expected {list(REFERENCE_COLUMNS)}; "
            "write it again with --write-reference."
        )
    groups: dict[tuple[str, str], dict[str, Any]] = {}
    try:
        records = list(reader)
    except csv.Error as exc:
        raise InputError(f"{name} is not a readable CSV table ({exc}).") from None
    for i, record in enumerate(records, start=1):
        if None in record or None in record.values():
            raise InputError(f"{name} row {i}: expected {len(REFERENCE_COLUMNS)} cells.")
        dataset, model, metric, folds, mean, half = _parse_record(record, f"{name} row {i}")
        row = groups.setdefault(
            (dataset, model), {"dataset": dataset, "model": model, "folds": folds, "metrics": {}}
        )
        if metric in row["metrics"] or folds != row["folds"]:
            raise InputError(
                f"{name} row {i}: {dataset}/{model} {metric} repeats or disagrees on its folds."
            )
        row["metrics"][metric] = (mean, half)
    rows = []
    for (dataset, model), group in groups.items():
        metrics = group.pop("metrics")
        outputs = [m[len("rmse.") :] for m in metrics if m.startswith("rmse.")]
        if "nlpd" not in metrics or "srmse" not in metrics or not outputs:
            raise InputError(
                f"{name}: {dataset}/{model} lacks nlpd, srmse or rmse.<output>; write it again."
            )
        rows.append(
            {
                **group,
                "nlpd": metrics["nlpd"][0],
                "nlpd_ci": metrics["nlpd"][1],
                "srmse": metrics["srmse"][0],
                "srmse_ci": metrics["srmse"][1],
                "outputs": outputs,
                "rmse": [metrics[f"rmse.{o}"][0] for o in outputs],
                "rmse_ci": [metrics[f"rmse.{o}"][1] for o in outputs],
            }
        )
    if not rows:
        raise InputError(f"{name} holds no results; write it again with --write-reference.")
    return settings, rows


def load_reference(path: str | Path, option: str = "--reference") -> tuple[dict[str, Any], list]:
    """Read the reference table at `path` (see `parse_reference`).

    Raises:
        InputError: Naming `option` and the file, for a missing, unreadable or damaged file.
    """
    name = f"{option} {path}"
    missing = (
        "give a table written by --write-reference (benchmarks/reference/ holds the committed "
        "ones)."
    )
    return parse_reference(read_user_text(path, name, missing), name)


def check_reference(
    settings: dict[str, Any],
    reference: tuple[dict[str, Any], list[dict[str, Any]]],
    pairs: list[tuple[str, str]],
    name: str = "--reference",
) -> None:
    """Raise `InputError` unless `reference` was made like this run and covers its pairs.

    Args:
        settings: `run_settings` of this run.
        reference: What `load_reference` returned.
        pairs: The run's (data set, model) pairs.
        name: How the error names the reference (the option and the file).
    """
    made, rows = reference
    differ = [k for k in _LIKE_WITH_LIKE if made[k] != settings[k]]
    if differ:
        was = ", ".join(f"{k}={json.dumps(made[k])}" for k in differ)
        now = ", ".join(f"{k}={json.dumps(settings[k])}" for k in differ)
        raise InputError(
            f"{name} was made with {was} but this run has {now}; run with the reference's "
            "settings, or write a new reference with --write-reference."
        )
    shapes = {
        n: (made["shapes"][n], shape)
        for n, shape in settings["shapes"].items()
        if n in made["shapes"] and made["shapes"][n] != shape
    }
    if shapes:
        raise InputError(
            f"{name}: the data changed (N, D, E was, now: {shapes}); write a new reference "
            "with --write-reference."
        )
    have = {(r["dataset"], r["model"]) for r in rows}
    missing = [f"{d}/{m}" for d, m in pairs if (d, m) not in have]
    if missing:
        raise InputError(
            f"{name} lacks {', '.join(missing)}; it covers data sets {made['datasets']} and "
            f"models {made['models']}: choose --datasets and --models among those, or write a "
            "new reference with --write-reference."
        )


def comparison_rows(
    summary_rows: list[dict[str, Any]],
    reference_rows: list[dict[str, Any]],
    nlpd_tol: float = NLPD_TOLERANCE,
    rmse_tol: float = RMSE_TOLERANCE,
) -> list[dict[str, Any]]:
    """Each mean of a run beside its reference's.

    Args:
        summary_rows: `summarise` rows of the run.
        reference_rows: Rows of `load_reference` (or `summarise` rows of another run).
        nlpd_tol: Nats per point by which a mean NLPD may exceed the reference's.
        rmse_tol: Relative amount by which a mean SRMSE or RMSE may exceed the reference's.

    Returns:
        One row per data set, model and metric (``nlpd``, ``srmse``, ``rmse.<output>``):
        ``folds`` and ``folds_reference`` (folds scored), ``reference``, ``reference_ci``,
        ``now``, ``now_ci`` (means and 95 % half-widths), ``difference`` (now minus
        reference), ``limit`` (the worst mean accepted) and ``status``: ``"worse"`` beyond
        the limit (or not scored), ``"better"`` by more than the tolerance, else ``"ok"``.

    Raises:
        InputError: For a tolerance that is not a finite number >= 0, or a (data set,
            model) of `summary_rows` that the reference lacks or scores on other outputs.
    """
    nlpd_tol = check_tolerance("nlpd_tol", nlpd_tol)
    rmse_tol = check_tolerance("rmse_tol", rmse_tol)
    refs = {(r["dataset"], r["model"]): r for r in reference_rows}
    out = []
    for row in summary_rows:
        ref = refs.get((row["dataset"], row["model"]))
        if ref is None or list(ref["outputs"]) != list(row["outputs"]):
            raise InputError(
                f"the reference lacks {row['dataset']}/{row['model']} with outputs "
                f"{list(row['outputs'])}; compare with a reference of the same data sets."
            )
        for (metric, now, now_half), (_, was, was_half) in zip(
            _metrics(row), _metrics(ref), strict=True
        ):
            if metric == "nlpd":
                limit, gain = was + nlpd_tol, was - nlpd_tol
            else:
                limit, gain = was * (1 + rmse_tol), was * (1 - rmse_tol)
            status = "worse" if not now <= limit else "better" if now < gain else "ok"
            out.append(
                {
                    "dataset": row["dataset"],
                    "model": row["model"],
                    "metric": metric,
                    "folds": row["folds"],
                    "folds_reference": ref["folds"],
                    "reference": was,
                    "reference_ci": was_half,
                    "now": now,
                    "now_ci": now_half,
                    "difference": now - was,
                    "limit": limit,
                    "status": status,
                }
            )
    return out


def compare_with_reference(
    summary_rows: list[dict[str, Any]],
    reference_rows: list[dict[str, Any]],
    nlpd_tol: float = NLPD_TOLERANCE,
    rmse_tol: float = RMSE_TOLERANCE,
) -> list[Regression]:
    """The regressions of a run against a reference (empty: none).

    A mean NLPD above the reference's plus `nlpd_tol`, a mean SRMSE or per-output RMSE above
    the reference's times ``1 + rmse_tol``, a metric that could not be scored, and fewer folds
    scored than the reference's (fits that failed) are regressions; improvements never are.

    Args:
        summary_rows: `summarise` rows of the run.
        reference_rows: Rows of `load_reference` (or `summarise` rows of another run).
        nlpd_tol: Nats per point (`NLPD_TOLERANCE` by default).
        rmse_tol: Relative (`RMSE_TOLERANCE` by default).

    Raises:
        InputError: As `comparison_rows`.
    """
    lines = comparison_rows(summary_rows, reference_rows, nlpd_tol, rmse_tol)
    folds = {
        (r["dataset"], r["model"]): Regression(
            r["dataset"],
            r["model"],
            "folds",
            r["folds_reference"],
            r["folds"],
            r["folds_reference"],
        )
        for r in lines
        if r["folds"] < r["folds_reference"]
    }
    worse = [
        Regression(r["dataset"], r["model"], r["metric"], r["reference"], r["now"], r["limit"])
        for r in lines
        if r["status"] == "worse"
    ]
    return [*folds.values(), *worse]


def comparison_markdown(
    lines: list[dict[str, Any]], reference: str, nlpd_tol: float, rmse_tol: float
) -> str:
    """`comparison_rows` as a Markdown table, with a heading naming the reference file."""
    out = [
        f"# Compared with {reference}",
        "",
        f"Worse: NLPD above the reference + {nlpd_tol:g} nats, SRMSE or RMSE above the "
        f"reference x {1 + rmse_tol:g}, or fewer folds scored. Cells: mean ± 95 % half-width.",
        "",
        "| data set | model | metric | folds | reference | now | now - reference | worst "
        "accepted | status |",
        "|" + "---|" * 9,
    ]
    for r in lines:
        cells = [
            r["dataset"],
            r["model"],
            r["metric"],
            f"{r['folds']}/{r['folds_reference']}",
            _fmt(r["reference"], r["reference_ci"], 4),
            _fmt(r["now"], r["now_ci"], 4),
            f"{r['difference']:+.4f}",
            f"{r['limit']:.4f}",
            "**WORSE**" if r["status"] == "worse" else r["status"],
        ]
        out.append("| " + " | ".join(cells) + " |")
    return "\n".join(out) + "\n"


# ---------------------------------------------------------------------------------- CLI
def comma_names(text: str, known: dict[str, Any], unknown: str) -> list[str]:
    """The distinct comma-separated names in `text`, each a key of `known`, in order.

    Raises:
        ValueError: ``"<unknown> 'a', 'b'; choose from <known>"`` for names not in `known`,
            or with ``(none given)`` for no name at all.
    """
    names = [t.strip() for t in text.split(",") if t.strip()]
    bad = [n for n in names if n not in known]
    if bad or not names:
        raise ValueError(
            f"{unknown} {', '.join(map(repr, bad)) or '(none given)'}; "
            f"choose from {', '.join(known)}"
        )
    return list(dict.fromkeys(names))


def _names(text: str | None, known: dict[str, Any], what: str) -> list[str]:
    """Comma-separated names (all of `known` if None); ValueError names an unknown one."""
    return list(known) if text is None else comma_names(text, known, f"unknown {what}")


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    """Command-line options."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--datasets", help=f"comma-separated, from {','.join(DATASETS)} (all)")
    ap.add_argument("--models", help=f"comma-separated, from {','.join(MODELS)} (all)")
    ap.add_argument("--folds", type=int, help="cross-validation folds (5; 2 with --smoke)")
    ap.add_argument("--seed", type=int, default=0, help="seed of the folds and the fits")
    ap.add_argument("--out", default="results/mixture_peers", help="output folder")
    ap.add_argument(
        "--workers",
        type=int,
        default=0,
        help="0 fits in this process; K > 0 on a local Dask cluster of K processes",
    )
    ap.add_argument(
        "--smoke",
        action="store_true",
        help=f"{SMOKE_ROWS} rows per data set, 2 folds, a few iterations",
    )
    ap.add_argument(
        "--rows",
        type=int,
        help=f"at most this many rows per data set, the full budget kept ({SMOKE_ROWS} with "
        "--smoke, else all); ch5 and ch4 generate this many pushes",
    )
    ap.add_argument(
        "--write-reference",
        metavar="FILE",
        help="write the run's means per data set and model, with its settings, as a "
        "reference table for --reference (atomically)",
    )
    ap.add_argument(
        "--reference",
        metavar="FILE",
        help="compare the run with this reference table (made with the same --folds, "
        "--seed, --rows and --smoke); exit status 1 for a regression",
    )
    ap.add_argument(
        "--tolerance",
        metavar="NATS",
        help=f"with --reference: nats per test point a mean NLPD may exceed the reference's "
        f"by ({NLPD_TOLERANCE:g})",
    )
    ap.add_argument(
        "--rmse-tolerance",
        metavar="REL",
        help="with --reference: relative amount a mean SRMSE or per-output RMSE may exceed "
        f"the reference's by ({RMSE_TOLERANCE:g}, i.e. {100 * RMSE_TOLERANCE:g} %%)",
    )
    ap.add_argument("--no-progress", action="store_true", help="hide progress bars")
    return ap.parse_args(argv)


def _tolerances(args: argparse.Namespace) -> tuple[float, float]:
    """``--tolerance`` and ``--rmse-tolerance`` (defaults if not given), checked."""
    if args.reference is None:
        given = [
            o
            for o, v in (("--tolerance", args.tolerance), ("--rmse-tolerance", args.rmse_tolerance))
            if v is not None
        ]
        if given:
            raise InputError(f"{given[0]} applies only with --reference FILE; add one.")
    nlpd_tol = NLPD_TOLERANCE if args.tolerance is None else args.tolerance
    rmse_tol = RMSE_TOLERANCE if args.rmse_tolerance is None else args.rmse_tolerance
    return (
        check_tolerance("--tolerance", nlpd_tol),
        check_tolerance("--rmse-tolerance", rmse_tol),
    )


def _check_against(
    rows: list[dict[str, Any]],
    reference: tuple[dict[str, Any], list[dict[str, Any]]],
    args: argparse.Namespace,
    out: Path,
) -> int:
    """Print and save the run beside its reference; 1 for a regression, else 0."""
    nlpd_tol, rmse_tol = _tolerances(args)
    lines = comparison_rows(rows, reference[1], nlpd_tol, rmse_tol)
    text = comparison_markdown(lines, args.reference, nlpd_tol, rmse_tol)
    atomic_write_text(out / "peers_vs_reference.md", text)
    print(text)
    regressions = compare_with_reference(rows, reference[1], nlpd_tol, rmse_tol)
    for r in regressions:
        print(f"mixture_peers: regression: {r}", file=sys.stderr)
    return 1 if regressions else 0


def _write_reference(
    path: str, settings: dict[str, Any], results: list[dict[str, Any]], rows: list[dict]
) -> int:
    """Write the reference table at `path`; 1 (and no file) if a fit failed, else 0."""
    failed = sum(bool(r["error"]) for r in results)
    if failed:
        print(
            f"mixture_peers: {failed} fit(s) failed (see peers.md); --write-reference {path} "
            "was not written",
            file=sys.stderr,
        )
        return 1
    atomic_write_text(path, reference_text(settings, rows))
    print(f"wrote reference {path}")
    return 0


def main(argv: list[str] | None = None) -> int:
    """Run (or resume) the comparison and write the CSV, Markdown and PNG; return the status.

    The status is 0, 1 for a regression against ``--reference`` (or a ``--write-reference``
    left unwritten because a fit failed), and 2 for a user's error (one line on stderr).
    """
    args = parse_args(argv)
    try:
        dataset_names = _names(args.datasets, DATASETS, "data set")
        model_names = _names(args.models, MODELS, "model")
        folds = args.folds if args.folds is not None else (2 if args.smoke else 5)
        if folds < 2:
            raise ValueError(f"--folds must be at least 2, got {folds}")
        if args.workers < 0:
            raise ValueError(f"--workers must be >= 0, got {args.workers}")
        if args.rows is not None and args.rows < folds:
            raise ValueError(f"--rows must be at least --folds ({folds}), got {args.rows}")
        _tolerances(args)
        if args.write_reference is not None:
            check_output_file("--write-reference", args.write_reference)
        reference = None if args.reference is None else load_reference(args.reference)
    except ValueError as exc:  # InputError included
        print(f"mixture_peers: {exc}", file=sys.stderr)
        return 2
    budget = SMOKE if args.smoke else FULL
    rows_cap = args.rows if args.rows is not None else SMOKE_ROWS if args.smoke else None
    out = Path(args.out)
    progress = not args.no_progress

    datasets = [DATASETS[name](out / "data", rows_cap, progress) for name in dataset_names]
    tasks = []
    for ds in datasets:
        if len(ds.X) < folds:
            print(
                f"mixture_peers: {ds.name} has {len(ds.X)} rows, fewer than {folds} folds",
                file=sys.stderr,
            )
            return 2
        tasks += make_tasks(ds, model_names, folds, args.seed, budget)
    settings = run_settings(datasets, model_names, folds, args.seed, rows_cap, args.smoke, budget)
    if reference is not None:
        try:
            pairs = [(d, m) for d in dataset_names for m in model_names]
            check_reference(settings, reference, pairs, f"--reference {args.reference}")
        except InputError as exc:
            print(f"mixture_peers: {exc}", file=sys.stderr)
            return 2
    results = run_tasks(
        fit_and_score,
        tasks,
        ResultStore(out / "tasks"),
        workers=args.workers or 0,
        progress=progress,
        desc="mixture peers",
    )

    rows = summarise(results)
    atomic_write_text(out / "peers.csv", _csv(results, datasets))
    atomic_write_text(
        out / "peers.md", _markdown(rows, datasets, folds, args.seed, budget, args.smoke)
    )
    plot(results, rows, datasets, out / "peers.png")
    print(f"wrote {out / 'peers.csv'}, {out / 'peers.md'} and {out / 'peers.png'}")
    status = 0 if reference is None else _check_against(rows, reference, args, out)
    if args.write_reference is not None:
        status = max(status, _write_reference(args.write_reference, settings, results, rows))
    return status


if __name__ == "__main__":
    sys.exit(main())
