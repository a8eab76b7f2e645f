"""Where a mixture of GP experts loses held-out RMSE: its gate or its experts.

On data whose true regimes are known, every fold fits, side by side in the same run:

* ``single_gp``: one `GPExpert` on every training row (length-scale prior), the baseline;
* ``em``: `MixtureOfGPExperts` with one expert per true regime, fitted by `fit_em` with its
  defaults (the noise floor of ``benchmarks/mixture_peers.py``), scored by its predictive
  distribution `predict` (its RMSE is that of the mixture's mean);
* ``em_stacked``: the same fit's point prediction `predict_point` (``point="stacked"``: per
  output, the mixture's mean stacked with one GP fitted on every row, the weights `alpha`
  chosen out of sample on the training rows; `probaff.models.mixture.point`). Only the point
  changes, so its NLPD is ``em``'s (the same predictive distribution, repeated);
* ``em_best_expert``: ``em``'s experts, each held-out row predicted by the mean of the
  expert closest to its target (squared error summed over the outputs, each divided by its
  standard deviation over the data set, as in ``srmse``): the best any gate choosing one
  expert per row can do with these experts. RMSE only: the choice looks at the target, so
  no NLPD is reported (blank in the CSV, ``—`` in the table);
* ``em_m3``: the same as ``em`` with M = 3, the size ``benchmarks/mixture_peers.py`` uses
  (the ``em`` fit itself where there are 3 true regimes);
* ``em_m3_stacked``: ``em_m3``'s stacked point, as ``em_stacked`` (NLPD ``em_m3``'s);
* ``em_oracle_gate``: ``em``'s experts, but each held-out row is predicted by the expert that
  holds most of its true regime's training responsibility (the gate replaced by the truth);
* ``regime_gps_oracle_gate``: one `GPExpert` per true regime, fitted on that regime's
  training rows only, each held-out row predicted by its own regime's GP (the experts
  replaced by the truth too);
* ``regime_gps_learned_gate``: the same GPs mixed by a `SoftmaxGate` fitted to the true
  regimes of the training rows (a gate that only has to classify).

``em``, ``em_stacked``, ``em_best_expert`` and ``em_oracle_gate`` share one fit per fold,
as do ``em_m3`` and ``em_m3_stacked``. How to read the rows (differences in the same folds):

* does the mixture's mean lose RMSE? ``em`` against ``single_gp``;
* the gate's error: ``em`` against ``em_oracle_gate`` (each row's true-regime expert) and
  against ``em_best_expert`` (each row's best expert, whatever its regime);
* the experts' error: ``em_best_expert`` against ``single_gp``. If even the best expert of
  every row loses to the single GP, no gate choosing one expert per row closes the gap:
  the experts' means are worse than the single GP's. (A soft gate blends the experts'
  means, and a blend can land nearer a target than any one expert, so strictly this
  bounds hard gates.) The converse is weaker: choosing by the target is optimistic (of
  two predictors with equally large, independent errors, the nearer one per row beats
  both), so a best expert that beats the single GP shows only that the experts are not
  uniformly worse, not that a gate from the features could reach it; ``em_oracle_gate``
  says whether the true regime picks the better expert. ``em_oracle_gate`` against
  ``regime_gps_oracle_gate`` is the experts' error from learning the responsibilities
  instead of being given them;
* what the stacked point repairs: ``em_stacked`` against ``em`` and ``single_gp`` (it should
  be no worse than ``single_gp``, up to the noise of choosing `alpha` on the training
  rows); ``OUT/ablation.md`` lists the mean `alpha` per output (the mixture mean's share:
  0 is the single GP's point, 1 the mixture's mean);
* ``regime_gps_learned_gate`` against ``regime_gps_oracle_gate`` is what classifying the
  regime from the features costs, and ``regime_gps_oracle_gate`` against ``single_gp``
  what knowing the regimes could buy at most.

Data sets (fixed data, seed 0; the CLI seed sets folds and fits):

* ``ch5``: the 321 simulated two-object pushes of ``benchmarks/mixture_peers.py`` (poses
  observed with `PoseNoise()`, f_o & f_c, the six effects); the true regime of a push is
  whether object 2 was touched (by the hand or by object 1): untouched, it does not move.
* ``synthetic``: ``softmax_regimes(400, seed=0)`` and its regime labels.

Scores per fold: RMSE of the point prediction per output (the predictive mean, except for
the ``*_stacked`` and ``em_best_expert`` points), their mean after dividing each by the
output's standard deviation over the data set (``srmse``), and NLPD per held-out row (the
per-output NLPDs summed). ``OUT/tasks/`` holds one JSON file per data set and fold (an
interrupted run resumes; a change of `MODELS` starts afresh), ``OUT/ablation.csv`` one
row per data set, fold and model, ``OUT/ablation.md`` means with 95 % t-intervals over
folds (SRMSE and NLPD, RMSE per output, the stacking weights), ``OUT/ablation.png`` SRMSE
by model.

Usage::

    python benchmarks/mixture_ablation.py [--datasets ch5,synthetic] [--folds 5] [--seed 0]
        [--out results/mixture_ablation] [--workers 0] [--smoke]
"""

