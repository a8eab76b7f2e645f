"""Saving and loading a fitted push model as one file.

Every registered model kind with a codec (`probaff.models.registry.Codec`: its format tag,
``dump`` and ``restore``) can be saved; the tag is stored in the file, and
`load` reads it and rebuilds a model of that kind. Files are ``torch.save`` archives of builtins and
tensors only, read back with ``weights_only=True``.

A file holds ``{"format": TAG, "sha256": HEX, "payload": BYTES}``: ``BYTES`` (a uint8 tensor)
is the ``torch.save`` archive of the model's payload dict (its own ``"format"`` tag, its
configuration, training data and state dicts) and ``HEX`` its SHA-256, which `load` checks
before it reads the payload, since torch's zip reader does not check the archive's CRCs: a
damaged byte would otherwise change the loaded model's predictions silently. Files written
before the hash existed are the payload archive itself; `load` still reads them, with a
warning that they cannot be checked.
"""

from __future__ import annotations

import hashlib
import io
import os
import pickle
import warnings
from collections.abc import Iterator, Mapping
from pathlib import Path
from typing import Any

import numpy as np
import torch

from probaff._checks import check_output_file
from probaff._io import atomic_write_bytes
from probaff.errors import InputError, ProbaffError
from probaff.models.mixture.em import FORMAT
from probaff.models.registry import Codec, model_kind, model_kinds

__all__ = ["FORMAT", "FORMATS", "load", "save"]


class _FormatTable(Mapping[type, str]):
    """The registry as ``model class -> format tag``, for every kind that can be saved."""

    def _table(self) -> dict[type, str]:
        return {
            k.model_class: k.codec.format
            for k in model_kinds().values()
            if k.model_class is not None and k.codec is not None
        }

    def __getitem__(self, cls: type) -> str:
        return self._table()[cls]

    def __iter__(self) -> Iterator[type]:
        return iter(self._table())

    def __len__(self) -> int:
        return len(self._table())

    def __repr__(self) -> str:
        return repr(self._table())


FORMATS: Mapping[type, str] = _FormatTable()
"""Format tag (identifier and version) of every model class `save` handles: a live view of
the model kinds registered with a format (`probaff.models.registry`)."""


def _codec_of(model: Any) -> Codec:
    """The codec of the registered kind of `model`."""
    try:
        codec = model_kind(model).codec
    except InputError:
        codec = None
    if codec is None:
        known = ", ".join(sorted(c.__name__ for c in FORMATS))
        raise InputError(f"cannot save a {type(model).__name__}; save handles {known}.")
    return codec


def _codec_of_format(tag: Any) -> Codec | None:
    for kind in model_kinds().values():
        if kind.codec is not None and kind.codec.format == tag:
            return kind.codec
    return None


# --------------------------------------------------------------- save / load
_FIX = "re-save the model from the fitted original, or re-fit it"


def save(model: Any, path: str | os.PathLike[str]) -> None:
    """Write a fitted model to `path` atomically.

    The file (``torch.save`` of a dict) holds the model's format tag (`FORMATS`) and the
    ``torch.save`` archive of its payload with the payload's SHA-256 (see the module
    docstring): its constructor configuration, what its fit needs to be restored (for the
    exact models, the training data, with the experts' sample weights) and its state dict(s);
    a `VariationalMixtureOfGPExperts`'s state dict holds the parameters Pyro trained. It is
    written through `probaff._io.atomic_write_bytes`, so `path` never holds a partial file;
    missing parent folders are created.

    Args:
        model: A fitted model of a registered kind with a format (`FORMATS`): a
            `MixtureOfGPExperts` fitted with `fit_em`, a `VariationalMixtureOfGPExperts`
            fitted with `fit_svi`, a fitted `ClusteredGPModel`, a `SkillTransitionModel` or
            `MonolithicTransitionModel` fitted with `fit_transition`, or a model of a kind
            added with `register_model_kind`.
        path: Destination file.

    Raises:
        NotFittedError: If `model` was never fitted.
        InputError: If `model` is of a class `save` does not handle, or `path` is a folder,
            lies under a regular file, or cannot be written.
    """
    codec = _codec_of(model)
    model.check_fitted()
    target = check_output_file("path", path)
    tag, dump = codec.format, codec.dump
    inner = io.BytesIO()
    torch.save({"format": tag, **dump(model)}, inner)
    payload = inner.getvalue()
    outer = io.BytesIO()
    torch.save(
        {
            "format": tag,
            "sha256": hashlib.sha256(payload).hexdigest(),
            "payload": torch.from_numpy(np.frombuffer(payload, dtype=np.uint8).copy()),
        },
        outer,
    )
    try:
        atomic_write_bytes(target, outer.getvalue())
    except OSError as err:
        raise InputError(
            f"cannot write the model to {os.fspath(target)!r} ({err.strerror or err}); choose "
            "a path in a folder you may write to, with free space."
        ) from err


