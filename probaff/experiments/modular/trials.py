"""One trial of the chapter 6 study: fit per-skill models on a training draw, predict tests.

A trial is a study task (`probaff.eval.tasks.run_tasks`): its arguments are dataset paths and
row indices, so Dask workers load the datasets themselves (once per process) and a record is
plain JSON. Two kinds:

* `push_trial`: on tabletop pushes (a two-object push scene: `modular_push`, or
  `resistance_push` where the hand meets resistance), fit the push model without and with
  its backward component and as a mixture of experts, the monolithic two-object GP
  (`MonolithicTransitionModel` on `scene_features`) and, with ``settings.stepped``, the
  stepped push model (`probaff.features.ch6_stepped.fit_stepped`, rolled out step by step).
  Predict the hand's effect on o1 of every test push, both objects of every test scene
  (modular chains, stepped rollouts with and without the backward components, and the
  monolithic GP) and every test chain of 3, 4, 5 objects.
* `skill_trial`: on side-view picks or places, fit the skill's model (GP, GP with the
  backward component, mixture) and predict each test case's effect, with the simulator's
  verdict (lifted, placed) to split the cases.

Effects are in the action frame: ``(dx, dy, rz)`` for pushes (off the push, along it, the
turn), ``(up, x, turn)`` for picks and places (`SIDEVIEW_EFFECT_COLUMNS`). Whole-scene
displacements are ``(off, along, turn)`` in the hand's action frame (`scene_effects`).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field, replace
from functools import cache
from typing import Any

import numpy as np
import torch
from torch.distributions import Distribution

from probaff._checks import check_bool, check_count
from probaff._threads import limit_threads
from probaff.data.schema import PushDataset
from probaff.data.skill_schema import SkillDataset
from probaff.data.store import load_dataset, load_skill_dataset
from probaff.errors import InputError
from probaff.eval.metrics import interval_coverage, nlpd
from probaff.experiments.config_cli import option_flags
from probaff.features import INTERACTION_GROUPS
from probaff.features.ch6_pick import SIDEVIEW_EFFECT_COLUMNS, pick_interactions
from probaff.features.ch6_push import (
    PLANAR_EFFECT_COLUMNS,
    REACTIONS,
    PushInteractions,
    push_interactions,
)
from probaff.features.ch6_scenes import push_scenes, scene_effects, scene_features
from probaff.features.ch6_stepped import fit_stepped, link_training_rows
from probaff.features.ch6_steps import (
    StepOptions,
    StepTrajectories,
    check_step_length,
    hand_steps,
    step_trajectories,
)
from probaff.features.chain_geometry import Ch6Geometry
from probaff.models import (
    TRANSITION_GP,
    EMOptions,
    GPOptions,
    ModularTransitionModel,
    MonolithicTransitionModel,
    SkillTransitionModel,
    fit_transition,
)
from probaff.models.transitions.stepped_transition import (
    SteppedModelOptions,
    SteppedPushModel,
    rollout,
)
from probaff.models.transitions.transition_base import check_transition_gp

__all__ = [
    "LEVEL",
    "PUSH_MODELS",
    "SKILL_MODELS",
    "STEPPED_MODELS",
    "TrialData",
    "TrialSettings",
    "chain_trained_trial",
    "geometry_for",
    "push_trial",
    "skill_rows",
    "skill_trial",
    "stepped_calibration",
]

LEVEL = 0.9
"""Probability of the central intervals whose coverage the study reports."""

PUSH_MODELS = ("forward", "backward", "mixture")
"""Push models fitted on the interaction rows: GP, GP with the backward component, mixture."""

SKILL_MODELS = ("forward", "backward", "mixture")
"""Pick and place models: the same three."""

STEPPED_MODELS = ("stepped_forward", "stepped_planned", "stepped_backward")
"""Stepped rollouts of a two-object test scene: the forward models of the stepped model with
the backward components (``stepped_backward``) and without them (``stepped_forward``: the
same forward models, the hand kept on its command), and forward models fitted on the
planned actions, as a rollout without reactions places the hand (``stepped_planned``: the
fair baseline of the backward components)."""

STEPPED_COMPONENTS = ("hand_forward", "hand_backward", "link_forward", "link_backward")
"""The stepped model's components, whose held-out calibration a trial records."""

