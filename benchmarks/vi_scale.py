"""Time Pyro SVI of a 3-expert mixture of sparse GP experts on 100k pushes.

The data come from `probaff.models.synthetic.regime_features` (three regimes chosen by two
feature columns, each regime a nonlinear map of its own columns to the effects), N = 100,000
training rows, D = 101, E = 6, like chapter 5's features and effects. Minibatch SVI touches a
minibatch per step, so its cost barely grows with N; the initial GMM, the gate initialisation
and the held-out evaluation are included in the time. A 2,000-row EM fit of the same model is
timed side by side as the exact-GP reference (exact GPs cannot take 100k rows).

Usage: python benchmarks/vi_scale.py [--n 100000] [--steps 1500] [--threads 1]
"""

import argparse
import time

import numpy as np

from probaff._threads import torch_threads
from probaff.eval.metrics import nlpd, rmse
from probaff.models import MixtureOfGPExperts, VariationalMixtureOfGPExperts, fit_em, fit_svi
from probaff.models.synthetic import regime_features


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--n", type=int, default=100_000)
    ap.add_argument("--test", type=int, default=5_000)
    ap.add_argument("--d", type=int, default=101)
    ap.add_argument("--e", type=int, default=6)
    ap.add_argument("--steps", type=int, default=1500)
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--em-n", type=int, default=2000)
    a = ap.parse_args()
    x, y, _ = regime_features(a.n + a.test, a.d, a.e, seed=0)
    xtr, ytr, xte, yte = x[: a.n], y[: a.n], x[a.n :], y[a.n :]
    gate = [0, 1, 2]
    with torch_threads(a.threads):
        start = time.perf_counter()
        vi = VariationalMixtureOfGPExperts(3, gate_features=gate, n_inducing=64)
        hist = fit_svi(vi, xtr, ytr, n_steps=a.steps, batch_size=256, seed=0)
        pred = vi.predict(xte)
        vi_s = time.perf_counter() - start
        vi_nlpd, vi_rmse = float(nlpd(pred, yte).sum()), rmse(pred, yte).mean().item()

        start = time.perf_counter()
        em = MixtureOfGPExperts(3, gate_features=gate, lengthscale_prior=True)
        fit_em(em, xtr[: a.em_n], ytr[: a.em_n], seed=0)
        pred = em.predict(xte)
        em_s = time.perf_counter() - start
        em_nlpd, em_rmse = float(nlpd(pred, yte).sum()), rmse(pred, yte).mean().item()
    losses = np.asarray(hist.loss)
    print(f"N={a.n}, D={a.d}, E={a.e}, M=3, {a.threads} threads")
    print(
        f"VI  {a.steps} SVI steps on {a.n} rows: {vi_s:7.1f} s  held-out NLPD {vi_nlpd:7.2f}  "
        f"mean RMSE {vi_rmse:.3f}  (target <= 600 s)"
    )
    print(
        f"EM  exact GPs on {a.em_n} rows:      {em_s:7.1f} s  held-out NLPD {em_nlpd:7.2f}  "
        f"mean RMSE {em_rmse:.3f}"
    )
    if losses.size:
        print(
            f"negative ELBO per sample: first {losses[0]:.1f}, last {losses[-1]:.1f}, "
            f"min {losses.min():.4g}, max {losses.max():.4g}"
        )


if __name__ == "__main__":
    main()
