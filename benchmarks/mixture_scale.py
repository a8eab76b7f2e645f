"""Scaling of the mixture of GP experts and its peers with the training size N.

Data (``--data``):

* ``regimes`` (default): `probaff.models.synthetic.regime_features` (three regimes chosen by
  two feature columns, D = 101, E = 6 by default). One draw of ``max(REGIMES_POOL, sizes) +
  test`` rows is made; the first `test` rows (1,000 by default) are the held-out set of every
  cell.
* ``randhie``: the RAND Health Insurance Experiment data shipped inside statsmodels
  (``statsmodels.api.datasets.randhie``, 20,190 rows, nothing downloaded): the target is
  ``log1p(mdvis)`` (E = 1), the other nine columns are the features (D = 9). The rows are
  shuffled once with ``--seed``; the first `test` rows (2,000 by default) are held out, so at
  most 18,190 rows train and larger sizes are left out with a note.

The next N rows after the held-out ones are the training set of a cell, so the cells of one
data set share their held-out points and each training set extends the smaller ones.

Every (method, N) cell is one fit timed on one torch and BLAS thread (``--threads``), in
wall-clock and in process CPU seconds (the latter is what to compare on a shared machine),
scored on the held-out rows by

* NLPD per test point (nats): the per-output marginal NLPDs of `probaff.eval.metrics.nlpd`
  summed over the outputs (the per-output values are stored too);
* RMSE of the predictive mean, averaged over the outputs.

Each cell is one fit with one seed (``--seed``): the table carries no error bars, and a
difference between methods smaller than the spread between seeds (not measured here) is not a
finding. Each cell is written atomically as ``<out>/<data>/<method>_N<N>.json`` and skipped
when that file holds a cell of the same draw and settings (`setup`), so an interrupted run
resumes where it stopped and runs with different ``--sizes`` or ``--methods`` add to one
table; a cell of another setup is recomputed. The table of every cell of the current setup
found in ``<out>/<data>`` is printed and written as ``scaling.md`` and ``scaling.csv`` next to
``scaling.png``: fit CPU seconds, NLPD and RMSE against N per method, with N, the time and the
RMSE on log axes (the NLPD axis is linear, as an NLPD can be negative).

Methods (``METHODS``; each is ``fit(X, Y, seed, n_experts, em=..., **options) -> model``,
`em` being `fit_em` overrides, whose ``predict(X_test)`` is a distribution with batch shape
``(N_test,)`` and event shape ``(E,)``; adding a method is one function decorated with
``@method("name")``):

* ``exact-em``: `MixtureOfGPExperts(M, experts="exact")` fitted by `fit_em` (defaults); above
  N = ``EXACT_MAX_N`` (2,000) its cells are recorded as skipped.
* ``exact-em-serial``: ``exact-em`` with the experts fitted one by one (`per_expert_fits`).
* ``sparse-em``: `MixtureOfGPExperts(M, experts="sparse")` (inducing-point experts,
  ``--n-inducing``, default ``min(DEFAULT_N_INDUCING, N)``) fitted by `fit_em` (defaults: above
  1,000 rows the search runs on 1,000 of them and the kept fit is refined on all).
* ``vi``: `VariationalMixtureOfGPExperts(M)` with ``min(128, N)`` inducing points per expert
  (``--n-inducing`` overrides) fitted by `fit_svi` with minibatches of 256 and ``--svi-steps``
  steps (its start, an EM fit on at most 2,000 rows, is timed with it).
* ``svgp``: one sparse variational GP per output (GPyTorch SVGP,
  `probaff.models.variational.vi.SVGPExpert`, ``min(128, N)`` inducing inputs drawn from the
  rows, a Gaussian likelihood per output) on standardised inputs and outputs, trained by Adam
  (step 0.01) on `gpytorch.mlls.VariationalELBO` with minibatches of 256 for ``--svgp-steps``
  steps.
* ``ccr``: scikit-learn cluster-classify-regress, ``ccr`` of ``benchmarks/mixture_peers.py``
  (a GMM on the joint standardised [x, y], a logistic-regression gate, one exact scikit-learn
  GP per cluster and output, ``--ccr-restarts`` optimizer restarts). It fits and predicts in
  one call, so its fit time includes predicting the held-out rows. Its GPs are exact, so above
  N = ``CCR_MAX_N`` (5,000) its cells are recorded as skipped.

``--max-iter``, ``--n-restarts``, ``--split-merge`` and ``--init`` change the `fit_em`
defaults of the EM methods; ``--init oracle`` starts one EM run from the true regimes (with
``--max-iter 1``: one M-step on the true assignment, which isolates the experts' part; only
``--data regimes`` has true regimes). ``--smoke`` runs every method in seconds: N = 60 and 120,
50 held-out rows, D = 16 and E = 2 for the regimes, two EM iterations from one start, 20 SVI
and SVGP steps, 16 inducing points, and VI started from the Gaussian mixture of the effects.

Usage::

    python benchmarks/mixture_scale.py --data randhie --sizes 1000,2000 \
        --methods exact-em,sparse-em,vi,svgp,ccr --out results/mixture_scale
"""

