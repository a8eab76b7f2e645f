"""Push datasets: a versioned schema, a sharded on-disk format, and generation on Dask."""

from probaff.data.generation import GenerateConfig, generate, make_shard, samples_to_arrays
from probaff.data.schema import OPTIONAL_ARRAYS, REQUIRED_ARRAYS, SCHEMA_VERSION, PushDataset
from probaff.data.store import load_dataset, read_manifest
from probaff.data.summary import summarize

__all__ = [
    "OPTIONAL_ARRAYS",
    "REQUIRED_ARRAYS",
    "SCHEMA_VERSION",
    "GenerateConfig",
    "PushDataset",
    "generate",
    "load_dataset",
    "make_shard",
    "read_manifest",
    "samples_to_arrays",
    "summarize",
]
