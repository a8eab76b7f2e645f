"""Deterministic, sharded, resumable dataset generation, serial or on Dask.

A scene name picks the world: a tabletop scene (``worlds/scenes/``) gives a push dataset
(`generate`), a side-view scene (``worlds/sideview_scenes/``) a skill dataset of picks or
places (`generate_skills`); both share the sharding, seeding, resumption and Dask machinery.

Shard ``i`` of a dataset with seed ``s`` is simulated from ``SeedSequence(s, spawn_key=(i,))``
alone, so a serial run, a local Dask cluster and a remote scheduler all produce the same bytes.
For pushes its three children drive, in order, the physics (scenes and pushes), the cloud sensor
and the optional pose-measurement noise; the noise stream is separate, so turning noise on
changes only the observed poses and effects, never which pushes are simulated. For skills its
first child drives the scene draws and the physics. Workers return arrays; only the calling
process writes files, so a remote cluster needs no shared file system.
"""

from __future__ import annotations

import hashlib
import os
from collections.abc import Hashable
from dataclasses import asdict, dataclass, replace
from pathlib import Path
from typing import Any, cast

import numpy as np

from probaff._checks import check_count, check_output_dir, check_positive
from probaff._dask import check_scheduler, check_workers, run_batch
from probaff._threads import torch_threads
from probaff.data.noise import PoseNoise, observe_poses
from probaff.data.queries import world_meta
from probaff.data.schema import PushDataset, schema_version_for
from probaff.data.skill_generation import make_skill_shard, skill_meta, skill_object_names
from probaff.data.skill_schema import SKILL_SCHEMA_VERSION, SkillDataset
from probaff.data.store import (
    FORMAT_NAME,
    count_rows,
    load_dataset,
    load_skill_dataset,
    manifest_kind,
    read_manifest,
    read_shard,
    shard_path,
    write_manifest,
    write_shard,
)
from probaff.errors import ConfigError, DatasetError, InputError
from probaff.sim.config import list_scenes, load_catalogue, worlds_dir
from probaff.sim.runner import PushSample, PushSimulator
from probaff.sim.sensing import object_cloud
from probaff.sim.sideview_config import list_sideview_scenes, load_sideview, load_sideview_scene

__all__ = [
    "GenerateConfig",
    "add_pose_noise",
    "generate",
    "generate_skills",
    "make_shard",
    "samples_to_arrays",
    "scene_kind",
]


class _UnknownSceneError(InputError, ConfigError):
    """An unknown scene name: a bad ``scene`` argument (`InputError`) naming no world file.

    It is also a `ConfigError`, which is what an unknown scene raised before side-view scenes
    existed, so code catching either keeps working.
    """


def scene_kind(scene: str) -> str:
    """The kind of dataset a scene name generates.

    Args:
        scene: A tabletop scene (``worlds/scenes/NAME.yaml``, `probaff.sim.list_scenes`) or a
            side-view scene (``worlds/sideview_scenes/NAME.yaml``,
            `probaff.sim.list_sideview_scenes`).

    Returns:
        ``"push"`` for a tabletop scene, ``"skill"`` for a side-view one.

    Raises:
        InputError: If `scene` is not a string, or names no scene (the message lists every
            known scene; the error is also a `ConfigError`).
        ConfigError: If both folders hold a scene of that name.
    """
    if not isinstance(scene, str):
        raise InputError(f"scene must be a scene name (a string), got {scene!r}.")
    push, side = scene in list_scenes(), scene in list_sideview_scenes()
    if push and side:
        root = worlds_dir()
        raise ConfigError(
            f"scene {scene!r} is defined twice, in {root / 'scenes' / f'{scene}.yaml'} and in "
            f"{root / 'sideview_scenes' / f'{scene}.yaml'}; rename one of the two files."
        )
    if not push and not side:
        raise _UnknownSceneError(
            f"unknown scene {scene!r}; available scenes: tabletop (push) {list_scenes()}, "
            f"side-view (pick/place) {list_sideview_scenes()}."
        )
    return "push" if push else "skill"


