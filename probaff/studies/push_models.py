"""The push-model study: chapters 5 and 4 on simulated data, EM and VI side by side.

Chapter 5 (Figure 5.6): about 321 two-object pushes, mixtures of M = 1..6 GP experts, 3-fold
cross-validation, four feature configurations (``o``: f_o; ``oc``: f_o & f_c; ``ocx``: f_o &
f_c & f_x; ``gx-eoc``: f_x for the gate with f_o & f_c for the experts), EM and Pyro SVI.
Chapter 4: about 120 single-object pushes near the battery, m = 1..4, 5-fold cross-validation,
its features, the mixture fitted by EM and the clustered baseline (GMM clusters, one GP each,
SVM gate).

Every (experiment, features, method, M, fold) is one task whose scores are saved as soon as it
finishes (`probaff.eval.tasks`), keyed also by a hash of the settings that shape it, so an
interrupted study resumes where it stopped, never mixes settings, and can run on Dask. Tables
(CSV, Markdown) and figures (PNG) go to the output folder.
"""

from __future__ import annotations

import csv
import hashlib
import io
import json
import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch
from sklearn.model_selection import KFold

from probaff._io import atomic_write_text
from probaff._threads import torch_threads
from probaff.data.generation import GenerateConfig, generate
from probaff.errors import InputError
from probaff.eval.metrics import interval_coverage, nlpd, rmse
from probaff.eval.model_figures import (
    plot_effect_clusters,
    plot_metric_vs_experts,
    plot_relevances,
)
from probaff.eval.tasks import ResultStore, run_tasks
from probaff.features import chapter4_features, chapter5_features
from probaff.models import (
    ClusteredGPModel,
    MixtureOfGPExperts,
    VariationalMixtureOfGPExperts,
    fit_em,
    fit_svi,
)

__all__ = ["CH4_FEATURES", "CH5_FEATURES", "PushModelStudyConfig", "run"]

CH5_FEATURES: dict[str, tuple[tuple[str, ...], tuple[str, ...]]] = {
    "o": (("f_o",), ("f_o",)),
    "oc": (("f_o", "f_c"), ("f_o", "f_c")),
    "ocx": (("f_o", "f_c", "f_x"), ("f_o", "f_c", "f_x")),
    "gx-eoc": (("f_x",), ("f_o", "f_c")),
}
"""Chapter 5 configurations: name -> (gate groups, expert groups)."""

CH4_FEATURES: dict[str, tuple[str, ...]] = {
    "o": ("f_o",),
    "oc": ("f_o", "f_c"),
    "ocx": ("f_o", "f_c", "f_x"),
}
"""Chapter 4 configurations: name -> groups used by the experts (and the gate)."""

CH5_EFFECTS = ("o1.dy", "o1.dz", "o1.dth", "o2.dy", "o2.dz", "o2.dth")
CH4_EFFECTS = ("dy", "dz", "dth")


