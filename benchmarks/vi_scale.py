"""EM and Pyro SVI side by side on the synthetic regimes: fit time, held-out NLPD and RMSE.

The data come from `probaff.models.synthetic.regime_features` (three regimes chosen by two
feature columns, each regime a nonlinear map of its own columns to the effects; D = 101,
E = 6 by default, like chapter 5's features and effects), with the gate on columns 0-2 and
1,000 held-out rows. For every training size N the script fits, in one process:

- ``EM``: `MixtureOfGPExperts` (exact GP experts) by `fit_em` with default settings;
- ``VI``: `VariationalMixtureOfGPExperts` by `fit_svi` with default settings (its start is
  an exact EM fit on at most ``init_rows`` rows, whose time is included);
- ``VI<-EM``: `fit_svi` started from the ``EM`` fit above (time of the SVI alone).

NLPD is summed over the outputs and averaged over held-out points (nats per point); RMSE is
averaged over the outputs. The ratio columns compare each VI row with EM.

Usage: python benchmarks/vi_scale.py [--n 250 500 1000] [--steps 1500] [--inducing 128]
"""

import argparse
import time
from collections.abc import Callable
from functools import partial
from typing import Any

from probaff._threads import limit_threads
from probaff.eval.metrics import nlpd, rmse
from probaff.models import MixtureOfGPExperts, VariationalMixtureOfGPExperts, fit_em, fit_svi
from probaff.models.synthetic import regime_features

_GATE = [0, 1, 2]


def _score(fit: Callable[[], Any], x_test: Any, y_test: Any) -> tuple[float, float, float, Any]:
    """Run `fit` (which returns the fitted model); its seconds, NLPD, RMSE and the model."""
    start = time.perf_counter()
    model = fit()
    seconds = time.perf_counter() - start
    pred = model.predict(x_test)
    return seconds, float(nlpd(pred, y_test).sum()), float(rmse(pred, y_test).mean()), model


def _em(m: int, x: Any, y: Any, seed: int) -> MixtureOfGPExperts:
    """`MixtureOfGPExperts` with default settings (gate on columns 0-2) fitted by EM."""
    model = MixtureOfGPExperts(m, gate_features=_GATE)
    fit_em(model, x, y, seed=seed)
    return model


def _vi(
    m: int, k: int, x: Any, y: Any, steps: int, seed: int, init: Any = "auto"
) -> VariationalMixtureOfGPExperts:
    """`VariationalMixtureOfGPExperts` with `k` inducing points fitted by SVI from `init`."""
    model = VariationalMixtureOfGPExperts(m, gate_features=_GATE, n_inducing=k)
    fit_svi(model, x, y, n_steps=steps, seed=seed, init=init)
    return model


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n", type=int, nargs="+", default=[250, 500, 1000])
    ap.add_argument("--test", type=int, default=1000)
    ap.add_argument("--d", type=int, default=101)
    ap.add_argument("--e", type=int, default=6)
    ap.add_argument("--experts", type=int, default=3)
    ap.add_argument("--steps", type=int, default=1500)
    ap.add_argument("--inducing", type=int, default=128)
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--seed", type=int, default=0)
    a = ap.parse_args()
    m = a.experts
    print(
        f"regime_features: D={a.d}, E={a.e}, M={m}, {a.test} held-out rows, {a.threads} thread(s)"
    )
    print(f"VI: {a.inducing} inducing points per expert, {a.steps} SVI steps\n")
    print("| N | method | seconds | NLPD | RMSE | NLPD - EM | RMSE / EM |")
    print("|---|---|---|---|---|---|---|")
    with limit_threads(a.threads):
        for n in a.n:
            x, y, _ = regime_features(n + a.test, a.d, a.e, seed=a.seed)
            xtr, ytr, xte, yte = x[:n], y[:n], x[n:], y[n:]

            em_s, em_nlpd, em_rmse, em = _score(partial(_em, m, xtr, ytr, a.seed), xte, yte)
            vi = partial(_vi, m, min(a.inducing, n), xtr, ytr, a.steps, a.seed)
            rows = [
                ("EM", em_s, em_nlpd, em_rmse),
                ("VI", *_score(vi, xte, yte)[:3]),
                ("VI<-EM", *_score(partial(vi, em), xte, yte)[:3]),
            ]
            for name, seconds, value, error in rows:
                print(
                    f"| {n} | {name} | {seconds:.1f} | {value:.3f} | {error:.4f} | "
                    f"{value - em_nlpd:+.3f} | {error / em_rmse:.3f} |",
                    flush=True,
                )


if __name__ == "__main__":
    main()