_Z90 = 1.6448536269514722  # standard normal quantile of 0.95


@dataclass(frozen=True)
class TrialSettings:
    """What shapes a trial besides its data.

    Attributes:
        push_groups: Interaction feature groups (`INTERACTION_GROUPS` names) the push
            models read; the geometry's motion columns are always added.
        skill_groups: The groups the pick and place models read. A pick's outcome hangs
            on the object's width against the gripper's span, which only the shape and
            contact groups see.
        chain_samples: Samples of every chained prediction.
        n_experts: Experts of the mixture option.
        em: The EM fit of the mixture option (`probaff.models.EMOptions`; flag
            ``--em-max-iter``); its seed is the trial's.
        gp: The GP settings of every transition model (`probaff.models.GPOptions`; flags
            ``--gp-max-iter`` and ``--gp-lengthscale-prior``): `TRANSITION_GP` with the
            length-scale prior on.
        chain_backward: Chain with the push model with the backward component (else
            without).
        reaction: What the push models' backward component predicts of the hand's
            deviation from its command (`probaff.features.ch6_push.REACTIONS`): ``"path"``
            (its end point and its mean along the push, the default) or ``"end"`` (the end
            point alone).
        stepped: Also fit the stepped push model and roll it out on the two-object test
            scenes (`STEPPED_MODELS`).
        step_length: Commanded hand travel per step of the stepped model (m); it must
            divide the push (0.025 cuts a 35 cm push into 14 steps).
    """

    push_groups: tuple[str, ...] = ("pose", "action")
    skill_groups: tuple[str, ...] = ("shape", "pose", "contact", "action")
    chain_samples: int = 256
    n_experts: int = 2
    em: EMOptions = field(
        default=EMOptions(max_iter=10),
        metadata=option_flags(("max_iter",)),
    )
    gp: GPOptions = field(
        default=replace(TRANSITION_GP, lengthscale_prior=True),
        metadata=option_flags(("max_iter", "lengthscale_prior")),
    )
    chain_backward: bool = True
    reaction: str = "path"
    stepped: bool = True
    step_length: float = 0.025

    def __post_init__(self) -> None:
        """Raise `InputError` for a bad count, group list, reaction or step length."""
        check_count("chain_samples", self.chain_samples, minimum=2)
        check_bool("stepped", self.stepped)
        check_step_length(self.step_length)
        if self.reaction not in REACTIONS:
            raise InputError(f"reaction must be one of {list(REACTIONS)}, got {self.reaction!r}.")
        check_count("n_experts", self.n_experts)
        if not isinstance(self.em, EMOptions):
            raise InputError(f"em must be an EMOptions, got {type(self.em).__name__}.")
        check_transition_gp(self.gp)
        geometry_for(self.push_groups, "push_groups")
        geometry_for(self.skill_groups, "skill_groups")


def geometry_for(groups: tuple[str, ...], name: str = "groups") -> Ch6Geometry:
    """The chapter 6 geometry keeping the feature columns of `groups`, plus the motion columns.

    Args:
        groups: `INTERACTION_GROUPS` names, each at most once.
        name: The argument's name for error messages (``"push_groups"``).

    Raises:
        InputError: For no group, an unknown group name or a group named twice.
    """
    if isinstance(groups, str) or not groups:
        raise InputError(
            f"{name} must be a non-empty list of feature groups from "
            f"{list(INTERACTION_GROUPS)}, got {groups!r}."
        )
    unknown = [g for g in groups if g not in INTERACTION_GROUPS]
    if unknown:
        raise InputError(
            f"{name}: unknown feature groups {unknown}; choose from {list(INTERACTION_GROUPS)}."
        )
    twice = sorted({g for g in groups if groups.count(g) > 1})
    if twice:
        raise InputError(f"{name} names {twice} more than once; give each feature group once.")
    columns = [c for g in groups for c in range(*INTERACTION_GROUPS[g].indices(10**6))]
    return Ch6Geometry(columns=columns)


