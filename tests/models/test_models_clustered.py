import numpy as np
import pytest
import torch
from sklearn.metrics import adjusted_rand_score

from probaff.errors import InputError, NotFittedError
from probaff.eval.metrics import rmse
from probaff.models.mixture.clustered import ClusteredGPModel


def _blocked_pushes(n=150, seed=0):
    """Free, partly and fully blocked pushes: three effect regimes set by one feature."""
    rng = np.random.default_rng(seed)
    x = rng.uniform(-1, 1, (n, 3))
    regime = np.digitize(x[:, 0], [-0.33, 0.33])
    dz = np.choose(regime, [0.15 + 0.01 * x[:, 1], 0.07 + 0.02 * x[:, 1], 0.0 * x[:, 1]])
    dy = np.choose(regime, [0.01 * x[:, 2], 0.03 + 0.01 * x[:, 2], 0.0 * x[:, 2]])
    y = np.stack([dy, dz], -1) + rng.normal(0, 0.003, (n, 2))
    return x, y, regime


def test_clusters_find_the_regimes_and_predict():
    x, y, regime = _blocked_pushes()
    xt, yt, regime_t = _blocked_pushes(seed=1)
    three = ClusteredGPModel(3, seed=0).fit(x, y)
    assert adjusted_rand_score(regime, three.labels_) > 0.9
    gate = three.gate_probs(xt)
    assert gate.shape == (150, 3)
    assert adjusted_rand_score(regime_t, gate.argmax(1).numpy()) > 0.7  # the SVM gate
    err = rmse(three.predict(xt), torch.as_tensor(yt))
    spread = torch.as_tensor(yt).std(0)
    assert torch.all(err < spread) and err[1] < 0.5 * spread[1]  # beats the mean; dz well


def test_soft_gate_probabilities():
    x, y, _ = _blocked_pushes(90)
    m = ClusteredGPModel(2, soft_gate=True).fit(x, y)
    p = m.gate_probs(x)
    assert torch.allclose(p.sum(1), torch.ones(90, dtype=torch.float64))


def test_errors():
    x, y, _ = _blocked_pushes(10)
    with pytest.raises(InputError, match="only 10 samples"):
        ClusteredGPModel(11).fit(x, y)
    with pytest.raises(InputError, match="cluster_dims"):
        ClusteredGPModel(2, cluster_dims=(0, 5)).fit(x, y)
    with pytest.raises(NotFittedError):
        ClusteredGPModel(2).predict(x)
    bad = x.copy()
    bad[0, 0] = np.inf
    with pytest.raises(InputError, match="NaN or infinite"):
        ClusteredGPModel(2).fit(bad, y)
