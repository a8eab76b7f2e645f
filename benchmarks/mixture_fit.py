"""Time an EM fit of a GP mixture against one scikit-learn ARD GP on the same data.

Usage::

    python benchmarks/mixture_fit.py [--n 321] [--d 101] [--e 6] [--sklearn-restarts 0]

The data come from `probaff.models.synthetic.regime_features`: three regimes selected by
the first two feature columns, each mapping its own four columns to the E effects. The
mixture (M experts, gate on columns 0-2, experts on every column) is fitted by `fit_em`;
the baseline is one `GaussianProcessRegressor` with an anisotropic RBF kernel (one length
scale per column, initialised like the experts' at sqrt(D)) times a constant, plus a white
noise kernel, on the same standardised features. Both run with `--threads` torch/BLAS
threads. A small EM fit runs first so that one-time import costs are not timed.
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np
import torch
from scipy.stats import norm
from sklearn.gaussian_process import GaussianProcessRegressor
from sklearn.gaussian_process.kernels import RBF, ConstantKernel, WhiteKernel
from sklearn.preprocessing import StandardScaler
from threadpoolctl import threadpool_limits

from probaff._threads import torch_threads
from probaff.models import MixtureOfGPExperts, fit_em
from probaff.models.synthetic import regime_features


def purity(assign: np.ndarray, labels: np.ndarray) -> float:
    """Fraction of samples whose cluster's majority label is their own label."""
    return sum(np.bincount(labels[assign == j]).max() for j in np.unique(assign)) / len(labels)


def time_em(
    args: argparse.Namespace, x: torch.Tensor, y: torch.Tensor, labels: np.ndarray
) -> tuple[MixtureOfGPExperts, float]:
    model = MixtureOfGPExperts(
        args.experts,
        groups={"f_x": slice(0, 3)},
        gate_features=("f_x",),
        expert_features=None,
        lengthscale_prior=args.lengthscale_prior,
    )
    fit_em(model, x[:40], y[:40], max_iter=1)  # warm-up: one-time imports and allocations
    start = time.perf_counter()
    history = fit_em(model, x, y, max_iter=args.em_iter, tol=0.0)
    elapsed = time.perf_counter() - start
    prior = ", length-scale prior" if args.lengthscale_prior else ""
    print(f"EM: M={args.experts}{prior}, {history.n_iter} iterations in {elapsed:.2f} s")
    print("  objective per iteration:", " ".join(f"{v:.1f}" for v in history.objective))
    assign = history.responsibilities.argmax(1).numpy()
    print(f"  assignment purity {purity(assign, labels):.3f}")
    return model, elapsed


def time_sklearn(
    args: argparse.Namespace, x: np.ndarray, y: np.ndarray
) -> tuple[GaussianProcessRegressor, float]:
    d = x.shape[1]
    rbf = RBF(length_scale=np.full(d, math.sqrt(d)), length_scale_bounds=(1e-3, 1e5))
    kernel = ConstantKernel(1.0) * rbf + WhiteKernel(0.1)
    gpr = GaussianProcessRegressor(
        kernel, normalize_y=True, n_restarts_optimizer=args.sklearn_restarts, random_state=0
    )
    start = time.perf_counter()
    gpr.fit(x, y)
    elapsed = time.perf_counter() - start
    print(
        f"sklearn GaussianProcessRegressor (ARD RBF + white noise, "
        f"{args.sklearn_restarts} restarts): {elapsed:.2f} s"
    )
    return gpr, elapsed


def main() -> None:
    """Run the benchmark and print both timings and their ratio."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=321, help="training samples")
    parser.add_argument("--d", type=int, default=101, help="feature columns")
    parser.add_argument("--e", type=int, default=6, help="effect dimensions")
    parser.add_argument("--experts", type=int, default=3)
    parser.add_argument("--em-iter", type=int, default=10)
    parser.add_argument("--sklearn-restarts", type=int, default=0)
    parser.add_argument("--skip-sklearn", action="store_true")
    parser.add_argument("--threads", type=int, default=1)
    parser.add_argument("--n-test", type=int, default=500, help="held-out samples for NLPD")
    parser.add_argument(
        "--lengthscale-prior", action="store_true", help="dimension-scaled length-scale prior"
    )
    args = parser.parse_args()

    x, y, labels = regime_features(args.n + args.n_test, args.d, args.e, seed=0)
    scaler = StandardScaler().fit(x[: args.n].numpy())
    xs = torch.as_tensor(scaler.transform(x.numpy()))
    x_tr, y_tr, x_te, y_te = xs[: args.n], y[: args.n], xs[args.n :], y[args.n :]
    print(f"data: N={args.n} D={args.d} E={args.e}, {args.n_test} held-out samples")

    with torch_threads(args.threads), threadpool_limits(args.threads):
        model, em_time = time_em(args, x_tr, y_tr, labels[: args.n].numpy())
        print(f"  held-out NLPD {-float(model.predict(x_te).log_prob(y_te).mean()):.3f}")
        if args.skip_sklearn:
            return
        gpr, sk_time = time_sklearn(args, x_tr.numpy(), y_tr.numpy())
        mean, std = gpr.predict(x_te.numpy(), return_std=True)
        print(f"  held-out NLPD {-float(norm.logpdf(y_te.numpy(), mean, std).sum(1).mean()):.3f}")
    print(f"EM {em_time:.2f} s vs sklearn {sk_time:.2f} s: EM is {sk_time / em_time:.1f}x faster")


if __name__ == "__main__":
    main()
