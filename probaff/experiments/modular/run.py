"""The chapter 6 study: modular transition models for push, pick and place, against a monolith.

`run` generates (or resumes) the datasets under ``out/data/``, all with the hand of
``config.hand`` (compliant by default: a Cartesian impedance that lags and deflects against
resistance, whose deviation from its command, the reaction, the datasets record along the
path; `probaff.sim.pusher`): a pool of tabletop pushes of ``config.push_scene``
(``modular_push``: two cuboids, a 35 cm push, the second up to 30 cm sideways;
``resistance_push``: heavy boxes pushed into others), of
side-view ``pick`` and ``place`` skills, and held-out test sets of each and of the
``chain_3`` .. ``chain_5`` rows of cuboids. Every (part, training-set scale, trial) is one
resumable task (`probaff.experiments.modular.trials`): trial t draws its training rows from
the pool (``scale x`` the thesis's 221 push, 168 pick and 20 place samples) and predicts its
own slice of ``test_scenes`` test scenes, so trials are independent repetitions and the
tables give 95 % Student-t intervals of the mean over trials.

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
* ``stepped.csv`` and ``stepped_paired.csv`` (with ``settings.stepped``): the stepped push
  model's rollouts of the two-object test scenes with and without its backward components,
  beside the whole-push chain, and the paired differences; ``stepped_calibration.csv``: its
  components' held-out NLPD and 90 % coverage;
* figures: predicted against observed motion on the table and in the side view, error
  against chain position, modular against monolithic, and errors against training size.
"""

from __future__ import annotations

from typing import Any

from probaff.data import GenerateConfig
from probaff.data.store import load_skill_dataset
from probaff.experiments.base import StudyRun
from probaff.experiments.modular.config import ModularStudyConfig
from probaff.experiments.modular.figures import study_figures
from probaff.experiments.modular.report import (
    report,
    summarise_backward,
    summarise_chains,
    summarise_skills,
    summarise_stepped,
    summarise_stepped_calibration,
    summarise_stepped_paired,
    summarise_two_objects,
)
from probaff.experiments.modular.trials import (
    TrialData,
    TrialSettings,
    chain_trained_trial,
    push_trial,
    skill_trial,
)

__all__ = ["modular_task", "run"]