from __future__ import annotations

import argparse
import csv
import hashlib
import io
import json
import sys
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch
from matplotlib.figure import Figure
from sklearn.model_selection import KFold
from torch import Tensor
from torch.distributions import Distribution, Independent, Normal

from probaff._cli_errors import run_cli
from probaff._io import atomic_save_figure, atomic_write_text
from probaff._threads import limit_threads
from probaff.errors import InputError
from probaff.eval.metrics import mean_halfwidth, nlpd, rmse
from probaff.eval.tasks import ResultStore, run_tasks
from probaff.models import GPExpert, GPOptions, MixtureOfGPExperts, fit_em
from probaff.models.gates.gate import make_gate
from probaff.models.gates.gated import mixture_distribution

MODELS = (
    "single_gp",
    "em",
    "em_stacked",
    "em_best_expert",
    "em_m3",
    "em_m3_stacked",
    "em_oracle_gate",
    "regime_gps_oracle_gate",
    "regime_gps_learned_gate",
)
"""Every model a fold scores, in table order."""

STACKED = {"em_stacked": "em", "em_m3_stacked": "em_m3"}
"""The stacked points, each with the model whose fit (and distribution) it shares."""

SMOKE_ROWS = 60
"""Rows per data set under ``--smoke``."""


@dataclass(frozen=True)
class RegimeData:
    """A regression data set with known regimes.

    Attributes:
        name: Short name (keys and tables).
        X: Features, `(N, D)` float64.
        Y: Targets, `(N, E)` float64.
        regime: True regime of each row, integers ``0 .. R - 1``, `(N,)`.
        outputs: Names of the `E` targets.
        noise_floor: Known noise standard deviation per output, or ``None``.
    """

    name: str
    X: np.ndarray
    Y: np.ndarray
    regime: np.ndarray
    outputs: tuple[str, ...]
    noise_floor: list[float] | None = None

    @property
    def n_regimes(self) -> int:
        """Number of true regimes `R`."""
        return int(self.regime.max()) + 1


def load_ch5(data_root: Path, rows: int | None, progress: bool) -> RegimeData:
    """The two-object pushes; regime 1 where object 2 was touched, else 0."""
    from probaff.data.generation import GenerateConfig, generate
    from probaff.data.noise import PoseNoise
    from probaff.features import chapter5_features

    n = 321
    ds = generate(
        GenerateConfig("two_objects", n, seed=0, pose_noise=PoseNoise()),
        data_root / f"two_objects-noisy-n{n}",  # the data of benchmarks/mixture_peers.py
        workers=0,
        resume=True,
        progress=progress,
    )
    X = np.asarray(chapter5_features(ds).select("f_o", "f_c"), dtype=np.float64)
    Y = np.asarray(ds["effect"][:, :2].reshape(len(ds), 6), dtype=np.float64)
    touched = np.asarray(ds["hand_contact"])[:, 1] | np.asarray(ds["object_contact"])[:, 0, 1]
    keep = slice(None) if rows is None else np.sort(np.random.default_rng(0).permutation(n)[:rows])
    return RegimeData(
        "ch5",
        X[keep],
        Y[keep],
        touched.astype(np.int64)[keep],
        ("o1.dy", "o1.dz", "o1.dth", "o2.dy", "o2.dz", "o2.dth"),
        PoseNoise().effect_std(2),
    )


