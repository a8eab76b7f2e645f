"""Saving and loading a fitted mixture of GP experts as one file."""

from __future__ import annotations

import os
import pickle
import tempfile
from pathlib import Path
from typing import Any

import torch

from probaff.errors import InputError
from probaff.models.mixture import MixtureOfGPExperts

__all__ = ["FORMAT", "load", "save"]

FORMAT = "probaff.models.MixtureOfGPExperts/1"
"""Identifier and version stored in every saved mixture."""


def save(model: MixtureOfGPExperts, path: str | os.PathLike[str]) -> None:
    """Write a fitted mixture to `path` atomically.

    The file (``torch.save`` of a dict) holds the constructor configuration, the training
    data with the experts' sample weights, and the state dict. It is first written to a
    temporary file in the same directory, then moved over `path`, so `path` never holds a
    partial file.

    Args:
        model: A mixture fitted with `fit_em`.
        path: Destination file.

    Raises:
        NotFittedError: If `model` was never fitted.
    """
    model.check_fitted()
    payload: dict[str, Any] = {
        "format": FORMAT,
        "config": model.config(),
        "n_features": model.n_features,
        "n_outputs": model.n_outputs,
        "X": model.train_X,
        "Y": model.train_Y,
        "weights": model.train_weights,
        "state_dict": model.state_dict(),
    }
    target = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=target.parent)
    try:
        with os.fdopen(fd, "wb") as f:
            torch.save(payload, f)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, target)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def load(path: str | os.PathLike[str]) -> MixtureOfGPExperts:
    """Read a mixture written by `save`; it predicts exactly as the saved one did.

    Args:
        path: File written by `save`.

    Returns:
        The fitted mixture.

    Raises:
        InputError: If `path` is not a saved mixture of this format.
        OSError: If `path` cannot be read.
    """
    try:
        payload = torch.load(path, map_location="cpu", weights_only=True)
    except (RuntimeError, EOFError, ValueError, pickle.UnpicklingError) as err:
        raise InputError(f"cannot read a saved mixture from {os.fspath(path)!r}: {err}") from err
    if not isinstance(payload, dict) or payload.get("format") != FORMAT:
        raise InputError(f"{os.fspath(path)!r} is not a saved mixture of format {FORMAT!r}.")
    model = MixtureOfGPExperts(**payload["config"])
    model.build(payload["n_features"], payload["n_outputs"])
    model.condition(payload["X"], payload["Y"], payload["weights"])
    model.load_state_dict(payload["state_dict"])
    return model
