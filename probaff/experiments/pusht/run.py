"""The Push-T study: learn push models from interaction in gym-pusht, plan over them, closed loop.

`run` records random pushes in the unmodified environment (`record_chunk`, one resumable task
per chunk under ``out/chunks/``), stores them as observation-only probaff push datasets
(``out/data/``), fits the mixture of GP experts (EM), the single GP and the analytic
quasi-static model at every training size and scores them on held-out pushes (RMSE, NLPD, 90 %
interval coverage), fits (or loads from ``out/models/``) the planners' models on
`PushTStudyConfig.plan_pushes` pushes, and runs every planner of `PLANNERS` on the same seeded
episodes: one resumable task per episode (``out/tasks/``), keyed by the planner, the episode
and a fingerprint of every setting that shapes it, so a killed run redoes only the missing
episodes. A worker process that dies mid-episode is restarted and the episode run again from
its reset (it is deterministic), so no finished episode is lost or run twice.

With `PushTStudyConfig.observation` ``"pixels"`` the planners observe only the policy's image,
and the pushes the models learn from are recorded from it too
(`probaff.experiments.pusht.data`: perceived poses, the state logged beside them for scoring
only); every key and file name of those pushes, datasets, models and episodes then
fingerprints the observation as well, so that nothing recorded or fitted from the state is
reused for a pixel run (state runs keep the keys they had).

Outputs in ``out/``: ``models.csv`` (held-out scores against training pushes),
``planners.csv`` (success rate with its 95 % Wilson interval, mean maximum coverage, pushes,
control steps and prediction error), ``curve.csv`` (success against training pushes),
``summary.md``, and the figures ``episodes.png``, ``success_vs_pushes.png`` and
``models.png`` (from pixels also ``frames.png``: the images planned on, with the perceived and
the true pose). Two runs of the same config write them, and every other file but those
named next, identical byte for byte, whether or not a run was killed and resumed. Planning
time per push is a measurement of the machine, not a result: it is kept apart, in
``timings.csv`` (per planner) and ``timings/tasks/KEY.json`` (per episode).
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
from typing import Any

import numpy as np

from probaff._threads import limit_threads
from probaff.data import save_dataset
from probaff.errors import DatasetError
from probaff.experiments.base import StudyRun
from probaff.experiments.pusht.config import PLANNERS, PushTStudyConfig
from probaff.experiments.pusht.data import (
    dataset_observation,
    push_dataset,
    record_chunk,
    with_worker,
)
from probaff.experiments.pusht.figures import (
    plot_episodes,
    plot_frames,
    plot_models,
    plot_success_curve,
)
from probaff.experiments.pusht.models import (
    LearnedModel,
    QuasiStaticTee,
    evaluate,
    fit_learned,
    push_effects,
    push_features,
)
from probaff.experiments.pusht.planner import SearchSettings, run_episode
from probaff.experiments.pusht.primitives import PrimitiveSettings
from probaff.experiments.pusht.report import (
    curve_rows,
    model_rows,
    planner_rows,
    summary_lines,
    timing_rows,
)
from probaff.experiments.pusht.transitions import EnvTransition, ModelTransition, TeePushes
from probaff.models import load as load_model
from probaff.models import save as save_model
from probaff.planning.transitions import Transition

__all__ = ["episode_task", "run"]

_VERSION = 5  # 2: SMEM by partial EM; 3: L-BFGS coroutines; 4: fused kernel; 5: lasso continuation
# Of the episodes only: 6: coverage with the T's shapes in a fixed order, planning times apart
_EPISODE_VERSION = 6
_DATA_FIELDS = ("seed", "primitives", "chunk")
_MODEL_FIELDS = (*_DATA_FIELDS, "experts", "em")
_MEASURED = ("plan_seconds",)  # wall-clock: kept in out/timings/, apart from the results


def _observed(c: PushTStudyConfig, fields: tuple[str, ...]) -> tuple[str, ...]:
    """`fields` and, when the poses are perceived, ``observation``: a key of its own.

    State runs keep the keys they had; pixel runs (pushes recorded, models fitted and
    episodes planned from perceived poses) never share one with them.
    """
    return fields if c.observation == "state" else (*fields, "observation")


def episode_task(
    planner: str,
    index: int,
    env_seed: int,
    trajectory: bool,
    *,
    models: dict[str, Any],
    search: SearchSettings,
    env_search: SearchSettings,
    primitives: PrimitiveSettings,
    python: str | None,
    observation: str = "state",
) -> dict[str, Any]:
    """Run one episode of one planner (a study task; Dask workers import it).

    Args:
        planner: A key of `PLANNERS`.
        index: The episode's index (its reset seed is shared by every planner).
        env_seed: The environment's reset seed.
        trajectory: Keep the block's poses.
        models: Fitted models by name (``moe``, ``gp``, ``analytic``).
        search: The search over a model.
        env_search: The search over the environment itself.
        primitives: The push primitives.
        python: The Push-T environment's Python.
        observation: What the planner observes: ``"state"`` or ``"pixels"`` (`run_episode`).

    Returns:
        The episode's record (`run_episode`) with ``planner`` and ``episode``.
    """
    spec = PLANNERS[planner]

    def one(worker: Any) -> dict[str, Any]:
        transition: Transition[TeePushes] | None = None
        settings = dataclasses.replace(search, depth=spec.depth, risk=spec.risk)
        if spec.model == "env":
            transition = EnvTransition(worker)
            settings = dataclasses.replace(env_search, depth=spec.depth, risk=spec.risk)
        elif spec.model:
            transition = ModelTransition(models[spec.model])
        with limit_threads(1):
            return run_episode(
                worker,
                env_seed,
                transition,
                settings,
                primitives,
                trajectory=trajectory,
                observation=observation,
            )

    record = with_worker(python, one)
    return {**record, "planner": planner, "episode": index}


def _chunks(study: StudyRun[PushTStudyConfig], role: str, n: int) -> list[dict[str, Any]]:
    """Record (or resume) the chunks holding the first `n` pushes of `role`."""
    c = study.config
    tag = c.tag(only=_observed(c, _DATA_FIELDS), version=_VERSION)
    count = math.ceil(n / c.chunk)
    tasks = [(f"{role}.chunk{i:04d}.{tag}", (role, i, c.seed, c.chunk)) for i in range(count)]
    shared = {"settings": c.primitives, "python": c.python, "observation": c.observation}
    return study.tasks(record_chunk, tasks, desc=f"{role} pushes", shared=shared, folder="chunks")


def _first(records: list[dict[str, Any]], n: int) -> list[dict[str, Any]]:
    """The chunk records cut to their first `n` pushes (their per-chunk counts kept)."""
    out, left = [], n
    for r in records:
        take = min(left, len(r["before"]))
        out.append({k: v[:take] if isinstance(v, list) else v for k, v in r.items()})
        left -= take
        if not left:
            break
    return out


def _datasets(study: StudyRun[PushTStudyConfig]) -> tuple[dict[int, Any], Any, list[float]]:
    """Training datasets by size, the held-out dataset, and the approach disturbances."""
    c = study.config
    sizes = sorted({*c.train_pushes, c.plan_pushes})
    train = _chunks(study, "train", sizes[-1])
    test = push_dataset(_chunks(study, "test", c.test_pushes), c.seed)
    sets = {n: push_dataset(_first(train, n), c.seed) for n in sizes}
    tag = c.tag(only=_observed(c, _DATA_FIELDS), version=_VERSION, length=8)
    for name, ds in ((f"train_n{sizes[-1]}", sets[sizes[-1]]), (f"test_n{c.test_pushes}", test)):
        path = study.out / "data" / f"pusht_{name}.{tag}"
        if not path.exists():
            with contextlib.suppress(DatasetError):  # written meanwhile by another run
                save_dataset(ds, path)
    moved = [float(v) for r in train for v in r["approach_moved"]]
    return sets, test, moved


def _learned(study: StudyRun[PushTStudyConfig], name: str, ds: Any, n: int) -> LearnedModel:
    """The mixture (``moe``) or single GP (``gp``) fitted on `ds`, saved or loaded."""
    c = study.config
    tag = c.tag(only=_observed(c, _MODEL_FIELDS), version=_VERSION, length=8)
    path = study.out / "models" / f"{name}.n{n}.{tag}.pt"
    observation = dataset_observation(ds)  # the file's key fingerprints it too
    if path.is_file():
        return LearnedModel(name, load_model(path), observation=observation)
    em = dataclasses.replace(c.em, seed=c.seed)
    experts = c.experts if name == "moe" else 1
    X, Y = push_features(ds), push_effects(ds)
    with limit_threads(1):
        fitted, _ = fit_learned(name, X, Y, experts=experts, em=em, observation=observation)
    path.parent.mkdir(parents=True, exist_ok=True)
    save_model(fitted.model, path)
    return fitted


def _models(study: StudyRun[PushTStudyConfig], ds: Any, n: int, names: set[str]) -> dict[str, Any]:
    """The models `names` (``moe``, ``gp``, ``analytic``) fitted on `ds` (`n` pushes)."""
    out: dict[str, Any] = {}
    for name in sorted(names):
        if name == "analytic":
            analytic = QuasiStaticTee(observation=dataset_observation(ds))
            out[name] = analytic.calibrate(push_features(ds), push_effects(ds))
        else:
            out[name] = _learned(study, name, ds, n)
    return out


def _episodes(
    study: StudyRun[PushTStudyConfig], jobs: list[tuple[str, int]], models: dict[str, Any], tag: str
) -> list[dict[str, Any]]:
    """Run (or resume) the episodes `jobs` ((planner, index) pairs): their records."""
    c = study.config
    if c.observation != "state":  # episodes observed otherwise are other tasks
        tag = f"{tag}.{c.observation}"
    tasks = [
        (f"{planner}.ep{i:04d}.{tag}", (planner, i, c.seed + i, i < c.keep_trajectories))
        for planner, i in jobs
    ]
    shared = {
        "models": models,
        "search": c.search,
        "env_search": c.env_search,
        "primitives": c.primitives,
        "python": c.python,
        "observation": c.observation,
    }
    return study.tasks(
        episode_task, tasks, desc="Push-T episodes", shared=shared, measured=_MEASURED
    )


def _planner_jobs(c: PushTStudyConfig) -> tuple[list[tuple[str, int]], list[tuple[str, int]]]:
    """(planner, episode) pairs: every planner's first episodes, then ``beam-moe``'s others.

    The first `baseline_episodes` run episode-major, so that every planner advances together.
    """
    env = c.baseline_episodes if c.env_episodes is None else c.env_episodes
    count = {p: c.baseline_episodes for p in c.planners} | {"beam-moe": c.episodes, "beam-env": env}
    span = max(c.baseline_episodes, env)
    head = [(p, i) for i in range(span) for p in c.planners if i < count[p]]
    tail = [("beam-moe", i) for i in range(span, c.episodes)]
    return head, tail if "beam-moe" in c.planners else []


def _curve(
    study: StudyRun[PushTStudyConfig], sets: dict[int, Any], planned: list[dict[str, Any]]
) -> list[dict[str, Any]]:
    """``beam-moe`` episodes at every training size (those at `plan_pushes` reused)."""
    c = study.config
    records: list[dict[str, Any]] = []
    if not c.curve_episodes:
        return records
    for n in c.train_pushes:
        if n == c.plan_pushes:
            mine = [r for r in planned if r["planner"] == "beam-moe"]
            records += [{**r, "train_pushes": n} for r in mine[: c.curve_episodes]]
            continue
        models = _models(study, sets[n], n, {"moe"})
        only = _observed(c, (*_MODEL_FIELDS, "search"))
        tag = c.tag(version=_EPISODE_VERSION, only=only) + f"n{n}"
        jobs = [("beam-moe", i) for i in range(c.curve_episodes)]
        done = _episodes(study, jobs, models, f"curve.{tag}")
        records += [{**r, "train_pushes": n} for r in done]
    return records


def run(config: PushTStudyConfig) -> dict[str, Any]:
    """Run (or resume) the study and write its tables and figures.

    Args:
        config: Study settings.

    Returns:
        ``{"models": model rows, "planners": planner rows, "curve": curve rows, "files":
        written paths}``.

    Raises:
        InputError: For an invalid config.
        PushTEnvError: If the Push-T environment is missing or of another version.
    """
    study = StudyRun(config, PushTStudyConfig)
    c = study.config
    with_worker(c.python, lambda w: w.versions)  # a missing environment fails here, first
    sets, test, moved = _datasets(study)
    scored = []
    for n in c.train_pushes:
        models = _models(study, sets[n], n, {"moe", "gp", "analytic"})
        Xt, Yt = push_features(test), push_effects(test)
        scored += [
            {"model": k, "train_pushes": n, **evaluate(m, Xt, Yt)} for k, m in models.items()
        ]
    mrows = model_rows(scored)
    study.table("models.csv", mrows)
    names = {PLANNERS[p].model for p in c.planners} - {"", "env"}
    plan_models = _models(study, sets[c.plan_pushes], c.plan_pushes, names)
    fields = _observed(c, (*_MODEL_FIELDS, "plan_pushes", "search", "env_search"))
    tag = c.tag(version=_EPISODE_VERSION, only=fields)
    head, tail = _planner_jobs(c)
    records = _episodes(study, head, plan_models, tag)
    curve = _curve(study, sets, records)  # before the long tail of beam-moe's episodes
    records += _episodes(study, tail, plan_models, tag) if tail else []
    prows = planner_rows(records)
    study.table("planners.csv", prows)
    study.table("timings.csv", timing_rows(records))
    crows = curve_rows(curve)
    if crows:
        study.table("curve.csv", crows)
        study.figure(plot_success_curve(crows, study.out / "success_vs_pushes.png"))
    study.figure(plot_models(mrows, study.out / "models.png"))
    study.figure(plot_episodes(records, study.out / "episodes.png"))
    if any(r.get("frames") for r in records):  # from pixels: the images planned on
        study.figure(plot_frames(records, study.out / "frames.png"))
    perception = sets[c.plan_pushes].meta.get("perception")
    study.summary(summary_lines(c, mrows, prows, crows, records, np.asarray(moved), perception))
    return {"models": mrows, "planners": prows, "curve": crows, "files": study.files}
