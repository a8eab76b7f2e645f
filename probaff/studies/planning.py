"""The planning study: push-to-edge planners (chapter 4) and two-step tool pushes (chapter 5).

`run` generates the training pushes of the task's scene (``probaff generate --scene
push_to_edge``, resumable), fits the planner models of `probaff.planning.edge_models` once
(saved under ``out/models/``, reused while the data and settings are the same), and runs every
planner on the same seeded episodes. Each episode is one resumable task (`run_tasks`): its
record lands in ``out/tasks/`` as JSON, keyed by the planner, the trial and a fingerprint of
every setting that shapes it, so a killed study reruns only the missing episodes.

Planners (`EDGE_PLANNERS`): A* with the mixture of experts (``astar-moe``), its risk-aware
variant (``astar-risk-moe``), A* with a single GP (``astar-gp``), with chapter 4's clustered
model (``astar-clustered``), with the true simulator (``astar-sim``, an upper bound), with the
analytic quasi-static model (``astar-quasistatic``), and the greedy one-step planner with the
mixture (``greedy-moe``).

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

import dataclasses
import hashlib
import math
from collections.abc import Callable
from dataclasses import dataclass
from functools import cache, partial
from pathlib import Path
from typing import Any, cast

import numpy as np

from probaff._checks import check_count, check_output_dir
from probaff._dask import check_scheduler, check_workers
from probaff._io import atomic_write_text
from probaff._threads import torch_threads
from probaff.data.generation import GenerateConfig, generate
from probaff.errors import InputError
from probaff.eval.fingerprint import config_fingerprint
from probaff.eval.metrics import wilson_interval
from probaff.eval.tables import markdown_table, write_csv
from probaff.eval.tasks import ResultStore, run_tasks
from probaff.models import load as load_model
from probaff.models import save as save_model
from probaff.planning.edge_episode import run_edge_episode
from probaff.planning.edge_models import EDGE_MODELS, fit_edge_model
from probaff.planning.edge_task import EdgeTask, load_edge_task
from probaff.planning.edge_transitions import (
    EdgeTransition,
    LearnedTransition,
    PushReachability,
    QuasiStaticTransition,
    SimulatorTransition,
)
from probaff.planning.learned import FeaturePushModel
from probaff.planning.tool_push import TOOL_PUSH_PLANNERS, fit_tool_push_model, run_tool_push_trial
from probaff.sim.config import worlds_dir
from probaff.sim.runner import PushSimulator

__all__ = [
    "EDGE_PLANNERS",
    "RUN_ONLY",
    "SMOKE_OVERRIDES",
    "THESIS_EDGE",
    "EdgePlannerSpec",
    "PlanningStudyConfig",
    "attribute_failures",
    "demo",
    "edge_trial",
    "run",
    "summarise",
    "summarise_tool",
    "tool_trial",
    "trial_seed",
]


@dataclass(frozen=True)
class EdgePlannerSpec:
    """One push-to-edge planner of the study.

    Attributes:
        search: ``"astar"`` or ``"greedy"``.
        model: A key of `EDGE_MODELS`, ``"simulator"`` or ``"quasistatic"``.
        risk: The risk-aware variant.
    """

    search: str
    model: str
    risk: bool = False


EDGE_PLANNERS: dict[str, EdgePlannerSpec] = {
    "astar-moe": EdgePlannerSpec("astar", "moe"),
    "astar-risk-moe": EdgePlannerSpec("astar", "moe", risk=True),
    "astar-gp": EdgePlannerSpec("astar", "gp"),
    "astar-clustered": EdgePlannerSpec("astar", "clustered"),
    "astar-sim": EdgePlannerSpec("astar", "simulator"),
    "astar-quasistatic": EdgePlannerSpec("astar", "quasistatic"),
    "greedy-moe": EdgePlannerSpec("greedy", "moe"),
}
"""The planners the study compares, by name."""

THESIS_EDGE = {"trials": 15, "successes": 14, "pushes": 4.4, "replans": 3.0, "error_cm": 3.65}
"""Chapter 4's published push-to-edge result (A* with the hierarchical model, m = 2)."""

RUN_ONLY = ("out", "workers", "scheduler", "progress")
"""Fields that decide where and how the study runs, not what it computes."""

