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

import time
from dataclasses import asdict, dataclass, fields
from pathlib import Path
from typing import Any

import numpy as np
import torch
from sklearn.model_selection import KFold

from probaff._checks import check_count
from probaff._dask import check_scheduler, check_workers
from probaff._io import atomic_write_text
from probaff._threads import torch_threads
from probaff.data.generation import GenerateConfig, generate
from probaff.data.noise import PoseNoise
from probaff.errors import InputError
from probaff.eval.fingerprint import config_fingerprint
from probaff.eval.metrics import interval_coverage, mean_halfwidth, nlpd, rmse
from probaff.eval.model_figures import (
    plot_effect_clusters,
    plot_metric_vs_experts,
    plot_relevances,
)
from probaff.eval.tables import markdown_table, write_csv
from probaff.eval.tasks import ResultStore, run_tasks
from probaff.features import chapter4_features, chapter5_features
from probaff.models import (
    ClusteredGPModel,
    MixtureOfGPExperts,
    VariationalMixtureOfGPExperts,
    fit_em_path,
    get_fitter,
)
from probaff.models.initialization import check_initialization

__all__ = [
    "CH4_FEATURES",
    "CH5_FEATURES",
    "SMOKE_OVERRIDES",
    "FoldTask",
    "PushModelStudyConfig",
    "run",
]

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

# Bumped whenever a change to the fitting code changes results, so stored tasks of an older
# version are refitted rather than mixed in.
_FIT_VERSION = 3

# Fields of `PushModelStudyConfig` that say where and how the study runs, not what it computes.
_RUN_ONLY = frozenset({"out", "workers", "scheduler", "progress"})

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
        em_init: EM's initialisation (see `probaff.models.fit_em`).
        em_restarts: EM starts tried for each M.
        gate: Kind of gate of the EM mixture (``"linear"`` or ``"fourier"``).
        vi_features: Feature configurations (of `ch5_features`) that VI is also fitted on;
            every VI mixture starts from the EM mixture of the same fold and M.
        vi_steps: SVI steps.
        vi_inducing: Inducing points per variational expert.
        gp_max_iter: L-BFGS iterations per expert fit.
        lengthscale_prior: Dimension-scaled log-normal prior on the ARD length scales (MAP
            instead of ML-II; with N close to D, ML-II overfits).
        pose_noise: Observe object poses with `probaff.data.PoseNoise`'s default noise
            (3 mm, 1 degree), as a depth camera would; the models then get the matching
            noise floor (the standard deviation of a difference of two noisy poses,
            sqrt(2) times the pose noise). Without it, the floor is ``"auto"``.
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
    em_init: str = "auto"
    em_restarts: int = 3
    gate: str = "linear"
    vi_features: tuple[str, ...] = ("oc",)
    vi_steps: int = 400
    vi_inducing: int = 32
    gp_max_iter: int = 50
    lengthscale_prior: bool = True
    pose_noise: bool = True
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
        if "em" not in self.methods:
            raise InputError("methods must include 'em': VI starts from the EM mixtures.")
        try:
            check_initialization(self.em_init)
        except InputError as err:
            raise InputError(f"em_init: {err}") from None
        for name in self.vi_features:
            if name not in self.ch5_features:
                raise InputError(
                    f"vi_features {name!r} is not among ch5_features {list(self.ch5_features)}."
                )
        if self.gate not in ("linear", "fourier"):
            raise InputError(f"unknown gate {self.gate!r}; use 'linear' or 'fourier'.")
        for name in (
            "em_iterations",
            "em_restarts",
            "vi_steps",
            "vi_inducing",
            "gp_max_iter",
            "ch5_pushes",
            "ch5_folds",
            "ch4_folds",
        ):
            check_count(name, getattr(self, name))
        check_count("ch4_pushes", self.ch4_pushes, minimum=0)
        check_count("seed", self.seed, minimum=0)
        for size in (*self.ch5_experts, *self.ch4_experts):
            check_count("number of experts", size)
        for folds in (self.ch5_folds, self.ch4_folds):
            if folds < 2:
                raise InputError(f"cross-validation needs at least 2 folds, got {folds}.")
        check_workers(self.workers)
        check_scheduler(self.scheduler)
        if self.ch5_pushes < self.ch5_folds:
            raise InputError("ch5_pushes must be at least ch5_folds.")


