"""The chapter 6 study: modular transition models for push, pick and place, against a monolith.

`run` generates (or resumes) the datasets under ``out/data/``: a pool of tabletop
``modular_push`` pushes (two cuboids, a 35 cm push, the second up to 30 cm sideways), of
side-view ``pick`` and ``place`` skills, and held-out test sets of each and of the
``chain_3`` .. ``chain_5`` rows of cuboids. Every (part, training-set scale, trial) is one
resumable task (`probaff.studies.modular_trials`): trial t draws its training rows from the
pool (``scale x`` the thesis's 221 push, 168 pick and 20 place samples) and predicts its own
slice of ``test_scenes`` test scenes, so trials are independent repetitions and the tables
give 95 % Student-t intervals of the mean over trials.

What it reports (``summary.md``, one CSV per table, PNG figures):

* ``backward.csv``: the hand's effect on o1 along and off the push, per push model (GP, GP
  with the backward component, mixture of experts), against the thesis's 5.8 -> 2.57 cm;
* ``two_objects.csv``: modular chains against the monolithic GP on two-object scenes, per
  object, along and off the push (thesis: 1.89 vs 4.83 cm for o1, 1.02 vs 2.49 cm for o2),
  with the motion each predicts for an o2 that truly stayed put;
* ``pick_place.csv``: pick and place predictions split by the simulator's verdict (cases
  that cannot be picked should be predicted at about zero displacement);
* ``chains.csv``: error and 90 % interval coverage of every object of 3-, 4- and 5-object
  chains, which the monolithic model cannot represent;
* figures: predicted against observed motion on the table and in the side view, error
  against chain position, modular against monolithic, and errors against training size.
"""

from __future__ import annotations

import dataclasses
import hashlib
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from probaff._checks import check_count, check_output_dir
from probaff._dask import check_scheduler, check_workers
from probaff._io import atomic_write_text
from probaff.data.generation import GenerateConfig, generate, generate_skills
from probaff.errors import InputError
from probaff.eval.fingerprint import config_fingerprint
from probaff.eval.metrics import mean_halfwidth
from probaff.eval.tables import markdown_table, write_csv
from probaff.eval.tasks import ResultStore, run_tasks
from probaff.sim.config import worlds_dir
from probaff.studies.modular_trials import (
    LEVEL,
    PUSH_MODELS,
    SKILL_MODELS,
    TrialSettings,
    chain_trained_trial,
    push_trial,
    skill_trial,
)

__all__ = [
    "DEMO_OVERRIDES",
    "RUN_ONLY",
    "SMOKE_OVERRIDES",
    "THESIS",
    "TRAININGS",
    "ModularStudyConfig",
    "demo",
    "modular_task",
    "run",
    "smoke_config",
    "summarise_backward",
    "summarise_chains",
    "summarise_skills",
    "summarise_two_objects",
]

THESIS = {
    "backward_along_cm": (5.8, 2.57),
    "modular_along_cm": (1.89, 1.02),
    "monolithic_along_cm": (4.83, 2.49),
}
"""Chapter 6's published numbers: push-along error without -> with the backward component;
modular and monolithic push-along errors of (o1, o2)."""

TRAININGS = {"push": "two-object scenes", "chained": "+ chain_3 rows"}
"""Chain summaries by task part: the thesis's training, and the extension's."""

RUN_ONLY = ("out", "workers", "scheduler", "progress")
"""Fields that decide where and how the study runs, not what it computes."""

_VERSION = 1
_TEST_SEED_OFFSET = 1000  # test datasets use seed + this, so they never share a draw
_STILL = 0.01  # m; an object that moved less than this is "stayed put"
_WORLD = (
    "scenes/modular_push.yaml",
    "scenes/chain_3.yaml",
    "scenes/chain_4.yaml",
    "scenes/chain_5.yaml",
    "sideview_scenes/pick.yaml",
    "sideview_scenes/place.yaml",
    "tabletop.yaml",
    "objects.yaml",
    "sideview.yaml",
    "cuboids.yaml",
)


