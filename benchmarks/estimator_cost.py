"""The estimator's cost at small N: `MixtureOfGPExpertsRegressor` against scikit-learn's ARD GP.

On scikit-learn's diabetes data (442 x 10, ``--rows`` to cap it), the same ``--folds`` folds
(shuffled by ``--seed``) are fitted and predicted side by side in this one process by:

* ``probaff``: ``MixtureOfGPExpertsRegressor()`` at its defaults (M = 2, the default EM; its
  threads are probaff's automatic choice, `probaff._threads`);
* ``sklearn_gpr``: ``GaussianProcessRegressor`` on standardised features with an ARD RBF kernel
  times a constant plus white noise, ``normalize_y=True`` and no optimiser restarts, on one
  BLAS thread.

It prints each model's CPU (process) and wall seconds over all folds, the held-out RMSE and
log density per point, and the CPU ratio of probaff to scikit-learn; the issue's goal is a
ratio of at most 2. Machines are noisy, so the two run alternately fold by fold.

Run time: about 20 s on a 2-core machine.

Usage::

    python benchmarks/estimator_cost.py [--folds 5] [--seed 0] [--rows N]
"""

from __future__ import annotations

import argparse
import contextlib
import math
import sys
import time
import warnings
from typing import Any

import numpy as np
from scipy import stats
from sklearn.datasets import load_diabetes
from sklearn.exceptions import ConvergenceWarning
from sklearn.gaussian_process import GaussianProcessRegressor
from sklearn.gaussian_process.kernels import RBF, WhiteKernel
from sklearn.gaussian_process.kernels import ConstantKernel as Constant
from sklearn.model_selection import KFold
from sklearn.pipeline import make_pipeline
from sklearn.preprocessing import StandardScaler
from threadpoolctl import threadpool_limits

from probaff._checks import check_count
from probaff._cli_errors import report_error, run_cli
from probaff.errors import ProbaffError
from probaff.models.sklearn import MixtureOfGPExpertsRegressor

MODELS = ("probaff", "sklearn_gpr")
"""The two rows of the table."""


def _make(name: str, n_features: int) -> Any:
    if name == "probaff":
        return MixtureOfGPExpertsRegressor()
    kernel = Constant(1.0) * RBF(np.ones(n_features)) + WhiteKernel(0.1)
    return make_pipeline(
        StandardScaler(), GaussianProcessRegressor(kernel, normalize_y=True, random_state=0)
    )


def compare(folds: int, seed: int, rows: int | None) -> list[dict[str, Any]]:
    """Fit and score both models on the same folds; one row of totals per model.

    Args:
        folds: Number of folds (at least 2).
        seed: Seed of the fold shuffle.
        rows: Use the first `rows` rows only (None for all 442).

    Returns:
        Rows with ``model``, ``cpu_s``, ``wall_s``, ``rmse`` (root of the pooled mean squared
        error) and ``log_density`` (mean held-out Gaussian log density per point).
    """
    X, y = load_diabetes(return_X_y=True)
    if rows is not None:
        X, y = X[:rows], y[:rows]
    totals = {m: {"cpu_s": 0.0, "wall_s": 0.0, "sq": 0.0, "logp": 0.0} for m in MODELS}
    for train, test in KFold(folds, shuffle=True, random_state=seed).split(X):
        for name in MODELS:
            limit = threadpool_limits(1) if name == "sklearn_gpr" else contextlib.nullcontext()
            cpu, wall = time.process_time(), time.perf_counter()
            with limit, warnings.catch_warnings():
                warnings.simplefilter("ignore", ConvergenceWarning)
                model = _make(name, X.shape[1]).fit(X[train], y[train])
                mean, std = model.predict(X[test], return_std=True)
            t = totals[name]
            t["cpu_s"] += time.process_time() - cpu
            t["wall_s"] += time.perf_counter() - wall
            t["sq"] += float(((mean - y[test]) ** 2).sum())
            t["logp"] += float(stats.norm.logpdf(y[test], mean, np.maximum(std, 1e-9)).sum())
    n = len(y)
    return [
        {
            "model": m,
            "cpu_s": t["cpu_s"],
            "wall_s": t["wall_s"],
            "rmse": math.sqrt(t["sq"] / n),
            "log_density": t["logp"] / n,
        }
        for m, t in totals.items()
    ]


def main(argv: list[str] | None = None) -> int:
    """Print the side-by-side table and the CPU ratio."""
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--folds", type=int, default=5)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--rows", type=int, default=None)
    args = ap.parse_args(argv)
    try:
        folds = check_count("--folds", args.folds, minimum=2)
        seed = check_count("--seed", args.seed, minimum=0)
        rows = None if args.rows is None else check_count("--rows", args.rows, minimum=2 * folds)
    except ProbaffError as exc:
        return report_error("estimator_cost", exc)
    table = compare(folds, seed, rows)
    print("model        |  CPU s | wall s |   RMSE | log density per point")
    for r in table:
        print(
            f"{r['model']:<12} | {r['cpu_s']:6.1f} | {r['wall_s']:6.1f} | {r['rmse']:6.2f} | "
            f"{r['log_density']:.3f}"
        )
    ratio = table[0]["cpu_s"] / max(table[1]["cpu_s"], 1e-9)
    print(f"CPU ratio probaff / sklearn_gpr: {ratio:.2f} (goal: at most 2)")
    return 0


if __name__ == "__main__":
    sys.exit(run_cli(main, prog="estimator_cost"))