SMOKE_OVERRIDES: dict[str, Any] = {
    "ch5_pushes": 40,
    "ch5_experts": (1, 2),
    "ch5_folds": 2,
    "ch5_features": ("ocx", "gx-eoc"),
    "ch4_pushes": 24,
    "ch4_experts": (1, 2),
    "ch4_folds": 2,
    "ch4_features": ("oc",),
    "em_iterations": 2,
    "em_restarts": 2,
    "vi_features": ("gx-eoc",),
    "vi_steps": 30,
    "gp_max_iter": 8,
    "progress": False,
}
"""Sizes of a tiny run that checks the whole pipeline in about a minute."""


def _key(*parts: object) -> str:
    return ".".join(str(p) for p in parts)


def _fingerprint(config: PushModelStudyConfig, exp: str) -> str:
    """Short hash of every setting that shapes experiment `exp`'s results.

    Run-only fields (where and how the study runs) and the other experiment's fields are
    left out, so changing chapter 4's settings never refits chapter 5.
    """
    other = "ch4" if exp == "ch5" else "ch5"
    own_vi = ("vi_features",) if exp == "ch4" else ()
    exclude = {
        *_RUN_ONLY,
        *own_vi,
        *(f.name for f in fields(config) if f.name.startswith(f"{other}_")),
    }
    return config_fingerprint(config, exclude=exclude, version=_FIT_VERSION, length=8)


def effect_noise_floor(pose_noise: bool, n_objects: int) -> list[float] | str:
    """The experts' noise floor: `PoseNoise().effect_std`, or ``"auto"`` for exact poses.

    Args:
        pose_noise: Whether the dataset observes poses with `PoseNoise()`.
        n_objects: Objects whose effects are stacked in the effect vector.
    """
    return PoseNoise().effect_std(n_objects) if pose_noise else "auto"


def _scores(pred: Any, y: torch.Tensor) -> dict[str, list[float]]:
    return {
        "rmse": rmse(pred, y).tolist(),
        "nlpd": nlpd(pred, y).tolist(),
        "coverage90": interval_coverage(pred, y, 0.9).tolist(),
    }


@dataclass(frozen=True)
class FoldTask:
    """One task of the study: an EM path (and VI) or one clustered fit on one fold.

    The data set itself is not part of the task: every task of an experiment reads the same
    ``(X, Y)``, which `run_tasks` sends to each Dask worker once.

    Attributes:
        kind: ``"path"`` (EM for every M, VI from it) or ``"clustered"``.
        experiment: ``"ch5"`` or ``"ch4"``.
        features: Name of the feature configuration.
        fold: Index of the cross-validation fold.
        train: Training rows, `(N_train,)`.
        test: Held-out rows, `(N_test,)`.
        groups: Feature group -> ``(start, stop)`` columns.
        gate: Groups the gate sees.
        experts: Groups the experts see.
        seed: Seed of the fits.
        gp_max_iter: L-BFGS iterations of a cold expert fit.
        prior: Length-scale prior on.
        noise_floor: The experts' noise floor (per effect) or ``"auto"``.
        sizes: Values of M (path tasks).
        M: Number of clusters (clustered tasks).
        em_init: EM's initialisation.
        em_restarts: EM starts per M.
        em_iterations: EM iterations.
        gate_kind: ``"linear"`` or ``"fourier"``.
        vi: Also fit VI from every EM mixture.
        vi_steps: SVI steps.
        vi_inducing: Inducing points per variational expert.
    """

    kind: str
    experiment: str
    features: str
    fold: int
    train: np.ndarray
    test: np.ndarray
    groups: dict[str, tuple[int, int]]
    gate: tuple[str, ...]
    experts: tuple[str, ...]
    seed: int
    gp_max_iter: int
    prior: bool
    noise_floor: list[float] | str
    sizes: tuple[int, ...] = ()
    M: int = 0
    em_init: str = "auto"
    em_restarts: int = 3
    em_iterations: int = 10
    gate_kind: str = "linear"
    vi: bool = False
    vi_steps: int = 400
    vi_inducing: int = 32

    @property
    def slices(self) -> dict[str, slice]:
        """Feature group -> column slice."""
        return {k: slice(*v) for k, v in self.groups.items()}

    def cost(self, n_features: int) -> float:
        """Rough relative cost (to start the longest tasks first), from the sizes alone."""
        n = len(self.train)
        width = sum(len(range(n_features)[self.slices[g]]) for g in self.experts)
        fit = n * n * (1.0 + width / 50.0)
        if self.kind != "path":
            return fit
        return fit * len(self.sizes) * (2.0 if self.vi else 1.0) * 10.0