@dataclass(frozen=True)
class TrialData:
    """The data of one trial: its datasets, the rows it fits and predicts, its seed.

    Attributes:
        train: Path of the training dataset (the pool of the trial's part).
        test: Path of the test dataset of the same scene; for `chain_trained_trial`, the
            added training pushes.
        train_rows: Rows of `train` to fit on (pushes, for push datasets).
        test_rows: Rows of `test` (and of every chain dataset) to predict.
        seed: Seed of the mixture's EM and of the chains' samples.
        chains: ``(K, path)`` of test datasets of K-object chains (push trials).
    """

    train: str
    test: str
    train_rows: list[int]
    test_rows: list[int]
    seed: int
    chains: tuple[tuple[int, str], ...] = ()


@cache
def _push_dataset(path: str) -> PushDataset:
    return load_dataset(path)


@cache
def _skill_dataset(path: str) -> SkillDataset:
    return load_skill_dataset(path)


@cache
def _push_rows(
    path: str, groups: tuple[str, ...], reaction: str
) -> tuple[PushInteractions, PushInteractions]:
    ds, geo = _push_dataset(path), geometry_for(groups)
    return push_interactions(ds, "hand", geometry=geo, reaction=reaction), push_interactions(
        ds, "objects", geometry=geo, reaction=reaction
    )


def _reaction_mm(rows: PushInteractions, use: np.ndarray) -> dict[str, float]:
    """Mean over the used hand rows of the end deviation and of the largest along the path."""
    end = 1000 * float(np.linalg.norm(rows.reaction[use][:, :2], axis=1).mean())
    path = rows.reaction_path[use]
    peak = 1000 * float(np.linalg.norm(path, axis=2).max(axis=1).mean()) if path.size else 0.0
    return {"reaction_mm": end, "reaction_path_mm": peak}


@cache
def skill_rows(path: str, skill: str, groups: tuple[str, ...]) -> Any:
    """The interaction rows of the skill dataset at `path` with the feature `groups`."""
    ds, geo = _skill_dataset(path), geometry_for(groups)
    if skill == "pick":
        return pick_interactions(ds, geometry=geo)
    from probaff.features.ch6_place import place_interactions

    return place_interactions(ds, geometry=geo)


def _moments(dist: Distribution) -> tuple[np.ndarray, np.ndarray]:
    return dist.mean.detach().numpy(), dist.variance.detach().sqrt().numpy()


def _scores(dist: Distribution, y: np.ndarray) -> dict[str, Any]:
    """Mean, sd, NLPD and interval coverage of a predictive distribution over `y (N, E)`."""
    mean, sd = _moments(dist)
    target = torch.as_tensor(y, dtype=torch.float64)
    return {
        "mean": mean.tolist(),
        "sd": sd.tolist(),
        "nlpd": nlpd(dist, target).tolist(),
        "coverage": interval_coverage(dist, target, LEVEL).tolist(),
    }