_EDGE_FIELDS = ("seed", "train_pushes", "em_iterations")
"""The fields that shape a push-to-edge episode's record (besides its planner and trial)."""

_TOOL_FIELDS = ("seed", "tool_train_pushes", "em_iterations")
"""The fields that shape a tool-push trial's record (besides its planner and trial)."""

_VERSION = 2
_KEEP_TRAJECTORIES = 6  # episodes per planner whose full trajectories are stored (figures)


@dataclass(frozen=True)
class PlanningStudyConfig:
    """Settings of the planning study.

    Attributes:
        out: Output folder (datasets, models, per-trial records, tables, figures).
        seed: Seed of the training pushes, the fits and the episodes.
        train_pushes: Training pushes of the task's scene for the learned models.
        trials: Episodes per planner (the same seeded starts for every planner).
        planners: Names from `EDGE_PLANNERS`.
        em_iterations: EM iterations of the mixture models.
        tool_trials: Tool-push trials per planner (0 skips chapter 5).
        tool_train_pushes: Training pushes of the tool-push scene for chapter 5's mixture.
        tool_planners: Names from `TOOL_PUSH_PLANNERS`.
        workers: 0 runs in this process; K > 0 or None uses a local Dask cluster.
        scheduler: Address of an existing Dask scheduler.
        progress: Show progress bars.
    """

    out: str = "results/planning"
    seed: int = 0
    train_pushes: int = 240
    trials: int = 100
    planners: tuple[str, ...] = tuple(EDGE_PLANNERS)
    em_iterations: int = 10
    tool_trials: int = 50
    tool_train_pushes: int = 300
    tool_planners: tuple[str, ...] = TOOL_PUSH_PLANNERS
    workers: int | None = 0
    scheduler: str | None = None
    progress: bool = True

    def validate(self) -> None:
        """Raise `InputError` for unknown planners or impossible sizes."""
        unknown = [p for p in self.planners if p not in EDGE_PLANNERS]
        if unknown or not self.planners:
            raise InputError(
                f"planners: unknown or no planners {unknown or list(self.planners)}; choose from "
                f"{list(EDGE_PLANNERS)}."
            )
        check_count("train_pushes", self.train_pushes)
        if self.train_pushes < 10:
            raise InputError(f"train_pushes must be at least 10, got {self.train_pushes}.")
        check_count("trials", self.trials)
        check_count("tool_trials", self.tool_trials, minimum=0)
        check_count("tool_train_pushes", self.tool_train_pushes)
        unknown = [p for p in self.tool_planners if p not in TOOL_PUSH_PLANNERS]
        if unknown:
            raise InputError(
                f"tool_planners: unknown tool planners {unknown}; choose from "
                f"{list(TOOL_PUSH_PLANNERS)}."
            )
        check_count("em_iterations", self.em_iterations)
        check_count("seed", self.seed, minimum=0)
        check_workers(self.workers)
        check_scheduler(self.scheduler)
        check_output_dir("out", self.out)


SMOKE_OVERRIDES: dict[str, Any] = {
    "train_pushes": 40,
    "trials": 2,
    "planners": ("astar-moe", "astar-risk-moe", "astar-quasistatic", "greedy-moe"),
    "em_iterations": 2,
    "tool_trials": 1,
    "tool_train_pushes": 40,
    "tool_planners": ("random", "two_step"),
    "progress": False,
}
"""Sizes of a tiny run that checks the whole pipeline in a minute or two."""


def trial_seed(seed: int, trial: int) -> int:
    """The episode seed of trial `trial`: the same for every planner."""
    return int(np.random.SeedSequence(seed, spawn_key=(trial,)).generate_state(1)[0])


@cache
def _episode_tools() -> tuple[EdgeTask, PushSimulator, PushReachability]:
    """The task, a simulator and a reachability cache, once per process.

    Their answers do not depend on the order in which episodes ask.
    """
    task = load_edge_task()
    return task, PushSimulator(task.scene, task.world), PushReachability(task)


def _transition(
    spec: EdgePlannerSpec, task: EdgeTask, models: dict[str, FeaturePushModel], seed: int
) -> EdgeTransition:
    if spec.model == "simulator":
        return SimulatorTransition(task)
    if spec.model == "quasistatic":
        return QuasiStaticTransition(task)
    return LearnedTransition(models[spec.model], task, seed=seed, name=spec.model)