def _base_row(task: FoldTask) -> dict[str, Any]:
    return {"experiment": task.experiment, "features": task.features, "fold": task.fold}


def _fit_path(task: FoldTask, X: np.ndarray, Y: np.ndarray) -> dict[str, Any]:
    """Fit the EM path M = 1..max on one fold (and VI from it); score every M held out."""
    train, test = task.train, task.test
    y = torch.as_tensor(Y[test])
    rows: list[dict[str, Any]] = []
    with torch_threads(1):
        template = MixtureOfGPExperts(
            1,
            groups=task.slices,
            gate_features=list(task.gate),
            expert_features=list(task.experts),
            gate=task.gate_kind,
            gp_max_iter=task.gp_max_iter,
            lengthscale_prior=task.prior,
            noise_floor=task.noise_floor,
        )
        start = time.perf_counter()
        path = fit_em_path(
            template,
            X[train],
            Y[train],
            task.sizes,
            init=task.em_init,
            n_restarts=task.em_restarts,
            max_iter=task.em_iterations,
            seed=task.seed,
        )
        seconds = time.perf_counter() - start
        for m, (model, hist) in sorted(path.items()):
            for gating, method in (("soft", "em"), ("hard", "em-hard")):
                row = {
                    **_base_row(task),
                    "method": method,
                    "M": m,
                    "seconds": seconds,
                    "objective": hist.best,
                    "init": hist.init,
                    **_scores(model.predict(X[test], gating=gating), y),
                }
                if method == "em":
                    row.update(
                        {
                            "objective_per_iteration": [float(v) for v in hist.objective],
                            "lengthscales": [ls.tolist() for ls in model.lengthscales()],
                            "expert_columns": list(map(int, model.expert_columns)),
                            "train_assignment": [
                                int(a) for a in hist.responsibilities.argmax(1).tolist()
                            ],
                            "train_index": train.tolist(),
                        }
                    )
                rows.append(row)
            if task.vi:
                vi = VariationalMixtureOfGPExperts(
                    m,
                    groups=task.slices,
                    gate_features=list(task.gate),
                    expert_features=list(task.experts),
                    n_inducing=task.vi_inducing,
                )
                start = time.perf_counter()
                get_fitter("svi")(
                    vi, X[train], Y[train], n_steps=task.vi_steps, seed=task.seed, init=model
                )
                rows.append(
                    {
                        **_base_row(task),
                        "method": "vi",
                        "M": m,
                        "seconds": time.perf_counter() - start,
                        **_scores(vi.predict(X[test]), y),
                    }
                )
    return {"rows": rows}


def _fit_clustered(task: FoldTask, X: np.ndarray, Y: np.ndarray) -> dict[str, Any]:
    """Fit chapter 4's clustered model with `task.M` clusters on one fold and score it."""
    train, test = task.train, task.test
    cols = np.concatenate([np.arange(X.shape[1])[task.slices[g]] for g in task.experts])
    floor = task.noise_floor
    start = time.perf_counter()
    with torch_threads(1):
        model = ClusteredGPModel(
            task.M,
            seed=task.seed,
            expert_kwargs={
                "max_iter": task.gp_max_iter,
                "lengthscale_prior": task.prior,
                "noise_floor": None if isinstance(floor, str) else floor,
            },
        )
        get_fitter("clustered")(model, X[train][:, cols], Y[train])
        pred = model.predict(X[test][:, cols])
    assert model.labels_ is not None
    row = {
        **_base_row(task),
        "method": "clustered",
        "M": task.M,
        "seconds": time.perf_counter() - start,
        **_scores(pred, torch.as_tensor(Y[test])),
        "train_assignment": [int(a) for a in model.labels_],
        "train_index": train.tolist(),
    }
    return {"rows": [row]}


def _run_task(task: FoldTask, *, data: dict[str, tuple[np.ndarray, np.ndarray]]) -> dict[str, Any]:
    """One task of the study on its experiment's ``(X, Y)`` from `data`."""
    X, Y = data[task.experiment]
    return (_fit_path if task.kind == "path" else _fit_clustered)(task, X, Y)


