"""Deterministic, sharded, resumable dataset generation of any registered kind, serial or on Dask.

A scene name picks its world kind and so its dataset kind (`probaff.data.kinds`): a tabletop
scene (``worlds/scenes/``) gives a push dataset, a side-view scene (``worlds/sideview_scenes/``)
a skill dataset of picks or places. `generate` makes either (or a kind registered later);
`generate_skills` is `generate` restricted to skill datasets. Every kind shares the sharding,
seeding, resumption and Dask machinery here.

Shard ``i`` of a dataset with seed ``s`` is simulated from ``SeedSequence(s, spawn_key=(i,))``
alone (the kind's ``make_shard`` spawns its streams from it), so a serial run, a local Dask
cluster and a remote scheduler all produce the same bytes. Workers return arrays; only the
calling process writes files, so a remote cluster needs no shared file system.
"""

from __future__ import annotations

import hashlib
import os
from collections.abc import Hashable
from pathlib import Path
from typing import Any, cast

import numpy as np

from probaff._checks import check_count, check_output_dir
from probaff._dask import check_batch, run_batch
from probaff.data.config import GenerateConfig
from probaff.data.kinds import DEFAULT_KIND, DatasetKind, dataset_kind
from probaff.data.skill_schema import SkillDataset
from probaff.data.store import (
    FORMAT_NAME,
    count_rows,
    load_any_dataset,
    manifest_kind,
    read_manifest,
    read_shard,
    shard_path,
    write_manifest,
    write_shard,
)
from probaff.errors import DatasetError, InputError
from probaff.sim.registry import kind_of_scene

__all__ = ["generate", "generate_skills", "make_shard"]


def make_shard(config: GenerateConfig, index: int) -> dict[str, np.ndarray]:
    """Simulate shard `index` of a dataset; depends only on the config and `index`.

    The scene's dataset kind makes the arrays (`probaff.data.kinds`): a tabletop scene gives
    push arrays (`probaff.data.schema`), a side-view scene skill arrays
    (`probaff.data.skill_schema`).

    Args:
        config: The dataset's generation config.
        index: Shard number.

    Returns:
        The shard's arrays.
    """
    index = check_count("index", index, minimum=0)
    seeds = np.random.SeedSequence(config.seed, spawn_key=(index,))
    return dataset_kind(config.kind).make_shard(config, config.shard_rows(index), seeds)


def _new_manifest(kind: DatasetKind, config: GenerateConfig) -> dict[str, Any]:
    """The manifest of a new dataset, loading (and so validating) its scene first."""
    entries = kind.manifest(config)
    want = {"schema_version", "object_names", "meta"}
    if set(entries) != want:
        raise InputError(
            f"the manifest entries of dataset kind {kind.name!r} must be {sorted(want)}, got "
            f"{sorted(entries)}."
        )
    named = {} if kind.name == DEFAULT_KIND else {"kind": kind.name}
    return {"format": FORMAT_NAME, **named, "plan": kind.plan(config), **entries, "shards": {}}


def _prepare(out: Path, config: GenerateConfig, kind: DatasetKind, resume: bool) -> dict[str, Any]:
    if out.exists() and not resume:
        raise DatasetError(
            f"{out} already exists; pass --resume (resume=True) to continue it, or choose a "
            "new output path."
        )
    plan = kind.plan(config)
    if out.exists() and (out / "manifest.json").is_file():
        manifest = read_manifest(out)
        problem = kind.resume_problem(manifest["plan"], plan) if kind.resume_problem else None
        if problem:
            raise DatasetError(f"{out} {problem}")
        if manifest_kind(manifest) != kind.name:
            raise DatasetError(
                f"{out} is a {manifest_kind(manifest)} dataset, but scene {config.scene!r} makes "
                f"{kind.name} datasets; choose a new output path."
            )
        if manifest["plan"] != plan:
            raise DatasetError(
                f"{out} was started with {manifest['plan']}, not {plan}; resume it "
                "with the same options or choose a new output path."
            )
        return manifest
    if out.exists() and any(out.iterdir()):
        raise DatasetError(f"{out} exists and is not a probaff dataset; choose a new path.")
    manifest = _new_manifest(kind, config)
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise DatasetError(
            f"cannot create the dataset folder {out} ({exc.strerror or exc}); choose an output "
            "path (--out) in a folder you may write to."
        ) from exc
    write_manifest(out, manifest)
    return manifest


