"""What to generate: `GenerateConfig`, and the dataset kind a scene name makes.

A scene name picks the world kind whose templates hold it (`probaff.sim.registry`), and the
world kind names the dataset kind its scenes generate: a tabletop scene (``worlds/scenes/``)
gives a push dataset, a side-view scene (``worlds/sideview_scenes/``) a skill dataset.

Covered by tests/data/test_data.py.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields, replace
from typing import Any

from probaff._checks import check_count, check_positive
from probaff.data.noise import PoseNoise
from probaff.errors import InputError
from probaff.sim.pusher import HAND_MODES, check_hand_world
from probaff.sim.registry import kind_of_scene

__all__ = ["GenerateConfig", "base_plan", "scene_kind"]


def scene_kind(scene: str) -> str:
    """The kind of dataset a scene name generates.

    Args:
        scene: A scene template of a registered world kind: a tabletop scene
            (``worlds/scenes/NAME.yaml``) or a side-view scene
            (``worlds/sideview_scenes/NAME.yaml``).

    Returns:
        The dataset kind: ``"push"`` for a tabletop scene, ``"skill"`` for a side-view one.

    Raises:
        InputError: If `scene` is not a string, names no scene (the message lists every
            known scene), or belongs to a world kind that makes no dataset.
        ConfigError: If two world kinds hold a scene of that name.
    """
    world = kind_of_scene(scene)
    if world.dataset_kind is None:
        raise InputError(f"scene {scene!r} is a {world.label} scene, which makes no dataset.")
    return world.dataset_kind


@dataclass(frozen=True)
class GenerateConfig:
    """What to generate.

    An option that only some dataset kinds read names them in its field's ``kinds`` metadata;
    `validate` refuses it, when set, for a scene of another kind.

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
        hand: How the hand follows its command, ``"stiff"`` or ``"compliant"``
            (`probaff.sim.pusher.HAND_MODES`), overriding the world file's ``hand.mode``;
            ``None`` (the default) keeps the world file's. Tabletop and side-view scenes
            only: the worlds with an arm's hand.
    """

    scene: str
    n: int
    seed: int = 0
    shard_size: int = 64
    trajectories: bool = True
    cloud_points: int = 256
    cloud_noise: float = 0.002
    pose_noise: PoseNoise | None = field(
        default=None, metadata={"kinds": ("push",), "hint": " (drop --pose-noise)"}
    )
    record_rate: float | None = field(default=None, metadata={"kinds": ("skill",)})
    hand: str | None = field(
        default=None, metadata={"kinds": ("push", "skill"), "hint": " (drop --hand)"}
    )

    def validate(self) -> GenerateConfig:
        """Check the config and return it with its counts as builtin ints.

        Returns:
            An equal config whose ``n``, ``seed``, ``shard_size`` and ``cloud_points`` are
            `int` (``numpy.int64(8)`` or ``8.0`` become ``8``).

        Raises:
            InputError: For a non-positive count or size, a negative seed or noise, a
                `pose_noise` that is not a `PoseNoise`, an unknown scene, a `hand` that is
                not a hand mode, or an option of another kind of dataset (`pose_noise` for a
                side-view scene, `record_rate` for a tabletop one, `hand` for a world
                without an arm's hand).
            ConfigError: For a scene name defined by two world kinds.
        """
        if self.hand is not None:
            check_hand_world(kind_of_scene(self.scene).name, "GenerateConfig.hand")
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
        if self.hand is not None and (
            not isinstance(self.hand, str) or self.hand not in HAND_MODES
        ):
            raise InputError(
                f"hand must be None (the world file's hand) or one of {list(HAND_MODES)}, got "
                f"{self.hand!r}."
            )
        record_rate = self.record_rate
        if record_rate is not None:
            check_positive("record_rate", record_rate)
            record_rate = float(record_rate)
        for f in fields(self):
            kinds = f.metadata.get("kinds")
            if kinds and kind not in kinds and getattr(self, f.name) is not None:
                label = kind_of_scene(self.scene).label
                raise InputError(
                    f"{f.name} applies to {' and '.join(kinds)} datasets only; scene "
                    f"{self.scene!r} is a {label} scene, which makes {kind} datasets: leave "
                    f"{f.name} at None{f.metadata.get('hint', '')}."
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
        """The kind of dataset `scene` generates (`scene_kind`), e.g. ``"push"``."""
        return scene_kind(self.scene)

    @property
    def n_shards(self) -> int:
        """Number of shards."""
        return -(-self.n // self.shard_size)

    def shard_rows(self, index: int) -> int:
        """Rows in shard `index`."""
        return min(self.shard_size, self.n - index * self.shard_size)


def base_plan(config: GenerateConfig) -> dict[str, Any]:
    """The manifest plan entries of every dataset kind.

    Returns:
        ``scene``, ``n``, ``seed``, ``shard_size`` and ``trajectories`` of `config`.
    """
    return {
        "scene": config.scene,
        "n": config.n,
        "seed": config.seed,
        "shard_size": config.shard_size,
        "trajectories": config.trajectories,
    }
