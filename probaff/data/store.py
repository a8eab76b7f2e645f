"""The on-disk dataset format: a folder of a JSON manifest and checksummed shards.

Layout of a push dataset (schema versions 1 and 2)::

    PATH/
      manifest.json        {"format": "probaff-push-dataset", "schema_version": 1 or 2,
                            "plan": {scene, n, seed, shard_size, ...[, pose_noise]},
                            "object_names": [...], "meta": {...},
                            "shards": {"00000": {"rows": R, "sha256": HEX}, ...}}
      shards/00000.npz     rows [0, shard_size) as a NumPy .npz archive, one .npy per array
      shards/00001.npz     ...

Shard ``i`` holds pushes ``i * shard_size`` to ``(i + 1) * shard_size - 1`` and is produced from
the dataset seed and ``i`` alone, so it is identical however and wherever it is computed. Every
file is written to a temporary name, flushed and renamed into place, so a run killed at any
moment leaves only complete files; the manifest is rewritten (atomically) after each shard. The
archives carry fixed timestamps, so the same seed gives byte-identical files.

Version 2 adds measurement noise on the recorded poses: ``plan.pose_noise`` holds its
parameters, ``{"position_std": metres, "yaw_std": radians}``, and each shard then also holds the
exact ``true_*`` arrays (see `probaff.data.schema`). A dataset without pose noise has no
``pose_noise`` key and is written as version 1, exactly as before version 2 existed.

Version 3 adds a second kind of dataset, side-view skills (`probaff.data.skill_schema`). Its
manifest has the same layout plus ``"kind": "skill"``, ``"schema_version": 3`` and the plan
``{scene, n, seed, shard_size, trajectories, record_rate}``; its shards hold the skill arrays.
A manifest without ``kind`` is a push dataset, so push datasets are written exactly as before;
``format`` stays ``probaff-push-dataset`` for both kinds, so an earlier release refuses a skill
dataset by its version number. `load_dataset` reads push datasets and `load_skill_dataset`
skill datasets; each refuses the other kind, naming the function to use.

Version 4 (push) and version 5 (skill) are observation-only datasets: what a robot logged,
without what only a simulator knows (`probaff.data.schema`, `probaff.data.skill_schema`). Their
layout is the same; their shards may lack the simulator's arrays, and a push dataset's may hold
``object_size``. `probaff generate` never writes them; `save_dataset` writes any in-memory
dataset (`probaff.data.observations.observation_dataset`, `probaff.data.hdf5.import_hdf5`)
under the version its arrays call for, so a simulated dataset keeps versions 1 to 3.

The kinds and the versions this probaff reads are those registered in `probaff.data.kinds`
(`probaff.data.kinds.readable_versions` and `probaff.data.kinds.observation_versions`);
`load_any_dataset` reads a dataset of any of them into the kind's dataset class.
"""

from __future__ import annotations

import hashlib
import io
import json
import os
import shutil
import warnings
import zipfile
from pathlib import Path
from typing import Any

import numpy as np

from probaff._checks import check_count, check_output_dir
from probaff._io import atomic_write_bytes
from probaff.data.dataset import ArrayDataset
from probaff.data.kinds import (
    DEFAULT_KIND,
    dataset_kind,
    kind_of_dataset,
    observation_versions,
    readable_versions,
)
from probaff.data.schema import PushDataset
from probaff.data.skill_schema import SkillDataset
from probaff.errors import DatasetError

__all__ = [
    "FORMAT_NAME",
    "check_new_dataset_folder",
    "count_rows",
    "load_any_dataset",
    "load_dataset",
    "load_skill_dataset",
    "manifest_kind",
    "read_manifest",
    "read_shard",
    "save_dataset",
    "shard_path",
    "write_manifest",
    "write_shard",
]

FORMAT_NAME = "probaff-push-dataset"
_EPOCH = (1980, 1, 1, 0, 0, 0)


def _readable() -> str:
    """What this probaff reads, in words, for error messages."""
    simulated = " and ".join(
        f"{kind} datasets of schema version{'s' if len(v) > 1 else ''} "
        + ", ".join(str(x) for x in v)
        for kind, v in readable_versions().items()
    )
    observed = " and ".join(
        f"{kind} datasets of schema version {v}" for kind, v in observation_versions().items()
    )
    return f"{simulated}; observation-only {observed}" if observed else simulated


