"""Fingerprints of study configurations: which stored results a resumed run may reuse."""

from __future__ import annotations

import dataclasses
import hashlib
import json
from collections.abc import Iterable, Mapping
from typing import Any

__all__ = ["config_fingerprint", "settings_fingerprint"]


def _plain(value: Any) -> Any:
    """`value` as JSON-able plain data (dataclasses, tuples and sets included)."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: _plain(getattr(value, f.name)) for f in dataclasses.fields(value)}
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, (set, frozenset)):
        return sorted(_plain(v) for v in value)
    if isinstance(value, (str, int, float, bool)) or value is None:
        return value
    return repr(value)


def settings_fingerprint(settings: Mapping[str, Any], *, version: int = 1, length: int = 10) -> str:
    """Short hash of named settings (plain values, dataclasses, mappings, sequences).

    Args:
        settings: Setting name -> value.
        version: Version of the code that computes the results.
        length: Number of hexadecimal characters returned.

    Returns:
        The first `length` characters of the SHA-256 of the canonical JSON of `settings`.
    """
    fields = {str(k): _plain(v) for k, v in settings.items()}
    text = json.dumps({"version": version, "fields": fields}, sort_keys=True)
    return hashlib.sha256(text.encode()).hexdigest()[:length]


def config_fingerprint(
    config: Any, *, exclude: Iterable[str] = (), version: int = 1, length: int = 10
) -> str:
    """Short hash of every field of a dataclass config except those named in `exclude`.

    A study config declares its run-only fields (output folder, workers, scheduler,
    progress bars: where and how a run happens, not what it computes) and passes them as
    `exclude`; every other field, nested option dataclasses included, shapes the results,
    so a stored result is reused only when all of them agree. A field added later changes
    every fingerprint, which is the safe default: results are refitted rather than mixed.

    Args:
        config: A dataclass instance.
        exclude: Names of top-level fields that do not change any result.
        version: Version of the code that computes the results; bump it when a change to
            the fitting code changes results.
        length: Number of hexadecimal characters returned.

    Returns:
        `settings_fingerprint` of the fields that are not excluded.

    Raises:
        TypeError: If `config` is not a dataclass instance.
    """
    if not dataclasses.is_dataclass(config) or isinstance(config, type):
        raise TypeError(f"config must be a dataclass instance, got {type(config).__name__}.")
    skip = set(exclude)
    fields = {f.name: getattr(config, f.name) for f in dataclasses.fields(config)}
    kept = {k: v for k, v in fields.items() if k not in skip}
    return settings_fingerprint(kept, version=version, length=length)