@dataclass(frozen=True)
class ModularStudyConfig:
    """Settings of the chapter 6 study.

    Attributes:
        out: Output folder (datasets, per-task records, tables, figures).
        seed: Seed of the datasets, the training draws and the fits.
        push_train: Training pushes at scale 1 (the thesis's 221 push samples).
        pick_train: Training picks at scale 1 (168).
        place_train: Training places at scale 1 (20).
        test_scenes: Test scenes per skill and trial (the thesis's 10).
        trials: Independent repetitions (a training draw and a test slice each).
        scales: Training-set sizes as multiples of the thesis's; 1 is the thesis's setting,
            larger ones show how the errors fall with data.
        chain_lengths: Objects per test chain.
        chain_train: ``chain_3`` pushes whose rows are added to the chain's push model in
            the extension part (``"chained"`` tasks: does a model that has seen packed rows
            of three predict rows of four and five?); 0 skips it.
        settings: Models, feature groups and sampling of every trial.
        workers: 0 runs in this process; K > 0 or None uses a local Dask cluster.
        scheduler: Address of an existing Dask scheduler.
        progress: Show progress bars.
    """

    out: str = "results/modular"
    seed: int = 0
    push_train: int = 221
    pick_train: int = 168
    place_train: int = 20
    test_scenes: int = 10
    trials: int = 5
    scales: tuple[float, ...] = (1.0, 2.0)
    chain_lengths: tuple[int, ...] = (3, 4, 5)
    chain_train: int = 60
    settings: TrialSettings = field(default_factory=TrialSettings)
    workers: int | None = 0
    scheduler: str | None = None
    progress: bool = True

    def validate(self) -> None:
        """Raise `InputError` for impossible sizes, scales, chains or settings."""
        for name in ("push_train", "pick_train", "place_train", "test_scenes", "trials"):
            check_count(name, getattr(self, name))
        check_count("seed", self.seed, minimum=0)
        check_count("chain_train", self.chain_train, minimum=0)
        if not self.scales or any(
            not isinstance(s, (int, float)) or not math.isfinite(s) or s < 1 for s in self.scales
        ):
            raise InputError(
                f"scales must be finite numbers >= 1 (multiples of the thesis's sizes), got "
                f"{self.scales!r}."
            )
        bad = [k for k in self.chain_lengths if k not in (3, 4, 5)]
        if bad:
            raise InputError(f"chain_lengths may hold 3, 4 and 5 (the chain scenes), got {bad}.")
        s = self.settings
        if not isinstance(s, TrialSettings):
            raise InputError(f"settings must be a TrialSettings, got {type(s).__name__}.")
        check_workers(self.workers)
        check_scheduler(self.scheduler)
        check_output_dir("out", self.out)

    def train_size(self, part: str, scale: float) -> int:
        """Training rows of `part` (``"push"``, ``"pick"``, ``"place"``) at `scale`."""
        base = {"push": self.push_train, "pick": self.pick_train, "place": self.place_train}
        return max(2, round(base[part] * scale))


SMOKE_OVERRIDES: dict[str, Any] = {
    "push_train": 24,
    "pick_train": 16,
    "place_train": 8,
    "test_scenes": 2,
    "trials": 2,
    "scales": (1.0,),
    "chain_lengths": (3,),
    "chain_train": 6,
    "settings": TrialSettings(chain_samples=16, em_iterations=2, gp_max_iter=10),
    "progress": False,
}
"""Sizes of a tiny run that checks the whole pipeline in a minute or two."""


def _tag(config: ModularStudyConfig, exclude: tuple[str, ...] = ()) -> str:
    """Fingerprint of the settings that shape a record (all but `exclude`) and the world files."""
    digest = hashlib.sha256()
    for name in _WORLD:
        digest.update((worlds_dir() / name).read_bytes())
    fields = config_fingerprint(config, exclude=RUN_ONLY + exclude, version=_VERSION, length=10)
    return f"{fields}{digest.hexdigest()[:6]}"


def _dataset(config: ModularStudyConfig, out: Path, scene: str, n: int, test: bool) -> str:
    """Generate (or resume) `n` samples of `scene` under ``out/data/``; return the folder."""
    seed = config.seed + (_TEST_SEED_OFFSET if test else 0)
    folder = out / "data" / f"{scene}_n{n}_s{seed}"
    make = generate_skills if scene in ("pick", "place") else generate
    make(
        GenerateConfig(scene=scene, n=n, seed=seed),
        folder,
        workers=config.workers,
        scheduler=config.scheduler,
        resume=folder.exists(),
        progress=config.progress,
    )
    return str(folder)


