"""Datasets of any registered kind: versioned schemas, a sharded format, Dask generation.

A scene's world kind names its dataset kind (`probaff.data.kinds`): tabletop scenes make push
datasets (`PushDataset`), side-view scenes pick or place datasets (`SkillDataset`). `generate`
makes any kind and `load_any_dataset` reads any kind; `load_dataset` and `load_skill_dataset`
read one kind each.
"""

from probaff.data.config import GenerateConfig, scene_kind
from probaff.data.dataset import ArrayDataset
from probaff.data.generation import generate, generate_skills, make_shard
from probaff.data.kinds import (
    DatasetKind,
    dataset_kind,
    dataset_kinds,
    readable_versions,
    register_dataset_kind,
)
from probaff.data.noise import PoseNoise, observe_poses, parse_pose_noise
from probaff.data.push_generation import add_pose_noise, samples_to_arrays
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
from probaff.data.store import load_any_dataset, load_dataset, load_skill_dataset, read_manifest
from probaff.data.summary import summarize, summarize_skills

__all__ = [
    "GROUND_TRUTH_ARRAYS",
    "NO_OBJECT",
    "OPTIONAL_ARRAYS",
    "READABLE_SCHEMA_VERSIONS",
    "REQUIRED_ARRAYS",
    "SCHEMA_VERSION",
    "SKILL_ARRAYS",
    "SKILL_SCHEMA_VERSION",
    "SKILL_TRAJECTORY_ARRAYS",
    "ArrayDataset",
    "DatasetKind",
    "GenerateConfig",
    "PoseNoise",
    "PushDataset",
    "SkillDataset",
    "SkillDimensions",
    "add_pose_noise",
    "dataset_kind",
    "dataset_kinds",
    "generate",
    "generate_skills",
    "load_any_dataset",
    "load_dataset",
    "load_skill_dataset",
    "make_shard",
    "observe_poses",
    "parse_pose_noise",
    "read_manifest",
    "readable_versions",
    "register_dataset_kind",
    "samples_to_arrays",
    "scene_kind",
    "skill_dimensions",
    "summarize",
    "summarize_skills",
]
