"""What each part of the default mixture fit costs at small N, and what it buys.

The default `fit_em` (`probaff.models.EMOptions`) spends its time on a few parts: the
Gaussian-mixture starts it screens (``n_init``), the EM restarts (``n_restarts``), the
split-and-merge moves (``split_merge``), the L-BFGS iterations of each expert's M-step
(``gp_max_iter``, 50, for an expert fitted from scratch; ``warm_max_iter``, 8, for one that
starts from its last hyperparameters) and the gate's cross-validated penalties (``gate_l2`` and
``gate_l1`` ``"cv"``). Each variant below turns one of them down, and every fold fits the
default and every variant side by side in this one process, on one thread:

==================  ===========================================================
variant             what changes against the default
==================  ===========================================================
``default``         nothing: `MixtureOfGPExperts(M)` fitted by `fit_em` (seed 0)
``n_init_5``        5 Gaussian-mixture starts instead of 20
``restarts_1``      one EM restart instead of 3
``no_split_merge``  no split-and-merge moves
``gp_iter_25``      25 L-BFGS iterations per cold expert fit instead of 50
``warm_iter_4``     4 L-BFGS iterations per warm-started M-step instead of 8
``gate_fixed``      the gate's ridge penalty fixed at 1 and no lasso (no CV)
==================  ===========================================================

For each data set (those of ``benchmarks/mixture_peers.py`` with at most 500 rows:
diabetes, engel, motorcycle, and 400 rows of the synthetic regimes) and each of ``--folds``
folds (shuffled, seed 0), a cell records the fit's CPU seconds (`time.process_time`, torch
and BLAS on one thread; the first fit of the process is a warm-up outside the table,
since it pays a one-time import of about 1 s inside GPyTorch's kernels), the held-out NLPD
(nats, summed over outputs) and the RMSE divided by each output's standard deviation over
the data set (SRMSE). The table gives, per variant and data set, the mean CPU seconds, its
ratio to the default's, and the fold-paired differences in NLPD and SRMSE against the
default with 95 % Student-t intervals: a part pays when turning it down costs held-out
accuracy (a positive NLPD difference whose interval excludes 0). A mean over folds can hide
a part that rescues an unlucky fit now and then: split-and-merge changes no mean here, yet
on softmax-gated regimes (`probaff.models.synthetic.softmax_regimes`, N = 400, data seed 0)
it turned a held-out NLPD of -0.35 into -1.80, so it stays in the default.

Run time: about 5 minutes on one core of a 2-core machine with the defaults (4 data sets x
5 folds x 7 variants; a default fit takes 0.5-4 CPU seconds there).

Usage::

    python benchmarks/mixture_cost.py [--datasets diabetes,engel,motorcycle,synthetic]
        [--folds 5] [--variants default,n_init_5,...] [--out results/mixture_cost]
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import torch
from sklearn.model_selection import KFold
from threadpoolctl import threadpool_limits

from probaff._cli_errors import run_cli
from probaff._io import atomic_write_text
from probaff._threads import limit_threads
from probaff.errors import InputError
from probaff.eval.metrics import mean_halfwidth, nlpd, rmse
from probaff.models import MixtureOfGPExperts, fit_em

sys.path.insert(0, str(Path(__file__).resolve().parent))
from mixture_peers import DATASETS, Dataset

__all__ = ["VARIANTS", "Variant", "fit_cell", "main", "summarise"]


@dataclass(frozen=True)
class Variant:
    """One way to fit: the model's constructor arguments and `fit_em`'s overrides.

    Attributes:
        name: Row name.
        model: Keyword arguments of `MixtureOfGPExperts` beside `n_experts`.
        fit: Keyword arguments of `fit_em` beside the seed.
    """

    name: str
    model: dict[str, Any] = field(default_factory=dict)
    fit: dict[str, Any] = field(default_factory=dict)


VARIANTS: dict[str, Variant] = {
    v.name: v
    for v in (
        Variant("default"),
        Variant("n_init_5", fit={"n_init": 5}),
        Variant("restarts_1", fit={"n_restarts": 1}),
        Variant("no_split_merge", fit={"split_merge": 0}),
        Variant("gp_iter_25", fit={"gp_max_iter": 25}),
        Variant("warm_iter_4", fit={"warm_max_iter": 4}),
        Variant("gate_fixed", model={"gate_l2": 1.0, "gate_l1": 0.0}),
    )
}
"""The variants, the default first."""

SMALL = ("diabetes", "engel", "motorcycle", "synthetic")
"""The data sets of ``benchmarks/mixture_peers.py`` used here (synthetic cut to 400 rows)."""


def fit_cell(
    ds: Dataset, train: np.ndarray, test: np.ndarray, variant: Variant, seed: int = 0
) -> dict[str, float]:
    """Fit one variant on one fold and score it.

    Args:
        ds: The data set.
        train: Training row indices.
        test: Held-out row indices.
        variant: How to fit.
        seed: Seed of the fit.

    Returns:
        ``cpu`` (process seconds of the fit and prediction), ``nlpd`` (nats, summed over the
        outputs) and ``srmse`` (RMSE over each output's standard deviation, averaged).
    """
    X = torch.as_tensor(ds.X, dtype=torch.float64)
    Y = torch.as_tensor(ds.Y, dtype=torch.float64)
    model = MixtureOfGPExperts(ds.n_experts, **variant.model)
    start = time.process_time()
    fit_em(model, X[train], Y[train], seed=seed, **variant.fit)
    with torch.no_grad():
        pred = model.predict(X[test])
        cpu = time.process_time() - start
        y = Y[test]
        return {
            "cpu": cpu,
            "nlpd": float(nlpd(pred, y).sum()),
            "srmse": float((rmse(pred, y) / Y.std(0)).mean()),
        }


def summarise(cells: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Per data set and variant: mean CPU, its ratio to the default's, paired differences.

    Args:
        cells: One dict per fit with ``dataset``, ``variant``, ``fold``, ``cpu``, ``nlpd``
            and ``srmse``.

    Returns:
        Rows with ``dataset``, ``variant``, ``cpu``, ``cpu_ratio``, ``nlpd``, ``d_nlpd``,
        ``d_nlpd_half``, ``srmse``, ``d_srmse`` and ``d_srmse_half``.
    """
    by = {(c["dataset"], c["variant"], c["fold"]): c for c in cells}
    rows = []
    for name in dict.fromkeys(c["dataset"] for c in cells):
        folds = sorted({c["fold"] for c in cells if c["dataset"] == name})
        base = [by[(name, "default", f)] for f in folds]
        for variant in dict.fromkeys(c["variant"] for c in cells if c["dataset"] == name):
            mine = [by[(name, variant, f)] for f in folds]
            d_nlpd = [m["nlpd"] - b["nlpd"] for m, b in zip(mine, base, strict=True)]
            d_srmse = [m["srmse"] - b["srmse"] for m, b in zip(mine, base, strict=True)]
            cpu = float(np.mean([m["cpu"] for m in mine]))
            rows.append(
                {
                    "dataset": name,
                    "variant": variant,
                    "cpu": cpu,
                    "cpu_ratio": cpu / float(np.mean([b["cpu"] for b in base])),
                    "nlpd": float(np.mean([m["nlpd"] for m in mine])),
                    "d_nlpd": float(np.mean(d_nlpd)),
                    "d_nlpd_half": mean_halfwidth(d_nlpd),
                    "srmse": float(np.mean([m["srmse"] for m in mine])),
                    "d_srmse": float(np.mean(d_srmse)),
                    "d_srmse_half": mean_halfwidth(d_srmse),
                }
            )
    return rows


def _markdown(rows: list[dict[str, Any]], folds: int) -> str:
    lines = [
        f"# Cost of the default mixture fit's parts ({folds} folds, one thread)",
        "",
        "| data set | variant | CPU s | x default | NLPD | ΔNLPD [95 %] | SRMSE | ΔSRMSE [95 %] |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(
            f"| {r['dataset']} | {r['variant']} | {r['cpu']:.2f} | {r['cpu_ratio']:.2f} | "
            f"{r['nlpd']:.3f} | {r['d_nlpd']:+.3f} ± {r['d_nlpd_half']:.3f} | "
            f"{r['srmse']:.3f} | {r['d_srmse']:+.3f} ± {r['d_srmse_half']:.3f} |"
        )
    lines += [
        "",
        "Δ: the variant minus the default in the same folds (positive NLPD or SRMSE: worse).",
    ]
    return "\n".join(lines) + "\n"


def _names(text: str, known: Any, option: str) -> list[str]:
    names = [n.strip() for n in text.split(",") if n.strip()]
    unknown = [n for n in names if n not in known]
    if not names or unknown:
        raise InputError(f"{option} names {unknown or 'nothing'}; choose from {list(known)}.")
    return names


def main(argv: list[str] | None = None) -> int:
    """Parse the flags, fit every cell, print and write the table.

    Args:
        argv: The flags (default: ``sys.argv[1:]``).

    Returns:
        0; a bad flag raises `InputError` (one line and exit status 2 through `run_cli`).
    """
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--datasets", default=",".join(SMALL))
    parser.add_argument("--folds", type=int, default=5)
    parser.add_argument("--variants", default=",".join(VARIANTS))
    parser.add_argument("--out", default="results/mixture_cost")
    args = parser.parse_args(argv)
    datasets = _names(args.datasets, SMALL, "--datasets")
    variants = _names(args.variants, VARIANTS, "--variants")
    if "default" not in variants:
        variants.insert(0, "default")
    if args.folds < 2:
        raise InputError(f"--folds must be an integer >= 2, got {args.folds}.")
    out = Path(args.out)
    cells: list[dict[str, Any]] = []
    with limit_threads(1), threadpool_limits(1):
        for name in datasets:
            ds = DATASETS[name](out / "data", 400 if name == "synthetic" else None, False)
            splits = KFold(args.folds, shuffle=True, random_state=0).split(ds.X)
            for fold, (train, test) in enumerate(splits):
                if not cells:  # warm-up: the first fit of a process pays one-time imports
                    fit_cell(ds, train, test, VARIANTS["default"])
                for variant in variants:
                    cell = fit_cell(ds, train, test, VARIANTS[variant])
                    cells.append({"dataset": name, "variant": variant, "fold": fold, **cell})
                    print(
                        f"{name} fold {fold} {variant}: {cell['cpu']:.2f} CPU s, "
                        f"NLPD {cell['nlpd']:.3f}, SRMSE {cell['srmse']:.3f}",
                        flush=True,
                    )
    rows = summarise(cells)
    text = _markdown(rows, args.folds)
    out.mkdir(parents=True, exist_ok=True)
    header = list(rows[0])
    csv = "\n".join([",".join(header)] + [",".join(str(r[k]) for k in header) for r in rows])
    atomic_write_text(out / "mixture_cost.csv", csv + "\n")
    atomic_write_text(out / "mixture_cost.md", text)
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(run_cli(main))
