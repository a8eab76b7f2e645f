"""The push-model study: chapters 5 and 4 on simulated data, EM and VI side by side.

Chapter 5 (Figure 5.6): about 321 two-object pushes, mixtures of M = 1..6 GP experts, 3-fold
cross-validation, four feature configurations (``o``: f_o; ``oc``: f_o & f_c; ``ocx``: f_o &
f_c & f_x; ``gx-eoc``: f_x for the gate with f_o & f_c for the experts), EM and Pyro SVI.
Chapter 4: about 120 single-object pushes near the battery, m = 1..4, 5-fold cross-validation,
its features, the mixture fitted by EM and the clustered baseline (GMM clusters, one GP each,
SVM gate).

Chapter 5's cross-validation can be repeated with new shuffles (``ch5_repeats``), so that its
claims are judged over more splits than 3 folds give. Its claims can also be judged over
independent trials on fresh data (``ch5_trials``, `TrialTask`): each trial simulates its own
training and held-out pushes, so the trials share no row and the plain t interval over them
is valid, where the splits of one dataset need the corrected one.

Every (experiment, features, method, M, repeat, fold) is one task whose scores are saved as
soon as it finishes (`probaff.eval.tasks`), keyed also by a hash of the settings that shape it,
so an interrupted study resumes where it stopped, never mixes settings, and can run on Dask. Tables
(CSV, Markdown) and figures (PNG) go to the output folder. The fits take the config's options
as they are (`em`, `svi`, `gp`), with the study's seed.
"""

from __future__ import annotations

import dataclasses
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
import torch
from sklearn.model_selection import RepeatedKFold

from probaff._threads import limit_threads
from probaff.data import GenerateConfig, generate
from probaff.data.noise import PoseNoise
from probaff.eval.metrics import interval_coverage, nlpd, rmse
from probaff.experiments.base import StudyRun
from probaff.experiments.push_models.claims import chapter5_claims
from probaff.experiments.push_models.config import (
    CH4_EFFECTS,
    CH4_FEATURES,
    CH5_EFFECTS,
    CH5_FEATURES,
    MAX_TRIALS,
    PushModelStudyConfig,
    effect_noise_floor,
)
from probaff.experiments.push_models.figures import study_figures
from probaff.experiments.push_models.report import (
    chapter4_section,
    chapter5_section,
    header,
    summarise,
    trials_section,
)
from probaff.features import chapter4_features, chapter5_features
from probaff.models import (
    ClusteredGPModel,
    MixtureOfGPExperts,
    VariationalMixtureOfGPExperts,
    fit_em_path,
    fit_svi,
    model_kind,
)

__all__ = ["TRIALS", "FoldTask", "TrialTask", "run", "trial_data"]

# Bumped whenever a change to the fitting code changes results, so stored tasks of an older
# version are refitted rather than mixed in.
_FIT_VERSION = 8  # 6: L-BFGS coroutines; 7: fused batched kernel and gradient; 8: l1 continuation

TRIALS = "ch5-trials"
"""The ``experiment`` of the rows of chapter 5's independent trials (`TrialTask`)."""

_TRIAL_SEED = 10_000_000
"""Trial datasets' seeds start here, far from the seeds a study's own dataset takes."""


