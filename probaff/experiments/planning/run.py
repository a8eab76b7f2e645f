"""The planning study: push-to-edge planners (chapter 4) and two-step tool pushes (chapter 5).

`run` generates the training pushes of the task's scene (``probaff generate --scene
push_to_edge``, resumable), fits the planner models of `probaff.planning.EDGE_MODELS` once
(saved under ``out/models/``, reused while the data and settings are the same), and runs every
planner on the same seeded episodes. Each episode is one resumable task (`run_tasks`): its
record lands in ``out/tasks/`` as JSON, keyed by the planner, the trial and a fingerprint of
every setting that shapes it, so a killed study reruns only the missing episodes.

Planners (`probaff.planning.EDGE_PLANNERS`): A* with the mixture of experts (``astar-moe``),
its risk-aware variant (``astar-risk-moe``), A* with a single GP (``astar-gp``), with chapter
4's clustered model (``astar-clustered``), with the true simulator (``astar-sim``, an upper
bound), with the analytic quasi-static model (``astar-quasistatic``), and the greedy one-step
planner with the mixture (``greedy-moe``).

Tool pushes (`probaff.planning.tool_push`): chapter 5's mixture (M = 3, f_o & f_c) is fitted
on ``probaff generate --scene tool_push`` pushes, and every planner of `TOOL_PUSH_PLANNERS`
(the thesis's two-step planner, random two-push sequences, the best single push, the two-step
planner with the true simulator) runs on the same seeded starts, one resumable task each.

Outputs in ``out/``: ``edge_summary.csv`` and ``summary.md`` (success rate with its 95 %
Wilson interval, pushes and replans per trial, the mean one-step prediction error, planning
time per plan, outcomes), ``edge_success.png``, ``edge_pushes.png`` and ``edge_episodes.png``
(planned against executed book trajectories over the table); ``tool_summary.csv`` and
``tool_success.png`` (the fraction of trials whose target ends reachable, with its interval,
and the target's final depth into the reachable region).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from functools import cache, partial
from pathlib import Path
from typing import Any, cast

from probaff._threads import limit_threads
from probaff.data import GenerateConfig
from probaff.experiments.base import StudyRun
from probaff.experiments.planning.config import PlanningStudyConfig, trial_seed
from probaff.experiments.planning.figures import edge_figures, plot_success_rates
from probaff.experiments.planning.report import (
    attribute_failures,
    edge_section,
    summarise,
    summarise_tool,
    tool_section,
)
from probaff.models import load as load_model
from probaff.models import save as save_model
from probaff.planning import (
    EDGE_MODELS,
    EDGE_PLANNERS,
    EdgeTask,
    FeaturePushModel,
    PushReachability,
    edge_transition,
    fit_edge_model,
    fit_tool_push_model,
    load_edge_task,
    run_edge_episode,
    run_tool_push_trial,
)
from probaff.sim import PushSimulator

__all__ = ["edge_models", "edge_trial", "run", "tool_trial"]

_EDGE_FIELDS = ("seed", "train_pushes", "em")
"""The fields that shape a push-to-edge episode's record (besides its planner and trial)."""

_TOOL_FIELDS = ("seed", "tool_train_pushes", "em")
"""The fields that shape a tool-push trial's record (besides its planner and trial)."""

_EDGE_WORLD = (
    "tasks/push_to_edge.yaml",
    "scenes/push_to_edge.yaml",
    "tabletop.yaml",
    "objects.yaml",
)
_TOOL_WORLD = ("scenes/tool_push.yaml", "tabletop.yaml", "objects.yaml")
_TOOL_GROUPS = ("f_o", "f_c")
_VERSION = 7  # 3: SMEM by partial EM; 4: L-BFGS coroutines; 5: fused kernel; 6: lasso continuation;
# 7: the push-to-edge models' prior width (EDGE_PRIOR_WIDTH)
_EPISODE_VERSION = 8  # push-to-edge episodes (models as _VERSION); 8: kept plans rechecked
_KEEP_TRAJECTORIES = 6  # episodes per planner whose full trajectories are stored (figures)


@cache
def _episode_tools() -> tuple[EdgeTask, PushSimulator, PushReachability]:
    """The task, a simulator and a reachability cache, once per process.

    Their answers do not depend on the order in which episodes ask.
    """
    task = load_edge_task()
    return task, PushSimulator(task.scene, task.world), PushReachability(task)