from __future__ import annotations

import argparse
import csv
import dataclasses
import importlib.util
import io
import json
import math
import resource
import sys
import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType
from typing import Any

import gpytorch
import numpy as np
import torch
from matplotlib.figure import Figure
from matplotlib.ticker import NullFormatter
from sklearn.exceptions import ConvergenceWarning
from threadpoolctl import threadpool_limits
from torch import Tensor
from torch.distributions import Distribution, Independent, Normal

from probaff._cli_errors import report_error, run_cli
from probaff._io import atomic_save_figure, atomic_write_text
from probaff._threads import limit_threads
from probaff.eval.metrics import nlpd, rmse
from probaff.models import MixtureOfGPExperts, VariationalMixtureOfGPExperts, fit_em, fit_svi
from probaff.models._scaling import Standardizer
from probaff.models.experts.expert_batch import per_expert_fits
from probaff.models.synthetic import regime_features
from probaff.models.variational.vi import SVGPExpert

PEERS_SCRIPT = Path(__file__).resolve().parent / "mixture_peers.py"
CCR_MAX_N = 5000
"""Largest training size of ``ccr`` (exact scikit-learn GPs); larger cells are skipped."""
EXACT_MAX_N = 2000
"""Largest training size of ``exact-em`` (about 16 CPU-minutes at N = 2,000, D = 101, E = 6,
and :math:`N^3` beyond); larger cells are skipped."""
BATCH_SIZE = 256
"""Minibatch size of ``vi`` and ``svgp``."""
N_INDUCING_SVI = 128
"""Default inducing points per expert (``vi``) and per output (``svgp``), capped at N."""
SMOKE_SIZES = "60,120"
SMOKE_TEST = 50

Fit = Callable[..., Any]
METHODS: dict[str, Fit] = {}
"""Every method by name: ``fit(X, Y, seed, n_experts, **options) -> fitted model``."""


def method(name: str) -> Callable[[Fit], Fit]:
    """Register ``fit(X, Y, seed, n_experts, **options)`` as method `name`."""

    def register(fit: Fit) -> Fit:
        METHODS[name] = fit
        return fit

    return register


@method("exact-em")
def exact_em(x: Tensor, y: Tensor, seed: int, n_experts: int, em: dict[str, Any], **_: Any) -> Any:
    """EM with exact GP experts (`fit_em` defaults, changed by `em`)."""
    model = MixtureOfGPExperts(n_experts, experts="exact")
    fit_em(model, x, y, seed=seed, **em)
    return model


@method("exact-em-serial")
def exact_em_serial(
    x: Tensor, y: Tensor, seed: int, n_experts: int, em: dict[str, Any], **_: Any
) -> Any:
    """`exact-em` with the experts fitted one after another (no batched M-step)."""
    with per_expert_fits():
        return exact_em(x, y, seed, n_experts, em)