def manifest_kind(manifest: dict[str, Any]) -> str:
    """The kind of dataset a manifest describes: its ``kind``, `DEFAULT_KIND` when it has none."""
    return str(manifest.get("kind", DEFAULT_KIND))


def count_rows(arrays: dict[str, np.ndarray]) -> int:
    """Rows of a shard's arrays (of either kind): the length of ``object_ids``, 0 without it."""
    return len(arrays.get("object_ids", ()))


def shard_path(root: Path, index: int) -> Path:
    """Path of shard `index` under dataset folder `root`."""
    return root / "shards" / f"{index:05d}.npz"


def _npz_bytes(arrays: dict[str, np.ndarray]) -> bytes:
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", compression=zipfile.ZIP_DEFLATED) as zf:
        for name in sorted(arrays):
            arr = np.ascontiguousarray(arrays[name])
            member = io.BytesIO()
            np.lib.format.write_array(member, arr, allow_pickle=False)
            info = zipfile.ZipInfo(f"{name}.npy", date_time=_EPOCH)
            info.compress_type = zipfile.ZIP_DEFLATED
            info.external_attr = 0o644 << 16
            zf.writestr(info, member.getvalue())
    return buf.getvalue()


def write_shard(root: Path, index: int, arrays: dict[str, np.ndarray]) -> str:
    """Write one shard atomically.

    Args:
        root: Dataset folder.
        index: Shard number.
        arrays: Named arrays with equal row counts.

    Returns:
        The SHA-256 hex digest of the written file.

    Raises:
        DatasetError: If the file cannot be written.
    """
    data = _npz_bytes(arrays)
    _write(shard_path(root, index), data)
    return hashlib.sha256(data).hexdigest()


def _write(path: Path, data: bytes) -> None:
    """`atomic_write_bytes`, reporting a failure as a `DatasetError` that names the path.

    Raises:
        DatasetError: For a file in the way, a full disk or a missing permission.
    """
    try:
        atomic_write_bytes(path, data)
    except DatasetError:
        raise
    except OSError as exc:
        raise DatasetError(
            f"cannot write {path} ({exc.strerror or exc}); choose a dataset folder (--out) you "
            "may write to, with free space, and no file in the way of its path."
        ) from exc


def read_shard(root: Path, index: int, sha256: str | None = None) -> dict[str, np.ndarray]:
    """Read one shard, checking its checksum when given.

    Raises:
        DatasetError: If the file is missing, not a file, truncated, corrupt or fails its
            checksum.
    """
    path = shard_path(root, index)
    try:
        data = path.read_bytes()
    except FileNotFoundError as exc:
        raise DatasetError(
            f"shard {path} is missing ({exc}); rerun `probaff generate ... --resume` to "
            "recreate it."
        ) from exc
    except OSError as exc:
        raise DatasetError(
            f"cannot read shard {path} ({exc.strerror or exc}); delete it and rerun "
            "`probaff generate ... --resume`."
        ) from exc
    if sha256 is not None and hashlib.sha256(data).hexdigest() != sha256:
        raise DatasetError(
            f"shard {path} does not match its checksum in manifest.json (truncated or "
            "modified); delete it and rerun `probaff generate ... --resume`."
        )
    try:
        with np.load(io.BytesIO(data), allow_pickle=False) as npz:
            return {k: npz[k] for k in npz.files}
    except Exception as exc:  # damaged archives fail in many ways (zlib.error, KeyError, ...)
        why = str(exc) or type(exc).__name__
        raise DatasetError(
            f"shard {path} is corrupt ({why}); delete it and rerun `probaff generate ... --resume`."
        ) from exc


def write_manifest(root: Path, manifest: dict[str, Any]) -> None:
    """Write ``manifest.json`` atomically (sorted keys, so equal content gives equal bytes).

    Raises:
        DatasetError: If the file cannot be written.
    """
    text = json.dumps(manifest, indent=1, sort_keys=True) + "\n"
    _write(root / "manifest.json", text.encode())