def load_synthetic(data_root: Path, rows: int | None, progress: bool) -> RegimeData:
    """Three softmax-gated regimes overlapping in output space, with their labels."""
    from probaff.models.synthetic import softmax_regimes

    x, y, labels = softmax_regimes(rows or 400, seed=0)
    return RegimeData("synthetic", x.numpy(), y.numpy(), labels.numpy(), ("y0", "y1"))


DATASETS: dict[str, Callable[[Path, int | None, bool], RegimeData]] = {
    "ch5": load_ch5,
    "synthetic": load_synthetic,
}


# ------------------------------------------------------------------------------ models
def _gp(x: np.ndarray, y: np.ndarray, floor: list[float] | None, gp_iter: int) -> GPExpert:
    return GPExpert(
        x.shape[1], y.shape[1], max_iter=gp_iter, lengthscale_prior=True, noise_floor=floor
    ).fit(x, y)


@dataclass(frozen=True)
class Prediction:
    """One model's prediction of the held-out rows.

    Attributes:
        dist: Predictive distribution over `(N, E)` (NLPD); None where NLPD means nothing.
        point: Point prediction `(N, E)` scored by RMSE; None for the mean of `dist`.
        alpha: The stacking weights of a stacked point `(E,)` (the mixture mean's share),
            else None.
    """

    dist: Distribution | None
    point: Tensor | None = None
    alpha: Tensor | None = None

    def __post_init__(self) -> None:
        if self.dist is None and self.point is None:
            raise ValueError("A prediction needs a distribution or a point.")

    @property
    def scored(self) -> Distribution | Tensor:
        """What RMSE scores: the point, or the distribution (by its mean)."""
        if self.point is not None:
            return self.point
        assert self.dist is not None  # __post_init__
        return self.dist


def _em(task: dict[str, Any], m: int) -> tuple[MixtureOfGPExperts, torch.Tensor]:
    """A default EM mixture of `m` experts and its training responsibilities `(N, m)`.

    The mixture's default ``point="stacked"`` makes `fit_em` fit its stacked point too.
    """
    x, y = task["X"][task["train"]], task["Y"][task["train"]]
    floor = task["noise_floor"]
    gp = GPOptions(
        max_iter=task["gp_iter"],
        lengthscale_prior=True,
        noise_floor="auto" if floor is None else floor,
    )
    model = MixtureOfGPExperts(m, gp=gp)
    history = fit_em(model, x, y, seed=task["seed"], max_iter=task["em_iter"])
    return model, history.responsibilities


def _em_predictions(model: MixtureOfGPExperts, x_test: np.ndarray) -> tuple[Prediction, Prediction]:
    """A fitted mixture's predictive distribution and its stacked point, sharing the former."""
    dist = model.predict(x_test)
    mean = dist.mean
    point = model.predict_point(x_test, mean=mean)
    weights = model.point_weights
    alpha = torch.ones_like(mean[0]) if weights is None else weights.detach().clone()
    return Prediction(dist), Prediction(dist, point.detach(), alpha)


def _oracle(components: Normal, chosen: torch.Tensor) -> Distribution:
    """Row `i` predicted by component `chosen[i]` of `components` `(N, M, E)` alone."""
    rows = torch.arange(chosen.shape[0])
    return Independent(Normal(components.loc[rows, chosen], components.scale[rows, chosen]), 1)


def _best_expert(means: Tensor, y: Tensor, scale: Tensor) -> Tensor:
    """Row `i` predicted by the mean nearest its target among `means` `(N, M, E)`.

    Args:
        means: Every expert's predictive mean of every row, `(N, M, E)`.
        y: The targets, `(N, E)`.
        scale: Each output's scale `(E,)`; the distance is the squared error summed over
            the outputs, each divided by its scale.

    Returns:
        `(N, E)`: the chosen expert's mean per row.
    """
    err = (((means - y[:, None, :]) / scale) ** 2).sum(-1)  # (N, M)
    return means[torch.arange(means.shape[0]), err.argmin(1)]