_VERSION = 7  # 2: path reaction, hand mode; 3: SMEM; 4: coroutines; 5: fused; 6: l1; 7: stepped
_TEST_SEED_OFFSET = 1000  # test datasets use seed + this, so they never share a draw
_WORLD = (
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


def _dataset(study: StudyRun[ModularStudyConfig], scene: str, n: int, test: bool) -> str:
    """Generate (or resume) `n` samples of `scene` under ``out/data/``; return the folder."""
    seed = study.config.seed + (_TEST_SEED_OFFSET if test else 0)
    hand = study.config.hand
    name = f"{scene}_{hand}_n{n}_s{seed}"
    study.dataset(GenerateConfig(scene=scene, n=n, seed=seed, hand=hand), name)
    return str(study.out / "data" / name)


def _datasets(study: StudyRun[ModularStudyConfig]) -> dict[str, str]:
    """Every dataset of the study: training pools, test sets and chains, by name."""
    config = study.config
    top = max(config.scales)
    n_test = config.test_scenes * config.trials
    paths = {}
    for part, scene in (("push", config.push_scene), ("pick", "pick"), ("place", "place")):
        paths[f"{part}_pool"] = _dataset(study, scene, config.train_size(part, top), False)
        paths[f"{part}_test"] = _dataset(study, scene, n_test, True)
    for k in config.chain_lengths:
        paths[f"chain_{k}"] = _dataset(study, f"chain_{k}", n_test, True)
    if config.chain_train:
        paths["chain_train"] = _dataset(study, "chain_3", config.chain_train, False)
    return paths


def _tasks(config: ModularStudyConfig, paths: dict[str, str]) -> list[tuple[str, tuple[Any, ...]]]:
    """Every (part, scale, trial) task, keyed by the settings that shape it."""
    # The extension does not shape the thesis's parts.
    world = (f"scenes/{config.push_scene}.yaml", *_WORLD)
    tag = config.tag(exclude=("chain_train",), world=world, version=_VERSION)
    chained_tag = config.tag(world=world, version=_VERSION)
    chains = tuple((k, paths[f"chain_{k}"]) for k in config.chain_lengths)
    tasks: list[tuple[str, tuple[Any, ...]]] = []
    for scale in config.scales:
        for trial in range(config.trials):
            test = list(range(trial * config.test_scenes, (trial + 1) * config.test_scenes))
            seed = config.seed + 7919 * trial
            for part in ("push", "pick", "place"):
                data = TrialData(
                    paths[f"{part}_pool"],
                    paths[f"{part}_test"],
                    config.draw(part, scale, trial),
                    test,
                    seed,
                    chains if part == "push" else (),
                )
                key = f"{part}.x{scale:g}.t{trial:03d}.{tag}"
                tasks.append((key, (part, data, config.settings)))
            if config.chain_train:
                draw = config.draw("push", scale, trial)
                data = TrialData(paths["push_pool"], paths["chain_train"], draw, test, seed, chains)
                key = f"chained.x{scale:g}.t{trial:03d}.{chained_tag}"
                tasks.append((key, ("chained", data, config.settings)))
    return tasks


def modular_task(part: str, data: TrialData, settings: TrialSettings) -> dict[str, Any]:
    """One study task (Dask workers import it): a push, chained or skill trial, tagged.

    For ``part="chained"``, ``data.test`` is the path of the added training pushes
    (`chain_trained_trial`).
    """
    if part == "push":
        record = push_trial(data, settings)
    elif part == "chained":
        record = chain_trained_trial(data, settings)
    else:
        record = skill_trial(part, data, settings)
    n_train, test_rows = len(data.train_rows), list(data.test_rows)
    return {**record, "part": part, "n_train": n_train, "test_rows": test_rows}


def _add_pick_causes(records: list[dict[str, Any]], paths: dict[str, str]) -> None:
    """Copy the simulator's slip flags of the test picks into the pick records (in place)."""
    slipped = load_skill_dataset(paths["pick_test"])["slipped"]
    for r in records:
        if r["part"] == "pick":
            r["slipped"] = slipped[r["test_rows"]].astype(bool).tolist()


def run(config: ModularStudyConfig) -> dict[str, Any]:
    """Run (or resume) the study and write its tables and figures.

    Args:
        config: Study settings.

    Returns:
        ``{"backward", "two_objects", "skills", "chains": summary rows, "stepped": its
        ``"rows"``, ``"paired"`` and ``"calibration"`` rows (empty without
        ``settings.stepped``), "files": paths}``.

    Raises:
        InputError: For an invalid config.
    """
    study = StudyRun(config, ModularStudyConfig)
    paths = _datasets(study)
    records = study.tasks(modular_task, _tasks(study.config, paths), desc="chapter 6 trials")
    _add_pick_causes(records, paths)
    backward = summarise_backward(records)
    two = summarise_two_objects(records)
    skills = summarise_skills(records)
    chains = summarise_chains(records)
    study.table("backward.csv", backward)
    study.table("two_objects.csv", two)
    study.table("pick_place.csv", skills)
    study.table("chains.csv", chains)
    stepped = {
        "rows": summarise_stepped(records),
        "paired": summarise_stepped_paired(records),
        "calibration": summarise_stepped_calibration(records),
    }
    if stepped["rows"]:
        study.table("stepped.csv", stepped["rows"])
        study.table("stepped_paired.csv", stepped["paired"])
        study.table("stepped_calibration.csv", stepped["calibration"])
    tables = {"backward": backward, "two": two, "skills": skills, "chains": chains}
    for path in study_figures(study.config.settings, paths, records, tables, study.out):
        study.figure(path)
    study.summary(report(study.config, backward, two, skills, chains, stepped))
    return {
        "backward": backward,
        "two_objects": two,
        "skills": skills,
        "chains": chains,
        "stepped": stepped,
        "files": study.files,
    }
