"""Exception types raised by probaff.

Every error message names the problem and how to fix it.
"""

__all__ = [
    "ClusterError",
    "ConfigError",
    "DatasetError",
    "InputError",
    "NotFittedError",
    "ProbaffError",
    "UnreachablePoseError",
]


class ProbaffError(Exception):
    """Base class of every error probaff raises on purpose."""


class InputError(ProbaffError, ValueError):
    """Numeric input is malformed: wrong shape, NaN/inf, empty, or out of range."""


class ConfigError(ProbaffError, ValueError):
    """A world, scene, object or run configuration is unknown or malformed."""


class UnreachablePoseError(ProbaffError, ValueError):
    """A commanded gripper pose lies outside the arm's reachable workspace."""


class DatasetError(ProbaffError, OSError):
    """An on-disk dataset is missing, truncated, corrupt or of another schema version."""


class NotFittedError(ProbaffError, RuntimeError):
    """A model was asked to predict, save or explain itself before it was fitted."""


class ClusterError(ProbaffError, RuntimeError):
    """The Dask cluster a batch ran on went away (its scheduler died or dropped this client)."""
