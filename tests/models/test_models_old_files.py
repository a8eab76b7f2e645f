"""A mixture saved by a release from before the content hash still loads and predicts as then.

The file and the predictions beside it were written by probaff at commit 4b5b220 (the last one
before model files carried a SHA-256; see tests/data/fixtures/README.md), with that commit's
code: they are what an earlier release wrote, not today's payload unwrapped.
"""

import warnings
from pathlib import Path

import numpy as np
import pytest
import torch

from probaff.errors import InputError
from probaff.models import MixtureOfGPExperts, load, save

FIXTURES = Path(__file__).resolve().parents[1] / "data" / "fixtures"
OLD = FIXTURES / "mixture_before_hash.pt"


def test_a_mixture_saved_before_the_hash_predicts_as_the_old_release_did(tmp_path):
    container = torch.load(OLD, weights_only=True)
    assert "sha256" not in container and "payload" not in container  # the old layout
    assert container["format"] == "probaff.models.MixtureOfGPExperts/1"
    with pytest.warns(UserWarning, match=r"mixture_before_hash\.pt' carries no content hash"):
        model = load(OLD)
    assert isinstance(model, MixtureOfGPExperts)
    want = np.load(FIXTURES / "mixture_before_hash_expected.npz")
    x = torch.as_tensor(want["x_test"])
    with torch.no_grad():
        pred = model.predict(x)
        log_prob = pred.log_prob(torch.zeros(len(x), 2, dtype=torch.float64))
    np.testing.assert_allclose(pred.mean.numpy(), want["mean"], rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(pred.variance.numpy(), want["variance"], rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(log_prob.numpy(), want["log_prob"], rtol=1e-9, atol=1e-9)
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