def _fit_skill_models(
    skill: str, X: np.ndarray, Y: np.ndarray, R: np.ndarray, settings: TrialSettings, seed: int
) -> tuple[dict[str, SkillTransitionModel], dict[str, float]]:
    """The three models of `SKILL_MODELS` fitted on one training draw, and their fit times."""
    models: dict[str, SkillTransitionModel] = {}
    seconds: dict[str, float] = {}
    for name in SKILL_MODELS:
        t0 = time.perf_counter()
        if name == "mixture":
            model = SkillTransitionModel(
                skill,
                kind="mixture",
                backward=False,
                n_experts=settings.n_experts,
                gp=settings.gp,
            )
            fit_transition(model, X, Y, options=settings.em, seed=seed)
        else:
            backward = name == "backward"
            model = SkillTransitionModel(skill, backward=backward, gp=settings.gp)
            fit_transition(model, X, Y, R if backward else None)
        models[name] = model
        seconds[name] = time.perf_counter() - t0
    return models, seconds


def _in_action(T_a: np.ndarray, d: np.ndarray) -> np.ndarray:
    """Planar displacements `d (..., K, 3)` (world dx, dy, dyaw) in the frame A's (x, y)."""
    R = T_a[:2, :2]
    xy = d[..., :2] @ R  # row vectors: (R^T v)^T
    return np.concatenate([xy, d[..., 2:]], axis=-1)


def _chain_records(
    chain: ModularTransitionModel,
    scenes: Any,
    rows: np.ndarray,
    samples: int,
    seed: int,
    keep: int,
) -> dict[str, Any]:
    """Chained predictions of scenes `rows`: means and intervals in the hand's frame A.

    Returns ``{"mean", "lo", "hi"}`` each (n, K, 3) as lists, ``"touched"`` (n, K) sample
    fractions, ``"seconds"`` per scene, and ``"samples"`` (keep, S, K, 3) world planar final
    poses of the first `keep` scenes, ``"start"`` their start poses, for figures.
    """
    mean, lo, hi, touched, shown, seconds = [], [], [], [], [], []
    for j, i in enumerate(rows):
        scene = scenes.chain_scene(i)
        t0 = time.perf_counter()
        pred = chain.predict_chain(scene, n_samples=samples, seed=seed + j)
        seconds.append(time.perf_counter() - t0)
        d = _in_action(scenes.T_world_action[i], pred.displacement)  # (S, K, 3)
        mean.append(d.mean(0))
        q = np.quantile(d, [(1 - LEVEL) / 2, (1 + LEVEL) / 2], axis=0)
        lo.append(q[0])
        hi.append(q[1])
        touched.append(pred.touched.mean(0))
        if j < keep:
            shown.append(pred.planar)
    return {
        "mean": np.array(mean).tolist(),
        "lo": np.array(lo).tolist(),
        "hi": np.array(hi).tolist(),
        "touched": np.array(touched).tolist(),
        "seconds": seconds,
        "samples": np.array(shown).round(5).tolist(),
    }


def _test_chains(
    chain: ModularTransitionModel, data: TrialData, settings: TrialSettings, keep: int
) -> dict[str, Any]:
    """Per K of ``data.chains``: the truth and the chained predictions of ``data.test_rows``."""
    rows, geo = np.asarray(data.test_rows), geometry_for(settings.push_groups)
    out = {}
    for n_objects, path in data.chains:
        ds = _push_dataset(path)
        scenes = push_scenes(ds, geometry=geo)
        out[str(n_objects)] = {
            "rows": rows.tolist(),
            "true": scene_effects(ds)[rows].reshape(-1, n_objects, 3).tolist(),
            **_chain_records(chain, scenes, rows, settings.chain_samples, data.seed, keep),
        }
    return out