@dataclass(frozen=True)
class GenerateConfig:
    """What to generate.

    Attributes:
        scene: Scene template name: a tabletop scene (a push dataset) or a side-view scene
            (a skill dataset); see `scene_kind`.
        n: Number of pushes or skills.
        seed: Dataset seed.
        shard_size: Rows per shard (the unit of work, of resumption and of Dask tasks).
        trajectories: Store gripper and object trajectories.
        cloud_points: Push only: points per object cloud.
        cloud_noise: Push only: standard deviation of the cloud noise (m).
        pose_noise: Push only: measurement noise on the recorded object poses, or ``None``
            (the default) to record the simulator's exact poses. With noise,
            ``state_before``, ``state_after`` and ``effect`` hold noisy observations and the
            exact values are kept in ``true_state_before``, ``true_state_after`` and
            ``true_effect``.
        record_rate: Skill only: samples per second (Hz) of the stored trajectories, or
            ``None`` (the default) for the side-view world's ``physics.record_rate``.
    """

    scene: str
    n: int
    seed: int = 0
    shard_size: int = 64
    trajectories: bool = True
    cloud_points: int = 256
    cloud_noise: float = 0.002
    pose_noise: PoseNoise | None = None
    record_rate: float | None = None

    def validate(self) -> GenerateConfig:
        """Check the config and return it with its counts as builtin ints.

        Returns:
            An equal config whose ``n``, ``seed``, ``shard_size`` and ``cloud_points`` are
            `int` (``numpy.int64(8)`` or ``8.0`` become ``8``).

        Raises:
            InputError: For a non-positive count or size, a negative seed or noise, a
                `pose_noise` that is not a `PoseNoise`, an unknown scene, or an option of the
                other kind of dataset (`pose_noise` for a side-view scene, `record_rate` for
                a tabletop one).
            ConfigError: For a scene name defined in both scene folders.
        """
        kind = scene_kind(self.scene)
        n = check_count("n", self.n)
        shard_size = check_count("shard_size", self.shard_size)
        cloud_points = check_count("cloud_points", self.cloud_points)
        seed = check_count("seed", self.seed, minimum=0)
        check_positive("cloud_noise", self.cloud_noise, allow_zero=True)
        if self.pose_noise is not None and not isinstance(self.pose_noise, PoseNoise):
            raise InputError(
                f"pose_noise must be None or a probaff.data.PoseNoise, got {self.pose_noise!r}."
            )
        record_rate = self.record_rate
        if record_rate is not None:
            check_positive("record_rate", record_rate)
            record_rate = float(record_rate)
        if kind == "skill" and self.pose_noise is not None:
            raise InputError(
                f"pose_noise applies to push datasets only; scene {self.scene!r} is a side-view "
                "scene: leave pose_noise at None (drop --pose-noise)."
            )
        if kind == "push" and record_rate is not None:
            raise InputError(
                f"record_rate applies to skill datasets only; scene {self.scene!r} is a tabletop "
                "scene, whose record rate is the world's: leave record_rate at None."
            )
        return replace(
            self,
            n=n,
            shard_size=shard_size,
            cloud_points=cloud_points,
            seed=seed,
            record_rate=record_rate,
        )

    @property
    def kind(self) -> str:
        """``"push"`` or ``"skill"``: the kind of dataset `scene` generates (`scene_kind`)."""
        return scene_kind(self.scene)

    @property
    def n_shards(self) -> int:
        """Number of shards."""
        return -(-self.n // self.shard_size)

    def shard_rows(self, index: int) -> int:
        """Pushes in shard `index`."""
        return min(self.shard_size, self.n - index * self.shard_size)


def samples_to_arrays(
    samples: list[PushSample],
    object_names: list[str],
    rng: np.random.Generator,
    cloud_points: int,
    cloud_noise: float,
    trajectories: bool,
) -> dict[str, np.ndarray]:
    """Stack simulated pushes into schema arrays, sensing each scene's clouds.

    Args:
        samples: Pushes of one scene template.
        object_names: Catalogue vocabulary for ``object_ids``.
        rng: Randomness for the clouds.
        cloud_points: Points per object cloud.
        cloud_noise: Cloud noise standard deviation (m).
        trajectories: Include the optional trajectories.

    Returns:
        Arrays named and typed as `probaff.data.schema` documents.
    """
    index = {n: i for i, n in enumerate(object_names)}
    clouds = [
        [
            object_cloud(o, p, cloud_points, cloud_noise, rng)
            for o, p in zip(s.scene.objects, s.scene.poses, strict=True)
        ]
        for s in samples
    ]

    def scene(field: str) -> np.ndarray:
        return np.array([getattr(s.scene, field) for s in samples])

    def outcome(field: str) -> np.ndarray:
        return np.array([getattr(s.outcome, field) for s in samples])

    out = {
        "object_ids": np.array(
            [[index[o.name] for o in s.scene.objects] for s in samples], dtype=np.int16
        ),
        "q_waypoints": np.array([s.q_waypoints for s in samples]),
        "support_weights": _pad([s.scene.support_weights for s in samples]),
        "walls": scene("walls").reshape(len(samples), -1, 4),
        "cloud_points": np.array([[c[0] for c in cs] for cs in clouds], dtype=np.float32),
        "cloud_normals": np.array([[c[1] for c in cs] for cs in clouds], dtype=np.float32),
    }
    for field in (
        "push_origin",
        "push_yaw",
        "push_distance",
        "mass",
        "ground_friction",
        "contact_friction",
    ):
        out[field] = scene(field)
    for field in (
        "state_before",
        "state_after",
        "effect",
        "hand_contact",
        "object_contact",
        "wall_contact",
        "fell_off",
        "hand_lag",
        "max_penetration",
    ):
        out[field] = outcome(field)
    if trajectories:
        out["traj_time"] = outcome("traj_time")
        out["traj_hand"] = outcome("traj_hand").astype(np.float32)
        out["traj_objects"] = outcome("traj_objects").astype(np.float32)
    return {k: v.astype(v.dtype, copy=False) for k, v in out.items()}


def _pad(rows: list[tuple[np.ndarray, ...]]) -> np.ndarray:
    """Stack ragged per-object vectors into (N, K, G), zero-padded."""
    g = max((len(w) for r in rows for w in r), default=0)
    out = np.zeros((len(rows), len(rows[0]) if rows else 0, g))
    for i, r in enumerate(rows):
        for k, w in enumerate(r):
            out[i, k, : len(w)] = w
    return out


def make_shard(config: GenerateConfig, index: int) -> dict[str, np.ndarray]:
    """Simulate shard `index` of a dataset; depends only on the config and `index`.

    A tabletop scene gives push arrays (`probaff.data.schema`), a side-view scene skill arrays
    (`probaff.data.skill_schema`).

    Args:
        config: The dataset's generation config.
        index: Shard number.

    Returns:
        The shard's arrays.
    """
    index = check_count("index", index, minimum=0)
    ss = np.random.SeedSequence(config.seed, spawn_key=(index,))
    if config.kind == "skill":
        return make_skill_shard(
            config.scene,
            config.shard_rows(index),
            np.random.default_rng(ss.spawn(1)[0]),
            record_rate=config.record_rate,
            trajectories=config.trajectories,
        )
    # spawn(3)'s first two children equal spawn(2)'s, so the noise stream leaves them unchanged
    sim_rng, sense_rng, noise_rng = (np.random.default_rng(s) for s in ss.spawn(3))
    with torch_threads(1):
        sim = PushSimulator(config.scene)
        samples = list(sim.run(config.shard_rows(index), sim_rng))
    arrays = samples_to_arrays(
        samples,
        sorted(load_catalogue()),
        sense_rng,
        config.cloud_points,
        config.cloud_noise,
        config.trajectories,
    )
    if config.pose_noise is not None:
        arrays = add_pose_noise(arrays, config.pose_noise, noise_rng)
    return arrays


def add_pose_noise(
    arrays: dict[str, np.ndarray], noise: PoseNoise, rng: np.random.Generator
) -> dict[str, np.ndarray]:
    """Turn exact recorded poses into noisy observations, keeping the exact ones.

    Args:
        arrays: Schema arrays with exact ``state_before``, ``state_after`` (N, K, 3) and
            ``effect`` (N, K, 3), as `samples_to_arrays` returns them.
        noise: The measurement noise.
        rng: Source of the noise, separate from the physics' and the sensor's.

    Returns:
        A new dict: the exact arrays moved to ``true_state_before``, ``true_state_after`` and
        ``true_effect``; ``state_before`` and ``state_after`` replaced by noisy measurements
        and ``effect`` by the pushing-frame difference between them. Other arrays are shared.
    """
    before, after, effect = observe_poses(
        noise, arrays["state_before"], arrays["state_after"], arrays["push_yaw"], rng
    )
    return {
        **arrays,
        "true_state_before": arrays["state_before"],
        "true_state_after": arrays["state_after"],
        "true_effect": arrays["effect"],
        "state_before": before,
        "state_after": after,
        "effect": effect,
    }


def _record_rate(config: GenerateConfig) -> float:
    """The record rate of a skill dataset: the config's, else the side-view world's (Hz)."""
    if config.record_rate is not None:
        return float(config.record_rate)
    return load_sideview().physics.record_rate


def _plan(config: GenerateConfig) -> dict[str, Any]:
    """The manifest's record of `config`.

    Push: every field but ``record_rate``; ``pose_noise`` appears only when it is set (so push
    manifests are what they were before skill datasets existed). Skill: ``scene``, ``n``,
    ``seed``, ``shard_size``, ``trajectories`` and the resolved ``record_rate``.
    """
    plan = asdict(config)
    del plan["pose_noise"], plan["record_rate"]
    if config.kind == "skill":
        for push_only in ("cloud_points", "cloud_noise"):
            del plan[push_only]
        plan["record_rate"] = _record_rate(config)
    elif config.pose_noise is not None:
        plan["pose_noise"] = config.pose_noise.to_dict()
    return plan


def _describe_noise(plan: dict[str, Any]) -> str:
    noise = plan.get("pose_noise")
    if noise is None:
        return "no pose noise"
    return f"pose noise position_std={noise['position_std']} m, yaw_std={noise['yaw_std']} rad"


def _new_manifest(config: GenerateConfig) -> dict[str, Any]:
    """The manifest of a new dataset, loading (and so validating) its scene first."""
    if config.kind == "skill":
        world = load_sideview()
        spec = load_sideview_scene(config.scene)
        return {
            "format": FORMAT_NAME,
            "kind": "skill",
            "schema_version": SKILL_SCHEMA_VERSION,
            "plan": _plan(config),
            "object_names": skill_object_names(world),
            "meta": skill_meta(spec, world, _record_rate(config)),
            "shards": {},
        }
    sim = PushSimulator(config.scene)  # validates the scene before any work starts
    return {
        "format": FORMAT_NAME,
        "schema_version": schema_version_for(config.pose_noise is not None),
        "plan": _plan(config),
        "object_names": sorted(load_catalogue()),
        "meta": {"scene": config.scene, **world_meta(sim.world)},
        "shards": {},
    }


def _prepare(out: Path, config: GenerateConfig, resume: bool) -> dict[str, Any]:
    if out.exists() and not resume:
        raise DatasetError(
            f"{out} already exists; pass --resume (resume=True) to continue it, or choose a "
            "new output path."
        )
    if out.exists() and (out / "manifest.json").is_file():
        manifest = read_manifest(out)
        if manifest["plan"].get("pose_noise") != _plan(config).get("pose_noise"):
            raise DatasetError(
                f"{out} was started with {_describe_noise(manifest['plan'])}, not "
                f"{_describe_noise(_plan(config))}; resume it with the same pose noise "
                "(--pose-noise) or choose a new output path."
            )
        if manifest_kind(manifest) != config.kind:
            raise DatasetError(
                f"{out} is a {manifest_kind(manifest)} dataset, but scene {config.scene!r} makes "
                f"{config.kind} datasets; choose a new output path."
            )
        if manifest["plan"] != _plan(config):
            raise DatasetError(
                f"{out} was started with {manifest['plan']}, not {_plan(config)}; resume it "
                "with the same options or choose a new output path."
            )
        return manifest
    if out.exists() and any(out.iterdir()):
        raise DatasetError(f"{out} exists and is not a probaff dataset; choose a new path.")
    manifest = _new_manifest(config)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise DatasetError(
            f"cannot create the dataset folder {out} ({exc.strerror or exc}); choose an output "
            "path (--out) in a folder you may write to."
        ) from exc
    write_manifest(out, manifest)
    return manifest


def _adopt_orphans(out: Path, config: GenerateConfig, manifest: dict[str, Any]) -> None:
    """Reconcile the shard files with the manifest before a (resumed) run.

    Forgets listed shards whose file is missing, deletes and forgets those that fail their
    checksum (both are then computed again, to the same bytes), registers complete shard
    files written just before a crash, and drops temporaries.
    """
    for key, entry in list(manifest["shards"].items()):
        path = shard_path(out, int(key))
        if not path.is_file():
            del manifest["shards"][key]
        elif hashlib.sha256(path.read_bytes()).hexdigest() != entry.get("sha256"):
            path.unlink()
            del manifest["shards"][key]
    shards_dir = out / "shards"
    if not shards_dir.is_dir():
        write_manifest(out, manifest)
        return
    for tmp in shards_dir.glob(".*.tmp-*"):
        tmp.unlink()
    for i in range(config.n_shards):
        key = f"{i:05d}"
        if key in manifest["shards"] or not shard_path(out, i).is_file():
            continue
        try:
            arrays = read_shard(out, i)
        except DatasetError:
            shard_path(out, i).unlink()
            continue
        if count_rows(arrays) == config.shard_rows(i):
            digest = hashlib.sha256(shard_path(out, i).read_bytes()).hexdigest()
            manifest["shards"][key] = {"rows": config.shard_rows(i), "sha256": digest}
        else:
            shard_path(out, i).unlink()
    write_manifest(out, manifest)


def _run(
    config: GenerateConfig,
    out: str | os.PathLike[str],
    kind: str,
    workers: int | None,
    scheduler: str | None,
    resume: bool,
    progress: bool,
) -> Path:
    """Generate (or finish) a dataset of `kind` on disk; returns its folder."""
    config = config.validate()
    if config.kind != kind:
        other = "generate_skills" if config.kind == "skill" else "generate"
        what = "a side-view" if config.kind == "skill" else "a tabletop"
        raise InputError(
            f"scene {config.scene!r} is {what} scene, which makes {config.kind} datasets; "
            f"generate it with probaff.data.{other} (or `probaff generate`)."
        )
    workers = check_workers(workers)
    check_scheduler(scheduler)
    path = check_output_dir("out", out)
    manifest = _prepare(path, config, resume)
    _adopt_orphans(path, config, manifest)
    todo = [i for i in range(config.n_shards) if f"{i:05d}" not in manifest["shards"]]

    def store(i: Hashable, arrays: dict[str, np.ndarray]) -> None:
        i = cast(int, i)
        digest = write_shard(path, i, arrays)
        manifest["shards"][f"{i:05d}"] = {"rows": config.shard_rows(i), "sha256": digest}
        write_manifest(path, manifest)

    run_batch(
        make_shard,
        [(i, (config, i)) for i in todo],
        store,
        workers=workers,
        scheduler=scheduler,
        progress=progress,
        total=config.n,
        done=config.n - sum(config.shard_rows(i) for i in todo),
        size=lambda i: config.shard_rows(cast(int, i)),
        unit="push" if kind == "push" else "skill",
        desc=f"generate {config.scene}",
    )
    return path


def generate(
    config: GenerateConfig,
    out: str | os.PathLike[str],
    *,
    workers: int | None = 0,
    scheduler: str | None = None,
    resume: bool = False,
    progress: bool = True,
) -> PushDataset:
    """Generate (or finish) a push dataset on disk and return it.

    Args:
        config: What to generate; its scene is a tabletop scene.
        out: Dataset folder to create.
        workers: 0 runs serially in this process; ``None`` or K > 0 starts a local Dask
            cluster of K single-threaded worker processes (``None``: one per core).
        scheduler: Address of an existing Dask scheduler; overrides `workers`.
        resume: Continue an existing folder made with the same config.
        progress: Show a tqdm progress bar.

    Returns:
        The complete dataset, loaded from disk.

    Raises:
        DatasetError: If `out` exists without `resume`, belongs to another config (another
            pose noise included), or cannot be written.
        InputError: For a bad config or `workers`, an unknown scene, a side-view scene (use
            `generate_skills`), or an `out` that is a file, lies under a file or in a folder
            that is not writable.
        ConfigError: For an unknown object.
    """
    return load_dataset(_run(config, out, "push", workers, scheduler, resume, progress))


def generate_skills(
    config: GenerateConfig,
    out: str | os.PathLike[str],
    *,
    workers: int | None = 0,
    scheduler: str | None = None,
    resume: bool = False,
    progress: bool = True,
) -> SkillDataset:
    """Generate (or finish) a side-view skill dataset on disk and return it.

    Sampled scenes the arm cannot reach are dropped and replaced by further draws from the
    shard's generator, so every shard holds exactly its row count.

    Args:
        config: What to generate; its scene is a side-view scene.
        out: Dataset folder to create.
        workers: 0 runs serially in this process; ``None`` or K > 0 starts a local Dask
            cluster of K single-threaded worker processes (``None``: one per core).
        scheduler: Address of an existing Dask scheduler; overrides `workers`.
        resume: Continue an existing folder made with the same config.
        progress: Show a tqdm progress bar.

    Returns:
        The complete dataset, loaded from disk.

    Raises:
        DatasetError: If `out` exists without `resume`, belongs to another config, or cannot
            be written.
        InputError: For a bad config or `workers`, an unknown scene, a tabletop scene (use
            `generate`), or an `out` that is a file, lies under a file or in a folder that is
            not writable.
        ConfigError: For a malformed scene template, or one whose reachable draws are too
            rare.
    """
    return load_skill_dataset(_run(config, out, "skill", workers, scheduler, resume, progress))
