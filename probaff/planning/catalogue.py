"""The catalogue of planners and their learned models, fitted on a push dataset.

Push-to-edge models (`EDGE_MODELS`), each fitted on chapter 4 features of pushes of the task's
scene (``probaff generate --scene push_to_edge``), predict the book's ``(dy_p, dz_p,
dtheta_p)``:

- ``"gp"``: one GP (the mixture with M = 1) on f_o & f_c;
- ``"moe"``: the mixture of two GP experts fitted by EM, its gate on the context f_x (is the
  battery or the edge in the way?) and its experts on f_o & f_c (the thesis used m = 2);
- ``"clustered"``: chapter 4's hierarchical model, m = 2 GMM effect clusters with one GP each
  and an SVM gate, on f_o & f_c.

All use the dimension-scaled length-scale prior (MAP), as the push-model study does: with a
few hundred pushes and tens of features, ML-II length scales overfit. A model's kind is a kind
of the model registry (`probaff.models.model_kind`): it is built from the spec's
`ModelSettings` and fitted by its registered fitter, so a new kind of model needs its
registration and one entry here.

Push-to-edge planners (`EDGE_PLANNERS`): a search of `EDGE_SEARCHES` over a model, either a
key of `EDGE_MODELS` or one of the models that need no fit (``"simulator"``,
``"quasistatic"``), mean-only or risk-aware; `edge_transition` builds a planner's transition.

The tool push's model (`fit_tool_push_model`) is chapter 5's mixture of GP experts on
chapter-5 features, predicting both objects' effects.

Covered by tests/planning/test_planning_catalogue.py.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, replace

import numpy as np

from probaff._checks import check_count, default_or_instance
from probaff._threads import limit_threads
from probaff.data.schema import PushDataset
from probaff.errors import InputError
from probaff.features.ch4 import chapter4_features
from probaff.features.ch5 import chapter5_features
from probaff.features.featureset import FeatureSet
from probaff.models import MIXTURE_GP, EMOptions, GPOptions, ModelSettings, model_kind
from probaff.planning.learned import FeaturePushModel
from probaff.planning.push_to_edge.episode import EDGE_SEARCHES
from probaff.planning.push_to_edge.task import EdgeTask
from probaff.planning.transitions import (
    LearnedTransition,
    QuasiStaticTransition,
    SimulatorTransition,
    Transition,
)

__all__ = [
    "EDGE_MODELS",
    "EDGE_PLANNERS",
    "EDGE_PRIOR_WIDTH",
    "EdgeModelSpec",
    "EdgePlannerSpec",
    "edge_transition",
    "fit_edge_model",
    "fit_tool_push_model",
]

_N_TOOL_OBJECTS = 2  # the tool push's tool and target

EDGE_PRIOR_WIDTH = math.sqrt(3.0)
r"""Width of the length-scale prior of the push-to-edge models (`fit_edge_model`).

Hvarfner et al.'s (2024) :math:`\sqrt 3`, wider than the library's default
(`probaff.models.experts.kernels.LENGTHSCALE_PRIOR_SCALE`, 1, chosen by held-out density on the
peer table). On the planning study's 100 push-to-edge episodes (seed 0, 240 training pushes,
the same episodes), the default width gave A* with the mixture 91, the risk-aware A* 88 and
A* with a single GP 90 successes; this width gave 94, 94 and 93 (and the mixture's one-step
error fell from 2.40 to 2.10 cm). The tool-push model keeps the default width (41/50 with it).
"""


@dataclass(frozen=True)
class EdgeModelSpec:
    """How one planner model is fitted.

    Attributes:
        kind: A registered model kind (`probaff.models.model_kinds`), e.g. ``"em"``
            (`MixtureOfGPExperts` by `fit_em`) or ``"clustered"`` (`ClusteredGPModel`).
        n_experts: M (or m clusters).
        gate: Feature groups of the gate (empty for a kind whose gate reads every column).
        experts: Feature groups of the experts.
        gp: The GP experts' settings, whole (`ModelSettings.gp`); None for the kind's
            default.
    """

    kind: str
    n_experts: int
    gate: tuple[str, ...]
    experts: tuple[str, ...]
    gp: GPOptions | None = None

    @property
    def groups(self) -> tuple[str, ...]:
        """Every group the model reads, in the feature set's order."""
        return tuple(g for g in ("f_o", "f_c", "f_x") if g in (*self.gate, *self.experts))