def edge_trial(
    planner: str,
    trial: int,
    seed: int,
    keep_trajectories: bool,
    *,
    models: dict[str, Any],
    replan_distance: float | None = None,
    recheck: bool = True,
) -> dict[str, Any]:
    """Run one episode of one planner (a study task; Dask workers import it).

    Args:
        planner: A key of `EDGE_PLANNERS`.
        trial: Trial index (its start is shared by every planner).
        seed: The episode's seed (`trial_seed`).
        keep_trajectories: Store the executed hand and book trajectories.
        models: Fitted planner models by name.
        replan_distance: The task's `EdgeTask.replan_distance` for this episode (m); None
            keeps the task file's.
        recheck: `run_edge_episode`'s ``recheck``.

    Returns:
        The episode's record (`EdgeEpisode.to_dict`) with ``trial``.
    """
    spec = EDGE_PLANNERS[planner]
    task, sim, reach = _episode_tools()
    if replan_distance is not None:
        task = replace(task, replan_distance=replan_distance)
    with limit_threads(1):
        episode = run_edge_episode(
            task,
            edge_transition(spec, task, models, seed),
            seed,
            search=spec.search,
            risk=spec.risk,
            label=planner,
            simulator=sim,
            reach=reach,
            trajectories=keep_trajectories,
            recheck=recheck,
        )
    return {**episode.to_dict(), "trial": trial}


def tool_trial(planner: str, trial: int, seed: int, *, tool_model: Any) -> dict[str, Any]:
    """Run one tool-push trial of one planner (a study task; Dask workers import it).

    Args:
        planner: A name from `TOOL_PUSH_PLANNERS`.
        trial: Trial index (its start is shared by every planner).
        seed: The trial's seed (`trial_seed`).
        tool_model: Chapter 5's fitted mixture with its features.

    Returns:
        The trial's record (`ToolPushTrial.to_dict`) with ``trial``.
    """
    model = tool_model if planner in ("two_step", "single_step") else None
    return {**run_tool_push_trial(planner, model, seed).to_dict(), "trial": trial}


def _training_pushes(study: StudyRun[PlanningStudyConfig], scene: str, n: int) -> Any:
    """Generate (or resume, or load) `n` training pushes of `scene` under ``out/data/``."""
    seed = study.config.seed
    config = GenerateConfig(scene=scene, n=n, seed=seed, trajectories=False)
    return study.dataset(config, f"{scene}_n{n}_s{seed}")


def _fit_or_load(
    path: Path,
    fit: Callable[[], FeaturePushModel],
    features: str,
    groups: tuple[str, ...],
    ds: Any,
) -> FeaturePushModel:
    """The model saved at `path`, or `fit()`'s, saved there (atomically) for the next run."""
    if path.is_file():
        return FeaturePushModel.for_dataset(load_model(path), features, groups, ds)
    fitted = fit()
    path.parent.mkdir(parents=True, exist_ok=True)
    save_model(cast(Any, fitted.model), path)
    return fitted


def edge_models(study: StudyRun[PlanningStudyConfig], names: set[str]) -> dict[str, Any]:
    """Generate the training pushes and fit (or load) the learned planner models `names`.

    Args:
        study: The run (its settings, and its output folder for the data and the models).
        names: Keys of `EDGE_MODELS`.

    Returns:
        Name -> fitted model with its features.
    """
    config = study.config
    ds = _training_pushes(study, "push_to_edge", config.train_pushes)
    tag = config.tag(only=_EDGE_FIELDS, world=_EDGE_WORLD, version=_VERSION, length=8)
    return {
        name: _fit_or_load(
            study.out / "models" / f"{name}.{tag}.pt",
            partial(fit_edge_model, name, ds, seed=config.seed, em=config.em),
            "ch4",
            EDGE_MODELS[name].groups,
            ds,
        )
        for name in sorted(names)
    }