def push_trial(data: TrialData, settings: TrialSettings, keep: int = 2) -> dict[str, Any]:
    """Fit the push models on the training pushes and predict the test scenes.

    Args:
        data: The training push dataset (two cuboids per scene) and its rows, the test
            dataset of the same scene and the chains' (both predicted at ``test_rows``).
        settings: Models and sampling.
        keep: Scenes per test set whose chain samples are kept for figures.

    Returns:
        A JSON-ready record: ``"hand"`` (o1's effect under each of `PUSH_MODELS`: means, sds,
        NLPD and coverage, and the truth), ``"two"`` (both objects' displacement in the hand's
        frame: ``"true"``, ``"modular"`` and ``"monolithic"`` means and intervals),
        ``"chains"`` (per K: truth and modular means and intervals), ``"fit_seconds"``,
        ``"reaction_mm"`` (mean ``|deviation|`` of the hand at its commanded end in the
        training rows), ``"reaction_path_mm"`` (mean of its largest ``|deviation|`` along the
        path) and the counts.
    """
    train, test, train_rows, test_rows = data.train, data.test, data.train_rows, data.test_rows
    seed = data.seed
    with limit_threads(1):
        X, Y, R = _push_training_rows(train, train_rows, settings)
        hand, objects = _push_rows(train, settings.push_groups, settings.reaction)
        use = np.isin(hand.push, train_rows)
        use_o = np.isin(objects.push, train_rows)
        cols = list(PLANAR_EFFECT_COLUMNS)
        models, seconds = _fit_skill_models("push", X, Y, R, settings, seed)

        ds_train, ds_test = _push_dataset(train), _push_dataset(test)
        t0 = time.perf_counter()
        mono = MonolithicTransitionModel(ds_train.n_objects, gp=settings.gp)
        rows = np.asarray(train_rows)
        fit_transition(mono, scene_features(ds_train)[rows], scene_effects(ds_train)[rows])
        seconds["monolithic"] = time.perf_counter() - t0

        test_hand, _ = _push_rows(test, settings.push_groups, settings.reaction)
        t_rows = np.asarray(test_rows)
        pick = np.flatnonzero(np.isin(test_hand.push, t_rows))
        y_hand = test_hand.effect[pick][:, cols]
        x_hand = torch.as_tensor(test_hand.features[pick], dtype=torch.float64)
        record: dict[str, Any] = {
            "hand": {
                "true": y_hand.tolist(),
                **{
                    name: _scores(m.predict(x_hand, skill="push"), y_hand)
                    for name, m in models.items()
                },
            },
            "fit_seconds": seconds,
            **_reaction_mm(hand, use),
            "n_rows": {"hand": int(use.sum()), "objects": int(use_o.sum())},
        }

        geo = geometry_for(settings.push_groups)
        push_model = models["backward" if settings.chain_backward else "forward"]
        chain = ModularTransitionModel({"push": push_model}, geo)
        scenes = push_scenes(ds_test, geometry=geo)
        mdist = mono.predict(scene_features(ds_test)[t_rows])
        m_mean, m_sd = _moments(mdist)
        k = ds_test.n_objects
        record["two"] = {
            "rows": t_rows.tolist(),
            "true": scene_effects(ds_test)[t_rows].reshape(-1, k, 3).tolist(),
            "modular": _chain_records(chain, scenes, t_rows, settings.chain_samples, seed, keep),
            "monolithic": {
                "mean": m_mean.reshape(-1, k, 3).tolist(),
                "lo": (m_mean - _Z90 * m_sd).reshape(-1, k, 3).tolist(),
                "hi": (m_mean + _Z90 * m_sd).reshape(-1, k, 3).tolist(),
            },
        }
        record["chains"] = _test_chains(chain, data, settings, keep)
        if settings.stepped:
            t0 = time.perf_counter()
            frames = scenes.T_world_action[t_rows]
            record["stepped"] = _stepped_record(data, settings, frames, record["two"]["true"])
            seconds["stepped"] = time.perf_counter() - t0
    return record


@cache
def _steps(path: str, groups: tuple[str, ...], step_length: float) -> StepTrajectories:
    ds = _push_dataset(path)
    options = StepOptions(step_length)
    return step_trajectories(ds, options, geometry=geometry_for(groups), reaction=True)