_EDGE_MIXTURE_GP = replace(MIXTURE_GP, lengthscale_prior=EDGE_PRIOR_WIDTH)
_EDGE_CLUSTERED_GP = GPOptions(lengthscale_prior=EDGE_PRIOR_WIDTH)

EDGE_MODELS: dict[str, EdgeModelSpec] = {
    "gp": EdgeModelSpec("em", 1, ("f_o", "f_c"), ("f_o", "f_c"), _EDGE_MIXTURE_GP),
    "moe": EdgeModelSpec("em", 2, ("f_x",), ("f_o", "f_c"), _EDGE_MIXTURE_GP),
    "clustered": EdgeModelSpec("clustered", 2, (), ("f_o", "f_c"), _EDGE_CLUSTERED_GP),
}
"""The planner models, by name: each kind's default GP settings (`MIXTURE_GP`, `GPOptions()`)
with the prior at `EDGE_PRIOR_WIDTH`."""


@dataclass(frozen=True)
class EdgePlannerSpec:
    """One push-to-edge planner.

    Attributes:
        search: A key of `EDGE_SEARCHES` (``"astar"`` or ``"greedy"``).
        model: A key of `EDGE_MODELS`, ``"simulator"`` or ``"quasistatic"``.
        risk: The risk-aware variant.
    """

    search: str
    model: str
    risk: bool = False


EDGE_PLANNERS: dict[str, EdgePlannerSpec] = {
    "astar-moe": EdgePlannerSpec("astar", "moe"),
    "astar-risk-moe": EdgePlannerSpec("astar", "moe", risk=True),
    "astar-gp": EdgePlannerSpec("astar", "gp"),
    "astar-clustered": EdgePlannerSpec("astar", "clustered"),
    "astar-sim": EdgePlannerSpec("astar", "simulator"),
    "astar-quasistatic": EdgePlannerSpec("astar", "quasistatic"),
    "greedy-moe": EdgePlannerSpec("greedy", "moe"),
}
"""The push-to-edge planners, by name."""


def edge_transition(
    spec: EdgePlannerSpec,
    task: EdgeTask,
    models: Mapping[str, FeaturePushModel],
    seed: int = 0,
) -> Transition:
    """The transition a push-to-edge planner plans with.

    Args:
        spec: The planner (a value of `EDGE_PLANNERS`).
        task: The task.
        models: Fitted models by name (`fit_edge_model`); a learned planner's must be there.
        seed: Seeds a learned transition's sensed clouds and draws.

    Returns:
        `SimulatorTransition`, `QuasiStaticTransition` or a `LearnedTransition` named after
        its model.

    Raises:
        InputError: For a `spec` that is not an `EdgePlannerSpec`, a search that is not one
            of `EDGE_SEARCHES`, or a learned model that `models` lacks.

    Example:
        Plan pushes of the book towards the table's edge with the A* planner over the
        analytic quasi-static model (a learned planner takes its fitted model from
        `fit_edge_model` in `models`); `probaff.planning.run_edge_episode` executes such plans
        closed-loop:

        >>> import numpy as np
        >>> from probaff.planning import EDGE_PLANNERS, PushReachability, edge_transition
        >>> from probaff.planning import load_edge_task, plan_astar, sample_episode
        >>> task = load_edge_task()
        >>> transition = edge_transition(EDGE_PLANNERS["astar-quasistatic"], task, {})
        >>> scene = sample_episode(task, np.random.default_rng(0))
        >>> book, battery = scene.poses  # world (x, y, theta)
        >>> plan = plan_astar(task, transition, book, battery, PushReachability(task))
        >>> plan.reaches_goal, len(plan), plan.predicted.shape  # pushes, predicted poses
        (True, 3, (3, 3))
    """
    if not isinstance(spec, EdgePlannerSpec) or spec.search not in EDGE_SEARCHES:
        raise InputError(
            f"spec must be an EdgePlannerSpec of a search in {sorted(EDGE_SEARCHES)}, got {spec!r}."
        )
    if spec.model == "simulator":
        return SimulatorTransition(task)
    if spec.model == "quasistatic":
        return QuasiStaticTransition(task)
    if spec.model not in models:
        raise InputError(
            f"the planner's model {spec.model!r} is not among the fitted models "
            f"{sorted(models)}; fit it with fit_edge_model({spec.model!r}, ds)."
        )
    return LearnedTransition(models[spec.model], task, seed=seed, name=spec.model)