def fold_predictions(task: dict[str, Any]) -> dict[str, Prediction]:
    """Every model of `MODELS` fitted on one training fold, predicting its held-out rows."""
    X, Y, regime = task["X"], task["Y"], task["regime"]
    train, test = task["train"], task["test"]
    r, floor, gp_iter = task["n_regimes"], task["noise_floor"], task["gp_iter"]
    x_test = X[test]
    y_test = torch.as_tensor(Y[test], dtype=torch.float64)
    single = _gp(X[train], Y[train], floor, gp_iter).predict(x_test)
    out: dict[str, Prediction] = {"single_gp": Prediction(Independent(single, 1))}
    model, resp = _em(task, r)  # one fit: em, em_stacked, em_best_expert, em_oracle_gate
    out["em"], out["em_stacked"] = _em_predictions(model, x_test)
    experts = model.expert_predictions(x_test)  # (N_test, r, E)
    scale = torch.as_tensor(task["y_std"], dtype=torch.float64)
    out["em_best_expert"] = Prediction(None, _best_expert(experts.loc, y_test, scale))
    if r == 3:
        out["em_m3"], out["em_m3_stacked"] = out["em"], out["em_stacked"]
    else:
        out["em_m3"], out["em_m3_stacked"] = _em_predictions(_em(task, 3)[0], x_test)
    # each regime's expert: the one holding most of its training rows' responsibility
    onehot = torch.nn.functional.one_hot(torch.as_tensor(regime[train]), r).double()
    expert_of = (onehot.T @ resp).argmax(1)  # (R,)
    truth = torch.as_tensor(regime[test])
    out["em_oracle_gate"] = Prediction(_oracle(experts, expert_of[truth]))
    gps = []
    for k in range(r):
        rows = train[regime[train] == k]
        gps.append(_gp(X[rows], Y[rows], floor, gp_iter).predict(x_test))
    parts = Normal(
        torch.stack([g.loc for g in gps], 1), torch.stack([g.scale for g in gps], 1)
    )  # (N_test, R, E)
    out["regime_gps_oracle_gate"] = Prediction(_oracle(parts, truth))
    gate = make_gate("linear", X.shape[1], r, seed=task["seed"]).fit(X[train], onehot)
    out["regime_gps_learned_gate"] = Prediction(
        mixture_distribution(gate.predict_proba(x_test), parts)
    )
    return out


def score_fold(task: dict[str, Any]) -> dict[str, Any]:
    """Fit every model on one fold and score it on the held-out rows."""
    y = torch.as_tensor(task["Y"][task["test"]], dtype=torch.float64)
    y_std = np.asarray(task["y_std"])
    with limit_threads(1), warnings.catch_warnings():
        warnings.simplefilter("ignore")
        predictions = fold_predictions(task)
    rows = []
    with torch.no_grad():
        for name in MODELS:
            pred = predictions[name]
            per_output = rmse(pred.scored, y).numpy()
            rows.append(
                {
                    "dataset": task["dataset"],
                    "fold": int(task["fold"]),
                    "model": name,
                    "srmse": float(np.mean(per_output / y_std)),
                    "nlpd": None if pred.dist is None else float(nlpd(pred.dist, y).sum()),
                    "rmse": [float(v) for v in per_output],
                    "alpha": None if pred.alpha is None else [float(v) for v in pred.alpha],
                }
            )
    return {"rows": rows}