def _datasets(config: ModularStudyConfig, out: Path) -> dict[str, str]:
    """Every dataset of the study: training pools, test sets and chains, by name."""
    top = max(config.scales)
    n_test = config.test_scenes * config.trials
    paths = {}
    for part, scene in (("push", "modular_push"), ("pick", "pick"), ("place", "place")):
        paths[f"{part}_pool"] = _dataset(config, out, scene, config.train_size(part, top), False)
        paths[f"{part}_test"] = _dataset(config, out, scene, n_test, True)
    for k in config.chain_lengths:
        paths[f"chain_{k}"] = _dataset(config, out, f"chain_{k}", n_test, True)
    if config.chain_train:
        paths["chain_train"] = _dataset(config, out, "chain_3", config.chain_train, False)
    return paths


def _draw(config: ModularStudyConfig, part: str, scale: float, trial: int) -> list[int]:
    """The training rows of one (part, scale, trial): a seeded draw from the pool."""
    pool = config.train_size(part, max(config.scales))
    n = config.train_size(part, scale)
    key = (trial, round(1000 * scale), ("push", "pick", "place").index(part))
    rng = np.random.default_rng(np.random.SeedSequence(config.seed, spawn_key=key))
    return sorted(rng.choice(pool, size=n, replace=False).tolist())


def _tasks(config: ModularStudyConfig, paths: dict[str, str]) -> list[tuple[str, tuple[Any, ...]]]:
    tag = _tag(config, exclude=("chain_train",))  # the extension does not shape these parts
    chained_tag = _tag(config)
    chains = tuple((k, paths[f"chain_{k}"]) for k in config.chain_lengths)
    tasks = []
    for scale in config.scales:
        for trial in range(config.trials):
            test = list(range(trial * config.test_scenes, (trial + 1) * config.test_scenes))
            seed = config.seed + 7919 * trial
            for part in ("push", "pick", "place"):
                key = f"{part}.x{scale:g}.t{trial:03d}.{tag}"
                train = _draw(config, part, scale, trial)
                if part == "push":
                    args: tuple[Any, ...] = (
                        "push",
                        paths["push_pool"],
                        paths["push_test"],
                        chains,
                        train,
                        test,
                        seed,
                        config.settings,
                    )
                else:
                    args = (
                        part,
                        paths[f"{part}_pool"],
                        paths[f"{part}_test"],
                        (),
                        train,
                        test,
                        seed,
                        config.settings,
                    )
                tasks.append((key, args))
            if config.chain_train:
                args = (
                    "chained",
                    paths["push_pool"],
                    paths["chain_train"],
                    chains,
                    _draw(config, "push", scale, trial),
                    test,
                    seed,
                    config.settings,
                )
                tasks.append((f"chained.x{scale:g}.t{trial:03d}.{chained_tag}", args))
    return tasks


def modular_task(
    part: str,
    train: str,
    test: str,
    chains: tuple[tuple[int, str], ...],
    train_rows: list[int],
    test_rows: list[int],
    seed: int,
    settings: TrialSettings,
) -> dict[str, Any]:
    """One study task (Dask workers import it): a push, chained or skill trial, tagged.

    For ``part="chained"``, `test` is the path of the added training pushes
    (`chain_trained_trial`).
    """
    if part == "push":
        record = push_trial(train, test, chains, train_rows, test_rows, seed, settings)
    elif part == "chained":
        record = chain_trained_trial(train, test, chains, train_rows, test_rows, seed, settings)
    else:
        record = skill_trial(part, train, test, train_rows, test_rows, seed, settings)
    return {**record, "part": part, "n_train": len(train_rows), "test_rows": list(test_rows)}


# ------------------------------------------------------------------ summaries
def _stat(values: list[float]) -> tuple[float, float]:
    """Mean over trials and its 95 % half-width."""
    return float(np.mean(values)), mean_halfwidth(values)


def _by(records: list[dict[str, Any]], part: str) -> dict[int, list[dict[str, Any]]]:
    """Records of `part` grouped by training size."""
    out: dict[int, list[dict[str, Any]]] = {}
    for r in records:
        if r["part"] == part:
            out.setdefault(int(r["n_train"]), []).append(r)
    return dict(sorted(out.items()))


