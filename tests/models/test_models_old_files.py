"""Models saved by earlier releases still load and predict as then: a mixture from before the
content hash, a mixture and a transition model from before their GP settings were one
`GPOptions`.

The file and the predictions beside it were written by probaff at commit 4b5b220 (the last one
before model files carried a SHA-256; see tests/data/fixtures/README.md), with that commit's
code: they are what an earlier release wrote, not today's payload unwrapped.
"""

import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import torch

from probaff.errors import InputError
from probaff.models import (
    MIXTURE_GP,
    TRANSITION_GP,
    GPOptions,
    MixtureOfGPExperts,
    SkillTransitionModel,
    load,
    save,
)
from probaff.models.mixture.em import _saved_config
from probaff.models.transitions.transition import _saved_config as _saved_transition_config

FIXTURES = Path(__file__).resolve().parents[1] / "data" / "fixtures"
OLD = FIXTURES / "mixture_before_hash.pt"


def _predicts_as_recorded(model, expected: str) -> torch.Tensor:
    """Check `model`'s predictions against the fixture `expected`; return its test inputs."""
    want = np.load(FIXTURES / expected)
    x = torch.as_tensor(want["x_test"])
    with torch.no_grad():
        pred = model.predict(x)
        log_prob = pred.log_prob(torch.zeros(len(x), 2, dtype=torch.float64))
    np.testing.assert_allclose(pred.mean.numpy(), want["mean"], rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(pred.variance.numpy(), want["variance"], rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(log_prob.numpy(), want["log_prob"], rtol=1e-9, atol=1e-9)
    return x


def _saved_again_is_the_same(model, expected: str, path) -> None:
    """Check `model` against `expected`, then that saved again (GPOptions' fields under "gp")
    it loads to the same settings and predictions."""
    x = _predicts_as_recorded(model, expected)
    save(model, path)
    again = load(path)
    assert again.gp == model.gp and again.config() == model.config()
    assert torch.equal(again.predict(x).mean, model.predict(x).mean)


def test_a_mixture_saved_before_the_hash_predicts_as_the_old_release_did(tmp_path):
    container = torch.load(OLD, weights_only=True)
    assert "sha256" not in container and "payload" not in container  # the old layout
    assert container["format"] == "probaff.models.MixtureOfGPExperts/1"
    with pytest.warns(UserWarning, match=r"mixture_before_hash\.pt' carries no content hash"):
        model = load(OLD)
    assert isinstance(model, MixtureOfGPExperts)
    x = _predicts_as_recorded(model, "mixture_before_hash_expected.npz")
    # saved again, it gains the hash and loads without a warning, predicting the same
    path = tmp_path / "again.pt"
    save(model, path)
    assert "sha256" in torch.load(path, weights_only=True)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        again = load(path)
    assert torch.equal(again.predict(x).mean, model.predict(x).mean)


def test_a_damaged_old_file_is_refused_by_name(tmp_path):
    data = OLD.read_bytes()
    bad = tmp_path / "old_truncated.pt"
    bad.write_bytes(data[: len(data) // 2])
    with pytest.raises(InputError, match=r"old_truncated\.pt'"):
        load(bad)


FLAT_GP = FIXTURES / "mixture_flat_gp.pt"


def test_a_mixture_saved_with_flat_gp_settings_loads_them_as_one_gp_options(tmp_path):
    """Files written before ``gp=GPOptions`` hold the experts' settings as flat keys."""
    container = torch.load(FLAT_GP, weights_only=True)
    assert container["format"] == "probaff.models.MixtureOfGPExperts/1"
    model = load(FLAT_GP)
    # the old keys, mapped to one GPOptions (the floor as the old code stored it: float32)
    assert model.gp.max_iter == 7 and model.gp.lengthscale_prior == 0.5
    assert model.gp.noise_floor == pytest.approx((0.01, 0.02), rel=1e-7)
    assert {"gp_max_iter", "lengthscale_prior", "noise_floor"}.isdisjoint(model.config())
    for expert in model.experts:
        assert expert.max_iter == 7 and expert.lengthscale_prior == 0.5
    _saved_again_is_the_same(model, "mixture_flat_gp_expected.npz", tmp_path / "again.pt")


def test_the_old_releases_flat_keys_map_to_gp_options_and_missing_ones_to_the_default():
    with pytest.warns(UserWarning, match="carries no content hash"):
        model = load(OLD)
    # written with gp_max_iter=10 and that release's other settings, stored beside it
    assert model.gp == GPOptions(max_iter=10, lengthscale_prior=False, noise_floor="auto")
    # a key a file lacks takes MIXTURE_GP's value
    config = _saved_config({"n_experts": 2, "gp_max_iter": 4})
    assert config["gp"] == replace(MIXTURE_GP, max_iter=4) and "gp_max_iter" not in config


FLAT_GP_TRANSITION = FIXTURES / "transition_flat_gp.pt"


def test_a_transition_model_saved_with_flat_gp_settings_loads_them_as_one_gp_options(tmp_path):
    """Files written before ``gp=GPOptions`` hold a transition model's GP settings flat."""
    container = torch.load(FLAT_GP_TRANSITION, weights_only=True)
    assert container["format"] == "probaff.models.SkillTransitionModel/1"
    model = load(FLAT_GP_TRANSITION)
    assert isinstance(model, SkillTransitionModel)
    assert model.gp == GPOptions(
        max_iter=7, lengthscale_prior=0.5, noise_floor=0.02, outputscale=0.2, noise=0.05
    )
    assert {"gp_max_iter", "lengthscale_prior", "noise_floor"}.isdisjoint(model.config())
    _saved_again_is_the_same(model, "transition_flat_gp_expected.npz", tmp_path / "again.pt")
    # a key a file lacks takes TRANSITION_GP's value; flat keys beside "gp" are refused
    config = _saved_transition_config({"skill": "push", "gp_max_iter": 4})
    assert config["gp"] == replace(TRANSITION_GP, max_iter=4) and "gp_max_iter" not in config
    with pytest.raises(InputError, match="must hold GPOptions' fields"):
        _saved_transition_config({"skill": "push", "noise": 0.1, "gp": {"max_iter": 4}})