@dataclass(frozen=True)
class PushModelStudyConfig:
    """Settings of the push-model study (defaults reproduce the thesis's setup).

    Attributes:
        out: Output folder (datasets, per-task results, tables, figures).
        seed: Seed of the datasets, folds and fits.
        ch5_pushes: Two-object pushes.
        ch5_experts: Values of M.
        ch5_folds: Cross-validation folds.
        ch5_features: Names from `CH5_FEATURES`.
        methods: ``"em"`` and/or ``"vi"``.
        ch4_pushes: Single-object pushes near the battery (0 skips chapter 4).
        ch4_experts: Values of m.
        ch4_folds: Cross-validation folds.
        ch4_features: Names from `CH4_FEATURES`.
        em_iterations: EM iterations.
        vi_steps: SVI steps.
        vi_inducing: Inducing points per variational expert.
        gp_max_iter: L-BFGS iterations per expert fit.
        lengthscale_prior: Dimension-scaled log-normal prior on the ARD length scales (MAP
            instead of ML-II; with N close to D, ML-II overfits).
        workers: 0 runs in this process; K > 0 or None uses a local Dask cluster.
        scheduler: Address of an existing Dask scheduler.
        progress: Show progress bars.
    """

    out: str = "results/push_models"
    seed: int = 0
    ch5_pushes: int = 321
    ch5_experts: tuple[int, ...] = (1, 2, 3, 4, 5, 6)
    ch5_folds: int = 3
    ch5_features: tuple[str, ...] = ("o", "oc", "ocx", "gx-eoc")
    methods: tuple[str, ...] = ("em", "vi")
    ch4_pushes: int = 120
    ch4_experts: tuple[int, ...] = (1, 2, 3, 4)
    ch4_folds: int = 5
    ch4_features: tuple[str, ...] = ("o", "oc", "ocx")
    em_iterations: int = 10
    vi_steps: int = 800
    vi_inducing: int = 32
    gp_max_iter: int = 50
    lengthscale_prior: bool = True
    workers: int | None = 0
    scheduler: str | None = None
    progress: bool = True

    def validate(self) -> None:
        """Raise `InputError` for unknown names or impossible sizes."""
        for name in self.ch5_features:
            if name not in CH5_FEATURES:
                raise InputError(f"unknown chapter 5 features {name!r}; use {list(CH5_FEATURES)}.")
        for name in self.ch4_features:
            if name not in CH4_FEATURES:
                raise InputError(f"unknown chapter 4 features {name!r}; use {list(CH4_FEATURES)}.")
        for m in self.methods:
            if m not in ("em", "vi"):
                raise InputError(f"unknown method {m!r}; use 'em' and/or 'vi'.")
        for folds in (self.ch5_folds, self.ch4_folds):
            if folds < 2:
                raise InputError(f"cross-validation needs at least 2 folds, got {folds}.")
        if self.ch5_pushes < self.ch5_folds:
            raise InputError("ch5_pushes must be at least ch5_folds.")


def _key(*parts: object) -> str:
    return ".".join(str(p) for p in parts)


def _fingerprint(config: PushModelStudyConfig, exp: str) -> str:
    """Short hash of every setting that shapes a task's result (not where or how it runs)."""
    keys = ("seed", "em_iterations", "vi_steps", "vi_inducing", "gp_max_iter",
            "lengthscale_prior", f"{exp}_pushes", f"{exp}_folds")
    settings = json.dumps({k: getattr(config, k) for k in keys}, sort_keys=True)
    return hashlib.sha1(settings.encode()).hexdigest()[:8]


def _fit_and_score(task: dict[str, Any]) -> dict[str, Any]:
    """Fit one model on one fold's training pushes and score it on the held-out ones."""
    X, Y = np.asarray(task["X"]), np.asarray(task["Y"])
    train, test = np.asarray(task["train"]), np.asarray(task["test"])
    groups = {k: slice(*v) for k, v in task["groups"].items()}
    m, method, seed = int(task["M"]), task["method"], int(task["seed"])
    gate_groups, expert_groups = task["gate"], task["experts"]
    start = time.perf_counter()
    extra: dict[str, Any] = {}
    with torch_threads(1):
        if method == "clustered":
            cols = np.concatenate([np.arange(X.shape[1])[groups[g]] for g in expert_groups])
            model: Any = ClusteredGPModel(m, seed=seed, expert_kwargs={
                "max_iter": task["gp_max_iter"], "lengthscale_prior": task["prior"]})
            model.fit(X[train][:, cols], Y[train])
            pred = model.predict(X[test][:, cols])
            assign = model.labels_
        elif method == "em":
            model = MixtureOfGPExperts(m, groups=groups, gate_features=gate_groups,
                                       expert_features=expert_groups,
                                       gp_max_iter=task["gp_max_iter"],
                                       lengthscale_prior=task["prior"])
            hist = fit_em(model, X[train], Y[train], max_iter=task["em_iterations"], seed=seed)
            pred = model.predict(X[test])
            assign = hist.responsibilities.argmax(1).numpy()
            extra["log_likelihood"] = [float(v) for v in hist.log_likelihood]
            extra["lengthscales"] = [ls.tolist() for ls in model.lengthscales()]
            extra["expert_columns"] = list(map(int, model.expert_columns))
        else:
            model = VariationalMixtureOfGPExperts(m, groups=groups, gate_features=gate_groups,
                                                  expert_features=expert_groups,
                                                  n_inducing=task["vi_inducing"])
            fit_svi(model, X[train], Y[train], n_steps=task["vi_steps"], seed=seed)
            pred = model.predict(X[test])
            assign = model.gate_probs(X[train]).argmax(1).numpy()
    seconds = time.perf_counter() - start
    y = torch.as_tensor(Y[test])
    return {
        "experiment": task["experiment"], "features": task["features"], "method": method,
        "M": m, "fold": int(task["fold"]), "seconds": seconds,
        "rmse": rmse(pred, y).tolist(), "nlpd": nlpd(pred, y).tolist(),
        "coverage90": interval_coverage(pred, y, 0.9).tolist(),
        "train_assignment": [int(a) for a in assign], "train_index": train.tolist(), **extra,
    }