@method("sparse-em")
def sparse_em(
    x: Tensor,
    y: Tensor,
    seed: int,
    n_experts: int,
    em: dict[str, Any],
    n_inducing: int | None = None,
    **_: Any,
) -> Any:
    """EM with sparse (inducing-point) GP experts (`fit_em` defaults, changed by `em`)."""
    model = MixtureOfGPExperts(n_experts, experts="sparse", n_inducing=n_inducing)
    fit_em(model, x, y, seed=seed, **em)
    return model


@method("vi")
def vi(
    x: Tensor,
    y: Tensor,
    seed: int,
    n_experts: int,
    n_inducing: int | None = None,
    svi_steps: int = 1500,
    smoke: bool = False,
    **_: Any,
) -> Any:
    """`VariationalMixtureOfGPExperts` fitted by `fit_svi` (minibatches of `BATCH_SIZE`).

    The start is `fit_svi`'s default (an EM fit on at most 2,000 rows), or with `smoke`
    the Gaussian mixture of the effects (no EM).
    """
    k = min(n_inducing or N_INDUCING_SVI, x.shape[0])
    model = VariationalMixtureOfGPExperts(n_experts, n_inducing=k)
    init = "effects" if smoke else "auto"
    fit_svi(model, x, y, n_steps=svi_steps, batch_size=BATCH_SIZE, seed=seed, init=init)
    return model


class SVGPRegressor:
    """One GPyTorch SVGP per output on standardised data (the ``svgp`` method).

    Args:
        n_inducing: Inducing inputs per output, drawn without replacement from the rows.
        n_steps: Adam steps on the variational ELBO.
        lr: Adam step size.
        batch_size: Minibatch rows per step (capped at N).
        seed: Seed of the inducing inputs and the minibatches.
    """

    def __init__(
        self, n_inducing: int, n_steps: int, lr: float = 0.01, batch_size: int = 256, seed: int = 0
    ) -> None:
        self.n_inducing, self.n_steps, self.lr = n_inducing, n_steps, lr
        self.batch_size, self.seed = batch_size, seed
        self.gp: SVGPExpert | None = None
        self.likelihood: gpytorch.likelihoods.GaussianLikelihood | None = None
        self.x_scaler: Standardizer | None = None
        self.y_scaler: Standardizer | None = None

    def fit(self, x: Tensor, y: Tensor) -> SVGPRegressor:
        """Fit to features `x: (N, D)` and outputs `y: (N, E)`; returns this regressor."""
        x, y = x.to(torch.float64), y.to(torch.float64)
        (n, d), e = x.shape, y.shape[1]
        self.x_scaler, self.y_scaler = Standardizer(d).fit(x), Standardizer(e).fit(y)
        xs, ys = self.x_scaler(x), self.y_scaler(y)
        gen = torch.Generator().manual_seed(self.seed)
        rows = torch.randperm(n, generator=gen)[: min(self.n_inducing, n)]
        gp = SVGPExpert(xs[rows].expand(e, -1, -1).clone())
        lik = gpytorch.likelihoods.GaussianLikelihood(batch_shape=torch.Size([e]))
        gp.double()
        lik.double()
        gp.train()
        lik.train()
        elbo = gpytorch.mlls.VariationalELBO(lik, gp, num_data=n)
        opt = torch.optim.Adam([*gp.parameters(), *lik.parameters()], lr=self.lr)
        batch = min(self.batch_size, n)
        for _ in range(self.n_steps):
            idx = torch.randint(n, (batch,), generator=gen)
            opt.zero_grad()
            loss = -elbo(gp(xs[idx].expand(e, batch, d)), ys[idx].T).sum()
            loss.backward()
            opt.step()
        gp.eval()
        lik.eval()
        self.gp, self.likelihood = gp, lik
        return self

    @torch.no_grad()
    def predict(self, x: Tensor) -> Distribution:
        """Predictive distribution at `x: (N, D)` in original units, batch `(N,)`, event `(E,)`."""
        if self.gp is None or self.likelihood is None or self.x_scaler is None:
            raise RuntimeError("SVGPRegressor.predict before fit")
        assert self.y_scaler is not None
        xs = self.x_scaler(x.to(torch.float64))
        e = self.gp.n_outputs
        pred = self.likelihood(self.gp(xs.expand(e, *xs.shape)))
        loc = pred.mean.T * self.y_scaler.std + self.y_scaler.mean
        scale = pred.variance.clamp_min(1e-12).sqrt().T * self.y_scaler.std
        return Independent(Normal(loc, scale), 1)


