"""Saving and loading a fitted push model as one file.

Every model class has its own format tag (``FORMATS``), stored in the file; `load` reads the
tag and rebuilds a model of that class. Files are ``torch.save`` archives of builtins and
tensors only, read back with ``weights_only=True``.
"""

from __future__ import annotations

import io
import os
from collections.abc import Callable
from pathlib import Path
from typing import Any

import torch

from probaff._io import atomic_write_bytes
from probaff.errors import InputError
from probaff.models.clustered import ClusteredGPModel
from probaff.models.gp_expert import GPExpert
from probaff.models.mixture import MixtureOfGPExperts
from probaff.models.transition import MonolithicTransitionModel, SkillTransitionModel
from probaff.models.vi import VariationalMixtureOfGPExperts

__all__ = ["FORMAT", "FORMATS", "SavableModel", "load", "save"]

SavableModel = (
    MixtureOfGPExperts
    | VariationalMixtureOfGPExperts
    | ClusteredGPModel
    | SkillTransitionModel
    | MonolithicTransitionModel
)
"""The model classes `save` and `load` handle."""

FORMAT = "probaff.models.MixtureOfGPExperts/1"
"""Identifier and version stored in every saved EM mixture."""

FORMATS: dict[type, str] = {
    MixtureOfGPExperts: FORMAT,
    VariationalMixtureOfGPExperts: "probaff.models.VariationalMixtureOfGPExperts/1",
    ClusteredGPModel: "probaff.models.ClusteredGPModel/1",
    SkillTransitionModel: "probaff.models.SkillTransitionModel/1",
    MonolithicTransitionModel: "probaff.models.MonolithicTransitionModel/1",
}
"""Format tag (identifier and version) of every model class `save` handles."""


# ----------------------------------------------------------------- payloads
def _dump_em(model: MixtureOfGPExperts) -> dict[str, Any]:
    return {
        "config": model.config(),
        "n_features": model.n_features,
        "n_outputs": model.n_outputs,
        "X": model.train_X,
        "Y": model.train_Y,
        "weights": model.train_weights,
        "state_dict": model.state_dict(),
    }


def _load_em(payload: dict[str, Any]) -> MixtureOfGPExperts:
    model = MixtureOfGPExperts(**payload["config"])
    model.build(payload["n_features"], payload["n_outputs"])
    model.condition(payload["X"], payload["Y"], payload["weights"])
    model.load_state_dict(payload["state_dict"])
    return model


def _dump_vi(model: VariationalMixtureOfGPExperts) -> dict[str, Any]:
    return {
        "config": model.config(),
        "n_features": model.n_features,
        "n_outputs": model.n_outputs,
        "n_inducing": model.inducing_size,
        "state_dict": model.state_dict(),
    }


def _load_vi(payload: dict[str, Any]) -> VariationalMixtureOfGPExperts:
    model = VariationalMixtureOfGPExperts(**payload["config"])
    model.build_empty(payload["n_features"], payload["n_outputs"], payload["n_inducing"])
    model.load_state_dict(payload["state_dict"])
    model.fitted = True
    model.eval()
    return model


def _dump_clustered(model: ClusteredGPModel) -> dict[str, Any]:
    assert model.labels_ is not None
    return {
        "config": model.config(),
        "X": model.train_X,
        "Y": model.train_Y,
        "labels": torch.as_tensor(model.labels_, dtype=torch.int64),
        "state_dict": [e.state_dict() for e in model.experts],
    }


def _load_clustered(payload: dict[str, Any]) -> ClusteredGPModel:
    model = ClusteredGPModel(**payload["config"])
    x, y, labels = payload["X"], payload["Y"], payload["labels"]
    experts = []
    for k, state in zip(labels.unique().tolist(), payload["state_dict"], strict=True):
        rows = labels == k
        expert = GPExpert(x.shape[1], y.shape[1], **model.expert_kwargs)
        expert.condition(x[rows], y[rows])
        expert.load_state_dict(state)
        experts.append(expert)
    model.experts = experts
    model.fit_gate(x, y, labels.numpy())
    return model


def _dump_skill(model: SkillTransitionModel) -> dict[str, Any]:
    return {
        "config": model.config(),
        "sizes": [model.n_features, model.n_outputs, model.n_reaction],
        "X": model.train_X,
        "Y": model.train_Y,
        "R": model.train_R,
        "weights": model.component_weights(),
        "state_dict": model.state_dict(),
    }


def _load_skill(payload: dict[str, Any]) -> SkillTransitionModel:
    model = SkillTransitionModel(**payload["config"])
    model.build(*payload["sizes"])
    model.condition(payload["X"], payload["Y"], payload["R"], payload["weights"])
    model.load_state_dict(payload["state_dict"])
    return model