@dataclass(frozen=True)
class FoldTask:
    """One task of the study: an EM path (and VI) or one clustered fit on one fold.

    The data set itself is not part of the task: every task of an experiment reads the same
    ``(X, Y)``, which `run_tasks` sends to each Dask worker once. The fit settings are the
    study config's own (`PushModelStudyConfig.em`, ``svi``, ``gp``, ``gate``,
    ``vi_inducing``, ``seed``), read where the fits take them.

    Attributes:
        kind: ``"path"`` (EM for every M, VI from it) or ``"clustered"``.
        experiment: ``"ch5"`` or ``"ch4"``.
        features: Name of the feature configuration.
        fold: Index of the cross-validation fold within its repeat.
        train: Training rows, `(N_train,)`.
        test: Held-out rows, `(N_test,)`.
        groups: Feature group -> ``(start, stop)`` columns.
        gate_features: Groups the gate sees.
        expert_features: Groups the experts see.
        noise_floor: The experts' noise floor (per effect) or ``"auto"``.
        study: The study's settings.
        sizes: Values of M (path tasks).
        M: Number of clusters (clustered tasks).
        vi: Also fit VI from every EM mixture.
        repeat: Index of the cross-validation's repeat (chapter 5's ``ch5_repeats``).
    """

    kind: str
    experiment: str
    features: str
    fold: int
    train: np.ndarray
    test: np.ndarray
    groups: dict[str, tuple[int, int]]
    gate_features: tuple[str, ...]
    expert_features: tuple[str, ...]
    noise_floor: list[float] | str
    study: PushModelStudyConfig
    sizes: tuple[int, ...] = ()
    M: int = 0
    vi: bool = False
    repeat: int = 0

    @property
    def slices(self) -> dict[str, slice]:
        """Feature group -> column slice."""
        return {k: slice(*v) for k, v in self.groups.items()}

    def cost(self, n_features: int) -> float:
        """Rough relative cost (to start the longest tasks first), from the sizes alone."""
        n = len(self.train)
        width = sum(len(range(n_features)[self.slices[g]]) for g in self.expert_features)
        fit = n * n * (1.0 + width / 50.0)
        if self.kind != "path":
            return fit
        return fit * len(self.sizes) * (2.0 if self.vi else 1.0) * 10.0


def _scores(pred: Any, y: torch.Tensor) -> dict[str, list[float]]:
    return {
        "rmse": rmse(pred, y).tolist(),
        "nlpd": nlpd(pred, y).tolist(),
        "coverage90": interval_coverage(pred, y, 0.9).tolist(),
    }


def _base_row(task: FoldTask) -> dict[str, Any]:
    return {
        "experiment": task.experiment,
        "features": task.features,
        "repeat": task.repeat,
        "fold": task.fold,
    }


def _em_rows(
    task: FoldTask, fit: tuple[int, Any, Any, float], X: np.ndarray, y: torch.Tensor
) -> list[dict[str, Any]]:
    """The ``em`` (soft) and ``em-hard`` rows of one fitted mixture of the path.

    `fit` is ``(M, model, history, seconds of the path)``; `y` the held-out effects.
    """
    m, model, hist, seconds = fit
    rows = []
    for gating, method in (("soft", "em"), ("hard", "em-hard")):
        row = {
            **_base_row(task),
            "method": method,
            "M": m,
            "seconds": seconds,
            "objective": hist.best,
            "init": hist.init,
            **_scores(model.predict(X[task.test], gating=gating), y),
        }
        if method == "em":
            row.update(
                {
                    "objective_per_iteration": [float(v) for v in hist.objective],
                    "lengthscales": [ls.tolist() for ls in model.lengthscales()],
                    "expert_columns": list(map(int, model.expert_columns)),
                    "train_assignment": [int(a) for a in hist.responsibilities.argmax(1).tolist()],
                    "train_index": task.train.tolist(),
                }
            )
        rows.append(row)
    return rows


def _fit_path(task: FoldTask, X: np.ndarray, Y: np.ndarray) -> dict[str, Any]:
    """Fit the EM path M = 1..max on one fold (and VI from it); score every M held out."""
    train, test, study = task.train, task.test, task.study
    y = torch.as_tensor(Y[test])
    rows: list[dict[str, Any]] = []
    with limit_threads(1):
        template = MixtureOfGPExperts(
            1,
            groups=task.slices,
            gate_features=list(task.gate_features),
            expert_features=list(task.expert_features),
            gate=study.gate,
            gp=dataclasses.replace(study.gp, noise_floor=task.noise_floor),  # the task's floor
        )
        start = time.perf_counter()
        path = fit_em_path(template, X[train], Y[train], task.sizes, study.em, seed=study.seed)
        seconds = time.perf_counter() - start
        for m, (model, hist) in sorted(path.items()):
            rows += _em_rows(task, (m, model, hist, seconds), X, y)
            if task.vi:
                vi = VariationalMixtureOfGPExperts(
                    m,
                    groups=task.slices,
                    gate_features=list(task.gate_features),
                    expert_features=list(task.expert_features),
                    n_inducing=study.vi_inducing,
                )
                start = time.perf_counter()
                fit_svi(vi, X[train], Y[train], study.svi, seed=study.seed, init=model)
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
    cols = np.concatenate([np.arange(X.shape[1])[task.slices[g]] for g in task.expert_features])
    floor = task.noise_floor
    # the study's GP settings with the task's floor (none where the mixtures' is "auto")
    gp = dataclasses.replace(task.study.gp, noise_floor=None if isinstance(floor, str) else floor)
    start = time.perf_counter()
    with limit_threads(1):
        model = ClusteredGPModel(task.M, seed=task.study.seed, gp=gp)
        model_kind("clustered").fit(model, X[train][:, cols], Y[train])
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