def _tasks(exp: str, X: np.ndarray, Y: np.ndarray, groups: dict[str, slice],
           configs: dict[str, tuple[tuple[str, ...], tuple[str, ...]]],
           methods: tuple[str, ...], experts: tuple[int, ...], folds: int,
           config: PushModelStudyConfig) -> list[tuple[str, tuple[Any, ...]]]:
    splits = list(KFold(folds, shuffle=True, random_state=config.seed).split(X))
    fingerprint = _fingerprint(config, exp)
    out = []
    for name, (gate, experts_groups) in configs.items():
        for method in methods:
            for m in experts:
                for f, (train, test) in enumerate(splits):
                    task = {
                        "experiment": exp, "features": name, "method": method, "M": m,
                        "fold": f, "seed": config.seed, "X": X, "Y": Y,
                        "train": train, "test": test,
                        "groups": {k: (v.start, v.stop) for k, v in groups.items()},
                        "gate": list(gate), "experts": list(experts_groups),
                        "em_iterations": config.em_iterations, "vi_steps": config.vi_steps,
                        "vi_inducing": config.vi_inducing, "gp_max_iter": config.gp_max_iter,
                        "prior": config.lengthscale_prior,
                    }
                    out.append((_key(exp, name, method, f"M{m}", f"fold{f}", fingerprint),
                                (task,)))
    return out


def _summarise(results: list[dict[str, Any]], effects: tuple[str, ...]) -> list[dict[str, Any]]:
    """Mean over folds per (features, method, M)."""
    table: dict[tuple[str, str, int], list[dict[str, Any]]] = {}
    for r in results:
        table.setdefault((r["features"], r["method"], r["M"]), []).append(r)
    rows = []
    for (feat, method, m), rs in sorted(table.items()):
        row: dict[str, Any] = {"features": feat, "method": method, "M": m, "folds": len(rs)}
        for metric in ("rmse", "nlpd", "coverage90"):
            mean = np.mean([r[metric] for r in rs], axis=0)
            for e, name in enumerate(effects):
                row[f"{metric}.{name}"] = float(mean[e])
        row["nlpd.total"] = float(np.mean([np.sum(r["nlpd"]) for r in rs]))
        row["seconds"] = float(np.mean([r["seconds"] for r in rs]))
        rows.append(row)
    return rows


def _csv(rows: list[dict[str, Any]]) -> str:
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=list(rows[0]))
    writer.writeheader()
    writer.writerows(rows)
    return buf.getvalue()


def _markdown(rows: list[dict[str, Any]], columns: list[str], digits: int = 4) -> str:
    head = "| " + " | ".join(columns) + " |\n|" + "---|" * len(columns) + "\n"
    body = ""
    for r in rows:
        cells = [f"{r[c]:.{digits}f}" if isinstance(r[c], float) else str(r[c]) for c in columns]
        body += "| " + " | ".join(cells) + " |\n"
    return head + body


def _best_by_nlpd(rows: list[dict[str, Any]]) -> dict[tuple[str, str], int]:
    best: dict[tuple[str, str], tuple[float, int]] = {}
    for r in rows:
        k = (r["features"], r["method"])
        if k not in best or r["nlpd.total"] < best[k][0]:
            best[k] = (r["nlpd.total"], r["M"])
    return {k: v[1] for k, v in best.items()}