def stepped_calibration(model: SteppedPushModel, test: StepTrajectories) -> dict[str, Any]:
    """Coverage and NLPD per dimension of a stepped model's components on held-out steps.

    Args:
        model: A stepped model fitted with its backward components.
        test: Held-out pushes at their step boundaries, cut with reactions.

    Returns:
        Per component of `STEPPED_COMPONENTS` (that `model` holds): ``"rows"``, and per
        output dimension ``"nlpd"`` and ``"coverage"`` of the central `LEVEL` interval
        (empty lists where no held-out step makes that contact).
    """
    geo = model.geometry
    assert isinstance(geo, Ch6Geometry)
    hand = hand_steps(test, geo)
    t = hand.touches
    rows = {
        "hand_forward": (hand.features[t], hand.effect[t]),
        "hand_backward": (np.concatenate([hand.features, hand.effect], 1), hand.reaction),
    }
    if test.n_objects > 1:
        links = link_training_rows(model, test, hand)
        rows["link_forward"] = (links.features, links.effect)
        rows["link_backward"] = (np.concatenate([links.features, links.effect], 1), links.reaction)
    out: dict[str, Any] = {}
    for name, (x, y) in rows.items():
        if name not in model.models:
            continue
        if len(x) == 0:
            out[name] = {"rows": 0, "nlpd": [], "coverage": []}
            continue
        with torch.no_grad():
            dist = model.models[name].predict(torch.as_tensor(x, dtype=torch.float64))
            target = torch.as_tensor(y, dtype=torch.float64)
            out[name] = {
                "rows": len(x),
                "nlpd": nlpd(dist, target).tolist(),
                "coverage": interval_coverage(dist, target, LEVEL).tolist(),
            }
    return out


def _stepped_record(
    data: TrialData, settings: TrialSettings, T_a: np.ndarray, true: list[Any]
) -> dict[str, Any]:
    """The stepped model fitted on the training pushes and rolled out on the test scenes.

    Args:
        data: The trial's data (`push_trial`'s).
        settings: Its settings.
        T_a: (n, 4, 4) the hand's action frames of the test scenes ``data.test_rows``.
        true: (n, K, 3) their observed displacements in those frames (the record's
            ``two["true"]``), kept beside the rollouts.

    Returns:
        ``{"true", <each of STEPPED_MODELS>: (n, K, 3) displacements (off, along, turn) in the
        hand's action frame, "calibration": `stepped_calibration` on the test pushes,
        "steps": steps per push}``.
    """
    geo = geometry_for(settings.push_groups)
    train = _steps(data.train, settings.push_groups, settings.step_length)
    test = _steps(data.test, settings.push_groups, settings.step_length)
    train, test = train.subset(data.train_rows), test.subset(data.test_rows)
    options = SteppedModelOptions(gp=settings.gp, seed=data.seed)
    model = fit_stepped(train, geo, options, backward=True)
    planned = fit_stepped(train, geo, options, backward=False)
    full = model.components(backward=True)
    variants = {
        "stepped_forward": full.without_backward(),
        "stepped_planned": planned.components(),
        "stepped_backward": full,
    }
    scenes = test.scenes()
    record: dict[str, Any] = {"true": true, "steps": int(test.n_steps)}
    for name, comps in variants.items():
        d = rollout(comps, geo, scenes).final - test.objects[:, 0]  # (n, K, 3) world
        d[..., 2] = (d[..., 2] + np.pi) % (2 * np.pi) - np.pi  # as scene_effects wraps it
        record[name] = np.stack([_in_action(T_a[i], d[i]) for i in range(len(d))]).tolist()
    record["calibration"] = stepped_calibration(model, test)
    return record