def read_manifest(root: Path) -> dict[str, Any]:
    """Read and check a dataset's manifest.

    Raises:
        DatasetError: If it is missing, not JSON, not a probaff dataset, of a kind or schema
            version this probaff does not read, or records pose noise under version 1.
    """
    path = Path(root) / "manifest.json"
    if not path.is_file():
        raise DatasetError(
            f"{root} is not a probaff dataset (no manifest.json); create one with "
            "`probaff generate`."
        )
    try:
        manifest = json.loads(path.read_text())
    except OSError as exc:
        raise DatasetError(
            f"cannot read {path} ({exc.strerror or exc}); check that you may read the dataset."
        ) from exc
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise DatasetError(
            f"{path} is truncated or not JSON ({exc}); regenerate the dataset with "
            "`probaff generate`."
        ) from exc
    if not isinstance(manifest, dict) or manifest.get("format") != FORMAT_NAME:
        raise DatasetError(f"{path} does not describe a {FORMAT_NAME}.")
    version = manifest.get("schema_version")
    kind = manifest.get("kind", DEFAULT_KIND)
    readable = readable_versions()
    if not isinstance(kind, str) or kind not in readable:
        raise DatasetError(
            f"{root} holds a dataset of kind {kind!r}, but this probaff reads {_readable()}; "
            "read it with the probaff release that wrote it, or regenerate it with "
            "`probaff generate`."
        )
    if version not in readable[kind] and version != observation_versions().get(kind):
        raise DatasetError(
            f"{root} is a {kind} dataset of schema version {version}, but this probaff reads "
            f"{_readable()}; read it with the probaff release that wrote it, or regenerate it "
            "with `probaff generate`."
        )
    problem = _layout_problem(manifest)
    if problem:
        raise DatasetError(
            f"{path} is malformed: {problem}; the manifest was edited or is corrupt: regenerate "
            "the dataset with `probaff generate`."
        )
    if version == 1 and manifest["plan"].get("pose_noise") is not None:
        raise DatasetError(
            f"{path} records pose noise under schema version 1, which has none; the manifest "
            "was edited or is corrupt: regenerate the dataset with `probaff generate`."
        )
    return manifest


def _is_count(value: Any, minimum: int) -> bool:
    return isinstance(value, int) and not isinstance(value, bool) and value >= minimum


def _layout_problem(manifest: dict[str, Any]) -> str | None:
    """What is wrong with the entries every reader of a manifest uses, or ``None``."""
    plan = manifest.get("plan")
    if not isinstance(plan, dict):
        return "its 'plan' is not a mapping"
    if not _is_count(plan.get("n"), 0) or not _is_count(plan.get("shard_size"), 1):
        return "its plan's 'n' and 'shard_size' must be integers (n >= 0, shard_size >= 1)"
    names = manifest.get("object_names")
    if not isinstance(names, list) or not all(isinstance(n, str) for n in names):
        return "its 'object_names' is not a list of names"
    if not isinstance(manifest.get("meta"), dict):
        return "its 'meta' is not a mapping"
    shards = manifest.get("shards", {})
    if not isinstance(shards, dict) or not all(
        isinstance(e, dict)
        and _is_count(e.get("rows"), 0)
        and isinstance(e.get("sha256") or "", str)
        for e in shards.values()
    ):
        return "its 'shards' must map shard numbers to {'rows': R, 'sha256': HEX}"
    return None