def edge_trial(
    planner: str, trial: int, seed: int, keep_trajectories: bool, *, models: dict[str, Any]
) -> dict[str, Any]:
    """Run one episode of one planner (a study task; Dask workers import it).

    Args:
        planner: A key of `EDGE_PLANNERS`.
        trial: Trial index (its start is shared by every planner).
        seed: The episode's seed (`trial_seed`).
        keep_trajectories: Store the executed hand and book trajectories.
        models: Fitted planner models by name.

    Returns:
        The episode's record (`EdgeEpisode.to_dict`) with ``trial``.
    """
    spec = EDGE_PLANNERS[planner]
    task, sim, reach = _episode_tools()
    with torch_threads(1):
        episode = run_edge_episode(
            task,
            _transition(spec, task, models, seed),
            seed,
            search=spec.search,
            risk=spec.risk,
            label=planner,
            simulator=sim,
            reach=reach,
            trajectories=keep_trajectories,
        )
    return {**episode.to_dict(), "trial": trial}


_EDGE_WORLD = (
    "tasks/push_to_edge.yaml",
    "scenes/push_to_edge.yaml",
    "tabletop.yaml",
    "objects.yaml",
)
_TOOL_WORLD = ("scenes/tool_push.yaml", "tabletop.yaml", "objects.yaml")


def _edge_tag(
    config: PlanningStudyConfig,
    length: int = 10,
    only: tuple[str, ...] = _EDGE_FIELDS,
    world: tuple[str, ...] = _EDGE_WORLD,
) -> str:
    """Fingerprint of the settings in `only`, the world files they read and the code's version.

    The task, scene, world and catalogue files under `worlds_dir()` shape the results as much
    as the config does, so an edited file never reuses a stored result.
    """
    others = {f.name for f in dataclasses.fields(config)} - set(only)
    digest = hashlib.sha256()
    for name in world:
        digest.update((worlds_dir() / name).read_bytes())
    fields_tag = config_fingerprint(config, exclude=others, version=_VERSION, length=length)
    return f"{fields_tag}{digest.hexdigest()[:6]}"


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


def _training_pushes(config: PlanningStudyConfig, out: Path, scene: str, n: int) -> Any:
    """Generate (or resume, or load) `n` training pushes of `scene` under ``out/data/``."""
    data_dir = out / "data" / f"{scene}_n{n}_s{config.seed}"
    return generate(
        GenerateConfig(scene=scene, n=n, seed=config.seed, trajectories=False),
        data_dir,
        workers=config.workers,
        scheduler=config.scheduler,
        resume=data_dir.exists(),
        progress=config.progress,
    )


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


def _tool_model(config: PlanningStudyConfig, out: Path) -> FeaturePushModel:
    """Generate the tool-push training pushes and fit (or load) chapter 5's mixture."""
    ds = _training_pushes(config, out, "tool_push", config.tool_train_pushes)
    return _fit_or_load(
        out / "models" / f"tool.{_edge_tag(config, 8, _TOOL_FIELDS, _TOOL_WORLD)}.pt",
        lambda: fit_tool_push_model(
            ds, n_experts=3, groups=_TOOL_GROUPS, max_iter=config.em_iterations, seed=config.seed
        ),
        "ch5",
        _TOOL_GROUPS,
        ds,
    )


_TOOL_GROUPS = ("f_o", "f_c")


