"""Side-view skill shards: sampled picks or places, stacked into `probaff.data.skill_schema` arrays.

A shard is drawn and simulated with `probaff.sim.run_sampled`, which drops the sampled scenes
the arm cannot reach and draws replacements from the same generator, so a shard always holds
exactly its row count and depends only on the generator's state. Every shard of a dataset has
the same array shapes: the object slots K, the waypoints W and the trajectory samples T are
bounds computed from the scene template and the world (`skill_dimensions`), not from the
sampled scenes. The module registers the ``skill`` dataset kind (`probaff.data.kinds`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from probaff._checks import check_count, check_positive
from probaff._threads import limit_threads
from probaff.data.config import GenerateConfig, base_plan
from probaff.data.kinds import DatasetKind, register_dataset_kind
from probaff.data.skill_schema import NO_OBJECT, SKILL_SCHEMA_VERSION, SkillDataset
from probaff.data.summary import summarize_skills
from probaff.errors import DatasetError
from probaff.sim.arm import load_arm
from probaff.sim.runner import trapezoid_progress
from probaff.sim.sideview import SideViewScene
from probaff.sim.sideview_config import (
    SideViewSceneSpec,
    SideViewSpec,
    load_sideview,
    load_sideview_scene,
)
from probaff.sim.skills import SkillOutcome, run_sampled
from probaff.sim.specs import load_catalogue

__all__ = [
    "SkillDimensions",
    "make_skill_shard",
    "outcomes_to_arrays",
    "resample_times",
    "skill_dimensions",
    "skill_manifest",
    "skill_meta",
    "skill_object_names",
    "skill_plan",
    "skill_shard",
]

_TIME_TOL = 1e-9  # s; a skill's end this close to a grid time is that grid time
# m; the bounds take every move this much longer, covering the rounding of the distances the
# skills compute from poses (a move of exactly k waypoint spacings may come out 1e-16 longer)
_DISTANCE_MARGIN = 1e-6
_TRAJ_FLOAT32: dict[str, tuple[int, ...]] = {  # per-step tail shapes; -1 stands for K
    "ee_commanded": (3,),
    "ee_actual": (3,),
    "opening_commanded": (),
    "opening_actual": (),
    "traj_objects": (-1, 3),
}


@dataclass(frozen=True)
class SkillDimensions:
    """Fixed per-row array sizes of a skill dataset.

    Attributes:
        n_objects: Object slots K.
        n_waypoints: IK waypoints W of the template's longest skill.
        n_samples: Trajectory samples T of its longest skill at the record rate.
    """

    n_objects: int
    n_waypoints: int
    n_samples: int


def skill_object_names(world: SideViewSpec | None = None) -> list[str]:
    """Sorted names of the side-view catalogue: the ``object_ids`` vocabulary."""
    world = world or load_sideview()
    return sorted(load_catalogue(world.catalogue))


def _ticks(distance: float, world: SideViewSpec) -> int:
    """Control ticks of a straight move of `distance` metres, its first tick included."""
    if distance < 1e-9:
        return 1
    rate = world.physics.control_rate
    return len(trapezoid_progress(distance, world.speed, world.acceleration, rate))


def _hold_ticks(seconds: float, world: SideViewSpec) -> int:
    return max(1, round(seconds * world.physics.control_rate))


def _samples(duration: float, rate: float) -> int:
    """Resampled trajectory length of a skill lasting `duration` seconds."""
    return len(resample_times(duration, rate))


def skill_dimensions(
    spec: SideViewSceneSpec, world: SideViewSpec, record_rate: float
) -> SkillDimensions:
    """Bounds K, W and T for every scene a template can draw.

    The longest skill of a pick is that of the tallest candidate object (the tcp goes down
    from ``approach_height`` above its top to ``grasp_fraction`` of its height); that of a
    place starts ``hold_height`` above the target and releases at the lowest release height.

    Args:
        spec: The scene template.
        world: The side-view world.
        record_rate: Trajectory samples per second (Hz).

    Returns:
        The dimensions.
    """
    check_positive("record_rate", record_rate)
    arm = load_arm(world.arm)
    rate = world.physics.control_rate
    k = len(spec.objects) + (1 if spec.skill == "place" else 0)
    if spec.skill == "pick":
        p = world.pick
        height = max(o.height for pl in spec.objects for o in pl.choices)
        down = p.approach_height + (1.0 - p.grasp_fraction) * height + _DISTANCE_MARGIN
        lift = p.lift + _DISTANCE_MARGIN
        w = arm.waypoint_count(down) + arm.waypoint_count(lift) - 1
        ticks = (
            _ticks(down, world)
            + _hold_ticks(p.close_time, world)
            + _ticks(lift, world)
            - 1
            + round(p.hold_time * rate)
        )
    else:
        pl = world.place
        drop = pl.hold_height - pl.release_height[0] + _DISTANCE_MARGIN
        w = arm.waypoint_count(drop)
        ticks = (
            _ticks(drop, world) + _hold_ticks(pl.open_time, world) + round(pl.settle_time * rate)
        )
    return SkillDimensions(k, w, _samples((ticks - 1) / rate, record_rate))


def resample_times(duration: float, rate: float) -> np.ndarray:
    """(L,) sample times of a skill: ``j / rate`` up to `duration`, then `duration` itself.

    Args:
        duration: The skill's last recorded time (s), >= 0.
        rate: Samples per second (Hz).

    Returns:
        Increasing times from 0; the last is `duration`.

    Raises:
        InputError: For a negative or non-finite `duration`, or a `rate` that is not > 0.
    """
    check_positive("duration", duration, allow_zero=True)
    check_positive("rate", rate)
    n = math.floor(duration * rate + _TIME_TOL) + 1
    times = np.arange(n) / rate
    times[-1] = min(times[-1], duration)
    if duration - times[-1] > _TIME_TOL:
        times = np.append(times, duration)
    return times


def _interp(times: np.ndarray, values: np.ndarray, at: np.ndarray) -> np.ndarray:
    """Linear interpolation of `values` (T_r, ...) recorded at `times` (T_r,) to `at` (L,)."""
    flat = values.reshape(len(times), -1)
    out = np.stack([np.interp(at, times, flat[:, c]) for c in range(flat.shape[1])], axis=1)
    return out.reshape(len(at), *values.shape[1:])


def _pad_rows(values: np.ndarray, length: int) -> np.ndarray:
    """Repeat the last row of `values` (L, ...) up to `length` rows."""
    if len(values) > length:
        raise DatasetError(
            f"a skill needs {len(values)} waypoints or trajectory samples, more than the "
            f"{length} its scene template allows; the template bounds (skill_dimensions) no "
            "longer match the skills."
        )
    return np.concatenate([values, np.repeat(values[-1:], length - len(values), axis=0)])


def _target_xz(scene: SideViewScene, world: SideViewSpec) -> tuple[float, float]:
    obj, pose = scene.objects[scene.target], scene.poses[scene.target]
    if scene.skill == "pick":
        bottom = pose[1] - 0.5 * obj.height
        return float(pose[0]), float(bottom + world.pick.grasp_fraction * obj.height)
    return float(pose[0]), scene.support_top


def outcomes_to_arrays(
    samples: list[tuple[SideViewScene, SkillOutcome]],
    object_names: list[str],
    dims: SkillDimensions,
    world: SideViewSpec,
    record_rate: float,
    trajectories: bool,
) -> dict[str, np.ndarray]:
    """Stack simulated skills into schema arrays, padded to `dims`.

    Args:
        samples: ``(scene, outcome)`` pairs of one scene template (`run_sampled`).
        object_names: Catalogue vocabulary for ``object_ids``.
        dims: The template's K, W and T (`skill_dimensions`).
        world: The side-view world.
        record_rate: Trajectory samples per second (Hz).
        trajectories: Include the optional trajectory arrays.

    Returns:
        Arrays named, typed and shaped as `probaff.data.skill_schema` documents.

    Raises:
        DatasetError: If a sample has more objects, waypoints or samples than `dims`.
    """
    index = {name: i for i, name in enumerate(object_names)}
    n, k = len(samples), dims.n_objects
    ids = np.full((n, k), NO_OBJECT, dtype=np.int16)
    size = np.zeros((n, k, 3))
    per_object = {name: np.zeros((n, k)) for name in ("mass", "friction")}
    states = {name: np.zeros((n, k, 3)) for name in ("state_before", "state_after")}
    dof = samples[0][1].q_waypoints.shape[1] if samples else 0
    q = np.zeros((n, dims.n_waypoints, dof))
    out: dict[str, np.ndarray] = {
        "target": np.array([s.target for s, _ in samples], dtype=np.int16),
        "support": np.array([s.support for s, _ in samples], dtype=np.int16),
        "target_xz": np.array([_target_xz(s, world) for s, _ in samples]).reshape(n, 2),
        "release_height": np.array([s.release_height for s, _ in samples], dtype=float),
        "n_waypoints": np.array([len(o.q_waypoints) for _, o in samples], dtype=np.int32),
    }
    for flag in ("grasped", "lifted", "slipped", "placed"):
        out[flag] = np.array([getattr(o, flag) for _, o in samples], dtype=bool)
    traj: dict[str, list[np.ndarray]] = {name: [] for name in _TRAJ_FLOAT32}
    times, lengths = [], []
    for i, (scene, outcome) in enumerate(samples):
        m = len(scene.objects)
        if m > k:
            raise DatasetError(
                f"a scene has {m} objects, more than the {k} slots of its scene template."
            )
        ids[i, :m] = [index[o.name] for o in scene.objects]
        size[i, :m] = [(o.size[0], o.size[1], o.height) for o in scene.objects]
        per_object["mass"][i, :m] = scene.mass
        per_object["friction"][i, :m] = scene.friction
        states["state_before"][i, :m] = outcome.state_before
        states["state_after"][i, :m] = outcome.state_after
        q[i] = _pad_rows(outcome.q_waypoints, dims.n_waypoints)
        if not trajectories:
            continue
        at = resample_times(float(outcome.times[-1]), record_rate)
        lengths.append(len(at))
        times.append(_pad_rows(at, dims.n_samples))
        objects = np.zeros((len(at), k, 3))
        objects[:, :m] = _interp(outcome.times, outcome.objects, at)
        recorded = {
            "ee_commanded": outcome.ee_commanded,
            "ee_actual": outcome.ee_actual,
            "opening_commanded": outcome.opening_commanded,
            "opening_actual": outcome.opening_actual,
        }
        for name, values in recorded.items():
            traj[name].append(_pad_rows(_interp(outcome.times, values, at), dims.n_samples))
        traj["traj_objects"].append(_pad_rows(objects, dims.n_samples))
    out.update(object_ids=ids, size=size, q_waypoints=q, **per_object, **states)
    if trajectories:
        out["traj_length"] = np.array(lengths, dtype=np.int32)
        out["traj_time"] = np.array(times, dtype=float).reshape(n, dims.n_samples)
        for name, tail in _TRAJ_FLOAT32.items():
            shape = (n, dims.n_samples, *(k if t == -1 else t for t in tail))
            out[name] = np.array(traj[name], dtype=np.float32).reshape(shape)
    return out


def skill_meta(spec: SideViewSceneSpec, world: SideViewSpec, record_rate: float) -> dict[str, Any]:
    """The world and template facts a skill dataset records in ``meta``.

    Args:
        spec: The scene template.
        world: The side-view world.
        record_rate: Trajectory samples per second (Hz).

    Returns:
        A JSON-ready dict: ``scene``, ``skill``, ``n_objects``, ``n_waypoints``,
        ``n_samples``, ``record_rate``, ``control_rate``, ``table_length``, ``gripper_span``,
        ``plane_y``, ``arm_base_xyz``, ``arm_base_yaw``, ``grasp_fraction`` and ``lift``.
    """
    dims = skill_dimensions(spec, world, record_rate)
    return {
        "scene": spec.name,
        "skill": spec.skill,
        "n_objects": dims.n_objects,
        "n_waypoints": dims.n_waypoints,
        "n_samples": dims.n_samples,
        "record_rate": float(record_rate),
        "control_rate": world.physics.control_rate,
        "table_length": world.table_length,
        "gripper_span": world.gripper.span,
        "plane_y": world.plane_y,
        "arm_base_xyz": list(world.arm.base_xyz),
        "arm_base_yaw": world.arm.base_yaw,
        "grasp_fraction": world.pick.grasp_fraction,
        "lift": world.pick.lift,
    }


def make_skill_shard(
    scene: str,
    rows: int,
    rng: np.random.Generator,
    *,
    record_rate: float | None = None,
    trajectories: bool = True,
    hand: str | None = None,
) -> dict[str, np.ndarray]:
    """Draw and simulate `rows` reachable skills of a side-view scene template.

    Args:
        scene: A name from `probaff.sim.list_sideview_scenes`.
        rows: Samples in the shard (a positive integer).
        rng: The shard's physics generator.
        record_rate: Trajectory samples per second (Hz); ``None``: the world's
            ``physics.record_rate``.
        trajectories: Include the optional trajectory arrays.
        hand: The hand's mode (``"stiff"``, ``"compliant"``), or ``None`` for the world
            file's.

    Returns:
        The shard's arrays.

    Raises:
        ConfigError: For an unknown scene, or one whose reachable draws are too rare.
        InputError: For a bad `rows` or `record_rate`.
    """
    rows = check_count("rows", rows)
    world = _side_world(hand)
    spec = load_sideview_scene(scene)
    rate = world.physics.record_rate if record_rate is None else float(record_rate)
    dims = skill_dimensions(spec, world, rate)
    with limit_threads(1):
        samples = run_sampled(spec, rows, rng, world)
    return outcomes_to_arrays(samples, skill_object_names(world), dims, world, rate, trajectories)


def _side_world(hand: str | None) -> SideViewSpec:
    """The side-view world file's world, its hand in mode `hand` unless that is ``None``."""
    world = load_sideview()
    return world if hand is None else world.with_hand(hand)