def _findings(rows: list[dict[str, Any]]) -> list[str]:
    """The thesis's chapter 5 claims, checked on these results (EM rows).

    RMSE changes are relative and averaged over the effect dimensions, so metres and radians
    weigh alike.
    """
    def get(feat: str, m: int, col: str) -> float | None:
        for r in rows:
            if (r["features"], r["method"], r["M"]) == (feat, "em", m):
                return r[col]
        return None

    def rel(feat_a: str, m_a: int, feat_b: str, m_b: int, dims: tuple[str, ...]
            ) -> float | None:
        """Mean over `dims` of RMSE(a) / RMSE(b) - 1, in %."""
        pairs = [(get(feat_a, m_a, f"rmse.{d}"), get(feat_b, m_b, f"rmse.{d}")) for d in dims]
        if any(a is None or b is None for a, b in pairs):
            return None
        return 100 * float(np.mean([a / b - 1 for a, b in pairs]))  # type: ignore[operator]

    lines = []
    feats = sorted({r["features"] for r in rows if r["method"] == "em"})
    ms = sorted({r["M"] for r in rows if r["method"] == "em"})
    for feat in feats:
        changes = {m: rel(feat, m, feat, 1, CH5_EFFECTS) for m in ms if m != 1}
        changes = {m: v for m, v in changes.items() if v is not None}
        nl = {m: get(feat, m, "nlpd.total") for m in ms}
        nl = {m: v for m, v in nl.items() if v is not None}
        if changes:
            txt = ", ".join(f"M={m}: {v:+.1f}%" for m, v in changes.items())
            best_nl = min(nl, key=lambda m: nl[m])
            lines.append(f"- features {feat}: RMSE relative to M=1 (negative = better): {txt}; "
                         f"lowest NLPD at M={best_nl}.")
    o1, o2 = CH5_EFFECTS[:3], CH5_EFFECTS[3:]
    for m in ms:
        a, b = rel("ocx", m, "o", m, o2), rel("ocx", m, "oc", m, o2)
        c, d = rel("ocx", m, "o", m, o1), rel("ocx", m, "oc", m, o1)
        if None not in (a, b, c, d):
            lines.append(f"- M={m}: adding f_x changes o2's RMSE by {a:+.1f}% vs f_o and {b:+.1f}% "
                         f"vs f_o&f_c (o1: {c:+.1f}% and {d:+.1f}%).")
        split, full, comb = (get(f, m, "rmse.o1.dz") for f in ("gx-eoc", "ocx", "oc"))
        if None not in (split, full, comb):
            lines.append(f"- M={m}: o1 along the push (dz) RMSE: gate-on-context {split:.4f} m, "
                         f"all features {full:.4f} m, f_o&f_c {comb:.4f} m.")
    return lines