def fit_edge_model(
    name: str,
    ds: PushDataset,
    *,
    cloud_points: int | None = None,
    cloud_noise: float | None = None,
    seed: int = 0,
    em: EMOptions | None = None,
) -> FeaturePushModel:
    """Fit one of `EDGE_MODELS` on a push dataset of the task's scene.

    Args:
        name: A key of `EDGE_MODELS`.
        ds: The training pushes (object 0 is the book).
        cloud_points: Points per cloud of `ds` (read from its clouds when ``None``).
        cloud_noise: Cloud noise of `ds` (m); from its metadata when ``None``.
        seed: Seeds the fit (it replaces `em`'s seed).
        em: The EM options of a kind fitted by EM (``"em"``), whole (e.g. a study's
            ``config.em``); None for `EMOptions()`. Kinds without options ignore it.

    Returns:
        The fitted model with its features.

    Raises:
        InputError: For an unknown name or model kind, a `ds` that is not a `PushDataset` or
            holds fewer than 10 pushes, a bad seed, or `em` that is not `EMOptions`.
    """
    if not isinstance(name, str) or name not in EDGE_MODELS:
        raise InputError(f"unknown planner model {name!r}; choose one of {sorted(EDGE_MODELS)}.")
    if not isinstance(ds, PushDataset):
        raise InputError(
            "ds must be a PushDataset of the task's scene (probaff generate --scene "
            f"push_to_edge), got {type(ds).__name__}."
        )
    seed = check_count("seed", seed, minimum=0)
    em = _check_em(em)
    if len(ds) < 10:
        raise InputError(
            f"the training dataset has {len(ds)} pushes; fit planner models on at least 10 "
            "(probaff generate --scene push_to_edge --n 240)."
        )
    spec = EDGE_MODELS[name]
    kind = model_kind(spec.kind)
    settings = ModelSettings(
        spec.n_experts,
        gate=spec.gate,
        experts=spec.experts,
        seed=seed,
        gp=spec.gp,
        fit=em if kind.options_type is EMOptions else {},
    )
    Y = np.asarray(ds["effect"][:, 0], dtype=float)
    fitted = _fit(kind.name, settings, "ch4", chapter4_features(ds), spec.groups, Y, ds)
    if cloud_points is None and cloud_noise is None:
        return fitted
    return replace(
        fitted,
        cloud_points=fitted.cloud_points if cloud_points is None else cloud_points,
        cloud_noise=fitted.cloud_noise if cloud_noise is None else cloud_noise,
    )