# ------------------------------------------------------------------------------- tasks
def make_tasks(
    ds: RegimeData, folds: int, seed: int, smoke: bool
) -> list[tuple[str, tuple[dict[str, Any]]]]:
    """One task per fold of `ds`; folds are stratified by nothing (``KFold``, shuffled)."""
    y_std = ds.Y.std(axis=0)
    settings = {
        "folds": folds,
        "seed": seed,
        "smoke": smoke,
        "models": MODELS,
        "data": hashlib.sha1(ds.X.tobytes() + ds.Y.tobytes() + ds.regime.tobytes()).hexdigest(),
    }
    tag = hashlib.sha1(json.dumps(settings, sort_keys=True).encode()).hexdigest()[:8]
    tasks = []
    for f, (train, test) in enumerate(KFold(folds, shuffle=True, random_state=seed).split(ds.X)):
        task = {
            "dataset": ds.name,
            "fold": f,
            "seed": seed,
            "X": ds.X,
            "Y": ds.Y,
            "regime": ds.regime,
            "n_regimes": ds.n_regimes,
            "train": train,
            "test": test,
            "noise_floor": ds.noise_floor,
            "y_std": np.where(y_std > 0, y_std, 1.0),
            "gp_iter": 5 if smoke else 50,
            "em_iter": 2 if smoke else 10,
        }
        tasks.append((f"{ds.name}.fold{f}.{tag}", (task,)))
    return tasks