def _tasks(
    exp: str,
    n: int,
    groups: dict[str, slice],
    configs: dict[str, tuple[tuple[str, ...], tuple[str, ...]]],
    *,
    vi_features: tuple[str, ...],
    clustered: bool,
    experts: tuple[int, ...],
    folds: int,
    noise_floor: list[float] | str,
    config: PushModelStudyConfig,
) -> list[tuple[str, tuple[FoldTask]]]:
    """The tasks of experiment `exp` on `n` samples, keyed for the result store."""
    splits = list(KFold(folds, shuffle=True, random_state=config.seed).split(np.zeros(n)))
    fingerprint = _fingerprint(config, exp)
    out: list[tuple[str, tuple[FoldTask]]] = []
    for name, (gate, experts_groups) in configs.items():
        for f, (train, test) in enumerate(splits):
            common: dict[str, Any] = {
                "experiment": exp,
                "features": name,
                "fold": f,
                "seed": config.seed,
                "train": train,
                "test": test,
                "groups": {k: (v.start, v.stop) for k, v in groups.items()},
                "gate": tuple(gate),
                "experts": tuple(experts_groups),
                "gp_max_iter": config.gp_max_iter,
                "prior": config.lengthscale_prior,
                "noise_floor": noise_floor,
            }
            path = FoldTask(
                kind="path",
                **common,
                sizes=tuple(experts),
                em_init=config.em_init,
                em_restarts=config.em_restarts,
                em_iterations=config.em_iterations,
                gate_kind=config.gate,
                vi=name in vi_features,
                vi_steps=config.vi_steps,
                vi_inducing=config.vi_inducing,
            )
            out.append((_key(exp, name, "em-path", f"fold{f}", fingerprint), (path,)))
            if clustered:
                for m in experts:
                    task = FoldTask(kind="clustered", **common, M=m)
                    out.append(
                        (_key(exp, name, "clustered", f"M{m}", f"fold{f}", fingerprint), (task,))
                    )
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
        totals = [float(np.sum(r["nlpd"])) for r in rs]
        row["nlpd.total"] = float(np.mean(totals))
        row["nlpd.total.ci95"] = mean_halfwidth(totals)
        row["seconds"] = float(np.mean([r["seconds"] for r in rs]))
        rows.append(row)
    return rows


def _best_by_nlpd(rows: list[dict[str, Any]]) -> dict[tuple[str, str], int]:
    best: dict[tuple[str, str], tuple[float, int]] = {}
    for r in rows:
        k = (r["features"], r["method"])
        if k not in best or r["nlpd.total"] < best[k][0]:
            best[k] = (r["nlpd.total"], r["M"])
    return {k: v[1] for k, v in best.items()}


def _lookup(rows: list[dict[str, Any]], feat: str, method: str, m: int, col: str) -> float | None:
    for r in rows:
        if (r["features"], r["method"], r["M"]) == (feat, method, m):
            return r[col]
    return None


def _relative(
    rows: list[dict[str, Any]],
    a: tuple[str, str, int],
    b: tuple[str, str, int],
    dims: tuple[str, ...],
) -> float | None:
    """Mean over `dims` of RMSE(a) / RMSE(b) - 1, in %; `a`, `b` are (features, method, M)."""
    pairs = [(_lookup(rows, *a, f"rmse.{d}"), _lookup(rows, *b, f"rmse.{d}")) for d in dims]
    if any(x is None or y is None for x, y in pairs):
        return None
    return 100 * float(np.mean([x / y - 1 for x, y in pairs]))  # type: ignore[operator]