def _read_bytes(path: str | os.PathLike[str]) -> tuple[str, bytes]:
    """The name of `path`, for messages, and its content.

    Raises:
        InputError: If `path` is not a path, does not exist, is a folder or cannot be read.
    """
    try:
        name = os.fspath(path)
    except TypeError:
        raise InputError(
            f"path must be the path of a file written by probaff.models.save, got {path!r}."
        ) from None
    try:
        return str(name), Path(name).read_bytes()
    except FileNotFoundError:
        raise InputError(
            f"there is no saved model at {name!r} (no such file); give the path of a file "
            "written by probaff.models.save."
        ) from None
    except IsADirectoryError:
        raise InputError(
            f"{name!r} is a folder, not a saved model; give the path of a file written by "
            "probaff.models.save."
        ) from None
    except OSError as err:
        raise InputError(
            f"cannot read a saved model from {name!r} ({err.strerror or err}); check that the "
            "file exists and that you may read it."
        ) from err


def _unpickle(name: str, data: bytes) -> Any:
    """``torch.load`` of `data` with ``weights_only=True``, on the CPU.

    Raises:
        InputError: If `data` is not a complete torch archive of builtins and tensors.
    """
    try:
        return torch.load(io.BytesIO(data), map_location="cpu", weights_only=True)
    except Exception as err:  # truncated or foreign files fail in many ways
        if isinstance(err, pickle.UnpicklingError):  # torch's text suggests unsafe loading
            why = "not a torch archive of builtins and tensors"
        else:
            lines = str(err).strip().splitlines() or [type(err).__name__]
            why = lines[0].split(". ")[0][:200]  # its first sentence
        raise InputError(
            f"cannot read a saved model from {name!r}: it is truncated, corrupted or not a file "
            f"written by probaff.models.save ({why}); {_FIX}."
        ) from err


def _verified_payload(name: str, container: dict[str, Any]) -> Any:
    """The payload of a hashed file, after checking it against its SHA-256.

    Raises:
        InputError: If the hash or payload entry is malformed, or the payload does not match.
    """
    digest, blob = container.get("sha256"), container.get("payload")
    if (
        not isinstance(digest, str)
        or not isinstance(blob, torch.Tensor)
        or blob.dtype != torch.uint8
        or blob.dim() != 1
    ):
        raise InputError(
            f"{name!r} is an incomplete saved model: its 'sha256' or 'payload' entry is missing "
            f"or malformed; {_FIX}."
        )
    data = blob.cpu().numpy().tobytes()
    if hashlib.sha256(data).hexdigest() != digest:
        raise InputError(
            f"{name!r} is corrupted: its content does not match the SHA-256 hash stored in it, "
            f"so it was damaged or modified after it was saved; {_FIX}."
        )
    payload = _unpickle(name, data)
    if not isinstance(payload, dict) or payload.get("format") != container.get("format"):
        raise InputError(
            f"{name!r} is corrupted: its payload's format tag does not match the file's; {_FIX}."
        )
    return payload


def load(path: str | os.PathLike[str]) -> Any:
    """Read a model written by `save`; it predicts exactly as the saved one did.

    The payload is checked against the SHA-256 stored with it before it is read. A file
    written before the hash existed loads with a warning (its damage cannot be detected).

    Args:
        path: File written by `save`.

    Returns:
        The fitted model, of the class its format tag names.

    Raises:
        InputError: If `path` does not exist, is a folder or cannot be read, or is not a
            complete, intact saved model of a known format (a truncated or corrupted file,
            one whose content fails its hash, another kind of file, an unknown tag, a
            missing entry, or entries that contradict one another, such as stored sizes
            that disagree with the stored data).
    """
    name, data = _read_bytes(path)
    payload = _unpickle(name, data)
    hashed = isinstance(payload, dict) and ("sha256" in payload or "payload" in payload)
    if hashed:
        payload = _verified_payload(name, payload)
    tag = payload.get("format") if isinstance(payload, dict) else None
    codec = _codec_of_format(tag) if isinstance(tag, str) else None
    if codec is None:
        known = ", ".join(repr(t) for t in sorted(FORMATS.values()))
        raise InputError(
            f"{name!r} is not a saved mixture or model of a known format ({known}); give the "
            "path of a file written by probaff.models.save."
        )
    if not hashed:
        warnings.warn(
            f"{name!r} carries no content hash (it was saved by an earlier probaff), so damage "
            "to it cannot be detected; re-save it with probaff.models.save to add one.",
            UserWarning,
            stacklevel=2,
        )
    missing = [k for k in codec.required if k not in payload]
    if missing:
        raise InputError(
            f"{name!r} is an incomplete saved model ({tag}): it lacks {missing}; {_FIX}."
        )
    try:
        return codec.restore(payload)
    except ProbaffError as err:  # its hash held, so its entries contradict one another
        raise InputError(
            f"{name!r} is an inconsistent saved model ({tag}): its stored sizes or settings "
            f"disagree with its data ({str(err).rstrip('.')}); {_FIX}."
        ) from err
    except Exception as err:  # entries of the wrong type or shape fail in many ways
        raise InputError(f"{name!r} holds a corrupt saved model ({tag}): {err}; {_FIX}.") from err