def _dump_monolithic(model: MonolithicTransitionModel) -> dict[str, Any]:
    return {
        "config": model.config(),
        "sizes": [model.n_features, model.n_outputs],
        "X": model.train_X,
        "Y": model.train_Y,
        "state_dict": model.state_dict(),
    }


def _load_monolithic(payload: dict[str, Any]) -> MonolithicTransitionModel:
    model = MonolithicTransitionModel(**payload["config"])
    model.build(*payload["sizes"])
    model.condition(payload["X"], payload["Y"])
    model.load_state_dict(payload["state_dict"])
    return model


_CODECS: dict[
    str, tuple[Callable[[Any], dict[str, Any]], Callable[[dict[str, Any]], Any], tuple[str, ...]]
] = {
    FORMATS[MixtureOfGPExperts]: (
        _dump_em,
        _load_em,
        ("config", "n_features", "n_outputs", "X", "Y", "weights", "state_dict"),
    ),
    FORMATS[VariationalMixtureOfGPExperts]: (
        _dump_vi,
        _load_vi,
        ("config", "n_features", "n_outputs", "n_inducing", "state_dict"),
    ),
    FORMATS[ClusteredGPModel]: (
        _dump_clustered,
        _load_clustered,
        ("config", "X", "Y", "labels", "state_dict"),
    ),
    FORMATS[SkillTransitionModel]: (
        _dump_skill,
        _load_skill,
        ("config", "sizes", "X", "Y", "R", "weights", "state_dict"),
    ),
    FORMATS[MonolithicTransitionModel]: (
        _dump_monolithic,
        _load_monolithic,
        ("config", "sizes", "X", "Y", "state_dict"),
    ),
}


def _format_of(model: Any) -> str:
    for cls, tag in FORMATS.items():
        if isinstance(model, cls):
            return tag
    known = ", ".join(sorted(c.__name__ for c in FORMATS))
    raise InputError(f"cannot save a {type(model).__name__}; save handles {known}.")


# --------------------------------------------------------------- save / load
def save(model: SavableModel, path: str | os.PathLike[str]) -> None:
    """Write a fitted model to `path` atomically.

    The file (``torch.save`` of a dict) holds the model's format tag (`FORMATS`), its
    constructor configuration, what its fit needs to be restored (for the exact models,
    the training data, with the experts' sample weights) and its state dict(s); a
    `VariationalMixtureOfGPExperts`'s state dict holds the parameters Pyro trained. It is
    written through `probaff._io.atomic_write_bytes`, so `path` never holds a partial file.

    Args:
        model: A `MixtureOfGPExperts` fitted with `fit_em`, a
            `VariationalMixtureOfGPExperts` fitted with `fit_svi`, a fitted
            `ClusteredGPModel`, or a `SkillTransitionModel` or `MonolithicTransitionModel`
            fitted with `fit_transition`.
        path: Destination file.

    Raises:
        NotFittedError: If `model` was never fitted.
        InputError: If `model` is of a class `save` does not handle.
    """
    tag = _format_of(model)
    model.check_fitted()
    dump = _CODECS[tag][0]
    buffer = io.BytesIO()
    torch.save({"format": tag, **dump(model)}, buffer)
    atomic_write_bytes(path, buffer.getvalue())


def load(path: str | os.PathLike[str]) -> Any:
    """Read a model written by `save`; it predicts exactly as the saved one did.

    Args:
        path: File written by `save`.

    Returns:
        The fitted model, of the class its format tag names.

    Raises:
        InputError: If `path` is not a complete saved model of a known format (a truncated
            or corrupt file, an unknown tag or a missing entry).
        OSError: If `path` cannot be read (e.g. it does not exist).
    """
    name = os.fspath(path)
    data = Path(path).read_bytes()
    try:
        payload = torch.load(io.BytesIO(data), map_location="cpu", weights_only=True)
    except Exception as err:  # truncated or foreign files fail in many ways
        raise InputError(f"cannot read a saved mixture from {name!r}: {err}") from err
    tag = payload.get("format") if isinstance(payload, dict) else None
    if not isinstance(tag, str) or tag not in _CODECS:
        known = ", ".join(repr(t) for t in sorted(_CODECS))
        raise InputError(f"{name!r} is not a saved mixture or model of a known format ({known}).")
    _, restore, required = _CODECS[tag]
    missing = [k for k in required if k not in payload]
    if missing:
        raise InputError(f"{name!r} is an incomplete saved model ({tag}): it lacks {missing}.")
    try:
        return restore(payload)
    except (KeyError, TypeError, ValueError, RuntimeError, IndexError, AttributeError) as err:
        raise InputError(f"{name!r} holds a corrupt saved model ({tag}): {err}") from err