@method("svgp")
def svgp(
    x: Tensor,
    y: Tensor,
    seed: int,
    n_experts: int,
    n_inducing: int | None = None,
    svgp_steps: int = 2000,
    **_: Any,
) -> Any:
    """A single sparse GP (`SVGPRegressor`); `n_experts` is unused."""
    k = n_inducing or N_INDUCING_SVI
    return SVGPRegressor(k, svgp_steps, batch_size=BATCH_SIZE, seed=seed).fit(x, y)


def load_peers() -> ModuleType:
    """``benchmarks/mixture_peers.py`` as a module (for its ``ccr``)."""
    spec = importlib.util.spec_from_file_location("_mixture_peers_for_scale", PEERS_SCRIPT)
    if spec is None or spec.loader is None:
        raise ImportError(f"cannot load {PEERS_SCRIPT}")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses need their module registered
    spec.loader.exec_module(module)
    return module


@dataclass(frozen=True)
class Predicted:
    """A fit that has already predicted its held-out rows (``ccr`` fits and predicts at once).

    Attributes:
        x_test: The held-out features it predicted, `(N_test, D)`.
        dist: Its predictive distribution there, batch `(N_test,)`, event `(E,)`.
    """

    x_test: Tensor
    dist: Distribution

    def predict(self, x: Tensor) -> Distribution:
        """The stored prediction; `x` must be the held-out rows given to the fit."""
        if x.shape != self.x_test.shape or not torch.equal(x, self.x_test):
            raise ValueError("this fit predicted other rows than those asked for")
        return self.dist


@method("ccr")
def ccr(
    x: Tensor,
    y: Tensor,
    seed: int,
    n_experts: int,
    x_test: Tensor,
    ccr_restarts: int = 2,
    smoke: bool = False,
    **_: Any,
) -> Any:
    """Cluster-classify-regress of ``benchmarks/mixture_peers.py`` (fit and held-out predict)."""
    peers = load_peers()
    budget = dataclasses.replace(peers.SMOKE if smoke else peers.FULL, sk_restarts=ccr_restarts)
    with warnings.catch_warnings():  # length scales at their bounds: irrelevant inputs
        warnings.simplefilter("ignore", ConvergenceWarning)
        dist = peers.ccr(
            x.numpy(), y.numpy(), x_test.numpy(), seed, n_experts=n_experts, budget=budget
        )
    return Predicted(x_test, dist)


SKIP_ABOVE = {"ccr": CCR_MAX_N, "exact-em": EXACT_MAX_N, "exact-em-serial": EXACT_MAX_N}
"""Methods recorded as skipped above a training size."""


# ---------------------------------------------------------------------------------- data
@dataclass(frozen=True)
class Data:
    """A data set cut into held-out rows and a pool of training rows.

    Attributes:
        name: ``"regimes"`` or ``"randhie"``.
        x_test: Held-out features, `(T, D)`.
        y_test: Held-out targets, `(T, E)`.
        x: Training pool features, `(P, D)`; a cell of size N takes the first N rows.
        y: Training pool targets, `(P, E)`.
        labels: True regimes of the pool rows, `(P,)`, or None where unknown.
    """

    name: str
    x_test: Tensor
    y_test: Tensor
    x: Tensor
    y: Tensor
    labels: Tensor | None


