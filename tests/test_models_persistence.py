import pytest
import torch

from probaff._threads import torch_threads
from probaff.errors import InputError
from probaff.models import MixtureOfGPExperts, NotFittedError, fit_em
from probaff.models.persistence import load, save
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
