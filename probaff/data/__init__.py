"""Push and side-view skill datasets: versioned schemas, a sharded format, Dask generation."""

from probaff.data.generation import (
    GenerateConfig,
    add_pose_noise,
    generate,
    generate_skills,
    make_shard,
    samples_to_arrays,
    scene_kind,
)
from probaff.data.noise import PoseNoise, observe_poses, parse_pose_noise
from probaff.data.schema import (
    GROUND_TRUTH_ARRAYS,
    OPTIONAL_ARRAYS,
    READABLE_SCHEMA_VERSIONS,
    REQUIRED_ARRAYS,
    SCHEMA_VERSION,
    PushDataset,
)
from probaff.data.skill_generation import SkillDimensions, skill_dimensions
from probaff.data.skill_schema import (
    NO_OBJECT,
    SKILL_ARRAYS,
    SKILL_SCHEMA_VERSION,
    SKILL_TRAJECTORY_ARRAYS,
    SkillDataset,
)
from probaff.data.store import (
    READABLE_VERSIONS,
    load_dataset,
    load_skill_dataset,
    read_manifest,
)
from probaff.data.summary import summarize, summarize_skills

__all__ = [
    "GROUND_TRUTH_ARRAYS",
    "NO_OBJECT",
    "OPTIONAL_ARRAYS",
    "READABLE_SCHEMA_VERSIONS",
    "READABLE_VERSIONS",
    "REQUIRED_ARRAYS",
    "SCHEMA_VERSION",
    "SKILL_ARRAYS",
    "SKILL_SCHEMA_VERSION",
    "SKILL_TRAJECTORY_ARRAYS",
    "GenerateConfig",
    "PoseNoise",
    "PushDataset",
    "SkillDataset",
    "SkillDimensions",
    "add_pose_noise",
    "generate",
    "generate_skills",
    "load_dataset",
    "load_skill_dataset",
    "make_shard",
    "observe_poses",
    "parse_pose_noise",
    "read_manifest",
    "samples_to_arrays",
    "scene_kind",
    "skill_dimensions",
    "summarize",
    "summarize_skills",
]