def load_regimes(n_train: int, test: int, args: argparse.Namespace) -> Data:
    """`regime_features` rows: `test` held out, then the training pool.

    `regime_features` draws its regression weights after the features, so a draw depends on
    its row count: the pool always holds ``max(n_train, REGIMES_POOL)`` rows, which makes
    runs with different ``--sizes`` share the same function and held-out rows.
    """
    rows = max(n_train, REGIMES_POOL) + test
    x, y, labels = regime_features(rows, args.d, args.e, seed=args.seed)
    return Data("regimes", x[:test], y[:test], x[test:], y[test:], labels[test:])


def load_randhie(n_train: int, test: int, args: argparse.Namespace) -> Data:
    """statsmodels' RAND HIE rows, shuffled by ``args.seed``: target ``log1p(mdvis)``."""
    import statsmodels.api as sm

    frame = sm.datasets.randhie.load_pandas().data
    values = torch.as_tensor(frame.to_numpy(dtype=np.float64))
    gen = torch.Generator().manual_seed(args.seed)
    values = values[torch.randperm(values.shape[0], generator=gen)]
    target = list(frame.columns).index("mdvis")
    y = torch.log1p(values[:, target : target + 1])
    x = torch.cat([values[:, :target], values[:, target + 1 :]], dim=1)
    end = test + n_train
    return Data("randhie", x[:test], y[:test], x[test:end], y[test:end], None)


DATA: dict[str, Callable[[int, int, argparse.Namespace], Data]] = {
    "regimes": load_regimes,
    "randhie": load_randhie,
}
DEFAULT_TEST = {"regimes": 1000, "randhie": 2000}
REGIMES_POOL = 100_000
"""Training rows drawn for ``regimes`` whatever the sizes (more if a size is larger)."""
RANDHIE_ROWS = 20190


# ---------------------------------------------------------------------------------- cells
def _em_options(args: argparse.Namespace, labels: Tensor | None) -> dict[str, Any]:
    """The `fit_em` overrides of the command line (`labels`: true regimes of the rows)."""
    em: dict[str, Any] = {}
    for name in ("max_iter", "n_restarts", "split_merge"):
        if getattr(args, name) is not None:
            em[name] = getattr(args, name)
    if args.init == "oracle":
        assert labels is not None  # main rejects oracle without true regimes
        em["init"] = torch.nn.functional.one_hot(labels, args.n_experts).to(torch.float64)
    elif args.init is not None:
        em["init"] = args.init
    return em


def _settings(args: argparse.Namespace) -> dict[str, Any]:
    """The command-line settings stored with every cell."""
    return {
        "threads": args.threads,
        "n_experts": args.n_experts,
        "n_inducing": args.n_inducing,
        "seed": args.seed,
        "svi_steps": args.svi_steps,
        "svgp_steps": args.svgp_steps,
        "ccr_restarts": args.ccr_restarts,
        "smoke": args.smoke,
    }


def setup(data: Data, args: argparse.Namespace) -> dict[str, Any]:
    """What a cell's numbers depend on besides its method and N: the draw and the settings.

    A stored cell is reused, and shown in the table, only under the same setup.
    """
    return {
        "data": data.name,
        "pool_rows": int(data.x.shape[0]),
        "n_test": int(data.x_test.shape[0]),
        "d": int(data.x.shape[1]),
        "e": int(data.y.shape[1]),
        **_settings(args),
        **{k: getattr(args, k) for k in ("init", "max_iter", "n_restarts", "split_merge")},
    }


