"""Chapter 4's hierarchical push model: effect clusters, one GP per cluster, an SVM gate.

Training clusters the pushes by a GMM on chosen effect dimensions (the in-plane displacement
(dy_p, dz_p) in the thesis), fits one exact ARD GP expert to each cluster on all effect
dimensions, and trains a multiclass SVM on the features to recognise the cluster. Prediction
asks the SVM for the cluster and returns that expert's prediction; with ``soft_gate=True`` the
SVM's calibrated probabilities weight all experts instead.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import torch
from sklearn.calibration import CalibratedClassifierCV
from sklearn.mixture import GaussianMixture
from sklearn.pipeline import make_pipeline
from sklearn.preprocessing import StandardScaler
from sklearn.svm import SVC
from torch.distributions import Categorical, Independent, MixtureSameFamily

from probaff._checks import check_count
from probaff.errors import InputError, NotFittedError
from probaff.models._tensors import as_matrix
from probaff.models.gp_expert import GPExpert

__all__ = ["ClusteredGPModel"]


class ClusteredGPModel:
    """GMM-clustered GP experts with an SVM gate (the chapter 4 baseline).

    Args:
        n_clusters: Number of clusters and experts m.
        cluster_dims: Effect columns the GMM clusters on.
        seed: Seed of the GMM (with `n_init` restarts) and the SVM.
        n_init: GMM restarts.
        svm_c: SVM regularisation C (RBF kernel, standardised features).
        soft_gate: Weight experts by the SVM's probabilities instead of picking one.
        expert_kwargs: Passed to each `GPExpert`.
    """

    def __init__(self, n_clusters: int, *, cluster_dims: tuple[int, ...] = (0, 1),
                 seed: int = 0, n_init: int = 5, svm_c: float = 1.0, soft_gate: bool = False,
                 expert_kwargs: dict[str, Any] | None = None) -> None:
        self.n_clusters = check_count("n_clusters", n_clusters)
        check_count("n_init", n_init)
        check_count("seed", seed, minimum=0)
        self.cluster_dims = tuple(cluster_dims)
        self.seed = seed
        self.n_init = n_init
        self.svm_c = svm_c
        self.soft_gate = soft_gate
        self.expert_kwargs = dict(expert_kwargs or {})
        self.experts: list[GPExpert] = []
        self.labels_: np.ndarray | None = None
        self._svm: Any = None
        self._classes: np.ndarray | None = None

    def fit(self, X: Any, Y: Any) -> ClusteredGPModel:
        """Cluster, fit the experts and the gate.

        Args:
            X: Features, (N, D).
            Y: Effects, (N, E).

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
        xn, yn = x.numpy(), y.numpy()
        if self.n_clusters == 1:
            labels = np.zeros(n, dtype=int)
        else:
            gmm = GaussianMixture(self.n_clusters, n_init=self.n_init, random_state=self.seed,
                                  reg_covar=1e-6)
            labels = gmm.fit_predict(yn[:, list(self.cluster_dims)])
        self._classes = np.unique(labels)
        self.experts = [GPExpert(x.shape[1], e, **self.expert_kwargs).fit(x[labels == k],
                                                                          y[labels == k])
                        for k in self._classes]
        self.labels_ = labels
        if len(self._classes) > 1:
            svm: Any = SVC(C=self.svm_c, kernel="rbf", random_state=self.seed)
            if self.soft_gate:
                svm = CalibratedClassifierCV(svm, ensemble=False)
            self._svm = make_pipeline(StandardScaler(), svm)
            self._svm.fit(xn, labels)
        return self

    def gate_probs(self, X: Any) -> torch.Tensor:
        """(N, m') probabilities of each fitted cluster (one-hot unless `soft_gate`)."""
        if not self.experts:
            raise NotFittedError("ClusteredGPModel is not fitted; call fit first.")
        x = as_matrix("features X", X, n_cols=self.experts[0].n_features).numpy()
        k = len(self.experts)
        if k == 1:
            return torch.ones(len(x), 1, dtype=torch.float64)
        if self.soft_gate:
            return torch.as_tensor(self._svm.predict_proba(x), dtype=torch.float64)
        assert self._classes is not None
        pick = np.searchsorted(self._classes, self._svm.predict(x))
        return torch.nn.functional.one_hot(torch.as_tensor(pick), k).double()

    def predict(self, X: Any) -> MixtureSameFamily:
        """Predictive distribution over effects, batch (N,), event (E,)."""
        probs = self.gate_probs(X)
        preds = [ex.predict(X) for ex in self.experts]
        loc = torch.stack([p.loc for p in preds], dim=1)  # (N, m', E)
        scale = torch.stack([p.scale for p in preds], dim=1)
        return MixtureSameFamily(Categorical(probs=probs),
                                 Independent(torch.distributions.Normal(loc, scale), 1))