def summarise_tool(records: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """One row per tool-push planner: success with its interval, depth, planning time.

    Success is the target ending inside the reachable region (95 % Wilson interval); depth
    is its final signed distance into the region (cm).

    Args:
        records: Trial records (``planner``, ``reached``, ``final_depth``, ``initial_depth``,
            ``planning_time_s``).

    Returns:
        Rows with ``planner``, ``trials``, ``successes``, ``success_rate``, ``success_low``,
        ``success_high``, ``depth_cm`` and its standard deviation ``depth_sd_cm``,
        ``gain_cm`` (mean final minus initial depth) and ``plan_seconds``.
    """
    rows = []
    for planner in dict.fromkeys(r["planner"] for r in records):
        rs = [r for r in records if r["planner"] == planner]
        k = sum(bool(r["reached"]) for r in rs)
        lo, hi = wilson_interval(k, len(rs))
        depth = 100 * np.array([r["final_depth"] for r in rs])
        start = 100 * np.array([r["initial_depth"] for r in rs])
        rows.append(
            {
                "planner": planner,
                "trials": len(rs),
                "successes": k,
                "success_rate": k / len(rs),
                "success_low": lo,
                "success_high": hi,
                "depth_cm": float(depth.mean()),
                "depth_sd_cm": float(depth.std(ddof=1)) if len(rs) > 1 else 0.0,
                "gain_cm": float((depth - start).mean()),
                "plan_seconds": float(np.mean([r["planning_time_s"] for r in rs])),
            }
        )
    return rows


def _models(config: PlanningStudyConfig, out: Path, names: set[str]) -> dict[str, Any]:
    """Generate the training pushes and fit (or load) the learned planner models."""
    ds = _training_pushes(config, out, "push_to_edge", config.train_pushes)
    tag = _edge_tag(config, length=8)
    return {
        name: _fit_or_load(
            out / "models" / f"{name}.{tag}.pt",
            partial(fit_edge_model, name, ds, seed=config.seed, em_iterations=config.em_iterations),
            "ch4",
            EDGE_MODELS[name].groups,
            ds,
        )
        for name in sorted(names)
    }


def summarise(records: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """One row per planner: success rate with its 95 % Wilson interval and the means.

    Args:
        records: Episode records (``planner`` keys).

    Returns:
        Rows with ``planner``, ``trials``, ``successes``, ``success_rate``, ``success_low``,
        ``success_high``, ``pushes`` (mean over trials), ``pushes_success`` (mean over
        successful trials), ``replans``, ``error_cm`` (mean one-step prediction error),
        ``plan_seconds`` (mean per planning call), ``plan_seconds_max``, and the counts of
        each outcome.
    """
    rows = []
    for planner in dict.fromkeys(r["planner"] for r in records):
        rs = [r for r in records if r["planner"] == planner]
        k = sum(bool(r["success"]) for r in rs)
        lo, hi = wilson_interval(k, len(rs))
        errors = [s["error"] for r in rs for s in r["steps"]]
        plan_s = [t for r in rs for t in r["planning_seconds"]]
        ok = [r["pushes"] for r in rs if r["success"]]
        row: dict[str, Any] = {
            "planner": planner,
            "trials": len(rs),
            "successes": k,
            "success_rate": k / len(rs),
            "success_low": lo,
            "success_high": hi,
            "pushes": float(np.mean([r["pushes"] for r in rs])),
            "pushes_success": float(np.mean(ok)) if ok else math.nan,
            "replans": float(np.mean([r["replans"] for r in rs])),
            "error_cm": 100 * float(np.mean(errors)) if errors else math.nan,
            "plan_seconds": float(np.mean(plan_s)) if plan_s else math.nan,
            "plan_seconds_max": float(np.max(plan_s)) if plan_s else math.nan,
        }
        for outcome in ("success", "fell", "budget", "stuck"):
            row[f"n_{outcome}"] = sum(r["outcome"] == outcome for r in rs)
        rows.append(row)
    return rows


def attribute_failures(
    records: list[dict[str, Any]], reference: str = "astar-sim"
) -> list[dict[str, Any]]:
    """Whether a planner's failures are its model's: compare each trial with the reference.

    The reference planner (A* with the true simulator) plans with the same search on the same
    start; where it succeeds and a planner with a learned or analytic model fails, the model
    is to blame, not the search. Where both fail, the start is hard for the search itself.

    Args:
        records: Episode records of several planners (``planner``, ``trial``, ``success``,
            ``outcome``, ``steps``).
        reference: The planner whose results stand for the search with a perfect model.

    Returns:
        One row per other planner: ``failures``, ``model_failures`` (the reference succeeded
        on that start), ``search_failures`` (it failed too), the outcomes of the model
        failures, and ``error_cm_failed`` / ``error_cm_succeeded``, the mean one-step
        prediction errors over the failed and the successful trials. Empty if the reference
        did not run.
    """
    ref = {r["trial"]: r for r in records if r["planner"] == reference}
    if not ref:
        return []
    rows = []
    for planner in dict.fromkeys(r["planner"] for r in records):
        if planner == reference:
            continue
        rs = [r for r in records if r["planner"] == planner and r["trial"] in ref]
        failed = [r for r in rs if not r["success"]]
        model = [r for r in failed if ref[r["trial"]]["success"]]

        def err(group: list[dict[str, Any]]) -> float:
            e = [s["error"] for r in group for s in r["steps"]]
            return 100 * float(np.mean(e)) if e else math.nan

        row: dict[str, Any] = {
            "planner": planner,
            "trials": len(rs),
            "failures": len(failed),
            "model_failures": len(model),
            "search_failures": len(failed) - len(model),
            "error_cm_failed": err(failed),
            "error_cm_succeeded": err([r for r in rs if r["success"]]),
        }
        for outcome in ("fell", "budget", "stuck"):
            row[f"model_{outcome}"] = sum(r["outcome"] == outcome for r in model)
        rows.append(row)
    return rows


def _thesis_row() -> dict[str, Any]:
    t = THESIS_EDGE
    lo, hi = wilson_interval(int(t["successes"]), int(t["trials"]))
    return {
        "planner": "thesis (A*, hierarchical m=2)",
        "trials": t["trials"],
        "successes": t["successes"],
        "success_rate": t["successes"] / t["trials"],
        "success_low": lo,
        "success_high": hi,
        "pushes": t["pushes"],
        "replans": t["replans"],
        "error_cm": t["error_cm"],
        **dict.fromkeys(("plan_seconds", "n_fell", "n_budget", "n_stuck"), ""),
    }


def run(config: PlanningStudyConfig) -> dict[str, Any]:
    """Run (or resume) the study and write its tables and figures.

    Args:
        config: Study settings.

    Returns:
        ``{"edge": summary rows, "tool": tool-push summary rows, "files": written paths}``.

    Raises:
        InputError: For an invalid config.
    """
    from probaff.eval.planning_figures import (
        plot_edge_episodes,
        plot_pushes_per_trial,
        plot_success_rates,
    )

    config.validate()
    out = Path(config.out)
    names = {EDGE_PLANNERS[p].model for p in config.planners} & set(EDGE_MODELS)
    models = _models(config, out, names)
    tag = _edge_tag(config)
    store = ResultStore(out / "tasks")
    tasks = [
        (
            f"edge.{planner}.trial{trial:04d}.{tag}",
            (planner, trial, trial_seed(config.seed, trial), trial < _KEEP_TRAJECTORIES),
        )
        for trial in range(config.trials)
        for planner in config.planners
    ]
    records = run_tasks(
        edge_trial,
        tasks,
        store,
        workers=config.workers,
        scheduler=config.scheduler,
        progress=config.progress,
        desc="push-to-edge episodes",
        shared={"models": models},
    )
    rows = summarise(records)
    files = [write_csv(out / "edge_summary.csv", rows)]
    task = load_edge_task()
    files.append(
        plot_success_rates(
            rows,
            out / "edge_success.png",
            title="Push to the edge: success rate (95 % Wilson intervals)",
            reference=("thesis 14/15", 14 / 15),
        )
    )
    by_planner = {p: [r for r in records if r["planner"] == p] for p in config.planners}
    files.append(plot_pushes_per_trial(by_planner, out / "edge_pushes.png"))
    shown = [r for p in config.planners[:3] for r in by_planner[p][:2]]
    files.append(plot_edge_episodes(shown, task, out / "edge_episodes.png"))
    columns = [
        "planner",
        "trials",
        "successes",
        "success_rate",
        "success_low",
        "success_high",
        "pushes",
        "replans",
        "error_cm",
        "plan_seconds",
        "n_fell",
        "n_budget",
        "n_stuck",
    ]
    md = [
        "# Planning study",
        "",
        "## Push to the edge, then grasp (chapter 4)",
        "",
        f"{config.trials} seeded episodes per planner, the same starts for every planner; "
        f"models fitted on {config.train_pushes} pushes of the `push_to_edge` scene.",
        "",
        markdown_table([*rows, _thesis_row()], columns, digits=3),
        "",
        "`success_low`/`success_high`: 95 % Wilson interval. `pushes`, `replans`: means per "
        "trial; `error_cm`: mean distance between the predicted and the executed book "
        "position after a push; `plan_seconds`: mean wall time per planning call.",
        "",
    ]
    blame = attribute_failures(records)
    if blame:
        files.append(write_csv(out / "edge_failures.csv", blame))
        md += [
            "Failures the model is to blame for: `model_failures` counts the starts on which "
            "A* with the true simulator succeeded (same search, same start) and this planner "
            "failed; `search_failures` those on which both failed.",
            "",
            markdown_table(
                blame,
                [
                    "planner",
                    "trials",
                    "failures",
                    "model_failures",
                    "search_failures",
                    "model_fell",
                    "model_budget",
                    "model_stuck",
                    "error_cm_failed",
                    "error_cm_succeeded",
                ],
                digits=3,
            ),
            "",
        ]
    tool_rows: list[dict[str, Any]] = []
    if config.tool_trials and config.tool_planners:
        tool_model = _tool_model(config, out)
        tool_tag = _edge_tag(config, only=_TOOL_FIELDS, world=_TOOL_WORLD)
        tool_tasks = [
            (
                f"tool.{planner}.trial{trial:04d}.{tool_tag}",
                (planner, trial, trial_seed(config.seed, trial)),
            )
            for trial in range(config.tool_trials)
            for planner in config.tool_planners
        ]
        tool_records = run_tasks(
            tool_trial,
            tool_tasks,
            store,
            workers=config.workers,
            scheduler=config.scheduler,
            progress=config.progress,
            desc="tool-push trials",
            shared={"tool_model": tool_model},
        )
        tool_rows = summarise_tool(tool_records)
        files.append(write_csv(out / "tool_summary.csv", tool_rows))
        files.append(
            plot_success_rates(
                tool_rows,
                out / "tool_success.png",
                title="Two-step tool push: target ends reachable (95 % Wilson intervals)",
            )
        )
        md += [
            "## Two-step tool push (chapter 5)",
            "",
            f"{config.tool_trials} seeded trials per planner, the same starts for every planner; "
            f"chapter 5's mixture (M = 3, f_o & f_c) fitted on {config.tool_train_pushes} pushes "
            "of the `tool_push` scene.",
            "",
            markdown_table(
                tool_rows,
                [
                    "planner",
                    "trials",
                    "successes",
                    "success_rate",
                    "success_low",
                    "success_high",
                    "depth_cm",
                    "depth_sd_cm",
                    "gain_cm",
                    "plan_seconds",
                ],
                digits=3,
            ),
            "",
            "`depth_cm`: the target's final signed distance into the reachable region "
            "(positive inside); `gain_cm`: final minus initial depth.",
            "",
        ]
    files.append(str(out / "summary.md"))
    atomic_write_text(out / "summary.md", "\n".join(md))
    return {"edge": rows, "tool": tool_rows, "files": files}


def demo(
    out: str | Path, *, seed: int = 0, train_pushes: int = 64, progress: bool = True
) -> dict[str, Any]:
    """One planned push-to-edge episode with the mixture of experts, rendered to a PNG.

    Generates `train_pushes` pushes of the task's scene, fits the ``"moe"`` model on them and
    runs one closed-loop A* episode; ``probaff demo`` calls it.

    Args:
        out: Output folder (the dataset, ``edge_episode.png``).
        seed: Seed of the pushes, the fit and the episode.
        train_pushes: Training pushes (at least 10).
        progress: Show the generator's progress bar.

    Returns:
        ``{"outcome", "pushes", "replans", "error_cm", "figure"}``.
    """
    from probaff.eval.planning_figures import plot_edge_episodes

    out = Path(out)
    config = PlanningStudyConfig(
        out=str(out), seed=seed, train_pushes=train_pushes, progress=progress
    )
    config.validate()
    models = _models(config, out, {"moe"})
    record = edge_trial("astar-moe", 0, trial_seed(seed, 0), True, models=models)
    figure = plot_edge_episodes(
        [record], load_edge_task(), out / "edge_episode.png", title="A* with the mixture of experts"
    )
    result = {
        "outcome": record["outcome"],
        "pushes": record["pushes"],
        "replans": record["replans"],
        "error_cm": 100 * record["mean_error"],
        "figure": figure,
    }
    print(
        f"push to the edge: {record['outcome']} after {record['pushes']} pushes, "
        f"{record['replans']} replans, mean one-step error {result['error_cm']:.2f} cm"
    )
    return result
