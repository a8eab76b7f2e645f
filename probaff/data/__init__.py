"""Push datasets: a versioned schema, a sharded on-disk format, and generation on Dask."""

from probaff.data.generation import (
    GenerateConfig,
    add_pose_noise,
    generate,
    make_shard,
    samples_to_arrays,
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
from probaff.data.store import load_dataset, read_manifest
from probaff.data.summary import summarize

__all__ = [
    "GROUND_TRUTH_ARRAYS",
    "OPTIONAL_ARRAYS",
    "READABLE_SCHEMA_VERSIONS",
    "REQUIRED_ARRAYS",
    "SCHEMA_VERSION",
    "GenerateConfig",
    "PoseNoise",
    "PushDataset",
    "add_pose_noise",
    "generate",
    "load_dataset",
    "make_shard",
    "observe_poses",
    "parse_pose_noise",
    "read_manifest",
    "samples_to_arrays",
    "summarize",
]
