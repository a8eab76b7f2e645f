"""probaff: learning robot affordances with probabilistic models and factor graphs.

Every capability is one hop from here:

Subpackages, low layers first (each imports only from those above it in this list):
    models: GP experts (exact, weighted), gates, the mixture of GP experts (EM, Pyro SVI),
        the clustered baseline (chapter 4), chapter 6's skill, modular and monolithic
        transition models, typed fit options (`EMOptions`, `SVIOptions`, `GPOptions`), the
        registry of model kinds with its type-dispatched `fit`, saving and loading.
    maps: a pure factor-graph library: the affordance MRF as a gtsam.DiscreteFactorGraph,
        exact, enumeration and batched loopy BP marginals, entropies.
    sim: the simulated robot: a registry of world kinds (tabletop, side view, warehouse,
        office), the URDF arm through pytorch-kinematics, push, pick and place skills, the
        ray-cast depth camera, the shared world-file readers.
    data: datasets of every registered kind (push, skill): schemas, checksummed shards, one
        resumable `generate` on Dask, pose noise, summaries.
    perception: occupancy and exploration (chapter 3); normals, region growing, segment
        features, label classifiers, refinement and multi-view merging (chapter 2).
    features: chapter 3 voxel, chapter 4 and 5 push and chapter 6 interaction features,
        computed from dataset arrays.
    planning: what is scored (one transition protocol: learned, simulator, quasi-static)
        apart from how it is searched (A*, greedy, sampling); one subpackage per task (push
        to edge, tool push, the chapter 3 manipulation loop) and the planner catalogue.
    eval: metrics (RMSE, NLPD, coverage), model selection, the resumable task runner,
        fingerprints, tables, shared plotting helpers.
    experiments: one folder per study over `StudyConfig` and `StudyRun`:
        point_cloud_labels (chapter 2), affordance_map (chapter 3), planning (chapters 4 and
        5), push_models (chapters 5 and 4), modular (chapter 6).
    cli: the ``probaff`` command (``demo``, ``generate``, ``describe``, ``scenes``,
        ``study``).

Errors: every error probaff raises on purpose is a `ProbaffError`.

Threads: model fits on at most 20,000 rows run on one torch and BLAS thread, larger ones with
torch's count (`probaff._threads.ONE_THREAD_MAX_ROWS`); `set_fit_threads` (or the environment
variable ``PROBAFF_FIT_THREADS``) sets the count of every fit instead.
"""

from typing import TYPE_CHECKING, Any

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
    "set_fit_threads",
]

if TYPE_CHECKING:
    from probaff._threads import set_fit_threads


def __getattr__(name: str) -> Any:
    """`set_fit_threads`, imported on first use (``import probaff`` alone loads no torch)."""
    if name == "set_fit_threads":
        from probaff._threads import set_fit_threads

        return set_fit_threads
    raise AttributeError(f"module 'probaff' has no attribute {name!r}")


__version__ = "0.1.0"
