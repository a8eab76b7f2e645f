"""probaff: learning robot affordances with probabilistic models and factor graphs.

Every capability is one hop from here:

Subpackages:
    sim: the simulated robot: pymunk worlds (tabletop, warehouse), the URDF arm through
        pytorch-kinematics, push skills and a simulated depth sensor.
    data: versioned, sharded, resumable push datasets, generated on Dask; pose noise.
    features: object, contact and context features (chapters 4, 5), per-cell features of
        the warehouse (chapter 3).
    perception: the occupancy grid and frontier exploration of the warehouse.
    models: GP experts, gates, the mixture of GP experts (EM, Pyro SVI), the clustered
        baseline (chapter 4), saving and loading.
    maps: a pure factor-graph library: the affordance MRF as a gtsam.DiscreteFactorGraph,
        exact, enumeration and batched loopy BP marginals, entropies.
    planning: acting on what was learned: the affordance classifier, information-gain pushes
        and the verify-by-pushing manipulation loop (chapter 3).
    eval: metrics (RMSE, NLPD, coverage), model selection, the resumable task runner,
        fingerprints, figures.
    studies: one ``run(config)`` per study (push models, affordance maps).
    cli: the ``probaff`` command (``probaff demo``, ``probaff generate``, ...).

Errors: every error probaff raises on purpose is a `ProbaffError`.
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