def run_cell(name: str, n: int, data: Data, args: argparse.Namespace) -> dict[str, Any]:
    """Fit method `name` on the first `n` pool rows of `data`, score it on the held-out rows."""
    x, y = data.x[:n], data.y[:n]
    labels = None if data.labels is None else data.labels[:n]
    record: dict[str, Any] = {
        "method": name,
        "data": data.name,
        "n": n,
        "n_test": int(data.x_test.shape[0]),
        "d": int(x.shape[1]),
        "e": int(y.shape[1]),
        **_settings(args),
        "setup": setup(data, args),
    }
    if n > SKIP_ABOVE.get(name, math.inf):
        return {**record, "skipped": f"too large: {name} runs up to N = {SKIP_ABOVE[name]}"}
    start, cpu_start = time.perf_counter(), time.process_time()
    with limit_threads(args.threads), threadpool_limits(args.threads):
        em = _em_options(args, labels)
        options = {k: v for k, v in _settings(args).items() if k in _METHOD_OPTIONS}
        model = METHODS[name](x, y, args.seed, args.n_experts, em=em, x_test=data.x_test, **options)
        fit_s = time.perf_counter() - start
        cpu_s = time.process_time() - cpu_start
        pred = model.predict(data.x_test)
    per_output = nlpd(pred, data.y_test)
    return {
        **record,
        "fit_s": fit_s,
        "fit_cpu_s": cpu_s,
        "nlpd": float(per_output.sum()),
        "nlpd_per_output": [float(v) for v in per_output],
        "rmse": float(rmse(pred, data.y_test).mean()),
        "peak_gib": peak_memory_gib(),
        "em": {k: "oracle" if k == "init" and args.init == "oracle" else v for k, v in em.items()},
    }


_METHOD_OPTIONS = ("n_inducing", "svi_steps", "svgp_steps", "ccr_restarts", "smoke")


# -------------------------------------------------------------------------------- outputs
COLUMNS = ("method", "n", "fit_s", "fit_cpu_s", "nlpd", "rmse", "peak_gib", "skipped")


def peak_memory_gib() -> float:
    """The process's peak resident memory so far, GiB (an upper bound for the last cell's)."""
    kib = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss  # KiB on Linux
    return kib / 2.0**20


def read_cells(out: Path, current: dict[str, Any] | None = None) -> list[dict[str, Any]]:
    """Every cell stored in `out` (of the `setup` `current`, if given), by method and N."""
    rows = [json.loads(p.read_text()) for p in sorted(out.glob("*_N*.json"))]
    if current is not None:
        rows = [r for r in rows if r.get("setup") == current]
    return sorted(rows, key=lambda r: (r["method"], r["n"]))


def _stored(cell: Path, current: dict[str, Any]) -> bool:
    """Whether `cell` holds a result of the setup `current` (an unreadable file does not)."""
    try:
        return bool(json.loads(cell.read_text()).get("setup") == current)
    except (OSError, ValueError, AttributeError):
        return False


def _num(row: dict[str, Any], key: str, fmt: str) -> str:
    return "" if key not in row else format(row[key], fmt)


def table_text(rows: list[dict[str, Any]]) -> str:
    """The cells as a fixed-width table (skipped cells say why)."""
    lines = [
        f"{'method':<16} {'N':>7} {'fit s':>9} {'CPU s':>9} {'NLPD':>8} {'RMSE':>7}",
        "-" * 61,
    ]
    for r in rows:
        if "skipped" in r:
            lines.append(f"{r['method']:<16} {r['n']:>7} skipped: {r['skipped']}")
            continue
        lines.append(
            f"{r['method']:<16} {r['n']:>7} {r['fit_s']:>9.1f} {r['fit_cpu_s']:>9.1f} "
            f"{r['nlpd']:>8.3f} {r['rmse']:>7.3f}"
        )
    return "\n".join(lines)


