"""The learned push models the push-to-edge planners compare, fitted on a push dataset.

Each is fitted on chapter 4 features of pushes of the task's scene (``probaff generate
--scene push_to_edge``) and predicts the book's ``(dy_p, dz_p, dtheta_p)``:

- ``"gp"``: one GP (the mixture with M = 1) on f_o & f_c;
- ``"moe"``: the mixture of two GP experts fitted by EM, its gate on the context f_x (is the
  battery or the edge in the way?) and its experts on f_o & f_c (the thesis used m = 2);
- ``"clustered"``: chapter 4's hierarchical model, m = 2 GMM effect clusters with one GP each
  and an SVM gate, on f_o & f_c.

All use the dimension-scaled length-scale prior (MAP), as the push-model study does: with a
few hundred pushes and tens of features, ML-II length scales overfit.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from probaff._checks import check_count
from probaff._threads import torch_threads
from probaff.data.schema import PushDataset
from probaff.errors import InputError
from probaff.features.ch4 import chapter4_features
from probaff.models import ClusteredGPModel, MixtureOfGPExperts, fit_em, get_fitter
from probaff.planning.learned import FeaturePushModel

__all__ = ["EDGE_MODELS", "EdgeModelSpec", "fit_edge_model"]


@dataclass(frozen=True)
class EdgeModelSpec:
    """How one planner model is fitted.

    Attributes:
        kind: ``"em"`` (`MixtureOfGPExperts` by `fit_em`) or ``"clustered"``.
        n_experts: M (or m clusters).
        gate: Feature groups of the gate (EM only).
        experts: Feature groups of the experts.
    """

    kind: str
    n_experts: int
    gate: tuple[str, ...]
    experts: tuple[str, ...]

    @property
    def groups(self) -> tuple[str, ...]:
        """Every group the model reads, in the feature set's order."""
        return tuple(g for g in ("f_o", "f_c", "f_x") if g in (*self.gate, *self.experts))


EDGE_MODELS: dict[str, EdgeModelSpec] = {
    "gp": EdgeModelSpec("em", 1, ("f_o", "f_c"), ("f_o", "f_c")),
    "moe": EdgeModelSpec("em", 2, ("f_x",), ("f_o", "f_c")),
    "clustered": EdgeModelSpec("clustered", 2, (), ("f_o", "f_c")),
}
"""The planner models, by name."""


def fit_edge_model(
    name: str,
    ds: PushDataset,
    *,
    seed: int = 0,
    em_iterations: int = 10,
    cloud_points: int | None = None,
    cloud_noise: float | None = None,
) -> FeaturePushModel:
    """Fit one of `EDGE_MODELS` on a push dataset of the task's scene.

    Args:
        name: A key of `EDGE_MODELS`.
        ds: The training pushes (object 0 is the book).
        seed: Seeds the fit.
        em_iterations: EM iterations (EM models).
        cloud_points: Points per cloud of `ds` (read from its clouds when ``None``).
        cloud_noise: Cloud noise of `ds` (m); from its metadata when ``None``.

    Returns:
        The fitted model with its features.

    Raises:
        InputError: For an unknown name, a `ds` that is not a `PushDataset` or holds fewer
            than 10 pushes, or a bad seed or iteration count.
    """
    if not isinstance(name, str) or name not in EDGE_MODELS:
        raise InputError(f"unknown planner model {name!r}; choose one of {sorted(EDGE_MODELS)}.")
    if not isinstance(ds, PushDataset):
        raise InputError(
            "ds must be a PushDataset of the task's scene (probaff generate --scene "
            f"push_to_edge), got {type(ds).__name__}."
        )
    seed = check_count("seed", seed, minimum=0)
    em_iterations = check_count("em_iterations", em_iterations)
    if len(ds) < 10:
        raise InputError(
            f"the training dataset has {len(ds)} pushes; fit planner models on at least 10 "
            "(probaff generate --scene push_to_edge --n 240)."
        )
    spec = EDGE_MODELS[name]
    fs = chapter4_features(ds)
    X = fs.select(*spec.groups)
    Y = np.asarray(ds["effect"][:, 0], dtype=float)
    offsets, start = {}, 0
    for g in spec.groups:
        width = fs.groups[g].stop - fs.groups[g].start
        offsets[g] = slice(start, start + width)
        start += width
    with torch_threads(1):
        model: MixtureOfGPExperts | ClusteredGPModel
        if spec.kind == "em":
            mixture = MixtureOfGPExperts(
                spec.n_experts,
                groups=offsets,
                gate_features=list(spec.gate),
                expert_features=list(spec.experts),
                lengthscale_prior=True,
            )
            fit_em(mixture, X, Y, seed=seed, max_iter=em_iterations)
            model = mixture
        else:
            cols = np.concatenate([np.arange(X.shape[1])[offsets[g]] for g in spec.experts])
            if len(cols) != X.shape[1]:
                raise InputError("a clustered planner model reads exactly its expert groups.")
            model = ClusteredGPModel(
                spec.n_experts, seed=seed, expert_kwargs={"lengthscale_prior": True}
            )
            get_fitter("clustered")(model, X, Y)
    fitted = FeaturePushModel.for_dataset(model, "ch4", spec.groups, ds)
    if cloud_points is None and cloud_noise is None:
        return fitted
    return replace(
        fitted,
        cloud_points=fitted.cloud_points if cloud_points is None else cloud_points,
        cloud_noise=fitted.cloud_noise if cloud_noise is None else cloud_noise,
    )