def _ch5_effects(ds: Any) -> np.ndarray:
    """(N, 6) chapter 5's effects (`CH5_EFFECTS`) of a two-object push dataset."""
    return ds["effect"][:, :2].reshape(len(ds), 6)


def _bounds(groups: dict[str, slice]) -> dict[str, tuple[int, int]]:
    """Feature group -> ``(start, stop)`` columns, as `FoldTask.groups` holds them."""
    return {k: (v.start, v.stop) for k, v in groups.items()}


def run_task(
    task: FoldTask | TrialTask, *, data: dict[str, tuple[np.ndarray, np.ndarray]]
) -> dict[str, Any]:
    """One task of the study on its experiment's ``(X, Y)`` from `data` (Dask imports it).

    A trial (`TrialTask`) simulates its own data instead (`run_trial`).
    """
    if isinstance(task, TrialTask):
        return run_trial(task)
    X, Y = data[task.experiment]
    return (_fit_path if task.kind == "path" else _fit_clustered)(task, X, Y)


@dataclass(frozen=True)
class TrialTask:
    """One independent trial of chapter 5: fresh pushes, every feature set's EM path on them.

    Attributes:
        trial: The trial's index (its data's seeds, `trial_data`).
        study: The study's settings (``ch5_pushes``, ``ch5_trial_test``, ``ch5_features``,
            ``ch5_experts``, the fit options and ``pose_noise``).
    """

    trial: int
    study: PushModelStudyConfig
    experiment: ClassVar[str] = TRIALS

    def cost(self, n_features: int) -> float:
        """Rough relative cost (as `FoldTask.cost`): a path per feature set on the trial."""
        n, study = self.study.ch5_pushes, self.study
        path = n * n * (1.0 + n_features / 50.0) * len(study.ch5_experts) * 10.0
        return path * len(study.ch5_features)


def trial_data(study: PushModelStudyConfig, trial: int) -> tuple[GenerateConfig, GenerateConfig]:
    """The training and held-out datasets of trial `trial`: two-object pushes, seeds of its own.

    Trial k of a study of seed s simulates ``ch5_pushes`` training pushes with seed
    ``10_000_000 + 2 (MAX_TRIALS s + k)`` and ``ch5_trial_test`` held-out pushes with the next
    seed, with the study's pose noise and without trajectories (the features do not read
    them). Every dataset seed spawns independent streams (`probaff.data.make_shard`), so no
    trial shares a push with another trial, with the study's own dataset or with another
    study seed's trials (``ch5_trials`` is at most `MAX_TRIALS`).
    """
    noise = PoseNoise() if study.pose_noise else None
    seed = _TRIAL_SEED + 2 * (MAX_TRIALS * study.seed + trial)
    train, test = (
        GenerateConfig("two_objects", n, seed=seed + i, trajectories=False, pose_noise=noise)
        for i, n in enumerate((study.ch5_pushes, study.ch5_trial_test))
    )
    return train, test