def _tool_model(study: StudyRun[PlanningStudyConfig]) -> FeaturePushModel:
    """Generate the tool-push training pushes and fit (or load) chapter 5's mixture."""
    config = study.config
    ds = _training_pushes(study, "tool_push", config.tool_train_pushes)
    tag = config.tag(only=_TOOL_FIELDS, world=_TOOL_WORLD, version=_VERSION, length=8)
    return _fit_or_load(
        study.out / "models" / f"tool.{tag}.pt",
        lambda: fit_tool_push_model(
            ds, n_experts=3, groups=_TOOL_GROUPS, em=config.em, seed=config.seed
        ),
        "ch5",
        _TOOL_GROUPS,
        ds,
    )


def _trials(
    study: StudyRun[PlanningStudyConfig], part: str, shared: dict[str, Any]
) -> list[dict[str, Any]]:
    """Run (or resume) every (trial, planner) task of `part`; their records.

    `part` is ``"edge"`` (push-to-edge episodes, `edge_trial`) or ``"tool"`` (tool-push
    trials, `tool_trial`). A task's key holds the planner, the trial and the tag of the
    settings and world files that shape it; its arguments are the planner, the trial, its
    seed (`trial_seed`, the same for every planner) and, for an episode, whether to keep its
    trajectories (the first episodes of each planner, for the figures).
    """
    c = study.config
    edge = part == "edge"
    planners, trials = (c.planners, c.trials) if edge else (c.tool_planners, c.tool_trials)
    fields, world = (_EDGE_FIELDS, _EDGE_WORLD) if edge else (_TOOL_FIELDS, _TOOL_WORLD)
    only: tuple[str, ...] = fields
    if edge:  # the defaults keep the keys they have
        only = (
            *fields,
            *(["replan_distance"] if c.replan_distance is not None else []),
            *(["recheck"] if not c.recheck else []),
        )
    tag = c.tag(only=only, world=world, version=_EPISODE_VERSION if edge else _VERSION)
    tasks = [
        (
            f"{part}.{planner}.trial{trial:04d}.{tag}",
            (planner, trial, trial_seed(c.seed, trial))
            + ((trial < _KEEP_TRAJECTORIES,) if edge else ()),
        )
        for trial in range(trials)
        for planner in planners
    ]
    fn, desc = (edge_trial, "push-to-edge episodes") if edge else (tool_trial, "tool-push trials")
    return study.tasks(fn, tasks, desc=desc, shared=shared)


def _edge(study: StudyRun[PlanningStudyConfig]) -> tuple[list[dict[str, Any]], list[str]]:
    """The push-to-edge episodes, their table and figures: summary rows and Markdown."""
    config = study.config
    names = {EDGE_PLANNERS[p].model for p in config.planners} & set(EDGE_MODELS)
    shared = {
        "models": edge_models(study, names),
        "replan_distance": config.replan_distance,
        "recheck": config.recheck,
    }
    records = _trials(study, "edge", shared)
    rows = summarise(records)
    study.table("edge_summary.csv", rows)
    task = load_edge_task()
    for path in edge_figures(rows, records, config.planners, task, study.out):
        study.figure(path)
    blame = attribute_failures(records)
    if blame:
        study.table("edge_failures.csv", blame)
    distance = task.replan_distance if config.replan_distance is None else config.replan_distance
    return rows, edge_section(config, rows, blame, replan_distance=distance)


def _tool(study: StudyRun[PlanningStudyConfig]) -> tuple[list[dict[str, Any]], list[str]]:
    """The tool-push trials, their table and figure: summary rows and Markdown."""
    records = _trials(study, "tool", {"tool_model": _tool_model(study)})
    rows = summarise_tool(records)
    study.table("tool_summary.csv", rows)
    title = "Two-step tool push: target ends reachable (95 % Wilson intervals)"
    study.figure(plot_success_rates(rows, study.out / "tool_success.png", title=title))
    return rows, tool_section(study.config, rows)


def run(config: PlanningStudyConfig) -> dict[str, Any]:
    """Run (or resume) the study and write its tables and figures.

    Args:
        config: Study settings.

    Returns:
        ``{"edge": summary rows, "tool": tool-push summary rows, "files": written paths}``.

    Raises:
        InputError: For an invalid config.
    """
    study = StudyRun(config, PlanningStudyConfig)
    rows, md = _edge(study)
    tool_rows: list[dict[str, Any]] = []
    if study.config.tool_trials and study.config.tool_planners:
        tool_rows, more = _tool(study)
        md += more
    study.summary(md)
    return {"edge": rows, "tool": tool_rows, "files": study.files}
