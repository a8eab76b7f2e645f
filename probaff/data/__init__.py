"""Datasets of any registered kind: versioned schemas, a sharded format, Dask generation.

A scene's world kind names its dataset kind (`probaff.data.kinds`): tabletop scenes make push
datasets (`PushDataset`), side-view scenes pick or place datasets (`SkillDataset`). `generate`
makes any kind and `load_any_dataset` reads any kind; `load_dataset` and `load_skill_dataset`
read one kind each.

A robot's own data comes in through `observation_dataset`, which builds a dataset from plain
arrays (only what a robot observes is required; what only a simulator knows is optional) and
checks their shapes, units, frames and finiteness; `save_dataset` writes any dataset as a
dataset folder. `export_hdf5` and `import_hdf5` carry push and skill datasets to and from
HDF5 files in a documented layout (`probaff.data.hdf5`).
"""

from probaff.data.config import GenerateConfig, scene_kind
from probaff.data.dataset import ArrayDataset
from probaff.data.generation import generate, generate_skills, make_shard
from probaff.data.hdf5 import export_hdf5, import_hdf5
from probaff.data.kinds import (
    DatasetKind,
    dataset_kind,
    dataset_kinds,
    observation_versions,
    readable_versions,
    register_dataset_kind,
)
from probaff.data.noise import PoseNoise, observe_poses, parse_pose_noise
from probaff.data.observations import CloudSampling, observation_dataset, observations_of
from probaff.data.push_generation import add_pose_noise, samples_to_arrays
from probaff.data.schema import (
    ARRAY_UNITS,
    GROUND_TRUTH_ARRAYS,
    OBSERVATION_ARRAYS,
    OBSERVATION_SCHEMA_VERSION,
    OPTIONAL_ARRAYS,
    READABLE_SCHEMA_VERSIONS,
    REQUIRED_ARRAYS,
    SCHEMA_VERSION,
    SIMULATOR_ARRAYS,
    PushDataset,
)
from probaff.data.skill_generation import SkillDimensions, skill_dimensions
from probaff.data.skill_schema import (
    NO_OBJECT,
    SKILL_ARRAY_UNITS,
    SKILL_ARRAYS,
    SKILL_OBSERVATION_ARRAYS,
    SKILL_OBSERVATION_SCHEMA_VERSION,
    SKILL_SCHEMA_VERSION,
    SKILL_SIMULATOR_ARRAYS,
    SKILL_TRAJECTORY_ARRAYS,
    SkillDataset,
)
from probaff.data.store import (
    load_any_dataset,
    load_dataset,
    load_skill_dataset,
    read_manifest,
    save_dataset,
)
from probaff.data.summary import summarize, summarize_skills

__all__ = [
    "ARRAY_UNITS",
    "GROUND_TRUTH_ARRAYS",
    "NO_OBJECT",
    "OBSERVATION_ARRAYS",
    "OBSERVATION_SCHEMA_VERSION",
    "OPTIONAL_ARRAYS",
    "READABLE_SCHEMA_VERSIONS",
    "REQUIRED_ARRAYS",
    "SCHEMA_VERSION",
    "SIMULATOR_ARRAYS",
    "SKILL_ARRAYS",
    "SKILL_ARRAY_UNITS",
    "SKILL_OBSERVATION_ARRAYS",
    "SKILL_OBSERVATION_SCHEMA_VERSION",
    "SKILL_SCHEMA_VERSION",
    "SKILL_SIMULATOR_ARRAYS",
    "SKILL_TRAJECTORY_ARRAYS",
    "ArrayDataset",
    "CloudSampling",
    "DatasetKind",
    "GenerateConfig",
    "PoseNoise",
    "PushDataset",
    "SkillDataset",
    "SkillDimensions",
    "add_pose_noise",
    "dataset_kind",
    "dataset_kinds",
    "export_hdf5",
    "generate",
    "generate_skills",
    "import_hdf5",
    "load_any_dataset",
    "load_dataset",
    "load_skill_dataset",
    "make_shard",
    "observation_dataset",
    "observation_versions",
    "observations_of",
    "observe_poses",
    "parse_pose_noise",
    "read_manifest",
    "readable_versions",
    "register_dataset_kind",
    "samples_to_arrays",
    "save_dataset",
    "scene_kind",
    "skill_dimensions",
    "summarize",
    "summarize_skills",
]