def table_markdown(rows: list[dict[str, Any]], data: str) -> str:
    """The cells as a Markdown table with a caption."""
    lines = [
        f"# Scaling with N on `{data}`",
        "",
        "One fit per cell (one seed, no error bars); NLPD in nats per held-out point summed"
        " over the outputs, RMSE averaged over the outputs; CPU s is the fit's process CPU time;"
        " peak GiB the process's peak resident memory after the cell (cells run in one process"
        " in order of N, so it bounds the cell's own).",
        "",
        "| method | N | fit s | CPU s | NLPD | RMSE | peak GiB |",
        "|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        if "skipped" in r:
            lines.append(f"| {r['method']} | {r['n']} | skipped: {r['skipped']} | | | | |")
        else:
            lines.append(
                f"| {r['method']} | {r['n']} | {r['fit_s']:.1f} | {r['fit_cpu_s']:.1f} | "
                f"{r['nlpd']:.3f} | {r['rmse']:.4f} | {_num(r, 'peak_gib', '.2f')} |"
            )
    return "\n".join(lines) + "\n"


def table_csv(rows: list[dict[str, Any]]) -> str:
    """The cells as CSV (`COLUMNS`; empty numbers for skipped cells)."""
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=COLUMNS, extrasaction="ignore", lineterminator="\n")
    writer.writeheader()
    for r in rows:
        writer.writerow({k: r.get(k, "") for k in COLUMNS})
    return buf.getvalue()


def plot(rows: list[dict[str, Any]], data: str, path: Path) -> None:
    """Fit CPU seconds, NLPD and RMSE against N, one line per method."""
    fig = Figure(figsize=(12, 3.8))
    axes = fig.subplots(1, 3)
    panels = [
        ("fit_cpu_s", "fit CPU seconds", True),
        ("nlpd", "NLPD (nats)", False),
        ("rmse", "RMSE", True),
    ]
    for ax, (key, label, log_y) in zip(axes, panels, strict=True):
        for name in sorted({r["method"] for r in rows}):
            done = [r for r in rows if r["method"] == name and "skipped" not in r]
            if done:
                ax.plot([r["n"] for r in done], [r[key] for r in done], "o-", label=name)
        ax.set_xscale("log")
        sizes = sorted({r["n"] for r in rows})
        ax.set_xticks(sizes, [f"{n:,}" for n in sizes], minor=False)
        ax.xaxis.set_minor_formatter(NullFormatter())
        if log_y:
            ax.set_yscale("log")
        ax.set_xlabel("training size N")
        ax.set_ylabel(label)
        ax.grid(True, which="both", alpha=0.3)
    axes[0].legend(fontsize=8)
    fig.suptitle(f"{data}: scaling with N (one seed per cell)")
    fig.tight_layout()
    atomic_save_figure(fig, path, dpi=120)


# ------------------------------------------------------------------------------------ CLI
def _sizes(text: str) -> list[int]:
    """Comma-separated positive integers; ValueError names a bad one."""
    sizes = []
    for part in (t.strip() for t in text.split(",")):
        if not part.isdigit() or int(part) <= 0:
            raise ValueError(f"--sizes takes positive integers separated by commas, got {part!r}")
        sizes.append(int(part))
    return list(dict.fromkeys(sizes))


def _names(text: str, known: dict[str, Any], flag: str) -> list[str]:
    """Comma-separated names from `known`; ValueError names an unknown one."""
    return load_peers().comma_names(text, known, f"{flag}: unknown")


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    """Command-line options."""
    ap = argparse.ArgumentParser(description=(__doc__ or "").split("\n")[0])
    ap.add_argument("--data", default="regimes", help=f"one of {', '.join(DATA)}")
    ap.add_argument("--sizes", default=None, help="training sizes (1k..100k; 60,120 in smoke)")
    ap.add_argument("--methods", default="exact-em,sparse-em,vi,svgp,ccr")
    ap.add_argument("--out", default="results/mixture_scale")
    ap.add_argument("--test", type=int, default=None, help="held-out rows (1000 / 2000)")
    ap.add_argument("--d", type=int, default=None, help="regimes features (101; 16 in smoke)")
    ap.add_argument("--e", type=int, default=None, help="regimes outputs (6; 2 in smoke)")
    ap.add_argument("--n-experts", type=int, default=3)
    ap.add_argument("--n-inducing", type=int, default=None)
    ap.add_argument("--svi-steps", type=int, default=None, help="vi steps (1500; 20 in smoke)")
    ap.add_argument("--svgp-steps", type=int, default=None, help="svgp steps (2000; 20 in smoke)")
    ap.add_argument("--ccr-restarts", type=int, default=2, help="sklearn GP restarts of ccr")
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--init", default=None, help="fit_em init, or 'oracle' (true regimes)")
    ap.add_argument("--max-iter", type=int, default=None)
    ap.add_argument("--n-restarts", type=int, default=None)
    ap.add_argument("--split-merge", type=int, default=None)
    ap.add_argument("--smoke", action="store_true", help="tiny sizes and budgets, seconds")
    return ap.parse_args(argv)