def fit_tool_push_model(
    ds: PushDataset,
    *,
    n_experts: int = 3,
    groups: tuple[str, ...] = ("f_o", "f_c"),
    em: EMOptions | None = None,
    gp: GPOptions | None = None,
    seed: int = 0,
    kind: str = "em",
) -> FeaturePushModel:
    """Fit chapter 5's mixture of GP experts on two-object pushes, for the tool-push planner.

    The gate and the experts read the chapter-5 feature groups `groups`; the targets are the
    pushing-frame effects ``(dy_p, dz_p, dtheta_p)`` of o1 then o2 (6 outputs). Another
    registered model kind (`kind`) is fitted on the same features and targets.

    Args:
        ds: Pushes of a two-object scene (e.g. ``probaff generate --scene tool_push``).
        n_experts: Experts M.
        groups: Chapter-5 feature groups, e.g. ``("f_o", "f_c")``.
        em: The EM options, whole (e.g. a study's ``config.em``); None for `EMOptions()`
            (10 iterations, 3 starts).
        gp: The experts' settings, whole (`GPOptions`); None for `MIXTURE_GP` (50 L-BFGS
            iterations per expert fit, the length-scale prior at its default width, a noise
            floor of 1 % of each effect's standard deviation).
        seed: Seed of the fit (it replaces `em`'s seed).
        kind: A registered model kind (`probaff.models.model_kinds`); ``"em"`` is chapter
            5's mixture. `em` is used by kinds fitted with `EMOptions` and ignored by others.

    Returns:
        The fitted model with the features it reads.

    Raises:
        InputError: If `ds` holds fewer than two objects per push, for bad counts, an unknown
            `kind`, or `em` that is not `EMOptions` or `gp` that is not `GPOptions`.
    """
    if not isinstance(ds, PushDataset) or ds["effect"].shape[1] < _N_TOOL_OBJECTS:
        raise InputError(
            "ds must be a PushDataset of a two-object scene (probaff generate --scene tool_push)."
        )
    n_experts = check_count("n_experts", n_experts)
    em = _check_em(em)
    check_count("seed", seed, minimum=0)
    groups = (groups,) if isinstance(groups, str) else tuple(groups)
    fs = chapter5_features(ds)
    if not groups or len(set(groups)) != len(groups) or not set(groups) <= set(fs.groups):
        raise InputError(
            f"groups {list(groups)} must name distinct chapter-5 feature groups; choose from "
            f"{list(fs.groups)}."
        )
    Y = ds["effect"][:, :_N_TOOL_OBJECTS].reshape(len(ds), 3 * _N_TOOL_OBJECTS)
    chosen = model_kind(kind) if isinstance(kind, str) else None
    if chosen is None:
        raise InputError(f"kind must be the name of a registered model kind, got {kind!r}.")
    settings = ModelSettings(
        n_experts,
        seed=seed,
        gp=gp,  # None: the kind's default (MIXTURE_GP for the mixture)
        fit=em if chosen.options_type is EMOptions else {},
    )
    return _fit(chosen.name, settings, "ch5", fs, groups, Y, ds)


def _check_em(em: EMOptions | None) -> EMOptions:
    """`em`, or `EMOptions()` for None; `InputError` naming `em` for anything else."""
    return default_or_instance(
        "em", em, EMOptions, EMOptions, "EMOptions (e.g. EMOptions(max_iter=10))"
    )


def _fit(
    kind: str,
    settings: ModelSettings,
    features: str,
    fs: FeatureSet,
    groups: tuple[str, ...],
    Y: np.ndarray,
    ds: PushDataset,
) -> FeaturePushModel:
    """A model of the registered `kind`, fitted on the columns `groups` of `fs` and on `Y`.

    `fs` is the feature set `features` of `ds`. The model reads the named column groups
    (``settings.groups`` is set here) with the settings' GP options, and joins the
    features it reads (`FeaturePushModel.for_dataset`).
    """
    offsets, start = {}, 0
    for g in groups:
        width = fs.groups[g].stop - fs.groups[g].start
        offsets[g] = slice(start, start + width)
        start += width
    settings = replace(settings, groups=offsets)
    with limit_threads(1):
        model = model_kind(kind).fit_new(fs.select(*groups), Y, settings)
    return FeaturePushModel.for_dataset(model, features, groups, ds)