def _adopt_orphans(out: Path, config: GenerateConfig, manifest: dict[str, Any]) -> None:
    """Reconcile the shard files with the manifest before a (resumed) run.

    Forgets listed shards whose file is missing, deletes and forgets those that fail their
    checksum (both are then computed again, to the same bytes), registers complete shard
    files written just before a crash, and drops temporaries.
    """
    for key, entry in list(manifest["shards"].items()):
        path = shard_path(out, int(key))
        if not path.is_file():
            del manifest["shards"][key]
        elif hashlib.sha256(path.read_bytes()).hexdigest() != entry.get("sha256"):
            path.unlink()
            del manifest["shards"][key]
    shards_dir = out / "shards"
    if not shards_dir.is_dir():
        write_manifest(out, manifest)
        return
    for tmp in shards_dir.glob(".*.tmp-*"):
        tmp.unlink()
    for i in range(config.n_shards):
        key = f"{i:05d}"
        if key in manifest["shards"] or not shard_path(out, i).is_file():
            continue
        try:
            arrays = read_shard(out, i)
        except DatasetError:
            shard_path(out, i).unlink()
            continue
        if count_rows(arrays) == config.shard_rows(i):
            digest = hashlib.sha256(shard_path(out, i).read_bytes()).hexdigest()
            manifest["shards"][key] = {"rows": config.shard_rows(i), "sha256": digest}
        else:
            shard_path(out, i).unlink()
    write_manifest(out, manifest)


def _run(
    config: GenerateConfig,
    out: str | os.PathLike[str],
    kind: str | None,
    workers: int | None,
    scheduler: str | None,
    resume: bool,
    progress: bool,
) -> Path:
    """Generate (or finish) a dataset on disk, of `kind` if given; returns its folder."""
    config = config.validate()
    if kind is not None and config.kind != kind:
        world = kind_of_scene(config.scene)
        raise InputError(
            f"scene {config.scene!r} is a {world.label} scene, which makes {config.kind} "
            "datasets; generate it with probaff.data.generate (or `probaff generate`)."
        )
    workers, scheduler = check_batch(workers, scheduler)
    path = check_output_dir("out", out)
    data_kind = dataset_kind(config.kind)
    manifest = _prepare(path, config, data_kind, resume)
    _adopt_orphans(path, config, manifest)
    todo = [i for i in range(config.n_shards) if f"{i:05d}" not in manifest["shards"]]

    def store(i: Hashable, arrays: dict[str, np.ndarray]) -> None:
        i = cast(int, i)
        digest = write_shard(path, i, arrays)
        manifest["shards"][f"{i:05d}"] = {"rows": config.shard_rows(i), "sha256": digest}
        write_manifest(path, manifest)

    run_batch(
        make_shard,
        [(i, (config, i)) for i in todo],
        store,
        workers=workers,
        scheduler=scheduler,
        progress=progress,
        total=config.n,
        done=config.n - sum(config.shard_rows(i) for i in todo),
        size=lambda i: config.shard_rows(cast(int, i)),
        unit=data_kind.unit,
        desc=f"generate {config.scene}",
    )
    return path


def generate(
    config: GenerateConfig,
    out: str | os.PathLike[str],
    *,
    workers: int | None = 0,
    scheduler: str | None = None,
    resume: bool = False,
    progress: bool = True,
    kind: str | None = None,
) -> Any:
    """Generate (or finish) a dataset of the kind its scene makes on disk, and return it.

    A scene of a world kind that makes no dataset (the warehouse, the office) is refused.

    Args:
        config: What to generate.
        out: Dataset folder to create.
        workers: 0 runs serially in this process; ``None`` or K > 0 starts a local Dask
            cluster of K single-threaded worker processes (``None``: one per core).
        scheduler: Address of an existing Dask scheduler; overrides `workers`.
        resume: Continue an existing folder made with the same config.
        progress: Show a tqdm progress bar.
        kind: The dataset kind the scene must make (e.g. ``"skill"``); ``None`` takes any.

    Returns:
        The complete dataset, loaded from disk: a `PushDataset` for a tabletop scene, a
        `SkillDataset` for a side-view one, the registered kind's dataset for another.

    Raises:
        DatasetError: If `out` exists without `resume`, belongs to another config (another
            pose noise included), or cannot be written.
        InputError: For a bad config or `workers`, an unknown scene, a scene of another `kind`,
            or an `out` that is a file, lies under a file or in a folder that is not writable.
        ConfigError: For a malformed scene template or an unknown object, or (skills) a
            template whose reachable draws are too rare.
    """
    return load_any_dataset(_run(config, out, kind, workers, scheduler, resume, progress))


def generate_skills(
    config: GenerateConfig, out: str | os.PathLike[str], **options: Any
) -> SkillDataset:
    """Generate (or finish) a side-view skill dataset on disk and return it.

    `generate` for side-view scenes only, with the same keyword options (``workers``,
    ``scheduler``, ``resume``, ``progress``). Sampled scenes the arm cannot reach are dropped
    and replaced by further draws from the shard's generator, so every shard holds exactly
    its row count.

    Args:
        config: What to generate; its scene is a side-view scene.
        out: Dataset folder to create.
        **options: The keyword options of `generate`.

    Returns:
        The complete dataset, loaded from disk.

    Raises:
        DatasetError: If `out` exists without `resume`, belongs to another config, or cannot
            be written.
        InputError: For a bad config or `workers`, an unknown scene, a tabletop scene (use
            `generate`), or an `out` that is a file, lies under a file or in a folder that is
            not writable.
        ConfigError: For a malformed scene template, or one whose reachable draws are too
            rare.
    """
    ds: SkillDataset = generate(config, out, kind="skill", **options)
    return ds