def run_trial(task: TrialTask) -> dict[str, Any]:
    """One trial: simulate its pushes, fit every feature set's path, score it held out.

    Dask imports it. The paths are fitted on the trial's training pushes and scored on its
    held-out ones. The pushes are simulated in a temporary folder (a remote worker needs no
    shared disk) and dropped; the task's saved rows are what resumes. The rows are `FoldTask`
    rows with ``experiment`` `TRIALS`, ``repeat`` the trial and ``fold`` 0.
    """
    study = task.study
    with tempfile.TemporaryDirectory() as tmp:
        sets = [
            generate(config, Path(tmp) / str(i), progress=False)
            for i, config in enumerate(trial_data(study, task.trial))
        ]
    features = [chapter5_features(ds) for ds in sets]
    X = np.vstack([f.values for f in features])
    Y = np.vstack([_ch5_effects(ds) for ds in sets])
    n = len(sets[0])
    rows: list[dict[str, Any]] = []
    for name in study.ch5_features:
        gate, experts = CH5_FEATURES[name]
        fold = FoldTask(
            kind="path",
            experiment=TRIALS,
            features=name,
            fold=0,
            train=np.arange(n),
            test=np.arange(n, len(Y)),
            groups=_bounds(features[0].groups),
            gate_features=gate,
            expert_features=experts,
            noise_floor=effect_noise_floor(study.pose_noise, 2),
            study=study,
            sizes=tuple(study.ch5_experts),
            repeat=task.trial,
        )
        rows += _fit_path(fold, X, Y)["rows"]
    return {"rows": rows}


def _tag(config: PushModelStudyConfig, exp: str) -> str:
    """Short hash of every setting that shapes experiment `exp`'s results.

    Run-only fields (where and how the study runs) and the other experiment's fields are
    left out, so changing chapter 4's settings never refits chapter 5. The number of repeats
    and of trials is left out too: a task's key names its repeat or trial, and more only add
    tasks. The trials (`TRIALS`) fit EM alone on data of their own, so the folds and the VI
    settings do not shape them, and the trials' settings do not shape the cross-validation.
    """
    other = "ch4" if exp in ("ch5", TRIALS) else "ch5"
    exclude = {
        "ch5_repeats",
        "ch5_trials",
        *(f.name for f in dataclasses.fields(config) if f.name.startswith(f"{other}_")),
    }
    if exp == "ch4":
        exclude.add("vi_features")
    elif exp == "ch5":
        exclude.add("ch5_trial_test")
    else:
        exclude |= {"ch5_folds", "methods", "vi_features", "svi", "vi_inducing"}
    return config.tag(exclude=exclude, version=_FIT_VERSION, length=8)


def _tasks(
    config: PushModelStudyConfig,
    exp: str,
    data: tuple[Any, np.ndarray],
    configs: dict[str, tuple[tuple[str, ...], tuple[str, ...]]],
    vi_features: tuple[str, ...],
) -> list[tuple[str, tuple[FoldTask]]]:
    """The tasks of experiment `exp` on its ``(features, Y)``, keyed for the result store."""
    features, Y = data
    experts, folds, repeats = (
        (config.ch5_experts, config.ch5_folds, config.ch5_repeats)
        if exp == "ch5"
        else (config.ch4_experts, config.ch4_folds, 1)
    )
    # the first repeat's folds are KFold(folds, shuffle=True, random_state=seed)'s
    cv = RepeatedKFold(n_splits=folds, n_repeats=repeats, random_state=config.seed)
    splits = list(cv.split(np.zeros(len(Y))))
    tag = _tag(config, exp)
    out: list[tuple[str, tuple[FoldTask]]] = []
    for name, (gate, expert_groups) in configs.items():
        for i, (train, test) in enumerate(splits):
            r, f = divmod(i, folds)
            split = f"r{r}.fold{f}" if r else f"fold{f}"  # repeat 0 keeps one run's keys
            common: dict[str, Any] = {
                "experiment": exp,
                "features": name,
                "repeat": r,
                "fold": f,
                "train": train,
                "test": test,
                "groups": _bounds(features.groups),
                "gate_features": tuple(gate),
                "expert_features": tuple(expert_groups),
                "noise_floor": effect_noise_floor(config.pose_noise, 2 if exp == "ch5" else 1),
                "study": config,
            }
            path = FoldTask(kind="path", **common, sizes=tuple(experts), vi=name in vi_features)
            out.append((f"{exp}.{name}.em-path.{split}.{tag}", (path,)))
            if exp == "ch4":
                for m in experts:
                    task = FoldTask(kind="clustered", **common, M=m)
                    out.append((f"{exp}.{name}.clustered.M{m}.{split}.{tag}", (task,)))
    return out