def _findings(rows: list[dict[str, Any]], method: str = "em") -> list[str]:
    """The thesis's chapter 5 claims, checked on these results (rows of `method`).

    RMSE changes are relative and averaged over the effect dimensions, so metres and radians
    weigh alike; NLPD is summed over the six effects and averaged over held-out pushes.
    """
    lines = []
    feats = sorted({r["features"] for r in rows if r["method"] == method})
    ms = sorted({r["M"] for r in rows if r["method"] == method})
    for feat in feats:
        changes: dict[int, float] = {
            m: v
            for m in ms
            if m != 1
            if (v := _relative(rows, (feat, method, m), (feat, method, 1), CH5_EFFECTS)) is not None
        }
        nl: dict[int, float] = {
            m: v for m in ms if (v := _lookup(rows, feat, method, m, "nlpd.total")) is not None
        }
        if changes and nl:
            txt = ", ".join(f"M={m}: {v:+.1f}%" for m, v in changes.items())
            best_nl = min(nl, key=lambda m: nl[m])
            best_rmse = min([1, *changes], key=lambda m: changes.get(m, 0.0))
            nl_txt = ", ".join(f"M={m}: {v:.2f}" for m, v in nl.items())
            lines.append(
                f"- features {feat}: RMSE relative to M=1 (negative = better; thesis: "
                f"-5.9 to -6.5%): {txt}; lowest RMSE at M={best_rmse}. NLPD: "
                f"{nl_txt}; lowest at M={best_nl} (thesis: M=3 best)."
            )
    o2 = CH5_EFFECTS[3:]
    for m in ms:
        a = _relative(rows, ("ocx", method, m), ("o", method, m), CH5_EFFECTS)
        b = _relative(rows, ("ocx", method, m), ("oc", method, m), CH5_EFFECTS)
        c = _relative(rows, ("ocx", method, m), ("o", method, m), o2)
        d = _relative(rows, ("ocx", method, m), ("oc", method, m), o2)
        if None not in (a, b, c, d):
            nls = [_lookup(rows, f, method, m, "nlpd.total") for f in ("o", "oc", "ocx")]
            lines.append(
                f"- M={m}: adding f_x changes RMSE by {a:+.1f}% vs f_o and {b:+.1f}% vs "
                f"f_o&f_c (thesis: -8.71% and -3.67%); o2: {c:+.1f}% and {d:+.1f}% "
                f"(thesis: -11.8% and -4.37%). NLPD f_o / f_o&f_c / all: "
                + " / ".join(f"{v:.2f}" for v in nls if v is not None)
                + "."
            )
        split, full, comb = (
            _lookup(rows, f, method, m, "rmse.o1.dz") for f in ("gx-eoc", "ocx", "oc")
        )
        if None not in (split, full, comb):
            lines.append(
                f"- M={m}: o1 along the push (dz) RMSE: gate-on-context {split:.4f} m, "
                f"all features {full:.4f} m, f_o&f_c {comb:.4f} m (thesis: the "
                "gate-on-context split is best)."
            )
    return lines


def _ch4_findings(rows: list[dict[str, Any]]) -> list[str]:
    """Chapter 4's claims (m = 3 best, dz gains over m = 1, context features) on these rows."""
    lines = []
    for method in ("clustered", "em"):
        for feat in sorted({r["features"] for r in rows if r["method"] == method}):
            ms = sorted({r["M"] for r in rows if r["method"] == method and r["features"] == feat})
            dz = {m: _lookup(rows, feat, method, m, "rmse.dz") for m in ms}
            nl = {m: _lookup(rows, feat, method, m, "nlpd.total") for m in ms}
            if 1 not in dz or dz[1] is None:
                continue
            gains = ", ".join(
                f"m={m}: {100 * (dz[1] - v):+.2f} cm"
                for m, v in dz.items()
                if m != 1 and v is not None
            )
            best = min((m for m in nl if nl[m] is not None), key=lambda m: nl[m])  # type: ignore
            lines.append(
                f"- {method}, features {feat}: dz RMSE gain over m=1 (thesis: m=2 "
                f"+1.83 cm, m=3 +2.63 cm): {gains}; lowest NLPD at m={best} (thesis: "
                "m=3 best)."
            )
        for m in sorted({r["M"] for r in rows if r["method"] == method}):
            rel = {
                d: _relative(rows, ("ocx", method, m), ("o", method, m), (d,)) for d in CH4_EFFECTS
            }
            if None not in rel.values():
                txt = ", ".join(f"{d} {v:+.1f}%" for d, v in rel.items())
                lines.append(
                    f"- {method}, m={m}: context features change RMSE by {txt} "
                    "(thesis: dth -13.79%, dy -8.93%, dz -9.75%)."
                )
    return lines


def _datasets(config: PushModelStudyConfig, out: Path) -> dict[str, tuple[Any, np.ndarray]]:
    """Generate (or resume) each experiment's dataset: name -> (features, effects)."""
    noise = PoseNoise() if config.pose_noise else None
    ds5 = generate(
        GenerateConfig("two_objects", config.ch5_pushes, seed=config.seed, pose_noise=noise),
        out / "data" / "two_objects",
        workers=0,
        resume=True,
        progress=config.progress,
    )
    data = {"ch5": (chapter5_features(ds5), ds5["effect"][:, :2].reshape(len(ds5), 6))}
    if config.ch4_pushes:
        ds4 = generate(
            GenerateConfig("near_obstacle", config.ch4_pushes, seed=config.seed, pose_noise=noise),
            out / "data" / "near_obstacle",
            workers=0,
            resume=True,
            progress=config.progress,
        )
        data["ch4"] = (chapter4_features(ds4), ds4["effect"][:, 0])
    return data


