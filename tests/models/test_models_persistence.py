import dataclasses
import hashlib
import io
import warnings
from dataclasses import replace

import numpy as np
import pytest
import torch

from probaff.errors import InputError
from probaff.models import (
    MIXTURE_GP,
    TRANSITION_GP,
    ClusteredGPModel,
    GPOptions,
    MixtureOfGPExperts,
    MonolithicTransitionModel,
    NotFittedError,
    SkillTransitionModel,
    VariationalMixtureOfGPExperts,
    fit_em,
    fit_svi,
    fit_transition,
)
from probaff.models.experts.sparse_expert import SparseGPExpert
from probaff.models.persistence import FORMATS, load, save
from probaff.models.synthetic import piecewise_1d

pytestmark = pytest.mark.usefixtures("single_thread")


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
        model = ClusteredGPModel(2, soft_gate=soft, gp=GPOptions(max_iter=10)).fit(x, y)
        path = tmp_path / f"clustered-{soft}.pt"
        save(model, path)
        loaded = load(path)
        assert type(loaded) is ClusteredGPModel and loaded.config() == model.config()
        assert np.array_equal(loaded.labels_, model.labels_)
        _assert_same_predictions(model, loaded, xt, yt)
    with pytest.raises(NotFittedError):
        save(ClusteredGPModel(2), tmp_path / "c.pt")
    # files written before `gp` hold the experts' keywords under "expert_kwargs"
    from probaff.models.mixture.clustered import _dump, _restore

    payload = _dump(model)
    assert payload["config"]["gp"] == dataclasses.asdict(GPOptions(max_iter=10))  # builtins
    del payload["config"]["gp"]
    payload["config"]["expert_kwargs"] = {"max_iter": 10}
    old = _restore(payload)
    assert old.gp == GPOptions(max_iter=10) and old.config() == model.config()
    _assert_same_predictions(model, old, xt, yt)


