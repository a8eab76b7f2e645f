"""Push shards: simulated tabletop pushes, sensed and stacked into `probaff.data.schema` arrays.

Shard ``i`` is simulated from the three children of ``SeedSequence(seed, spawn_key=(i,))``,
which drive, in order, the physics (scenes and pushes), the cloud sensor and the optional
pose-measurement noise; the noise stream is separate, so turning noise on changes only the
observed poses and effects, never which pushes are simulated.

The module registers the ``push`` dataset kind (`probaff.data.kinds`).

Covered by tests/data/test_data.py and tests/data/test_data_noise.py.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from probaff._threads import limit_threads
from probaff.data.config import GenerateConfig, base_plan
from probaff.data.kinds import DatasetKind, register_dataset_kind
from probaff.data.noise import PoseNoise, observe_poses
from probaff.data.queries import world_meta
from probaff.data.schema import READABLE_SCHEMA_VERSIONS, PushDataset, schema_version_for
from probaff.data.summary import summarize_pushes
from probaff.errors import InputError
from probaff.sim.runner import PushSample, PushSimulator
from probaff.sim.sensing import object_cloud
from probaff.sim.specs import load_catalogue
from probaff.sim.tabletop_config import TabletopSpec, load_tabletop

__all__ = [
    "add_pose_noise",
    "make_push_shard",
    "push_manifest",
    "push_plan",
    "push_resume_problem",
    "push_world",
    "samples_to_arrays",
]


def push_world(config: GenerateConfig) -> TabletopSpec:
    """The tabletop world of a push dataset: the world file's, with the config's hand mode.

    Args:
        config: The dataset's generation config; its ``hand`` (if set) replaces the world
            file's ``hand.mode``.
    """
    world = load_tabletop()
    return world if config.hand is None else world.with_hand(config.hand)


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
    out["hand_reaction"] = outcome("reaction").astype(np.float64)
    if trajectories:
        out["traj_time"] = outcome("traj_time")
        out["traj_hand"] = outcome("traj_hand").astype(np.float32)
        out["traj_objects"] = outcome("traj_objects").astype(np.float32)
        out["traj_commanded"] = outcome("traj_commanded").astype(np.float32)
    return {k: v.astype(v.dtype, copy=False) for k, v in out.items()}


def _pad(rows: list[tuple[np.ndarray, ...]]) -> np.ndarray:
    """Stack ragged per-object vectors into (N, K, G), zero-padded."""
    g = max((len(w) for r in rows for w in r), default=0)
    out = np.zeros((len(rows), len(rows[0]) if rows else 0, g))
    for i, r in enumerate(rows):
        for k, w in enumerate(r):
            out[i, k, : len(w)] = w
    return out


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

    Raises:
        InputError: For `arrays` that are not a mapping holding ``state_before``,
            ``state_after``, ``push_yaw`` and ``effect``, or any error of `observe_poses`.
    """
    if not isinstance(arrays, Mapping):
        raise InputError(f"arrays must map array names to arrays, got {type(arrays).__name__}.")
    missing = [k for k in ("state_before", "state_after", "push_yaw", "effect") if k not in arrays]
    if missing:
        raise InputError(
            f"arrays lacks {missing}; give the schema arrays of samples_to_arrays (exact poses)."
        )
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


def make_push_shard(
    config: GenerateConfig, rows: int, seeds: np.random.SeedSequence
) -> dict[str, np.ndarray]:
    """Simulate the `rows` pushes of one shard.

    Args:
        config: The dataset's generation config (a tabletop scene).
        rows: Pushes in the shard.
        seeds: The shard's seed sequence.

    Returns:
        The shard's arrays (`probaff.data.schema`).
    """
    # spawn(3)'s first two children equal spawn(2)'s, so the noise stream leaves them unchanged
    sim_rng, sense_rng, noise_rng = (np.random.default_rng(s) for s in seeds.spawn(3))
    with limit_threads(1):
        sim = PushSimulator(config.scene, push_world(config))
        samples = list(sim.run(rows, sim_rng))
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


def push_plan(config: GenerateConfig) -> dict[str, Any]:
    """The manifest's record of a push `config`.

    Every field but ``record_rate``; ``pose_noise`` and ``hand`` (as ``hand_mode``) appear
    only when they are set, so push manifests are what they were before pose noise, skill
    datasets and hand modes existed.
    """
    plan = {
        **base_plan(config),
        "cloud_points": config.cloud_points,
        "cloud_noise": config.cloud_noise,
    }
    if config.pose_noise is not None:
        plan["pose_noise"] = config.pose_noise.to_dict()
    if config.hand is not None:
        plan["hand_mode"] = config.hand
    return plan


def push_manifest(config: GenerateConfig) -> dict[str, Any]:
    """The schema version, object names and meta of a new push dataset (validates the scene)."""
    sim = PushSimulator(config.scene, push_world(config))  # validates the scene first
    return {
        "schema_version": schema_version_for(config.pose_noise is not None, reaction=True),
        "object_names": sorted(load_catalogue()),
        "meta": {"scene": config.scene, **world_meta(sim.world)},
    }


def _describe_noise(plan: dict[str, Any]) -> str:
    noise = plan.get("pose_noise")
    if noise is None:
        return "no pose noise"
    return f"pose noise position_std={noise['position_std']} m, yaw_std={noise['yaw_std']} rad"


def push_resume_problem(started: dict[str, Any], plan: dict[str, Any]) -> str | None:
    """Why a push dataset started with plan `started` cannot be resumed with `plan`, or ``None``.

    Another pose noise is named as such; other differences are left to the generic check.
    """
    if started.get("pose_noise") == plan.get("pose_noise"):
        return None
    return (
        f"was started with {_describe_noise(started)}, not {_describe_noise(plan)}; resume it "
        "with the same pose noise (--pose-noise) or choose a new output path."
    )


register_dataset_kind(
    DatasetKind(
        name="push",
        dataset_type=PushDataset,
        world_kind="tabletop",
        make_shard=make_push_shard,
        unit="push",
        manifest=push_manifest,
        loader="load_dataset",
        plan=push_plan,
        schema_versions=READABLE_SCHEMA_VERSIONS,
        summarize=summarize_pushes,
        resume_problem=push_resume_problem,
        order=0,
    )
)
