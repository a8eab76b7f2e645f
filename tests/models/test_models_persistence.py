import numpy as np
import pytest
import torch

from probaff._threads import torch_threads
from probaff.errors import InputError
from probaff.models import (
    ClusteredGPModel,
    MixtureOfGPExperts,
    NotFittedError,
    VariationalMixtureOfGPExperts,
    fit_em,
    fit_svi,
)
from probaff.models.persistence import FORMATS, load, save
from probaff.models.synthetic import piecewise_1d


@pytest.fixture(autouse=True, scope="module")
def _single_thread():
    with torch_threads(1):
        yield


def test_save_load_round_trip_is_bit_identical(tmp_path):
    x, y, _ = piecewise_1d(60, seed=0)
    xt, yt, _ = piecewise_1d(40, seed=1)
    x = torch.cat([x, x.square()], dim=1)
    xt = torch.cat([xt, xt.square()], dim=1)
    model = MixtureOfGPExperts(
        3, groups={"f_x": [0], "f_sq": slice(1, 2)}, gate_features="f_x", expert_features=None
    )
    fit_em(model, x, y, max_iter=3)
    path = tmp_path / "mixture.pt"
    save(model, path)
    assert [p.name for p in tmp_path.iterdir()] == ["mixture.pt"]
    loaded = load(path)
    assert loaded.config() == model.config()
    a, b = model.predict(xt), loaded.predict(xt)
    assert torch.equal(a.mean, b.mean)
    assert torch.equal(a.variance, b.variance)
    assert torch.equal(a.log_prob(yt), b.log_prob(yt))
    assert torch.equal(model.gate_probs(xt), loaded.gate_probs(xt))
    for la, lb in zip(model.lengthscales(), loaded.lengthscales(), strict=True):
        assert torch.equal(la, lb)

    # overwriting is atomic and leaves no temporary file behind
    save(loaded, path)
    assert [p.name for p in tmp_path.iterdir()] == ["mixture.pt"]
    assert torch.equal(load(path).predict(xt).mean, a.mean)


def test_save_unfitted_and_load_garbage(tmp_path):
    with pytest.raises(NotFittedError, match="fit_em"):
        save(MixtureOfGPExperts(2), tmp_path / "m.pt")
    garbage = tmp_path / "garbage.pt"
    garbage.write_bytes(b"not a model")
    with pytest.raises(InputError, match="cannot read"):
        load(garbage)
    other = tmp_path / "other.pt"
    torch.save({"format": "something else"}, other)
    with pytest.raises(InputError, match="not a saved mixture"):
        load(other)


def _assert_same_predictions(a_model, b_model, xt, yt):
    a, b = a_model.predict(xt), b_model.predict(xt)
    assert torch.equal(a.mean, b.mean)
    assert torch.equal(a.variance, b.variance)
    assert torch.equal(a.log_prob(yt), b.log_prob(yt))
    assert torch.equal(a_model.gate_probs(xt), b_model.gate_probs(xt))


def test_variational_mixture_round_trip_is_bit_identical(tmp_path):
    x, y, _ = piecewise_1d(40, seed=0)
    xt, yt, _ = piecewise_1d(25, seed=1)
    model = VariationalMixtureOfGPExperts(2, n_inducing=8, gate_features=[0])
    fit_svi(model, x, y, n_steps=10, batch_size=20, init="effects", seed=1)
    path = tmp_path / "vi.pt"
    save(model, path)
    loaded = load(path)
    assert type(loaded) is VariationalMixtureOfGPExperts
    assert torch.load(path, weights_only=True)["format"] == FORMATS[VariationalMixtureOfGPExperts]
    assert loaded.config() == model.config() and loaded.is_fitted
    # every parameter Pyro trained comes back
    params = dict(model.named_parameters())
    loaded_params = dict(loaded.named_parameters())
    assert params.keys() == loaded_params.keys() and len(params) > 0
    for name, value in params.items():
        assert torch.equal(value, loaded_params[name]), name
    _assert_same_predictions(model, loaded, xt, yt)
    torch.testing.assert_close(
        loaded.expert_predictions(xt).loc, model.expert_predictions(xt).loc, rtol=0, atol=0
    )


def test_clustered_model_round_trip_is_bit_identical(tmp_path):
    rng = np.random.default_rng(0)
    x = rng.uniform(-1, 1, (60, 2))
    y = np.stack(
        [np.where(x[:, 0] > 0, 0.1, 0.0) + 0.01 * x[:, 1], np.where(x[:, 0] > 0, 0.0, 0.05)], -1
    ) + rng.normal(0, 0.003, (60, 2))
    xt = torch.as_tensor(rng.uniform(-1, 1, (30, 2)))
    yt = torch.zeros(30, 2, dtype=torch.float64)
    for soft in (False, True):
        model = ClusteredGPModel(2, soft_gate=soft, expert_kwargs={"max_iter": 10}).fit(x, y)
        path = tmp_path / f"clustered-{soft}.pt"
        save(model, path)
        loaded = load(path)
        assert type(loaded) is ClusteredGPModel and loaded.config() == model.config()
        assert np.array_equal(loaded.labels_, model.labels_)
        _assert_same_predictions(model, loaded, xt, yt)
    with pytest.raises(NotFittedError):
        save(ClusteredGPModel(2), tmp_path / "c.pt")


def test_load_rejects_truncated_and_incomplete_files(tmp_path):
    x, y, _ = piecewise_1d(30, seed=0)
    model = MixtureOfGPExperts(1, gp_max_iter=5)
    fit_em(model, x, y, init="effects", max_iter=1, n_restarts=1, split_merge=0)
    path = tmp_path / "m.pt"
    save(model, path)
    data = path.read_bytes()
    for size in (0, 10, len(data) // 2, len(data) - 20):
        cut = tmp_path / f"cut{size}.pt"
        cut.write_bytes(data[:size])
        with pytest.raises(InputError, match="cannot read"):
            load(cut)
    payload = torch.load(path, weights_only=True)
    del payload["state_dict"]
    incomplete = tmp_path / "incomplete.pt"
    torch.save(payload, incomplete)
    with pytest.raises(InputError, match="state_dict"):
        load(incomplete)
    with pytest.raises(FileNotFoundError):
        load(tmp_path / "missing.pt")
    with pytest.raises(InputError, match="cannot save a dict"):
        save({}, tmp_path / "d.pt")