def _load_parts(root: Path, manifest: dict[str, Any], make: type[ArrayDataset]) -> list[Any]:
    """Every shard of a complete dataset, verified and wrapped by the dataset class `make`.

    Raises:
        DatasetError: If a shard is missing, corrupt or has another row count.
    """
    plan = manifest["plan"]
    n, size = int(plan["n"]), int(plan["shard_size"])
    n_shards = -(-n // size)
    shards = manifest.get("shards", {})
    missing = [i for i in range(n_shards) if f"{i:05d}" not in shards]
    if missing:
        raise DatasetError(
            f"{root} is incomplete: {len(missing)} of {n_shards} shards are missing (first: "
            f"{missing[0]}); finish it with `probaff generate ... --resume`."
        )
    unchecked = [i for i in range(n_shards) if shards[f"{i:05d}"].get("sha256") is None]
    if unchecked:
        warnings.warn(
            f"{len(unchecked)} of the {n_shards} shards of {root} have no checksum in "
            f"manifest.json (first: {unchecked[0]}), so damage to them may go unnoticed; rerun "
            "`probaff generate ... --resume` to recompute them with checksums.",
            UserWarning,
            stacklevel=4,
        )
    names, meta = list(manifest["object_names"]), manifest["meta"]
    observed = manifest["schema_version"] == make.OBSERVATION_VERSION
    parts = []
    for i in range(n_shards):
        entry = shards[f"{i:05d}"]
        arrays = read_shard(root, i, entry.get("sha256"))
        rows = count_rows(arrays)
        if rows != entry["rows"]:
            raise DatasetError(
                f"shard {shard_path(root, i)} has {rows} rows, manifest.json says "
                f"{entry['rows']}; delete it and rerun `probaff generate ... --resume`."
            )
        try:
            part = make(arrays, names, meta)
            if part.missing_simulated and not observed:
                raise DatasetError(
                    f"{part.KIND} dataset is missing arrays {part.missing_simulated}"
                )
            if part.observation_only and not observed:
                extra = sorted(set(part.OBSERVED_ONLY) & set(arrays))
                raise DatasetError(
                    f"{part.KIND} dataset holds observation-only arrays {extra} under schema "
                    f"version {manifest['schema_version']}"
                )
        except DatasetError as exc:
            raise DatasetError(
                f"shard {shard_path(root, i)} does not hold a valid dataset ({exc}); delete it "
                "and rerun `probaff generate ... --resume`."
            ) from exc
        parts.append(part)
    return parts


def _load(root: str | os.PathLike[str], kind: str | None) -> Any:
    """Load a complete dataset of `kind` (any registered kind for ``None``), shard by shard.

    Raises:
        DatasetError: If the dataset is incomplete, corrupt, of another version, of another
            kind than `kind` (naming the function that loads it), or its shards contradict
            its manifest's plan.
    """
    root = Path(root)
    manifest = read_manifest(root)
    found = manifest_kind(manifest)
    if kind is not None and found != kind:
        scene = manifest.get("plan", {}).get("scene")
        raise DatasetError(
            f"{root} is a {found} dataset (scene {scene!r}), not a {kind} dataset; load it with "
            f"probaff.data.{dataset_kind(found).loader}."
        )
    dtype = dataset_kind(found).dataset_type
    ds = dtype.concatenate(_load_parts(root, manifest, dtype))
    plan = manifest["plan"]
    problem = ds.check_plan(plan)
    if problem:
        raise DatasetError(
            f"the shards of {root} {problem}; regenerate the dataset with `probaff generate`."
        )
    ds.meta = {**manifest["meta"], **plan}
    return ds


def load_any_dataset(root: str | os.PathLike[str]) -> Any:
    """Load a complete dataset of any registered kind, verifying every shard.

    Args:
        root: Dataset folder written by `probaff generate`.

    Returns:
        The dataset of the kind its manifest names (a `PushDataset`, a `SkillDataset`, ...).

    Raises:
        DatasetError: If the dataset is incomplete, corrupt, of a kind or version this probaff
            does not read, or its shards contradict its manifest.
    """
    return _load(root, None)


def load_dataset(root: str | os.PathLike[str]) -> PushDataset:
    """Load a complete push dataset folder into memory, verifying every shard.

    Args:
        root: Dataset folder written by `probaff generate` for a push scene.

    Raises:
        DatasetError: If the dataset is incomplete, corrupt, of another version, or a skill
            dataset (read those with `load_skill_dataset`).
    """
    ds: PushDataset = _load(root, "push")
    return ds


def load_skill_dataset(root: str | os.PathLike[str]) -> SkillDataset:
    """Load a complete side-view skill dataset folder into memory, verifying every shard.

    Args:
        root: Dataset folder written by `probaff generate` for a side-view scene.

    Raises:
        DatasetError: If the dataset is incomplete, corrupt, of another version, or a push
            dataset (read those with `load_dataset`).
    """
    ds: SkillDataset = _load(root, "skill")
    return ds


def check_new_dataset_folder(out: Path) -> None:
    """Raise `DatasetError` unless `out` is absent or an empty folder; nothing is touched.

    Args:
        out: The folder a new dataset is to be written to.
    """
    if (out / "manifest.json").is_file():
        try:
            what = f"a {manifest_kind(read_manifest(out))} dataset"
        except DatasetError:
            what = "a dataset (its manifest.json)"
        raise DatasetError(
            f"{out} already holds {what}; nothing was written and it is left as it was. Choose "
            "a new folder, or delete that dataset first."
        )
    if out.is_dir() and any(out.iterdir()):
        raise DatasetError(
            f"{out} exists and is not empty (and not a probaff dataset); nothing was written. "
            "Choose a new folder."
        )


def _manifest_for(ds: ArrayDataset, shard_size: int, given: dict[str, Any] | None) -> dict:
    """The manifest `ds` is saved with, without shards: `given`'s, checked, or a new one."""
    kind = kind_of_dataset(ds)
    version = ds.schema_version or kind.schema_versions[-1]
    if given is None:
        plan = {
            "scene": ds.meta.get("scene"),
            "n": len(ds),
            "seed": ds.meta.get("seed"),
            "shard_size": shard_size,
            **ds.plan_entries(),
        }
        named = {} if kind.name == DEFAULT_KIND else {"kind": kind.name}
        return {
            "format": FORMAT_NAME,
            **named,
            "schema_version": version,
            "plan": plan,
            "object_names": list(ds.object_names),
            "meta": {k: v for k, v in ds.meta.items() if k not in plan},
        }
    manifest = {k: v for k, v in given.items() if k != "shards"}
    problem = _layout_problem({**manifest, "shards": {}})
    found = (manifest_kind(manifest), manifest.get("schema_version"))
    if problem is None and found != (kind.name, version):
        problem = (
            f"it describes a {found[0]} dataset of schema version {found[1]}, but the arrays "
            f"make a {kind.name} dataset of schema version {version}"
        )
    if problem is None and manifest["plan"]["n"] != len(ds):
        problem = f"its plan's n is {manifest['plan']['n']}, but the dataset has {len(ds)} rows"
    if problem is None and manifest["object_names"] != list(ds.object_names):
        problem = "its object_names differ from the dataset's"
    if problem is None:
        problem = ds.check_plan(manifest["plan"])
    if problem:
        raise DatasetError(f"the manifest given for the dataset does not fit it: {problem}.")
    return manifest


def save_dataset(
    ds: ArrayDataset,
    out: str | os.PathLike[str],
    *,
    shard_size: int = 64,
    manifest: dict[str, Any] | None = None,
) -> Path:
    """Write an in-memory dataset as a dataset folder (manifest and shards), atomically.

    The folder is written under a temporary name beside `out` and renamed into place, so a
    failure leaves `out` as it was. A dataset that lacks what only a simulator knows is
    written under its kind's observation-only schema version (4 for pushes, 5 for skills);
    a simulated one under the version `probaff generate` would give it.

    Args:
        ds: The dataset (a `PushDataset`, a `SkillDataset` or one of a registered kind).
        out: The folder to create; it must not exist, or be an empty folder.
        shard_size: Rows per shard of a new manifest, a positive integer.
        manifest: A manifest to keep (e.g. that of the dataset `ds` was exported from): its
            format, kind, schema version, plan, object names and meta are written as they are
            (its shards are recomputed; its plan's ``shard_size`` is used). ``None`` makes one:
            the plan records ``scene`` and ``seed`` from ``ds.meta``, ``n``, `shard_size` and
            the dataset's own entries (`ArrayDataset.plan_entries`); the meta is ``ds.meta``
            without the plan's keys.

    Returns:
        `out` as a `Path`.

    Raises:
        InputError: For an `out` that is a file, lies under one or in a folder that cannot
            be written, or a bad `shard_size`.
        DatasetError: If `out` already holds a dataset or other files (nothing is written),
            the `manifest` does not fit `ds`, or a file cannot be written.
    """
    path = check_output_dir("out", out)
    shard_size = check_count("shard_size", shard_size)
    check_new_dataset_folder(path)
    entries = _manifest_for(ds, shard_size, manifest)
    size = int(entries["plan"]["shard_size"])
    tmp = path.parent / f".{path.name}.tmp-{os.getpid()}"
    shutil.rmtree(tmp, ignore_errors=True)
    try:
        shards = {}
        for i, start in enumerate(range(0, len(ds), size)):
            rows = slice(start, start + size)
            digest = write_shard(tmp, i, {k: v[rows] for k, v in ds.arrays.items()})
            shards[f"{i:05d}"] = {"rows": len(ds.arrays[ds.ROWS][rows]), "sha256": digest}
        write_manifest(tmp, {**entries, "shards": shards})
        os.replace(tmp, path)
    except OSError as exc:
        shutil.rmtree(tmp, ignore_errors=True)
        if isinstance(exc, DatasetError):
            raise
        raise DatasetError(
            f"cannot write the dataset folder {path} ({exc.strerror or exc}); choose a folder "
            "you may write to, with free space, that nothing else writes to meanwhile."
        ) from exc
    return path