def _all_tasks(
    config: PushModelStudyConfig, data: dict[str, tuple[Any, np.ndarray]]
) -> list[tuple[str, tuple[FoldTask]]]:
    """Every task of the study, longest first so that the workers finish together."""
    f5, Y5 = data["ch5"]
    tasks = _tasks(
        "ch5",
        len(Y5),
        f5.groups,
        {k: CH5_FEATURES[k] for k in config.ch5_features},
        vi_features=config.vi_features if "vi" in config.methods else (),
        clustered=False,
        experts=config.ch5_experts,
        folds=config.ch5_folds,
        noise_floor=effect_noise_floor(config.pose_noise, 2),
        config=config,
    )
    if "ch4" in data:
        f4, Y4 = data["ch4"]
        tasks += _tasks(
            "ch4",
            len(Y4),
            f4.groups,
            {k: (CH4_FEATURES[k], CH4_FEATURES[k]) for k in config.ch4_features},
            vi_features=(),
            clustered=True,
            experts=config.ch4_experts,
            folds=config.ch4_folds,
            noise_floor=effect_noise_floor(config.pose_noise, 1),
            config=config,
        )
    width = {exp: features.values.shape[1] for exp, (features, _) in data.items()}
    return sorted(tasks, key=lambda t: -t[1][0].cost(width[t[1][0].experiment]))


def _noise_text(config: PushModelStudyConfig) -> str:
    if config.pose_noise:
        return (
            f"Poses are observed with {PoseNoise()} (seeded, recorded in each dataset's "
            "manifest) and the experts' noise floor is sqrt(2) times that noise, the "
            "noise of an effect; scores are against the observed effects."
        )
    return "Poses are exact; the experts' noise floor is 1 % of each effect's standard deviation."


def _chapter5(
    config: PushModelStudyConfig,
    results: list[dict[str, Any]],
    Y5: np.ndarray,
    groups: dict[str, slice],
    out: Path,
) -> tuple[list[dict[str, Any]], list[str], list[str]]:
    """Chapter 5's tables, figures and findings: (summary rows, Markdown lines, files)."""
    ch5 = [r for r in results if r["experiment"] == "ch5"]
    rows5 = _summarise(ch5, CH5_EFFECTS)
    files = [write_csv(out / "ch5_folds.csv", ch5), write_csv(out / "ch5_summary.csv", rows5)]
    md = [
        "## Chapter 5: two-object pushes, mean over folds",
        "",
        markdown_table(
            rows5,
            ["features", "method", "M"]
            + [f"rmse.{e}" for e in CH5_EFFECTS]
            + ["nlpd.total", "nlpd.total.ci95", "seconds"],
        ),
        "90% interval coverage:",
        "",
        markdown_table(
            rows5, ["features", "method", "M"] + [f"coverage90.{e}" for e in CH5_EFFECTS], digits=2
        ),
        "Number of experts chosen by cross-validated NLPD:",
        "",
    ]
    md += [
        f"- {feat} / {method}: M = {m}"
        for (feat, method), m in sorted(_best_by_nlpd(rows5).items())
    ]
    md += [
        "",
        "Checks of the thesis's findings (EM, gated mixture):",
        "",
        *_findings(rows5),
        "",
        "The same with the most probable expert only:",
        "",
        *_findings(rows5, "em-hard"),
        "",
    ]
    plot_metric_vs_experts(
        rows5,
        CH5_EFFECTS,
        "rmse",
        out / "ch5_rmse_vs_M.png",
        title="Chapter 5: RMSE vs number of experts (m, rad)",
    )
    plot_metric_vs_experts(
        rows5,
        CH5_EFFECTS,
        "coverage90",
        out / "ch5_coverage_vs_M.png",
        title="Chapter 5: 90% interval coverage",
    )
    files += [str(out / "ch5_rmse_vs_M.png"), str(out / "ch5_coverage_vs_M.png")]
    shown = "ocx" if "ocx" in config.ch5_features else config.ch5_features[-1]
    example = next(
        (
            r
            for r in ch5
            if (r["features"], r["method"], r["fold"]) == (shown, "em", 0)
            and r["M"] == min(3, max(config.ch5_experts))
        ),
        None,
    )
    if example is not None:
        idx = np.asarray(example["train_index"])
        plot_effect_clusters(
            Y5[idx][:, [1, 4]],
            np.asarray(example["train_assignment"]),
            ("o1 dz_p (m)", "o2 dz_p (m)"),
            out / "ch5_clusters.png",
            title=f"Chapter 5: EM assignments, M={example['M']}",
        )
        plot_relevances(
            example["lengthscales"],
            example["expert_columns"],
            groups,
            out / "ch5_ard_relevance.png",
        )
        files += [str(out / "ch5_clusters.png"), str(out / "ch5_ard_relevance.png")]
    return rows5, md, files