def _complete(args: argparse.Namespace) -> tuple[list[int], list[str]]:
    """Check the options, fill the defaults that depend on ``--smoke`` and ``--data``."""
    if args.data not in DATA:
        raise ValueError(f"--data: unknown {args.data!r}; choose from {', '.join(DATA)}")
    names = _names(args.methods, METHODS, "--methods")
    sizes = _sizes(
        args.sizes or (SMOKE_SIZES if args.smoke else "1000,2000,5000,10000,30000,100000")
    )
    smoke = args.smoke
    defaults = {
        "test": SMOKE_TEST if smoke else DEFAULT_TEST[args.data],
        "d": 16 if smoke else 101,
        "e": 2 if smoke else 6,
        "svi_steps": 20 if smoke else 1500,
        "svgp_steps": 20 if smoke else 2000,
        "n_inducing": 16 if smoke else None,
        "max_iter": 2 if smoke else None,
        "n_restarts": 1 if smoke else None,
    }
    for key, value in defaults.items():
        if getattr(args, key) is None:
            setattr(args, key, value)
    for flag in ("test", "d", "e", "n_experts", "threads", "svi_steps", "svgp_steps"):
        if getattr(args, flag) <= 0:
            raise ValueError(f"--{flag.replace('_', '-')} must be a positive integer")
    if args.init == "oracle" and args.data != "regimes":
        raise ValueError("--init oracle needs true regimes: use it with --data regimes")
    return sizes, names


def main(argv: list[str] | None = None) -> int:
    """Run every missing (method, N) cell, print the table and write it and the figure."""
    args = parse_args(argv)
    try:
        sizes, names = _complete(args)
    except ValueError as exc:
        return report_error("mixture_scale", exc)
    if args.data == "randhie":
        room = RANDHIE_ROWS - args.test
        if args.test >= RANDHIE_ROWS:
            return report_error("mixture_scale", ValueError(f"--test must be < {RANDHIE_ROWS}"))
        dropped = [n for n in sizes if n > room]
        if dropped:
            print(f"randhie has {room} training rows: sizes {dropped} left out", flush=True)
        sizes = [n for n in sizes if n <= room]
    out = Path(args.out) / args.data
    out.mkdir(parents=True, exist_ok=True)
    data = DATA[args.data](max(sizes, default=0), args.test, args)
    current = setup(data, args)
    for n in sorted(sizes):
        for name in names:
            cell = out / f"{name}_N{n}.json"
            if _stored(cell, current):
                continue
            record = run_cell(name, n, data, args)
            atomic_write_text(cell, json.dumps(record, indent=1) + "\n")
            if "skipped" in record:
                print(f"{name} N={n}: skipped ({record['skipped']})", flush=True)
            else:
                print(
                    f"{name} N={n}: {record['fit_s']:.1f} s ({record['fit_cpu_s']:.1f} CPU s), "
                    f"NLPD {record['nlpd']:.3f}, RMSE {record['rmse']:.3f}",
                    flush=True,
                )
    rows = read_cells(out, current)
    atomic_write_text(out / "scaling.md", table_markdown(rows, args.data))
    atomic_write_text(out / "scaling.csv", table_csv(rows))
    plot(rows, args.data, out / "scaling.png")
    print(table_text(rows))
    print(f"wrote {out / 'scaling.md'}, {out / 'scaling.csv'} and {out / 'scaling.png'}")
    return 0


if __name__ == "__main__":
    sys.exit(run_cli(main, prog="mixture_scale"))
