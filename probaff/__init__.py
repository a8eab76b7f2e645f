"""probaff: learning robot affordances with probabilistic models and factor graphs.

Subpackages:
    sim: pymunk worlds, the pytorch-kinematics arm, skills and simulated sensors.
    data: versioned, sharded, resumable datasets and their generation on Dask.
"""

from probaff.errors import (
    ConfigError,
    DatasetError,
    InputError,
    NotFittedError,
    ProbaffError,
    UnreachablePoseError,
)

__all__ = [
    "ConfigError",
    "DatasetError",
    "InputError",
    "NotFittedError",
    "ProbaffError",
    "UnreachablePoseError",
]

__version__ = "0.1.0"