def _chapter4(
    config: PushModelStudyConfig, results: list[dict[str, Any]], Y4: np.ndarray, out: Path
) -> tuple[list[dict[str, Any]], list[str], list[str]]:
    """Chapter 4's tables, figures and findings: (summary rows, Markdown lines, files)."""
    ch4 = [r for r in results if r["experiment"] == "ch4"]
    rows4 = _summarise(ch4, CH4_EFFECTS)
    files = [write_csv(out / "ch4_summary.csv", rows4)]
    md = [
        "## Chapter 4: single-object pushes near the battery",
        "",
        markdown_table(
            rows4,
            ["features", "method", "M"]
            + [f"rmse.{e}" for e in CH4_EFFECTS]
            + ["nlpd.total", "nlpd.total.ci95"],
        ),
        "",
        "Checks of the thesis's chapter 4 findings:",
        "",
        *_ch4_findings(rows4),
        "",
    ]
    plot_metric_vs_experts(
        rows4,
        CH4_EFFECTS,
        "rmse",
        out / "ch4_rmse_vs_m.png",
        title="Chapter 4: RMSE vs number of clusters (m, rad)",
    )
    files.append(str(out / "ch4_rmse_vs_m.png"))
    shown = "ocx" if "ocx" in config.ch4_features else config.ch4_features[-1]
    ex4 = next(
        (
            r
            for r in ch4
            if (r["features"], r["method"], r["fold"]) == (shown, "clustered", 0)
            and r["M"] == min(3, max(config.ch4_experts))
        ),
        None,
    )
    if ex4 is not None:
        idx = np.asarray(ex4["train_index"])
        plot_effect_clusters(
            Y4[idx][:, :2],
            np.asarray(ex4["train_assignment"]),
            ("dy_p (m)", "dz_p (m)"),
            out / "ch4_clusters.png",
            title=f"Chapter 4: GMM clusters of the effects, m={ex4['M']}",
        )
        files.append(str(out / "ch4_clusters.png"))
    return rows4, md, files


def run(config: PushModelStudyConfig) -> dict[str, Any]:
    """Run (or resume) the study and write its tables and figures.

    Args:
        config: Study settings.

    Returns:
        ``{"ch5": summary rows, "ch4": summary rows, "files": [written paths]}``.
    """
    config.validate()
    out = Path(config.out)
    data = _datasets(config, out)
    arrays = {exp: (features.values, Y) for exp, (features, Y) in data.items()}
    done = run_tasks(
        _run_task,
        _all_tasks(config, data),
        ResultStore(out / "tasks"),
        workers=config.workers,
        scheduler=config.scheduler,
        progress=config.progress,
        desc="push models",
        shared={"data": arrays},
    )
    results = [row for task in done for row in task["rows"]]
    summary: dict[str, Any] = {"config": asdict(config)}
    md = [
        "# Push-model study",
        "",
        f"Settings: `{summary['config']}`",
        "",
        _noise_text(config),
        "",
        "Methods: `em` is the gated mixture fitted by EM (default initialisation and "
        "restarts), `em-hard` the same fit predicting with its most probable expert only, "
        "`vi` SVI started from the EM fit, `clustered` chapter 4's model. `seconds` of EM "
        "is the whole path M = 1..max on a fold.",
        "",
    ]
    f5, Y5 = data["ch5"]
    summary["ch5"], lines, files = _chapter5(config, results, Y5, f5.groups, out)
    md += lines
    if "ch4" in data:
        summary["ch4"], lines, more = _chapter4(config, results, data["ch4"][1], out)
        md += lines
        files += more
    atomic_write_text(out / "summary.md", "\n".join(md))
    summary["files"] = [*files, str(out / "summary.md")]
    return summary