# ----------------------------------------------------------------------------- reports
def summarise(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Per data set and model: folds, mean and 95 % t half-width of the scores.

    Returns:
        One entry per data set and model: ``srmse``, ``nlpd`` (None for a model without
        NLPD) and ``rmse`` (per output), each with its ``*_half``, and ``alpha`` (per
        output, the mean stacking weight over folds; None for a model that does not stack).
    """
    out = []
    for name in dict.fromkeys(r["dataset"] for r in rows):
        for model in MODELS:
            mine = [r for r in rows if r["dataset"] == name and r["model"] == model]
            entry: dict[str, Any] = {"dataset": name, "model": model, "folds": len(mine)}
            for metric in ("srmse", "nlpd"):
                values = [r[metric] for r in mine if r[metric] is not None]
                entry[metric] = float(np.mean(values)) if values else None
                entry[f"{metric}_half"] = mean_halfwidth(values) if values else None
            per_output = np.asarray([r["rmse"] for r in mine], dtype=np.float64)  # (F, E)
            entry["rmse"] = per_output.mean(0).tolist()
            entry["rmse_half"] = [mean_halfwidth(list(col)) for col in per_output.T]
            alphas = [r["alpha"] for r in mine if r.get("alpha") is not None]
            entry["alpha"] = np.mean(alphas, axis=0).tolist() if alphas else None
            out.append(entry)
    return out


def _csv(rows: list[dict[str, Any]]) -> str:
    buf = io.StringIO()
    writer = csv.writer(buf)
    writer.writerow(["dataset", "fold", "model", "srmse", "nlpd", "rmse", "alpha"])
    for r in rows:
        rmse_text = " ".join(f"{v:.6g}" for v in r["rmse"])
        alpha = r.get("alpha")
        alpha_text = "" if alpha is None else " ".join(f"{v:.4g}" for v in alpha)
        nlpd_text = "" if r["nlpd"] is None else r["nlpd"]
        writer.writerow(
            [r["dataset"], r["fold"], r["model"], r["srmse"], nlpd_text, rmse_text, alpha_text]
        )
    return buf.getvalue()


def _interval(mean: float | None, half: float | None, digits: int = 3) -> str:
    return "—" if mean is None or half is None else f"{mean:.{digits}f} ± {half:.{digits}f}"


def _markdown(
    summary: list[dict[str, Any]], folds: int, seed: int, outputs: dict[str, tuple[str, ...]]
) -> str:
    """The tables of ``ablation.md``; `outputs` names each data set's outputs."""
    lines = [
        "# Gate error against expert error",
        "",
        f"{folds}-fold cross-validation (seed {seed}); mean ± 95 % t half-width over folds.",
        "RMSE of the predictive mean, except the stacked points (`*_stacked`) and the best",
        "expert per row (`em_best_expert`, chosen by its target: no NLPD). A stacked",
        "point's NLPD is its mixture's (the same distribution).",
        "",
        "| data | model | SRMSE | NLPD |",
        "|---|---|---|---|",
    ]
    for s in summary:
        lines.append(
            f"| {s['dataset']} | {s['model']} | {_interval(s['srmse'], s['srmse_half'])} "
            f"| {_interval(s['nlpd'], s['nlpd_half'])} |"
        )
    for name in dict.fromkeys(s["dataset"] for s in summary):
        mine = [s for s in summary if s["dataset"] == name]
        names = outputs.get(name) or tuple(f"y{e}" for e in range(len(mine[0]["rmse"])))
        lines += [
            "",
            f"## {name}: RMSE per output (output units)",
            "",
            "| model | " + " | ".join(names) + " |",
            "|---|" + "---|" * len(names),
        ]
        for s in mine:
            cells = [_interval(m, h, 4) for m, h in zip(s["rmse"], s["rmse_half"], strict=True)]
            lines.append(f"| {s['model']} | " + " | ".join(cells) + " |")
        stacked = [s for s in mine if s["alpha"] is not None]
        if stacked:
            lines += [
                "",
                f"{name}: stacking weight `alpha` per output, mean over folds (the mixture "
                "mean's share; 0 is the single GP's point):",
                "",
                "| model | " + " | ".join(names) + " |",
                "|---|" + "---|" * len(names),
            ]
            for s in stacked:
                lines.append(
                    f"| {s['model']} | " + " | ".join(f"{a:.2f}" for a in s["alpha"]) + " |"
                )
    return "\n".join(lines) + "\n"


def plot(summary: list[dict[str, Any]], path: Path) -> None:
    """SRMSE by model per data set, with 95 % intervals over folds."""
    names = list(dict.fromkeys(s["dataset"] for s in summary))
    fig = Figure(figsize=(4.0 * len(names), 3.6), layout="constrained")
    for i, name in enumerate(names):
        ax = fig.add_subplot(1, len(names), i + 1)
        mine = [s for s in summary if s["dataset"] == name]
        ax.barh(
            range(len(mine)),
            [s["srmse"] for s in mine],
            xerr=[s["srmse_half"] for s in mine],
            color="tab:blue",
        )
        ax.set_yticks(range(len(mine)), [s["model"] for s in mine] if i == 0 else [])
        ax.invert_yaxis()
        ax.set_xlabel("held-out SRMSE")
        ax.set_title(name)
    atomic_save_figure(fig, path, dpi=120)


# --------------------------------------------------------------------------------- CLI
def parse_args(argv: list[str] | None) -> argparse.Namespace:
    """The command line."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--datasets", default=",".join(DATASETS))
    p.add_argument("--folds", type=int, default=None, help="default 5 (2 with --smoke)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--out", default="results/mixture_ablation")
    p.add_argument("--workers", type=int, default=0)
    p.add_argument("--smoke", action="store_true", help="60 rows per data set, 2 folds")
    p.add_argument("--no-progress", action="store_true")
    return p.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    """Run (or resume) the ablation and write the CSV, Markdown and PNG."""
    args = parse_args(argv)
    names = [n for n in args.datasets.split(",") if n]
    unknown = [n for n in names if n not in DATASETS]
    if unknown or not names:
        raise InputError(f"--datasets: unknown {unknown or names}; choose from {list(DATASETS)}.")
    folds = args.folds if args.folds is not None else (2 if args.smoke else 5)
    if folds < 2 or args.seed < 0 or args.workers < 0:
        raise InputError("--folds must be at least 2, --seed and --workers at least 0.")
    out, progress = Path(args.out), not args.no_progress
    datasets = [
        DATASETS[n](out / "data", SMOKE_ROWS if args.smoke else None, progress) for n in names
    ]
    tasks = [t for ds in datasets for t in make_tasks(ds, folds, args.seed, args.smoke)]
    results = run_tasks(
        score_fold,
        tasks,
        ResultStore(out / "tasks"),
        workers=args.workers,
        progress=progress,
        desc="mixture ablation",
    )
    rows = [row for result in results for row in result["rows"]]
    summary = summarise(rows)
    atomic_write_text(out / "ablation.csv", _csv(rows))
    table = _markdown(summary, folds, args.seed, {ds.name: ds.outputs for ds in datasets})
    atomic_write_text(out / "ablation.md", table)
    plot(summary, out / "ablation.png")
    print(table)
    return 0


if __name__ == "__main__":
    sys.exit(run_cli(main))
