"""Chapter 4's hierarchical push model: effect clusters, one GP per cluster, an SVM gate.

Training clusters the pushes by a GMM on chosen effect dimensions (the in-plane displacement
(dy_p, dz_p) in the thesis), fits one exact ARD GP expert to each cluster on all effect
dimensions, and trains a multiclass SVM on the features to recognise the cluster. Prediction
asks the SVM for the cluster and returns that expert's prediction; with ``soft_gate=True`` the
SVM's calibrated probabilities weight all experts instead.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import numpy as np
import torch
from sklearn.calibration import CalibratedClassifierCV
from sklearn.mixture import GaussianMixture
from sklearn.pipeline import make_pipeline
from sklearn.preprocessing import StandardScaler
from sklearn.svm import SVC
from torch.distributions import MixtureSameFamily, Normal

from probaff._checks import check_count
from probaff._threads import threads_by_rows
from probaff.errors import InputError, NotFittedError
from probaff.models.experts.gp_expert import GPExpert
from probaff.models.gates.gated import gated_probs, mixture_distribution
from probaff.models.options import GPOptions
from probaff.models.registry import Codec, ModelKind, ModelSettings, register_model_kind
from probaff.models.tensors import as_matrix

__all__ = ["ClusteredGPModel", "fit_clustered"]


class ClusteredGPModel:
    """GMM-clustered GP experts with an SVM gate (the chapter 4 baseline).

    Args:
        n_clusters: Number of clusters and experts m.
        cluster_dims: Effect columns the GMM clusters on.
        seed: Seed of the GMM (with `n_init` restarts) and the SVM.
        n_init: GMM restarts.
        svm_c: SVM regularisation C (RBF kernel, standardised features).
        soft_gate: Weight experts by the SVM's probabilities instead of picking one.
        gp: The settings of every expert, whole (`GPOptions`); None for `GPOptions()`, a
            single `GPExpert`'s defaults.

    Raises:
        InputError: For a bad count or seed, or a `gp` that is not a `GPOptions`.
    """

    def __init__(
        self,
        n_clusters: int,
        *,
        cluster_dims: tuple[int, ...] = (0, 1),
        seed: int = 0,
        n_init: int = 5,
        svm_c: float = 1.0,
        soft_gate: bool = False,
        gp: GPOptions | None = None,
    ) -> None:
        self.n_clusters = check_count("n_clusters", n_clusters)
        check_count("n_init", n_init)
        check_count("seed", seed, minimum=0)
        self.cluster_dims = tuple(cluster_dims)
        self.seed = seed
        self.n_init = n_init
        self.svm_c = svm_c
        self.soft_gate = soft_gate
        if gp is not None and type(gp) is not GPOptions:
            raise InputError(
                f"gp must be GPOptions (the experts' settings, e.g. GPOptions(max_iter=20)) or "
                f"None, got {type(gp).__name__}."
            )
        self.gp = GPOptions() if gp is None else gp
        self.experts: list[GPExpert] = []
        self.n_features: int | None = None
        self.n_outputs: int | None = None
        self.train_X: torch.Tensor | None = None
        self.train_Y: torch.Tensor | None = None
        self.labels_: np.ndarray | None = None
        self._svm: Any = None
        self._classes: np.ndarray | None = None

    def config(self) -> dict[str, Any]:
        """Constructor arguments, so that ``ClusteredGPModel(**model.config())`` rebuilds it.

        Builtins, except ``gp``, the experts' `GPOptions` whole (`save` stores its fields).
        """
        names = ("n_clusters", "cluster_dims", "seed", "n_init", "svm_c", "soft_gate", "gp")
        return {n: getattr(self, n) for n in names}

    @property
    def is_fitted(self) -> bool:
        """Whether `fit` has run."""
        return bool(self.experts) and self.labels_ is not None

    def check_fitted(self) -> None:
        """Raise `NotFittedError` unless the model has been fitted."""
        if not self.is_fitted:
            raise NotFittedError("ClusteredGPModel is not fitted; call fit first.")

    @threads_by_rows("X")
    def fit(self, X: Any, Y: Any) -> ClusteredGPModel:
        """Cluster, fit the experts and the gate.

        Args:
            X: Features, (N, D).
            Y: Effects, (N, E).

        Returns:
            This model.

        Raises:
            InputError: On malformed data, a cluster dimension that does not exist, or more
                clusters than samples.
        """
        x = as_matrix("features X", X)
        y = as_matrix("effects Y", Y, n_rows=x.shape[0])
        n, e = y.shape
        if any(not 0 <= d < e for d in self.cluster_dims):
            raise InputError(f"cluster_dims {self.cluster_dims} outside the {e} effect columns.")
        if self.n_clusters > n:
            raise InputError(
                f"{self.n_clusters} clusters but only {n} samples; use at most {n} clusters."
            )
        yn = y.numpy()
        if self.n_clusters == 1:
            labels = np.zeros(n, dtype=int)
        else:
            gmm = GaussianMixture(
                self.n_clusters, n_init=self.n_init, random_state=self.seed, reg_covar=1e-6
            )
            labels = gmm.fit_predict(yn[:, list(self.cluster_dims)])
        self.experts = [
            GPExpert(x.shape[1], e, self.gp).fit(x[labels == k], y[labels == k])
            for k in np.unique(labels)
        ]
        self.fit_gate(x, y, labels)
        return self

    def fit_gate(self, X: Any, Y: Any, labels: Any) -> None:
        """Set the clustering and train the SVM gate on it (the experts are left alone).

        Called by `fit`, and by `probaff.models.load`, which restores the experts from their
        saved state and refits the (deterministic) gate on the saved clustering.

        Args:
            X: Features, (N, D).
            Y: Effects, (N, E).
            labels: Cluster of every sample, (N,).
        """
        x = as_matrix("features X", X)
        y = as_matrix("effects Y", Y, n_rows=x.shape[0])
        labels = np.asarray(labels, dtype=int)
        xn = x.numpy()
        self.n_features, self.n_outputs = int(x.shape[1]), int(y.shape[1])
        self.train_X, self.train_Y = x, y
        self._classes = np.unique(labels)
        self.labels_ = labels
        self._svm = None
        if len(self._classes) > 1:
            svm: Any = SVC(C=self.svm_c, kernel="rbf", random_state=self.seed)
            if self.soft_gate:
                svm = CalibratedClassifierCV(svm, ensemble=False)
            self._svm = make_pipeline(StandardScaler(), svm)
            self._svm.fit(xn, labels)

    def gate_probs(self, X: Any) -> torch.Tensor:
        """(N, m') probabilities of each fitted cluster (one-hot unless `soft_gate`)."""
        self.check_fitted()
        x = as_matrix("features X", X, n_cols=self.experts[0].n_features).numpy()
        k = len(self.experts)
        if k == 1:
            return torch.ones(len(x), 1, dtype=torch.float64)
        if self.soft_gate:
            return torch.as_tensor(self._svm.predict_proba(x), dtype=torch.float64)
        assert self._classes is not None
        pick = np.searchsorted(self._classes, self._svm.predict(x))
        return torch.nn.functional.one_hot(torch.as_tensor(pick), k).double()

    def expert_predictions(self, X: Any) -> Normal:
        """Every cluster expert's predictive distribution, loc and scale (N, m', E)."""
        self.check_fitted()
        preds = [ex.predict(X) for ex in self.experts]
        return Normal(
            torch.stack([p.loc for p in preds], dim=1), torch.stack([p.scale for p in preds], dim=1)
        )

    def predict(self, X: Any, *, gating: str = "soft") -> MixtureSameFamily:
        """Predictive distribution over effects, batch (N,), event (E,).

        Args:
            X: Features, (N, D).
            gating: ``"soft"`` (default) mixes the experts by `gate_probs` (one-hot unless
                `soft_gate`); ``"hard"`` uses the most probable cluster only.
        """
        return mixture_distribution(
            gated_probs(self.gate_probs(X), gating), self.expert_predictions(X)
        )


# ----------------------------------------------------- the "clustered" kind
def fit_clustered(
    model: ClusteredGPModel, X: Any, Y: Any, options: None = None, **overrides: Any
) -> ClusteredGPModel:
    """Fit chapter 4's clustered model (`ClusteredGPModel.fit`).

    Args:
        model: The model to fit.
        X: Features, `(N, D)`.
        Y: Effects, `(N, E)`.
        options: Must be None: the model's settings are its constructor's.
        **overrides: Must be empty, for the same reason.

    Returns:
        The fitted model.

    Raises:
        InputError: If `model` is not a `ClusteredGPModel`, options are given, or as
            `ClusteredGPModel.fit`.
    """
    if not isinstance(model, ClusteredGPModel):
        raise InputError(
            f"the 'clustered' fitter fits a ClusteredGPModel, got {type(model).__name__}."
        )
    if options is not None or overrides:
        given = sorted(overrides) + (["options"] if options is not None else [])
        raise InputError(
            f"a ClusteredGPModel takes no fitting options, got {given}; set its seed and "
            "gp=GPOptions(...) in its constructor."
        )
    return model.fit(X, Y)


def _dump(model: ClusteredGPModel) -> dict[str, Any]:
    assert model.labels_ is not None
    return {
        "config": {**model.config(), "gp": dataclasses.asdict(model.gp)},  # GPOptions' fields
        "X": model.train_X,
        "Y": model.train_Y,
        "labels": torch.as_tensor(model.labels_, dtype=torch.int64),
        "state_dict": [e.state_dict() for e in model.experts],
    }


def _saved_config(config: dict[str, Any]) -> dict[str, Any]:
    """A saved model's constructor arguments, its experts' settings as one `GPOptions`.

    Files written since hold `GPOptions`' fields under ``gp``; older files hold the
    keywords each `GPExpert` was given under ``expert_kwargs`` (fields of `GPOptions` too).
    """
    out = dict(config)
    saved = out.pop("expert_kwargs", None) if "gp" not in out else out["gp"]
    out["gp"] = GPOptions(**(saved or {}))
    return out


def _restore(payload: dict[str, Any]) -> ClusteredGPModel:
    model = ClusteredGPModel(**_saved_config(payload["config"]))
    x, y, labels = payload["X"], payload["Y"], payload["labels"]
    experts = []
    for k, state in zip(labels.unique().tolist(), payload["state_dict"], strict=True):
        rows = labels == k
        expert = GPExpert(x.shape[1], y.shape[1], model.gp)
        expert.condition(x[rows], y[rows])
        expert.load_state_dict(state)
        experts.append(expert)
    model.experts = experts
    model.fit_gate(x, y, labels.numpy())
    return model


def _build(settings: ModelSettings) -> ClusteredGPModel:
    if settings.gate:
        raise InputError(
            "a ClusteredGPModel's gate is an SVM on every column it is given; leave gate unset "
            f"(got {list(settings.gate)})."
        )
    # settings.gp whole; None is GPOptions(), a single GPExpert's defaults
    return ClusteredGPModel(settings.n_experts, seed=settings.seed, gp=settings.gp)


_FORMAT = "probaff.models.ClusteredGPModel/1"
_CODEC = Codec(_FORMAT, _dump, _restore, ("config", "X", "Y", "labels", "state_dict"))
register_model_kind(ModelKind("clustered", ClusteredGPModel, fit_clustered, None, _CODEC, _build))