def skill_trial(skill: str, data: TrialData, settings: TrialSettings) -> dict[str, Any]:
    """Fit the pick or place models on training rows and predict the test rows.

    Args:
        skill: ``"pick"`` or ``"place"``.
        data: The training skill dataset and its rows, the test dataset of the same scene
            and its rows, and the seed of the mixture's EM.
        settings: Models.

    Returns:
        A JSON-ready record: ``"true"`` (n, 3) effects ``(up, x, turn)`` in the action frame,
        ``"success"`` (n,) the simulator's verdict (lifted, placed), and per model of
        `SKILL_MODELS` its means, sds, NLPD and coverage; ``"fit_seconds"``,
        ``"reaction_mm"``.
    """
    if skill not in ("pick", "place"):
        raise InputError(f"skill must be 'pick' or 'place', got {skill!r}.")
    train, test, train_rows, test_rows = data.train, data.test, data.train_rows, data.test_rows
    with limit_threads(1):
        rows = skill_rows(train, skill, settings.skill_groups)
        use = np.asarray(train_rows)
        cols = list(SIDEVIEW_EFFECT_COLUMNS)
        models, seconds = _fit_skill_models(
            skill,
            rows.features[use],
            rows.effect[use][:, cols],
            rows.reaction[use],
            settings,
            data.seed,
        )
        test_set = skill_rows(test, skill, settings.skill_groups)
        t_rows = np.asarray(test_rows)
        y = test_set.effect[t_rows][:, cols]
        x = torch.as_tensor(test_set.features[t_rows], dtype=torch.float64)
        success = test_set.lifted if skill == "pick" else test_set.placed
        return {
            "true": y.tolist(),
            "success": success[t_rows].astype(bool).tolist(),
            **{name: _scores(m.predict(x, skill=skill), y) for name, m in models.items()},
            "fit_seconds": seconds,
            "reaction_mm": 1000 * float(np.linalg.norm(rows.reaction[use], axis=1).mean()),
        }


def _push_training_rows(
    path: str, rows: list[int] | None, settings: TrialSettings
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Features, planar effects and reactions of the hand and object rows of pushes `rows`."""
    hand, objects = _push_rows(path, settings.push_groups, settings.reaction)
    use = np.ones(len(hand), bool) if rows is None else np.isin(hand.push, rows)
    use_o = np.ones(len(objects), bool) if rows is None else np.isin(objects.push, rows)
    cols = list(PLANAR_EFFECT_COLUMNS)
    return (
        np.concatenate([hand.features[use], objects.features[use_o]]),
        np.concatenate([hand.effect[use][:, cols], objects.effect[use_o][:, cols]]),
        np.concatenate([hand.reaction[use], objects.reaction[use_o]]),
    )


def chain_trained_trial(data: TrialData, settings: TrialSettings) -> dict[str, Any]:
    """The chain's push model fitted on two-object rows plus every row of longer scenes.

    The same push model as `push_trial`'s chain (with the backward component if
    ``settings.chain_backward``), but its training rows also hold the hand and object rows
    of every push of `extra` (e.g. three-object chains): object-on-object pushes straight
    through a packed row, which two-object scenes with the second object anywhere up to
    30 cm sideways rarely show. It then predicts the test chains, longer ones included.

    Args:
        data: The two-object training pool and its rows (``train``, ``train_rows``), the
            added training pushes (``test``, every row), the test chains and the scenes of
            each to predict (``test_rows``), and the seed of the chains' samples.
        settings: Models and sampling.

    Returns:
        ``{"chains": per K the truth and the modular means and intervals, "n_rows"}``.
    """
    train, extra, train_rows = data.train, data.test, data.train_rows
    with limit_threads(1):
        parts = [
            _push_training_rows(train, train_rows, settings),
            _push_training_rows(extra, None, settings),
        ]
        X, Y, R = (np.concatenate(a) for a in zip(*parts, strict=True))
        backward = settings.chain_backward
        model = SkillTransitionModel("push", backward=backward, gp=settings.gp)
        fit_transition(model, X, Y, R if backward else None)
        geo = geometry_for(settings.push_groups)
        chain = ModularTransitionModel({"push": model}, geo)
        return {"chains": _test_chains(chain, data, settings, 0), "n_rows": {"total": len(X)}}