def _datasets(study: StudyRun[PushModelStudyConfig]) -> dict[str, tuple[Any, np.ndarray]]:
    """Generate (or resume) each experiment's dataset: name -> (features, effects)."""
    config = study.config
    noise = PoseNoise() if config.pose_noise else None
    ds5 = study.dataset(
        GenerateConfig("two_objects", config.ch5_pushes, seed=config.seed, pose_noise=noise),
        "two_objects",
        local=True,
    )
    data = {"ch5": (chapter5_features(ds5), _ch5_effects(ds5))}
    if config.ch4_pushes:
        ds4 = study.dataset(
            GenerateConfig("near_obstacle", config.ch4_pushes, seed=config.seed, pose_noise=noise),
            "near_obstacle",
            local=True,
        )
        data["ch4"] = (chapter4_features(ds4), ds4["effect"][:, 0])
    return data


def _all_tasks(
    config: PushModelStudyConfig, data: dict[str, tuple[Any, np.ndarray]]
) -> list[tuple[str, tuple[FoldTask | TrialTask]]]:
    """Every task of the study, longest first so that the workers finish together."""
    vi = config.vi_features if "vi" in config.methods else ()
    tasks = _tasks(
        config, "ch5", data["ch5"], {k: CH5_FEATURES[k] for k in config.ch5_features}, vi
    )
    if "ch4" in data:
        ch4 = {k: (CH4_FEATURES[k], CH4_FEATURES[k]) for k in config.ch4_features}
        tasks += _tasks(config, "ch4", data["ch4"], ch4, ())
    width = {exp: features.values.shape[1] for exp, (features, _) in data.items()}
    width[TRIALS] = width["ch5"]
    tag = _tag(config, TRIALS)
    every: list[tuple[str, tuple[FoldTask | TrialTask]]] = [*tasks]
    every += [(f"{TRIALS}.t{k}.{tag}", (TrialTask(k, config),)) for k in range(config.ch5_trials)]
    return sorted(every, key=lambda t: -t[1][0].cost(width[t[1][0].experiment]))


def run(config: PushModelStudyConfig) -> dict[str, Any]:
    """Run (or resume) the study and write its tables and figures.

    Args:
        config: Study settings.

    Returns:
        ``{"config": the settings, "ch5": summary rows, "ch5_claims": chapter 5's claims
        judged with intervals over folds (`chapter5_claims`), "ch4": summary rows, "files":
        [written paths]}``.

    Raises:
        InputError: For an invalid config.
    """
    study = StudyRun(config, PushModelStudyConfig)
    config, out = study.config, study.out
    data = _datasets(study)
    arrays = {exp: (features.values, Y) for exp, (features, Y) in data.items()}
    tasks = _all_tasks(config, data)
    done = study.tasks(run_task, tasks, desc="push models", shared={"data": arrays})
    results = [row for task in done for row in task["rows"]]
    summary: dict[str, Any] = {"config": dataclasses.asdict(config)}
    ch5 = [r for r in results if r["experiment"] == "ch5"]
    summary["ch5"] = summarise(ch5, CH5_EFFECTS)
    study.table("ch5_folds.csv", ch5)
    study.table("ch5_summary.csv", summary["ch5"])
    summary["ch5_claims"] = chapter5_claims(ch5)
    study.table("ch5_claims.csv", summary["ch5_claims"])
    md = header(config) + chapter5_section(summary["ch5"], summary["ch5_claims"])
    if config.ch5_trials:
        rows = [r for r in results if r["experiment"] == TRIALS]
        summary["ch5_trials"] = summarise(rows, CH5_EFFECTS)
        summary["ch5_trial_claims"] = chapter5_claims(rows)
        study.table("ch5_trials.csv", rows)
        study.table("ch5_trial_summary.csv", summary["ch5_trials"])
        study.table("ch5_trial_claims.csv", summary["ch5_trial_claims"])
        md += trials_section(config, summary["ch5_trials"], summary["ch5_trial_claims"])
    if "ch4" in data:
        summary["ch4"] = summarise([r for r in results if r["experiment"] == "ch4"], CH4_EFFECTS)
        study.table("ch4_summary.csv", summary["ch4"])
        md += chapter4_section(summary["ch4"])
    for path in study_figures(config, summary, results, data, out):
        study.figure(path)
    study.summary(md)
    summary["files"] = study.files
    return summary