def _record_rate(config: GenerateConfig) -> float:
    """The record rate of a skill dataset: the config's, else the side-view world's (Hz)."""
    if config.record_rate is not None:
        return float(config.record_rate)
    return load_sideview().physics.record_rate


def skill_shard(
    config: GenerateConfig, rows: int, seeds: np.random.SeedSequence
) -> dict[str, np.ndarray]:
    """The `rows` skills of one shard, drawn and simulated from its seeds' first child.

    Args:
        config: The dataset's generation config (a side-view scene).
        rows: Skills in the shard.
        seeds: The shard's seed sequence.

    Returns:
        The shard's arrays (`probaff.data.skill_schema`).
    """
    return make_skill_shard(
        config.scene,
        rows,
        np.random.default_rng(seeds.spawn(1)[0]),
        record_rate=config.record_rate,
        trajectories=config.trajectories,
        hand=config.hand,
    )


def skill_plan(config: GenerateConfig) -> dict[str, Any]:
    """The manifest's record of a skill `config`.

    `base_plan`, the resolved ``record_rate``, and ``hand`` (as ``hand_mode``) when it is set.
    """
    plan = {**base_plan(config), "record_rate": _record_rate(config)}
    if config.hand is not None:
        plan["hand_mode"] = config.hand
    return plan


def skill_manifest(config: GenerateConfig) -> dict[str, Any]:
    """The schema version, object names and meta of a new skill dataset (validates the scene)."""
    world = _side_world(config.hand)
    spec = load_sideview_scene(config.scene)
    return {
        "schema_version": SKILL_SCHEMA_VERSION,
        "object_names": skill_object_names(world),
        "meta": {**skill_meta(spec, world, _record_rate(config)), "hand": world.hand.to_dict()},
    }


register_dataset_kind(
    DatasetKind(
        name="skill",
        dataset_type=SkillDataset,
        world_kind="sideview",
        make_shard=skill_shard,
        unit="skill",
        manifest=skill_manifest,
        loader="load_skill_dataset",
        plan=skill_plan,
        schema_versions=(SKILL_SCHEMA_VERSION,),
        summarize=summarize_skills,
        order=1,
    )
)