def summarise_backward(records: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """One row per (training size, push model): o1's effect errors under the hand's push.

    Returns:
        Rows with ``n_train``, ``model``, ``trials``, ``along_cm`` / ``off_cm`` (mean
        absolute error of dy and dx) and ``turn_rad`` with their ``*_ci`` half-widths,
        ``nlpd`` (summed over the three effects), ``coverage90``, and
        ``reaction_mm`` (the hand's mean deviation from its commanded end in training).
    """
    rows = []
    for n, rs in _by(records, "push").items():
        for model in PUSH_MODELS:
            err = [
                np.abs(np.array(r["hand"][model]["mean"]) - np.array(r["hand"]["true"])).mean(0)
                for r in rs
            ]
            along, along_ci = _stat([100 * e[1] for e in err])
            off, off_ci = _stat([100 * e[0] for e in err])
            turn, turn_ci = _stat([e[2] for e in err])
            rows.append(
                {
                    "n_train": n,
                    "model": model,
                    "trials": len(rs),
                    "along_cm": along,
                    "along_ci": along_ci,
                    "off_cm": off,
                    "off_ci": off_ci,
                    "turn_rad": turn,
                    "turn_ci": turn_ci,
                    "nlpd": float(np.mean([sum(r["hand"][model]["nlpd"]) for r in rs])),
                    "coverage90": float(np.mean([r["hand"][model]["coverage"] for r in rs])),
                    "reaction_mm": float(np.mean([r["reaction_mm"] for r in rs])),
                }
            )
    return rows


def _coverage(true: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """(K,) fraction of the (off, along) coordinates of each object inside its interval."""
    inside = (lo[..., :2] <= true[..., :2]) & (true[..., :2] <= hi[..., :2])
    return inside.mean(axis=(0, 2))


def summarise_two_objects(records: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """One row per (training size, model, object, axis) of the two-object test scenes.

    Returns:
        Rows with ``n_train``, ``model`` (``"modular"`` or ``"monolithic"``), ``object``
        (1-based), ``axis`` (``"along"``, ``"off"``), ``trials``, ``error_cm`` and
        ``error_ci``, ``coverage90`` of the object's (off, along) intervals, and
        ``still_motion_cm``: the mean predicted |along| motion of objects that truly moved
        less than 1 cm (NaN when none did).
    """
    rows = []
    for n, rs in _by(records, "push").items():
        for model in ("modular", "monolithic"):
            per: dict[tuple[int, str], list[float]] = {}
            cover: dict[int, list[float]] = {}
            still: dict[int, list[float]] = {}
            for r in rs:
                true = np.array(r["two"]["true"])
                pred = r["two"][model]
                mean = np.array(pred["mean"])
                err = np.abs(mean - true).mean(0)  # (K, 3)
                cov = _coverage(true, np.array(pred["lo"]), np.array(pred["hi"]))
                for k in range(true.shape[1]):
                    per.setdefault((k, "along"), []).append(100 * err[k, 1])
                    per.setdefault((k, "off"), []).append(100 * err[k, 0])
                    cover.setdefault(k, []).append(float(cov[k]))
                    put = np.linalg.norm(true[:, k, :2], axis=1) < _STILL
                    still.setdefault(k, []).extend((100 * np.abs(mean[put, k, 1])).tolist())
            for (k, axis), values in per.items():
                e, ci = _stat(values)
                rows.append(
                    {
                        "n_train": n,
                        "model": model,
                        "object": k + 1,
                        "axis": axis,
                        "trials": len(rs),
                        "error_cm": e,
                        "error_ci": ci,
                        "coverage90": float(np.mean(cover[k])),
                        "still_motion_cm": float(np.mean(still[k])) if still[k] else math.nan,
                    }
                )
    return rows


def summarise_skills(records: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """One row per (skill, training size, model, case) of the pick and place tests.

    Cases: ``"all"``, ``"succeeded"`` (lifted, placed) and ``"failed"``; for records that
    carry the simulator's ``"slipped"`` flags (picks, see `run`), the failed picks split
    into ``"slipped"`` (closed on but too heavy to hold: no geometric feature sees a mass)
    and ``"not grasped"`` (too wide for the span).

    Returns:
        Rows with ``skill``, ``n_train``, ``model``, ``case``, ``n`` (test cases over all
        trials), ``predicted_cm`` and ``true_cm`` (mean norm of the predicted and the
        observed displacement), ``error_cm`` and its ``error_ci`` over trials (mean norm of
        the position error), ``turn_rad`` (mean absolute turn error), ``nlpd`` and
        ``coverage90`` (all cases only) and, for picks, ``misjudged`` (cases whose
        predicted lift is on the other side of half the lift from the observed one).
    """
    rows = []
    for skill in ("pick", "place"):
        for n, rs in _by(records, skill).items():
            for model in SKILL_MODELS:
                for case in ("all", "succeeded", "failed", "slipped", "not grasped"):
                    pred_norm, true_norm, turn, per_trial = [], [], [], []
                    misjudged = 0
                    for r in rs:
                        true = np.array(r["true"])
                        mean = np.array(r[model]["mean"])
                        ok = np.array(r["success"], dtype=bool)
                        slipped = np.array(r.get("slipped", np.zeros_like(ok)), dtype=bool)
                        sel = {
                            "all": np.ones_like(ok),
                            "succeeded": ok,
                            "failed": ~ok,
                            "slipped": ~ok & slipped,
                            "not grasped": ~ok & ~slipped,
                        }[case]
                        if case in ("slipped", "not grasped") and "slipped" not in r:
                            continue
                        if not sel.any():
                            continue
                        pred_norm += np.linalg.norm(mean[sel, :2], axis=1).tolist()
                        true_norm += np.linalg.norm(true[sel, :2], axis=1).tolist()
                        err = np.linalg.norm(mean[sel, :2] - true[sel, :2], axis=1)
                        per_trial.append(float(100 * err.mean()))
                        turn += np.abs(mean[sel, 2] - true[sel, 2]).tolist()
                        half = 0.5 * np.abs(true[ok, 0]).mean() if ok.any() else math.inf
                        misjudged += int(((np.abs(mean[sel, 0]) > half) != ok[sel]).sum())
                    if not per_trial:
                        continue
                    e, ci = _stat(per_trial)
                    row: dict[str, Any] = {
                        "skill": skill,
                        "n_train": n,
                        "model": model,
                        "case": case,
                        "n": len(pred_norm),
                        "predicted_cm": 100 * float(np.mean(pred_norm)),
                        "true_cm": 100 * float(np.mean(true_norm)),
                        "error_cm": e,
                        "error_ci": ci,
                        "turn_rad": float(np.mean(turn)),
                        "nlpd": (
                            float(np.mean([sum(r[model]["nlpd"]) for r in rs]))
                            if case == "all"
                            else math.nan
                        ),
                        "coverage90": (
                            float(np.mean([r[model]["coverage"] for r in rs]))
                            if case == "all"
                            else math.nan
                        ),
                        "misjudged": misjudged if skill == "pick" else "",
                    }
                    rows.append(row)
    return rows


def summarise_chains(records: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """One row per (training, training size, chain length, object) of the test chains.

    Returns:
        Rows with ``training`` (`TRAININGS`: the push model of the two-object scenes, or
        the extension's with the three-object rows added), ``n_train`` (two-object
        pushes), ``n_objects``, ``object`` (1-based place in the chain),
        ``trials``, ``error_cm`` / ``error_ci`` (distance between the mean predicted and
        the observed final position), ``along_cm``, ``coverage90`` / ``coverage_ci`` (of
        the object's off and along intervals), ``touched`` (fraction of samples in which
        the object was pushed), ``moved`` (fraction of scenes in which it truly moved by
        1 cm or more) and ``seconds`` (mean time of one chained prediction).
    """
    rows = []
    for part, training in TRAININGS.items():
        rows += _chain_rows(records, part, training)
    return rows


def _chain_rows(records: list[dict[str, Any]], part: str, training: str) -> list[dict[str, Any]]:
    rows = []
    for n, rs in _by(records, part).items():
        lengths = sorted({int(k) for r in rs for k in r["chains"]})
        for k in lengths:
            recs = [r["chains"][str(k)] for r in rs]
            for obj in range(k):
                err, along, cov, touched, moved = [], [], [], [], []
                for c in recs:
                    true, mean = np.array(c["true"]), np.array(c["mean"])
                    d = np.linalg.norm(mean[:, obj, :2] - true[:, obj, :2], axis=1)
                    err.append(100 * float(d.mean()))
                    along.append(100 * float(np.abs(mean[:, obj, 1] - true[:, obj, 1]).mean()))
                    cov.append(float(_coverage(true, np.array(c["lo"]), np.array(c["hi"]))[obj]))
                    touched.append(float(np.mean(np.array(c["touched"])[:, obj])))
                    moved.append(float(np.mean(np.linalg.norm(true[:, obj, :2], axis=1) >= _STILL)))
                e, e_ci = _stat(err)
                c90, c_ci = _stat(cov)
                rows.append(
                    {
                        "training": training,
                        "n_train": n,
                        "n_objects": k,
                        "object": obj + 1,
                        "trials": len(recs),
                        "error_cm": e,
                        "error_ci": e_ci,
                        "along_cm": float(np.mean(along)),
                        "coverage90": c90,
                        "coverage_ci": c_ci,
                        "touched": float(np.mean(touched)),
                        "moved": float(np.mean(moved)),
                        "seconds": float(np.mean([np.mean(c["seconds"]) for c in recs])),
                    }
                )
    return rows


def _fmt(rows: list[dict[str, Any]], columns: list[str]) -> str:
    return markdown_table(rows, columns, digits=3)


def _report(
    config: ModularStudyConfig,
    backward: list[dict[str, Any]],
    two: list[dict[str, Any]],
    skills: list[dict[str, Any]],
    chains: list[dict[str, Any]],
) -> str:
    fwd, bwd = THESIS["backward_along_cm"]
    mod, mono = THESIS["modular_along_cm"], THESIS["monolithic_along_cm"]
    md = [
        "# Chapter 6: modular transition models",
        "",
        f"{config.trials} trials per training size; each trial fits on its own draw of the "
        f"training pool and predicts its own {config.test_scenes} test scenes per skill. "
        "`*_ci`: half-width of the 95 % Student-t interval of the mean over trials; "
        f"coverage: fraction of observations inside the central {LEVEL:.0%} interval.",
        "",
        "## The backward component (o1 under the hand's push)",
        "",
        f"Thesis: push-along error {fwd} cm without, {bwd} cm with the backward component. "
        "`reaction_mm`: the simulated hand's mean deviation from its commanded end point, "
        "the signal the backward component learns.",
        "",
        _fmt(
            backward,
            [
                "n_train",
                "model",
                "trials",
                "along_cm",
                "along_ci",
                "off_cm",
                "off_ci",
                "turn_rad",
                "nlpd",
                "coverage90",
                "reaction_mm",
            ],
        ),
        "",
        "## Modular against monolithic (two-object scenes)",
        "",
        f"Thesis, along the push: modular {mod[0]} vs monolithic {mono[0]} cm for o1, "
        f"{mod[1]} vs {mono[1]} cm for o2; the monolithic model was better off the axis. "
        "`still_motion_cm`: mean predicted motion along the push of objects that truly "
        "moved less than 1 cm.",
        "",
        _fmt(
            two,
            [
                "n_train",
                "model",
                "object",
                "axis",
                "trials",
                "error_cm",
                "error_ci",
                "coverage90",
                "still_motion_cm",
            ],
        ),
        "",
        "## Pick and place",
        "",
        "Effects in the action frame: up (along the lift or the lowering), x, the turn. "
        "Thesis: cases that cannot be picked are predicted at about zero displacement; two "
        "graspable objects were predicted not pickable.",
        "",
        _fmt(
            skills,
            [
                "skill",
                "n_train",
                "model",
                "case",
                "n",
                "predicted_cm",
                "true_cm",
                "error_cm",
                "error_ci",
                "turn_rad",
                "nlpd",
                "coverage90",
                "misjudged",
            ],
        ),
        "",
        "## Chains of 3 to 5 objects",
        "",
        "The monolithic model cannot predict these scenes (another number of objects); the "
        "modular model chains its push model through them. `training`: the push model of the "
        "two-object scenes (the thesis's), or the same model with the hand and object rows of "
        f"{config.chain_train} three-object `chain_3` pushes added (so the 4- and 5-object "
        "chains are longer than any it saw). `touched`: share of samples in which the object "
        "was pushed; `moved`: share of scenes in which it truly moved by 1 cm or more.",
        "",
        _fmt(
            chains,
            [
                "training",
                "n_train",
                "n_objects",
                "object",
                "trials",
                "error_cm",
                "error_ci",
                "along_cm",
                "coverage90",
                "coverage_ci",
                "touched",
                "moved",
                "seconds",
            ],
        ),
        "",
    ]
    return "\n".join(md)


def _add_pick_causes(records: list[dict[str, Any]], paths: dict[str, str]) -> None:
    """Copy the simulator's slip flags of the test picks into the pick records (in place)."""
    from probaff.data.store import load_skill_dataset

    slipped = load_skill_dataset(paths["pick_test"])["slipped"]
    for r in records:
        if r["part"] == "pick":
            r["slipped"] = slipped[r["test_rows"]].astype(bool).tolist()


def run(config: ModularStudyConfig) -> dict[str, Any]:
    """Run (or resume) the study and write its tables and figures.

    Args:
        config: Study settings.

    Returns:
        ``{"backward", "two_objects", "skills", "chains": summary rows, "files": paths}``.

    Raises:
        InputError: For an invalid config.
    """
    config.validate()
    out = Path(config.out)
    paths = _datasets(config, out)
    records = run_tasks(
        modular_task,
        _tasks(config, paths),
        ResultStore(out / "tasks"),
        workers=config.workers,
        scheduler=config.scheduler,
        progress=config.progress,
        desc="chapter 6 trials",
    )
    _add_pick_causes(records, paths)
    backward = summarise_backward(records)
    two = summarise_two_objects(records)
    skills = summarise_skills(records)
    chains = summarise_chains(records)
    files = [
        write_csv(out / "backward.csv", backward),
        write_csv(out / "two_objects.csv", two),
        write_csv(out / "pick_place.csv", skills),
        write_csv(out / "chains.csv", chains),
    ]
    from probaff.studies.modular_plots import study_figures

    files += study_figures(config, paths, records, two, chains, backward, skills, out)
    atomic_write_text(out / "summary.md", _report(config, backward, two, skills, chains))
    files.append(str(out / "summary.md"))
    return {
        "backward": backward,
        "two_objects": two,
        "skills": skills,
        "chains": chains,
        "files": files,
    }


def smoke_config(out: str) -> ModularStudyConfig:
    """The smoke-sized config writing to `out`."""
    return dataclasses.replace(ModularStudyConfig(out=out), **SMOKE_OVERRIDES)


DEMO_OVERRIDES: dict[str, Any] = {
    "push_train": 48,
    "pick_train": 32,
    "place_train": 16,
    "test_scenes": 3,
    "trials": 1,
    "scales": (1.0,),
    "chain_lengths": (3,),
    "chain_train": 0,
    "settings": TrialSettings(chain_samples=64, em_iterations=3, gp_max_iter=30),
}
"""The demo's sizes: one small trial of every part, a three-object chain among them."""


def demo(out: str | Path, *, seed: int = 0, progress: bool = True) -> dict[str, Any]:
    """A small run of the study: a pick, a place and a chained three-object push, drawn.

    ``probaff demo`` calls it. It fits the per-skill models on a few dozen samples of each
    skill, predicts three test scenes of each and prints one line per skill.

    Args:
        out: Output folder (datasets, records, ``tabletop_predictions.png``,
            ``sideview_predictions.png`` and the tables).
        seed: Seed of the datasets and the fits.
        progress: Show the generators' progress bars.

    Returns:
        `run`'s summary.
    """
    config = dataclasses.replace(
        ModularStudyConfig(out=str(out), seed=seed, progress=progress), **DEMO_OVERRIDES
    )
    summary = run(config)
    chain = [r for r in summary["chains"] if r["n_objects"] == 3]
    errors = " / ".join(f"{r['error_cm']:.1f}" for r in chain)
    print(f"three-object chain: position error per object {errors} cm (o1 / o2 / o3)")
    for r in summary["skills"]:
        if r["model"] == "forward" and r["case"] != "all":
            print(
                f"{r['skill']} ({r['case']}, {r['n']} cases): predicted displacement "
                f"{r['predicted_cm']:.1f} cm, observed {r['true_cm']:.1f} cm"
            )
    return summary