def run(config: PushModelStudyConfig) -> dict[str, Any]:
    """Run (or resume) the study and write its tables and figures.

    Args:
        config: Study settings.

    Returns:
        ``{"ch5": summary rows, "ch4": summary rows, "files": [written paths]}``.
    """
    config.validate()
    out = Path(config.out)
    store = ResultStore(out / "tasks")
    files: list[str] = []
    summary: dict[str, Any] = {"config": {k: v for k, v in asdict(config).items()}}

    ds5 = generate(GenerateConfig("two_objects", config.ch5_pushes, seed=config.seed),
                   out / "data" / "two_objects", workers=0, resume=True,
                   progress=config.progress)
    f5 = chapter5_features(ds5)
    Y5 = ds5["effect"][:, :2].reshape(len(ds5), 6)
    configs5 = {k: CH5_FEATURES[k] for k in config.ch5_features}
    tasks = _tasks("ch5", f5.values, Y5, f5.groups, configs5, config.methods,
                   config.ch5_experts, config.ch5_folds, config)
    if config.ch4_pushes:
        ds4 = generate(GenerateConfig("near_obstacle", config.ch4_pushes, seed=config.seed),
                       out / "data" / "near_obstacle", workers=0, resume=True,
                       progress=config.progress)
        f4 = chapter4_features(ds4)
        Y4 = ds4["effect"][:, 0]
        configs4 = {k: (CH4_FEATURES[k], CH4_FEATURES[k]) for k in config.ch4_features}
        tasks += _tasks("ch4", f4.values, Y4, f4.groups, configs4, ("em", "clustered"),
                        config.ch4_experts, config.ch4_folds, config)
    results = run_tasks(_fit_and_score, tasks, store, workers=config.workers,
                        scheduler=config.scheduler, progress=config.progress,
                        desc="push models")

    ch5 = [r for r in results if r["experiment"] == "ch5"]
    rows5 = _summarise(ch5, CH5_EFFECTS)
    summary["ch5"] = rows5
    atomic_write_text(out / "ch5_folds.csv", _csv([{k: v for k, v in r.items()
                                                     if not isinstance(v, list)} for r in ch5]))
    atomic_write_text(out / "ch5_summary.csv", _csv(rows5))
    files += [str(out / "ch5_folds.csv"), str(out / "ch5_summary.csv")]
    md = ["# Push-model study", "", f"Settings: `{summary['config']}`", "",
          "## Chapter 5: two-object pushes, mean over folds", "",
          _markdown(rows5, ["features", "method", "M"] + [f"rmse.{e}" for e in CH5_EFFECTS]
                    + ["nlpd.total", "seconds"]),
          "90% interval coverage:", "",
          _markdown(rows5, ["features", "method", "M"]
                    + [f"coverage90.{e}" for e in CH5_EFFECTS], digits=2),
          "Number of experts chosen by cross-validated NLPD:", ""]
    md += [f"- {feat} / {method}: M = {m}" for (feat, method), m in
           sorted(_best_by_nlpd(rows5).items())]
    md += ["", "Checks of the thesis's findings (EM):", "", *_findings(rows5), ""]
    plot_metric_vs_experts(rows5, CH5_EFFECTS, "rmse", out / "ch5_rmse_vs_M.png",
                           title="Chapter 5: RMSE vs number of experts (m, rad)")
    plot_metric_vs_experts(rows5, CH5_EFFECTS, "coverage90", out / "ch5_coverage_vs_M.png",
                           title="Chapter 5: 90% interval coverage")
    files += [str(out / "ch5_rmse_vs_M.png"), str(out / "ch5_coverage_vs_M.png")]
    shown = "ocx" if "ocx" in config.ch5_features else config.ch5_features[-1]
    example = next((r for r in ch5 if (r["features"], r["method"], r["fold"]) == (shown, "em", 0)
                    and r["M"] == min(3, max(config.ch5_experts))), None)
    if example is not None:
        idx = np.asarray(example["train_index"])
        plot_effect_clusters(Y5[idx][:, [1, 4]], np.asarray(example["train_assignment"]),
                             ("o1 dz_p (m)", "o2 dz_p (m)"), out / "ch5_clusters.png",
                             title=f"Chapter 5: EM assignments, M={example['M']}")
        plot_relevances(example["lengthscales"], example["expert_columns"], f5.groups,
                        out / "ch5_ard_relevance.png")
        files += [str(out / "ch5_clusters.png"), str(out / "ch5_ard_relevance.png")]

    if config.ch4_pushes:
        ch4 = [r for r in results if r["experiment"] == "ch4"]
        rows4 = _summarise(ch4, CH4_EFFECTS)
        summary["ch4"] = rows4
        atomic_write_text(out / "ch4_summary.csv", _csv(rows4))
        files.append(str(out / "ch4_summary.csv"))
        md += ["## Chapter 4: single-object pushes near the battery", "",
               _markdown(rows4, ["features", "method", "M"] + [f"rmse.{e}" for e in CH4_EFFECTS]
                         + ["nlpd.total"]), ""]
        plot_metric_vs_experts(rows4, CH4_EFFECTS, "rmse", out / "ch4_rmse_vs_m.png",
                               title="Chapter 4: RMSE vs number of clusters (m, rad)")
        files.append(str(out / "ch4_rmse_vs_m.png"))
        shown = "ocx" if "ocx" in config.ch4_features else config.ch4_features[-1]
        ex4 = next((r for r in ch4 if (r["features"], r["method"], r["fold"]) ==
                    (shown, "clustered", 0) and r["M"] == min(3, max(config.ch4_experts))), None)
        if ex4 is not None:
            idx = np.asarray(ex4["train_index"])
            plot_effect_clusters(Y4[idx][:, :2], np.asarray(ex4["train_assignment"]),
                                 ("dy_p (m)", "dz_p (m)"), out / "ch4_clusters.png",
                                 title=f"Chapter 4: GMM clusters of the effects, m={ex4['M']}")
            files.append(str(out / "ch4_clusters.png"))
    atomic_write_text(out / "summary.md", "\n".join(md))
    files.append(str(out / "summary.md"))
    summary["files"] = files
    return summary