def test_load_rejects_truncated_and_incomplete_files(tmp_path):
    x, y, _ = piecewise_1d(30, seed=0)
    model = MixtureOfGPExperts(1, gp=replace(MIXTURE_GP, max_iter=5))
    fit_em(model, x, y, init="effects", max_iter=1, n_restarts=1, split_merge=0)
    path = tmp_path / "m.pt"
    save(model, path)
    data = path.read_bytes()
    for size in (0, 10, len(data) // 2, len(data) - 20):
        cut = tmp_path / f"cut{size}.pt"
        cut.write_bytes(data[:size])
        with pytest.raises(InputError, match="cannot read"):
            load(cut)
    payload = torch.load(io.BytesIO(_inner_bytes(path)), weights_only=True)
    del payload["state_dict"]
    incomplete = tmp_path / "incomplete.pt"
    torch.save(payload, incomplete)
    with (
        pytest.warns(UserWarning, match="no content hash"),
        pytest.raises(InputError, match="state_dict"),
    ):
        load(incomplete)
    with pytest.raises(InputError, match=r"there is no saved model at .*missing\.pt"):
        load(tmp_path / "missing.pt")
    with pytest.raises(InputError, match="cannot save a dict"):
        save({}, tmp_path / "d.pt")


# ------------------------------------------------------------- content hash
def _inner_bytes(path):
    """The payload archive inside a saved model file (what earlier releases wrote alone)."""
    return torch.load(path, weights_only=True)["payload"].numpy().tobytes()


def _em_model():
    x, y, _ = piecewise_1d(30, seed=0)
    model = MixtureOfGPExperts(2, gp=replace(MIXTURE_GP, max_iter=5))
    fit_em(model, x, y, init="effects", max_iter=1, n_restarts=1, split_merge=0)
    return model, x


def _vi_model():
    x, y, _ = piecewise_1d(40, seed=0)
    model = VariationalMixtureOfGPExperts(2, n_inducing=8, gate_features=[0])
    fit_svi(model, x, y, n_steps=5, batch_size=20, init="effects", seed=1)
    return model, x


def _clustered_model():
    rng = np.random.default_rng(0)
    x = rng.uniform(-1, 1, (40, 2))
    y = np.stack([np.where(x[:, 0] > 0, 0.1, 0.0), 0.01 * x[:, 1]], -1)
    y = y + rng.normal(0, 0.003, (40, 2))
    model = ClusteredGPModel(2, gp=GPOptions(max_iter=5)).fit(x, y)
    return model, torch.as_tensor(x)


def _skill_data(n=30):
    g = torch.Generator().manual_seed(0)
    x = torch.rand(n, 3, generator=g, dtype=torch.float64) * 2 - 1
    y = torch.stack([torch.sin(2 * x.sum(1)), 0.5 * x[:, 0]], dim=1)
    y = y + 0.02 * torch.randn(n, 2, generator=g, dtype=torch.float64)
    r = (0.8 * x.sum(1) + 0.01 * torch.randn(n, generator=g, dtype=torch.float64))[:, None]
    return x, y, r


def _skill_gp_model():
    x, y, r = _skill_data()
    model = SkillTransitionModel("push", gp=replace(TRANSITION_GP, max_iter=5))
    fit_transition(model, x, y, r)
    return model, x


def _skill_mixture_model():
    x, y, r = _skill_data()
    gp = replace(TRANSITION_GP, max_iter=5)
    model = SkillTransitionModel("pick", kind="mixture", n_experts=2, gp=gp)
    fit_transition(model, x, y, r, n_restarts=1, max_iter=1, split_merge=0)
    return model, x


def _monolithic_model():
    x, y, _ = _skill_data()
    model = MonolithicTransitionModel(1, gp=replace(TRANSITION_GP, max_iter=5))
    fit_transition(model, x, y)
    return model, x


KINDS = {
    "em": _em_model,
    "vi": _vi_model,
    "clustered": _clustered_model,
    "skill_gp": _skill_gp_model,
    "skill_mixture": _skill_mixture_model,
    "monolithic": _monolithic_model,
}


def _tensor_offset(data, model):
    """Offset in `data` of the middle of the largest stored tensor of `model`."""
    tensors = [getattr(model, "train_X", None)]
    if isinstance(model, torch.nn.Module):
        tensors += list(model.state_dict().values())
    raw = max(
        (t.detach().contiguous().numpy().tobytes() for t in tensors if t is not None),
        key=len,
    )
    start = data.find(raw)
    assert len(raw) >= 64 and start >= 0
    return start + len(raw) // 2


@pytest.mark.parametrize("kind", sorted(KINDS))
def test_corrupted_tensor_is_refused_and_old_files_load_with_a_warning(tmp_path, kind):
    model, x = KINDS[kind]()
    path = tmp_path / f"{kind}.pt"
    save(model, path)
    container = torch.load(path, weights_only=True)
    assert container["format"] == FORMATS[type(model)]
    assert container["sha256"] == hashlib.sha256(_inner_bytes(path)).hexdigest()
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a hashed file loads without a warning
        assert torch.equal(load(path).predict(x).mean, model.predict(x).mean)

    data = bytearray(path.read_bytes())
    at = _tensor_offset(bytes(data), model)
    data[at : at + 8] = bytes(b ^ 0x5A for b in data[at : at + 8])
    corrupt = tmp_path / "corrupt.pt"
    corrupt.write_bytes(bytes(data))
    with pytest.raises(InputError, match=r"corrupt\.pt' is corrupted: its content does not match"):
        load(corrupt)

    old = tmp_path / "old.pt"  # what earlier releases wrote: the payload archive alone
    old.write_bytes(_inner_bytes(path))
    with pytest.warns(UserWarning, match=r"old\.pt' carries no content hash"):
        loaded = load(old)
    assert torch.equal(loaded.predict(x).mean, model.predict(x).mean)


def test_malformed_hash_entries_and_foreign_files(tmp_path):
    model, _ = _em_model()
    path = tmp_path / "m.pt"
    save(model, path)
    container = torch.load(path, weights_only=True)
    for change in ({"sha256": 5}, {"payload": torch.zeros(3)}, {"sha256": "0" * 64}):
        bad = tmp_path / "bad.pt"
        torch.save({**container, **change}, bad)
        with pytest.raises(InputError, match=r"bad\.pt' is (an incomplete saved model|corrupted)"):
            load(bad)
    text = tmp_path / "notes.json"
    text.write_text('{"format": "probaff.models.MixtureOfGPExperts/1"}')
    with pytest.raises(InputError, match=r"cannot read a saved model from .*notes\.json.*re-fit"):
        load(text)
    with pytest.raises(InputError, match="is a folder, not a saved model"):
        load(tmp_path)
    with pytest.raises(InputError, match="path must be the path of a file"):
        load(3)


def test_save_to_a_bad_path_names_it(tmp_path):
    model, _ = _em_model()
    regular = tmp_path / "somefile.txt"
    regular.write_text("x")
    with pytest.raises(InputError, match=r"path .*somefile.txt/model.pt lies under .*somefile"):
        save(model, regular / "model.pt")
    with pytest.raises(InputError, match=r"path .* is a folder, not a file"):
        save(model, tmp_path)
    save(model, tmp_path / "new" / "deeper" / "m.pt")  # missing folders are created
    assert isinstance(load(tmp_path / "new" / "deeper" / "m.pt"), MixtureOfGPExperts)


def test_sparse_mixture_round_trip_is_bit_identical(tmp_path):
    x, y, _ = piecewise_1d(60, seed=0)
    xt, yt, _ = piecewise_1d(40, seed=1)
    model = MixtureOfGPExperts(
        2, experts="sparse", n_inducing=12, gp=replace(MIXTURE_GP, max_iter=10)
    )
    fit_em(model, x, y, max_iter=2, n_restarts=1, split_merge=0)
    path = tmp_path / "sparse.pt"
    save(model, path)
    loaded = load(path)
    assert loaded.config() == model.config() and loaded.built_expert_kind == "sparse"
    assert all(isinstance(e, SparseGPExpert) for e in loaded.experts)
    for a, b in zip(model.experts, loaded.experts, strict=True):
        assert torch.equal(a.inducing, b.inducing)
    pa, pb = model.predict(xt), loaded.predict(xt)
    assert torch.equal(pa.mean, pb.mean) and torch.equal(pa.variance, pb.variance)
    assert torch.equal(pa.log_prob(yt), pb.log_prob(yt))
    assert torch.equal(model.loo_log_lik(x, y), loaded.loo_log_lik(x, y))


def test_a_file_whose_stored_sizes_disagree_with_its_data_is_named_inconsistent(tmp_path):
    model, _ = _skill_gp_model()
    path = tmp_path / "skill.pt"
    save(model, path)
    container = torch.load(path, weights_only=True)
    payload = torch.load(io.BytesIO(_inner_bytes(path)), weights_only=True)
    payload["sizes"] = [payload["sizes"][0] + 1, *payload["sizes"][1:]]  # 4 features, data has 3
    inner = io.BytesIO()
    torch.save(payload, inner)
    data = inner.getvalue()
    container["payload"] = torch.from_numpy(np.frombuffer(data, dtype=np.uint8).copy())
    container["sha256"] = hashlib.sha256(data).hexdigest()  # a valid hash
    torch.save(container, tmp_path / "resized.pt")
    with pytest.raises(
        InputError,
        match=r"resized\.pt' is an inconsistent saved model \(probaff\.models\."
        r"SkillTransitionModel/1\): its stored sizes or settings disagree with its data "
        r"\(.*shape.*\); re-save the model",
    ):
        load(tmp_path / "resized.pt")
